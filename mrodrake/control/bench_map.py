"""Benchmark of the point-world map on an office-like test layout (200 m x 200 m, 1 m walls, 4-8 m doors)."""

from __future__ import annotations

import sys
import time

import numpy as np
import shapely
from shapely.geometry import Point, box
from shapely.ops import unary_union

from mrodrake.control.pointworld import PointWorldMap

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
