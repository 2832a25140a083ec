"""``mrodrake bench control``: point-world map and adaptive-control simulation benchmark (case study I).

Prints the map construction time and panel count for the case-study office (free space of a robot for
its longest navigation, with the other entities present), the time per map + Jacobian (+ Hessians)
evaluation, and wall time vs simulated time for that navigation.  Targets: map built in <= 0.2 s, one evaluation
of H, J_H and the Hessians in <= 20 us, a 150 m navigation simulated in <= 5 s wall.

:func:`run_map_benchmark` (not run by the command) times the map on a larger office-like test layout
(200 m x 200 m, 1 m walls, 4-8 m doors, :func:`office_like_free_space`, also used by the control tests).
"""

from __future__ import annotations

import itertools
import math
import sys
import time
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import Point, box
from shapely.ops import unary_union

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
    pw.evaluate(pts[0])  # first call: loads the compiled kernels
    pw(pts[0])
    t0 = time.perf_counter()
    for p in pts:
        pw.evaluate(p)
    t_eval = (time.perf_counter() - t0) / len(pts)
    t0 = time.perf_counter()
    for p in pts:
        pw.evaluate_direct(p)
    t_direct = (time.perf_counter() - t0) / len(pts)
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
        "eval_direct_us": 1e6 * t_direct,
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
          f"(best of {repeats}, options {MAP_OPTIONS}; target <= 200 ms)", file=stream)
    print(f"  H + J_H + Hessians     {out['eval_us']:9.1f} us per point (treecode; direct sum over all panels "
          f"{out['eval_direct_us']:.1f} us; target <= 20 us)", file=stream)
    print(f"  H and J_H (2 calls)    {out['value_jacobian_us']:9.1f} us per point", file=stream)
    print(f"  navigation {out['transition']}: reached={out['reached']}, path {path:.1f} m, "
          f"{out['sim_time_s']:.1f} s simulated, {out['steps']} steps "
          f"({out['implicit_s']:.1f} s simulated with the implicit integrator)", file=stream)
    print(f"  simulation wall        {out['wall_s']:9.2f} s ({out['wall_incl_map_s']:.2f} s with free space + map)",
          file=stream)
    print(f"  wall per 150 m         {out['wall_per_150m_s']:9.2f} s (target <= 5 s)", file=stream)
    return out


OFFICE_SIZE = 200.0
WALL = 1.0


def _wall_with_doors(horizontal: bool, at: float, lo: float, hi: float, doors) -> list:
    """Rectangles of a 1 m wall along x (horizontal) or y at coordinate ``at``, with door gaps (start, end)."""
    cuts = [lo] + [c for d in sorted(doors) for c in d] + [hi]
    parts = []
    for a, b in zip(cuts[::2], cuts[1::2]):
        if b > a:
            if horizontal:
                parts.append(box(a, at - WALL / 2, b, at + WALL / 2))
            else:
                parts.append(box(at - WALL / 2, a, at + WALL / 2, b))
    return parts


def office_obstacles() -> list:
    """Walls, furniture and disks (other entities / regions) of the test office, unbuffered."""
    s = OFFICE_SIZE
    walls = []
    walls += _wall_with_doors(True, 90.0, 0.0, s, [(20, 24), (70, 76), (120, 128), (170, 175)])
    walls += _wall_with_doors(True, 110.0, 0.0, s, [(30, 35), (80, 86), (130, 134), (175, 182)])
    for x in (50.0, 100.0, 150.0):
        walls += _wall_with_doors(False, x, 0.0, 89.5, [(40, 46)] if x == 100.0 else [])
        walls += _wall_with_doors(False, x, 110.5, s, [(150, 155)] if x == 50.0 else [])
    walls.append(box(10, 40, 35, 41))  # free-standing partition
    walls.append(box(160, 150, 161, 185))  # free-standing partition
    furniture = [
        box(60, 20, 64, 22), box(70, 20, 74, 22), box(60, 60, 62, 61), box(80, 55, 84, 57),
        box(110, 10, 112, 11), box(130, 70, 134, 72), box(5, 120, 9, 122), box(20, 170, 22, 171),
        box(115, 130, 119, 132), box(185, 20, 187, 28), box(90, 100, 92, 101),
    ]
    disks = [Point(160, 40).buffer(3.0), Point(60, 150).buffer(2.5), Point(140, 100).buffer(0.5),
             Point(25, 60).buffer(0.5), Point(185, 130).buffer(1.5)]
    return walls + furniture + disks


