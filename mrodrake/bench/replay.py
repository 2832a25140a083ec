"""``mrodrake bench replay``: time the HTML replay writer (:func:`~mrodrake.viz.replay.write_replay`) on
synthetic missions of a scenario."""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

from mrodrake.scenario import load_scenario
from mrodrake.viz.replay import choose_speedup, synthetic_mission, write_replay

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "case_study_1.yaml"


def bench_replay(scenario_path=None, durations=(200.0, 1000.0, 3000.0), out_dir=None, seed: int = 0) -> list[dict]:
    """Time :func:`write_replay` on synthetic missions (case study I by default) and print a table:
    simulated seconds, speed-up, replay seconds, frames, write time, HTML size."""
    if scenario_path is None:
        scenario_path = SCENARIO
    scenario = load_scenario(scenario_path)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(out_dir) if out_dir is not None else Path(tmp)
        for duration in durations:
            traj, grasps = synthetic_mission(scenario, duration, seed=seed)
            start = time.perf_counter()
            html = write_replay(scenario, traj, out / f"replay_{duration:g}.html", grasps=grasps)
            wall = time.perf_counter() - start
            speedup = choose_speedup(duration)
            rows.append({"simulated_s": duration, "entities": len(scenario.robots) + len(scenario.objects),
                         "speedup": speedup, "replay_s": duration / speedup,
                         "frames": int(math.ceil(duration / speedup * 30 - 1e-9)) + 1,
                         "write_s": wall, "html_MB": html.stat().st_size / 1e6})
    print(f"{'simulated_s':>11} {'entities':>8} {'speedup':>7} {'replay_s':>8} {'frames':>6} {'write_s':>7} "
          f"{'html_MB':>7}")
    for r in rows:
        print(f"{r['simulated_s']:>11g} {r['entities']:>8d} {r['speedup']:>7g} {r['replay_s']:>8.1f} "
              f"{r['frames']:>6d} {r['write_s']:>7.2f} {r['html_MB']:>7.2f}")
    return rows
