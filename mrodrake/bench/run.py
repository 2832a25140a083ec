"""``mrodrake bench run [--scenario FILE]``: wall time, simulated time and real-time factor of a whole mission
(default case I, prefix + one suffix cycle; target ≤ 5 min wall on 2 cores), its integration steps, derivative
evaluations and point-world maps (built in the mission, by the map worker or reused; the builds in the
mission: median / max and share of the wall time), and per-primitive averages."""

from __future__ import annotations

import contextlib
import statistics
import sys
import time
from pathlib import Path

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "case_study_1.yaml"


@contextlib.contextmanager
def _recording_map_builds():
    """Collects the wall time of every point-world map built meanwhile (a list, filled in place)."""
    from mrodrake.control.pointworld import PointWorldMap

    seconds: list[float] = []
    build = PointWorldMap.__dict__["build"]

    def recorded(cls, *args, **kwargs):
        pw = build.__func__(cls, *args, **kwargs)
        seconds.append(pw.build_seconds)
        return pw

    PointWorldMap.build = classmethod(recorded)
    try:
        yield seconds
    finally:
        PointWorldMap.build = build


def run_mission_benchmark(stream=None, scenario_path=None, plan=None, suffix_cycles: int = 1,
                          seed: int = 0) -> dict:
    """Plan (STyLuS*, ``seed``) unless ``plan`` is given, simulate, print a table to ``stream``; returns the
    numbers as a dict."""
    from mrodrake.planning.plan import plan_scenario
    from mrodrake.scenario import load_scenario
    from mrodrake.systems.mission import Mission

    stream = stream or sys.stdout
    scenario = load_scenario(scenario_path or SCENARIO)
    t0 = time.perf_counter()
    if plan is None:
        plan = plan_scenario(scenario, "stylus", seed=seed)
    t_plan = time.perf_counter() - t0
    t1 = time.perf_counter()
    mission = Mission(scenario, plan, suffix_cycles=suffix_cycles, seed=seed)
    t_build = time.perf_counter() - t1
    with _recording_map_builds() as builds:
        log = mission.run()
    steps = mission.simulator.get_num_steps_taken()
    evaluations = mission.simulator.get_integrator().get_num_derivative_evaluations()
    map_wall = sum(builds)
    prim = log.primitive_events.copy()
    prim["kind"] = prim["action"].str.split().str[0]
    prim["sim_s"] = prim["t_end"] - prim["t_start"]
    rtf = log.sim_seconds / log.wall_seconds if log.wall_seconds > 0 else float("nan")
    rows = [("planning wall [s]", f"{t_plan:.2f}"), ("diagram build wall [s]", f"{t_build:.2f}"),
            ("mission wall [s]", f"{log.wall_seconds:.1f}"), ("simulated time [s]", f"{log.sim_seconds:.1f}"),
            ("real-time factor (sim/wall)", f"{rtf:.1f}"), ("integration steps", f"{steps}"),
            ("derivative evaluations", f"{evaluations}"),
            ("maps: built in the mission / by the map worker / reused",
             "{built} / {worker} / {cached}".format(**mission.sequencer.map_sources)),
            ("map builds in the mission: median / max [s]",
             f"{statistics.median(builds):.2f} / {max(builds):.2f}" if builds else "-"),
            ("map builds in the mission: share of its wall",
             f"{map_wall / log.wall_seconds:.0%}" if log.wall_seconds else "-"),
            ("plan steps", f"{log.steps_done}/{log.steps_total}"),
            ("primitives ok", f"{int(prim['ok'].sum())}/{len(prim)}"), ("outcome", "ok" if log.ok else log.message)]
    if scenario.name == "case_study_1":
        rows.append(("target: mission wall <= 300 s", "met" if log.ok and log.wall_seconds <= 300 else "NOT met"))
    print(f"mission benchmark: {scenario.name}, prefix + {suffix_cycles} suffix cycle(s)", file=stream)
    width = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"  {k:<{width}}  {v}", file=stream)
    per = prim.groupby("kind")["sim_s"].agg(["count", "mean", "max"])
    wall_share = log.wall_seconds / max(log.sim_seconds, 1e-9)
    print("  per primitive (simulated s; wall estimated by the mission's real-time factor):", file=stream)
    print(f"  {'kind':<10} {'count':>5} {'mean sim':>9} {'max sim':>9} {'mean wall':>9}", file=stream)
    for kind, r in per.iterrows():
        print(f"  {kind:<10} {int(r['count']):>5} {r['mean']:>9.1f} {r['max']:>9.1f} {r['mean'] * wall_share:>9.2f}",
              file=stream)
    return {"wall": log.wall_seconds, "sim": log.sim_seconds, "rtf": rtf, "steps": steps, "ok": log.ok,
            "derivative_evaluations": evaluations, "map_builds": list(builds),
            "map_sources": dict(mission.sequencer.map_sources),
            "primitives": len(prim), "per_kind": per.to_dict()}