def office_like_free_space(robot_radius: float = 0.5):
    """Free space of a disk robot of radius ``robot_radius`` in the test office (a Polygon with holes)."""
    outer = box(0.0, 0.0, OFFICE_SIZE, OFFICE_SIZE).buffer(-robot_radius, join_style="mitre")
    obstacles = unary_union(office_obstacles()).buffer(robot_radius)
    free = outer.difference(obstacles)
    if free.geom_type == "MultiPolygon":
        free = max(free.geoms, key=lambda g: g.area)
    return free


def _best(fn, repeats):
    """(best wall seconds, best CPU seconds) of ``repeats`` calls of fn."""
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(wall), min(cpu)


def run_map_benchmark(stream=None, repeats: int = 3) -> dict:
    """Print build time, panel count, per-point evaluation times and accuracy of the office map; return them."""
    stream = stream or sys.stdout
    free = office_like_free_space()
    built = []
    build_wall, build_cpu = _best(lambda: built.append(PointWorldMap.build(free)), repeats)
    pw = built[-1]
    rng = np.random.default_rng(0)
    minx, miny, maxx, maxy = free.bounds
    pts = rng.uniform((minx, miny), (maxx, maxy), size=(4000, 2))
    pts = pts[shapely.contains_xy(free, pts[:, 0], pts[:, 1])][:1000]
    single = pts[:300]

    def loop(fn):
        return lambda: [fn(p) for p in single]

    eval_wall, eval_cpu = _best(loop(pw.evaluate), repeats)
    value_wall, value_cpu = _best(loop(pw), repeats)
    batch_wall, _ = _best(lambda: pw.evaluate(pts), repeats)
    outer_err, hole_errs = pw.boundary_errors()
    b = pw.hole_points
    sep = 1.0 - np.linalg.norm(b, axis=1)  # per hole: half the distance to the circle or the nearest other b
    if len(b) > 1:
        pair = np.linalg.norm(b[:, None] - b[None], axis=-1) + np.diag(np.full(len(b), np.inf))
        sep = np.minimum(sep, pair.min(axis=1))
    sep *= 0.5
    out = {
        "build_s": build_wall,
        "build_cpu_s": build_cpu,
        "n_panels": pw.n_panels,
        "n_holes": len(b),
        "eval_us": 1e6 * eval_wall / len(single),
        "eval_cpu_us": 1e6 * eval_cpu / len(single),
        "value_us": 1e6 * value_wall / len(single),
        "batch_us_per_point": 1e6 * batch_wall / len(pts),
        "boundary_error_outer": outer_err,
        "boundary_error_holes": float(hole_errs.max(initial=0.0)),
        "hole_error_over_separation": float((hole_errs / sep).max(initial=0.0)),
        "r_bar_max": float(sep.min(initial=np.inf)),
    }
    print(f"point-world map, office {OFFICE_SIZE:.0f} m x {OFFICE_SIZE:.0f} m, {out['n_holes']} holes", file=stream)
    print(f"  build time           {build_wall * 1e3:8.1f} ms wall, {build_cpu * 1e3:.1f} ms CPU"
          f" (best of {repeats})", file=stream)
    print(f"  panels               {out['n_panels']:8d}  (lengths {pw.panel_length.min():.2f}"
          f"..{pw.panel_length.max():.2f} m)", file=stream)
    print(f"  H+J+Hess per point   {out['eval_us']:8.1f} us wall, {out['eval_cpu_us']:.1f} us CPU", file=stream)
    print(f"  H per point          {out['value_us']:8.1f} us", file=stream)
    print(f"  batch H+J+Hess       {out['batch_us_per_point']:8.1f} us per point ({len(pts)} points)", file=stream)
    print(f"  boundary error       outer {outer_err:.2e}, holes {out['boundary_error_holes']:.2e}"
          f" (max {out['hole_error_over_separation']:.3f} x the hole's separation; r_bar <= {out['r_bar_max']:.4f})",
          file=stream)
    return out


if __name__ == "__main__":
    run_control_benchmark()
