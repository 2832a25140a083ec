"""``mrodrake bench control``: point-world map and adaptive-control simulation benchmark (case study I).

Prints the map construction time and panel count for the case-study office (free space of a robot for
its longest navigation, with the other entities present), the time per map + Jacobian (+ Hessians)
evaluation, and wall time vs simulated time for that navigation.  Targets: map built in <= 1 s, a 150 m
navigation simulated in <= 5 s wall.
"""

from __future__ import annotations

import itertools
import math
import sys
import time
from pathlib import Path

import numpy as np
import shapely

from mrodrake.control.pointworld import PointWorldMap
from mrodrake.scenario import load_scenario

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "case_study_1.yaml"


def _longest_pair(scenario) -> tuple[int, int]:
    """Ordered region pair with the largest centre distance (the case's longest navigation)."""
    c = np.array([g.center for g in scenario.regions])
    pairs = list(itertools.permutations(range(len(c)), 2))
    return max(pairs, key=lambda p: float(np.hypot(*(c[p[0]] - c[p[1]]))))


def longest_navigation(scenario_path: str | Path = SCENARIO):
    """(scenario, robot, src, dst, placed entities, goal spot name, other entities, free space) of the first
    robot's longest navigation, with the other entities placed as in the benchmark (seed 0)."""
    from mrodrake.control.freespace import entity_free_space
    from mrodrake.control.tasks import entity_layout

    sc = load_scenario(scenario_path)
    robot = sc.robots[0]
    src, dst = _longest_pair(sc)
    spot = f"{robot.name}@goal"
    placed = entity_layout(sc, {robot.name: src}, seed=0, reserve={dst: [(spot, robot.radius)]})
    others = [d for n, d in placed.items() if n not in (robot.name, spot)]
    free = entity_free_space(sc, robot.radius, placed[robot.name].center, placed[spot].center, src, dst, others)
    return sc, robot, src, dst, placed, spot, others, free


def run_control_benchmark(stream=None, repeats: int = 3, scenario_path: str | Path = SCENARIO) -> dict:
    """Run the benchmark, print a table to ``stream`` (default stdout) and return the numbers."""
    from mrodrake.control.tasks import MAP_OPTIONS
    from mrodrake.systems.transition import simulate_transition

    stream = stream or sys.stdout
    sc, robot, src, dst, placed, spot, others, free = longest_navigation(scenario_path)
    builds, cpus, pw = [], [], None
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        pw = PointWorldMap.build(free.polygon, **MAP_OPTIONS)
        builds.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    rng = np.random.default_rng(0)
    minx, miny, maxx, maxy = free.polygon.bounds
    pts = rng.uniform((minx, miny), (maxx, maxy), size=(4000, 2))
    pts = pts[shapely.contains_xy(free.polygon, pts[:, 0], pts[:, 1])][:300]
    t0 = time.perf_counter()
    for p in pts:
        pw.evaluate(p)
    t_eval = (time.perf_counter() - t0) / len(pts)
    t0 = time.perf_counter()
    for p in pts:
        pw(p)
        pw.jacobian(p)
    t_hj = (time.perf_counter() - t0) / len(pts)

    res = simulate_transition(sc, "navigate", robot.name, src_region=src, dst_region=dst, others=others,
                              start=placed[robot.name].center, goal=placed[spot].center, t_max=3000.0)
    xy = res.positions
    path = float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))
    out = {
        "panels": pw.n_panels,
        "holes": len(pw.hole_points),
        "map_build_s": min(builds),
        "map_build_cpu_s": min(cpus),
        "map_solves": pw.n_solves,
        "eval_us": 1e6 * t_eval,
        "value_jacobian_us": 1e6 * t_hj,
        "transition": f"{robot.name}: {sc.regions[src].name} -> {sc.regions[dst].name}",
        "reached": res.reached,
        "path_m": path,
        "sim_time_s": res.t_final,
        "wall_s": res.sim_seconds,
        "wall_incl_map_s": res.wall_seconds,
        "steps": res.steps,
        "implicit_s": res.implicit_seconds,
        "wall_per_150m_s": res.sim_seconds * 150.0 / path if path > 0 else math.nan,
    }
    print(f"control benchmark, {sc.name} ({Path(scenario_path).name})", file=stream)
    print(f"  free space of {robot.name} ({sc.regions[src].name} -> {sc.regions[dst].name}): "
          f"{out['holes']} holes, {out['panels']} panels", file=stream)
    print(f"  map build              {out['map_build_s'] * 1e3:9.1f} ms wall, "
          f"{out['map_build_cpu_s'] * 1e3:.1f} ms CPU, {out['map_solves']} solve(s) "
          f"(best of {repeats}, options {MAP_OPTIONS}; target <= 1000 ms)", file=stream)
    print(f"  H + J_H + Hessians     {out['eval_us']:9.1f} us per point", file=stream)
    print(f"  H and J_H (2 calls)    {out['value_jacobian_us']:9.1f} us per point", file=stream)
    print(f"  navigation {out['transition']}: reached={out['reached']}, path {path:.1f} m, "
          f"{out['sim_time_s']:.1f} s simulated, {out['steps']} steps "
          f"({out['implicit_s']:.1f} s simulated with the implicit integrator)", file=stream)
    print(f"  simulation wall        {out['wall_s']:9.2f} s ({out['wall_incl_map_s']:.2f} s with free space + map)",
          file=stream)
    print(f"  wall per 150 m         {out['wall_per_150m_s']:9.2f} s (target <= 5 s)", file=stream)
    return out


if __name__ == "__main__":
    run_control_benchmark()
