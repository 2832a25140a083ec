"""Receding windows (no Drake): where the point-world map of the whole free space flattens into the rounding
floor (a dead-end aisle whose walls are all one hole), the map of a window around the entity resolves the
motion and its ideal flow leaves the aisle, while the flow on the whole map goes nowhere."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely

from mrodrake.control.freespace import Disk, entity_free_space
from mrodrake.control.tasks import build_map, build_task, inside_circle
from mrodrake.control.windows import (
    RESOLUTION,
    STALL_FRACTION,
    WINDOW_GROWTH,
    WINDOW_RADIUS,
    goal_window_free_space,
    grid_path,
    point_resolution,
    progress,
    resolution,
    window_free_space,
)
from mrodrake.planning.generate import generate_scenario, load_map
from mrodrake.scenario import scenario_from_dict

WAREHOUSE = load_map("warehouse")


def _flow(task, x, seconds: float, dt: float = 0.25) -> np.ndarray:
    """x after following the ideal flow ẋ = v_d of ``task`` for ``seconds`` (explicit Euler)."""
    x = np.asarray(x, dtype=float)
    for _ in range(int(seconds / dt)):
        ev = task.evaluate(x, np.zeros(2), 0.5, 5.0)
        x = x + dt * ev.v_d
    return x


def test_a_dead_end_aisle_runs_on_a_window_map():
    """Campaign mission gen_warehouse_n3_m1_k3_s1-p0-l0-d0, "navigate r2 p6->p4" where the point-world law
    starts: r1 and r3 parked in p6 merge shelf rows 3 and 4 into one hole, so aisle 3 west of them is a 31 m
    dead end (3.5 m wide for r2) whose walls are all that hole; r2 chattered there at 2 m/s on the spot with
    steps of 1e-4 s (RTF 0.1) until the time limit."""
    sc = generate_scenario(3, 1, 3, 1, map=WAREHOUSE)
    start, goal = np.array([43.0153, 32.3202]), np.array([45.2398, 18.0114])
    others = [Disk("r1", (45.0118, 32.4472), 0.75), Disk("r3", (43.9728, 34.1527), 0.75),
              Disk("o1", (44.0, 17.0), 0.31)]
    free = entity_free_space(sc, 0.75, start, goal, "p6", "p4", others)
    assert ["shelf_3", "shelf_4", "r1", "r3"] in free.hole_names
    pw = build_map(free)
    assert resolution(pw, [start])[0] < 1e-3 * RESOLUTION  # flattened like exp(−π s/w) 31 m into the aisle
    whole = build_task(sc, free, pw_map=pw)
    assert _flow(whole, start, 20.0)[0] > start[0] - 1.0  # rounding decides v_d: no progress along the aisle

    path = grid_path(free.polygon, start, goal)
    assert path[:, 0].min() < 12.0  # out of the aisle's west mouth
    window, wpw = window_free_space(free, start, path)
    assert window.polygon.difference(free.polygon).area < 1e-9
    assert window.goal[0] < start[0] - 8.0  # the waypoint lies 8+ m west, along the aisle
    assert resolution(wpw, [start, window.goal]).min() >= RESOLUTION
    x = _flow(build_task(sc, window, pw_map=wpw), start, 60.0)
    assert x[0] < start[0] - 3.0
    assert shapely.contains_xy(free.polygon, x[0], x[1])


def test_a_goal_inside_a_narrow_aisle_is_not_resolved():
    """Campaign mission gen_warehouse_n3_m1_k3_s3-p0-l0-d0, "transport o1 by r1+r2+r3 p2->p5": the team
    (covering radius 1.93 m) has 1 m of aisle 2 between shelf rows 2 and 3; its goal 4.5 m inside maps where
    the whole map is flat along the aisle (the law crawled at 0.01 m/s for 1 000 s, then chattered)."""
    sc = generate_scenario(3, 1, 3, 3, map=WAREHOUSE)
    start, goal = np.array([30.0, 3.5]), np.array([16.45, 25.0])
    free = entity_free_space(sc, 1.9254, start, goal, "p2", "p5")
    pw = build_map(free)
    res = resolution(pw, [start, goal, (30.0, 25.0)])
    assert res[0] >= RESOLUTION and res[1] < 1e-2 * RESOLUTION and res[2] < 1e-6 * RESOLUTION


def test_a_goal_at_the_end_of_a_narrow_corridor_runs_on_a_window_map():
    """Maps campaign, gen_corridor_n2_m1_k3_s1-p0-l0-d0, "transport o1 by r1 p3->p6": the team (covering
    radius 1.886 m) has a 1.2 m band along the 6 m corridor, and p6 lies at its dead end.  The outer boundary
    runs once around the unit circle by arc length, so the dead end gets a sliver of it and the goal maps at
    ‖χ‖ = 0.9989, beyond the circle barrier ρ₀ = 0.9952 of the whole map: no task can be built there.  A window
    ending at the goal has a boundary of tens of metres instead of hundreds, and its law reaches the goal."""
    sc = generate_scenario(2, 1, 3, 1, map=load_map("corridor"))
    start, goal = np.array([46.0003, 21.8906]), np.array([3.469999, 13.0])
    free = entity_free_space(sc, 1.8860, start, goal, "p3", "p6", [])
    pw = build_map(free)
    assert not inside_circle(pw, [goal])[0] and inside_circle(pw, [start])[0]
    with pytest.raises(ValueError, match="not inside the circle barrier"):
        build_task(sc, free, pw_map=pw)

    x = np.array([12.0, 13.0])  # in the corridor, 8.5 m from the goal
    window, wpw = window_free_space(free, x, grid_path(free.polygon, x, goal))
    assert np.allclose(window.goal, goal)
    assert inside_circle(wpw, [x, goal]).all()
    end = _flow(build_task(sc, replace(window, start=x), pw_map=wpw), x, 600.0)
    assert np.linalg.norm(end - goal) < 0.5


LAB_POCKET = dict(n=3, m=1, k=3, seed=502)  # generate_scenario arguments: p4 is 2 m wide, next to a wall


def test_a_goal_in_a_pocket_between_parked_robots_runs_on_a_window_around_the_goal():
    """Campaign mission gen_lab_n3_m1_k3_s502 (randomized), "transport o1 by r3 p2->p4": r1 and r2 are parked
    in p4 and merge with the wall into the outer boundary, so the team's goal (covering radius 1.296 m) lies in
    a pocket 0.03 m from the boundary.  It maps beyond the circle barrier of the whole map and of every window
    around the team 2.1 m away; the mission failed there.  The map of a window around the goal puts both
    inside, and its law reaches the goal."""
    sc = generate_scenario(LAB_POCKET["n"], LAB_POCKET["m"], LAB_POCKET["k"], LAB_POCKET["seed"], map="lab")
    x, goal = np.array([12.11510062, 7.81096361]), np.array([13.84387929, 9.03465719])
    others = [Disk("r1", (12.793178204297014, 10.621201849753534), 0.5),
              Disk("r2", (12.089160449026098, 9.758283615077858), 0.5)]
    free = entity_free_space(sc, 1.2958871416512372, x, goal, "p2", "p4", others)
    pw = build_map(free)
    assert inside_circle(pw, [x])[0] and not inside_circle(pw, [goal])[0]
    window, wpw = window_free_space(free, x, grid_path(free.polygon, x, goal))
    assert not inside_circle(wpw, [goal])[0]

    window, wpw = goal_window_free_space(free, x, goal)
    assert window.polygon.difference(free.polygon).area < 1e-9
    assert np.allclose(window.goal, goal) and inside_circle(wpw, [x, goal]).all()
    end = _flow(build_task(sc, window, n_members=1, pw_map=wpw), x, 600.0)
    assert np.linalg.norm(end - goal) < 0.1


def test_a_start_in_a_pocket_runs_on_a_smaller_window():
    """The same mission, "transport o1 by r2 p4->p1": the team starts at its previous goal in the pocket, now
    between r1, r3 and the wall, 0.06 m from the boundary, beyond the circle barrier of the whole map and of
    the 12 m window (‖χ‖ = 0.998); a window of 7 m or less puts it inside, toward a waypoint out of the
    pocket."""
    sc = generate_scenario(LAB_POCKET["n"], LAB_POCKET["m"], LAB_POCKET["k"], LAB_POCKET["seed"], map="lab")
    x, goal = np.array([13.83002803, 8.99474179]), np.array([2.774286054275942, 2.594162521369889])
    others = [Disk("r1", (12.793178204297014, 10.621201849753534), 0.5),
              Disk("r3", (12.030324261022397, 9.782222975331505), 0.5)]
    free = entity_free_space(sc, 1.310618144650329, x, goal, "p4", "p1", others)
    assert not inside_circle(build_map(free), [x])[0]
    path = grid_path(free.polygon, x, goal)
    with pytest.raises(ValueError, match="outside the window map's circle barrier"):
        window_free_space(free, x, path, growth=math.inf)  # the 12 m window only

    window, wpw = window_free_space(free, x, path)
    assert window.polygon.difference(free.polygon).area < 1e-9
    reach = np.linalg.norm(np.asarray(window.polygon.exterior.coords) - x, axis=1).max()
    assert reach <= WINDOW_RADIUS / WINDOW_GROWTH + 1e-9
    assert inside_circle(wpw, [x, window.goal]).all()
    end = _flow(build_task(sc, window, n_members=1, pw_map=wpw), x, 120.0)
    assert np.linalg.norm(end - x) > 1.0 and shapely.contains_xy(window.polygon, end[0], end[1])


def test_a_start_in_an_aisle_closed_by_a_parked_robot_runs_on_a_window_that_resolves_it():
    """A robot parked across an aisle 2 m wide joins both shelves into one hole, which lies wholly inside the
    12 m window around a robot that starts in the aisle south of it: H flattens in that dead end on the whole map
    and on that window alike (resolution ~1e-4 at the start; in the warehouse the law then ran into a shelf at
    2 m/s).  A smaller window cuts the hole into its outer boundary and resolves the start, and the law leaves
    the aisle by its open end."""
    sc = scenario_from_dict({
        "name": "aisle",
        "workspace": {"boundary": [[0, 0], [12, 0], [12, 8], [0, 8]],
                      "obstacles": [{"name": "shelf_w", "polygon": [[3.0, 2.0], [3.8, 2.0], [3.8, 6.0], [3.0, 6.0]]},
                                    {"name": "shelf_e", "polygon": [[5.8, 2.0], [6.6, 2.0], [6.6, 6.0], [5.8, 6.0]]}]},
        "regions": [{"name": "p1", "center": [4.8, 3.2], "radius": 0.9},
                    {"name": "p2", "center": [9.0, 7.0], "radius": 0.7}],
        "robots": [{"name": "r1", "mass": 1.0, "radius": 0.3, "power": 1, "initial_region": "p1"},
                   {"name": "r2", "mass": 1.0, "radius": 0.3, "power": 1, "initial_region": "p1"}],
        "objects": [],
        "control": {"margin": 0.3},
        "task": {"formula": "F r1_p2"},
    })
    x, goal = np.array([4.8, 2.6]), np.array([9.0, 6.8])
    free = entity_free_space(sc, 0.3, x, goal, "p1", "p2", [Disk("r2", (4.8, 3.75), 0.38)])
    assert ["shelf_w", "shelf_e", "r2"] in free.hole_names
    assert resolution(build_map(free), [x])[0] < RESOLUTION
    window, wpw = window_free_space(free, x, grid_path(free.polygon, x, goal))
    assert window.polygon.difference(free.polygon).area < 1e-9
    assert resolution(wpw, [x])[0] >= RESOLUTION
    end = _flow(build_task(sc, window, n_members=1, pw_map=wpw), x, 20.0)
    assert end[1] < 2.0 and shapely.contains_xy(window.polygon, end[0], end[1])  # out of the aisle's south end


def test_resolution_is_the_smallest_singular_value_of_the_jacobian():
    """The closed form of σ_min(J_H) agrees with the SVD within its rounding (a few ulps of σ_max), at single
    points and batches, including near the boundary where J_H is far from conformal-looking."""
    from mrodrake.control.pointworld import PointWorldMap

    free = shapely.Polygon([(0, 0), (10, 0), (10, 6), (0, 6)], [[(4, 2), (5, 2), (5, 3), (4, 3)]])
    pw = PointWorldMap.build(free)
    rng = np.random.default_rng(3)
    pts = rng.uniform((0.01, 0.01), (9.99, 5.99), size=(400, 2))
    pts = pts[shapely.contains_xy(free, pts[:, 0], pts[:, 1])]
    diam = math.hypot(10.0, 6.0)
    s = np.linalg.svd(pw.jacobian(pts), compute_uv=False)
    tol = 1e-14 * s[:, 0] * diam
    assert np.all(np.abs(resolution(pw, pts) - s[:, 1] * diam) <= tol)
    for p in pts[:20]:
        s1 = np.linalg.svd(pw.jacobian(p), compute_uv=False)
        assert abs(resolution(pw, [p])[0] - s1[1] * diam) <= 1e-14 * s1[0] * diam


def test_every_leg_of_a_grid_path_lies_in_the_free_space():
    """Campaign mission gen_warehouse_n3_m1_k4_s902 (randomized), "transport o1 by r1 p5->p3": the team
    (covering radius 1.99 m) came to rest 0.12 m from ∂F, where the grid of points 1 m inside F has no node
    nearby; the path joined the nearest node, 16 m away behind a shelf row, by a straight leg through it.  The
    windows steered toward waypoints on that leg, and the team chattered against ∂F (RTF 4) until the time
    limit.  Every leg now lies in F, the path follows the aisle, and the window around the team resolves it."""
    sc = generate_scenario(3, 1, 4, 902, map=WAREHOUSE)
    x, goal = np.array([31.226076, 24.610661]), np.array([49.9751819579182, 3.989370089797309])
    others = [Disk("r2", (31.65932344, 3.970961822), 0.75), Disk("r3", (6.580624014, 37.42265786), 0.75)]
    free = entity_free_space(sc, 1.99, x, goal, "p5", "p3", others)
    assert resolution(build_map(free), [x])[0] < 1e-6 * RESOLUTION
    path = grid_path(free.polygon, x, goal)
    assert np.allclose(path[0], x) and np.allclose(path[-1], goal)
    legs = [shapely.LineString([a, b]) for a, b in zip(path[:-1], path[1:])]
    assert all(free.polygon.buffer(1e-9).covers(leg) for leg in legs)
    assert np.linalg.norm(path[1] - x) < 1.0
    window, wpw = window_free_space(free, x, path)
    assert inside_circle(wpw, [x, window.goal]).all() and resolution(wpw, [x]).min() >= RESOLUTION
    end = _flow(build_task(sc, window, pw_map=wpw), x, 60.0)
    assert end[0] > x[0] + 3.0 and shapely.contains_xy(free.polygon, end[0], end[1])


def test_point_resolution_is_the_resolution_at_one_point():
    sc = generate_scenario(3, 1, 3, 1, map=WAREHOUSE)
    free = entity_free_space(sc, 0.75, np.array([43.0153, 32.3202]), np.array([45.2398, 18.0114]), "p6", "p4", [])
    pw = build_map(free)
    rng = np.random.default_rng(3)
    minx, miny, maxx, maxy = free.polygon.bounds
    pts = rng.uniform([minx, miny], [maxx, maxy], size=(400, 2))
    pts = pts[shapely.contains_xy(free.polygon, pts[:, 0], pts[:, 1])][:60]
    ref = resolution(pw, pts)
    got = np.array([point_resolution(pw, p) for p in pts])
    assert np.allclose(got, ref, rtol=1e-12, atol=0.0)  # the same Jacobian, closed forms on floats


def test_a_grid_path_passes_a_channel_between_two_grid_rows():
    """Two rooms joined by a channel 0.14 m wide (y in [5.05, 5.19]): no row of the 0.25 m grid lies in it,
    one of the 0.125 m grid does (a team's centre space in a door it just fits through)."""
    west = shapely.box(0.0, 0.0, 10.0, 10.0)
    east = shapely.box(11.0, 0.0, 21.0, 10.0)
    poly = shapely.union_all([west, east, shapely.box(9.0, 5.05, 12.0, 5.19)])
    start, goal = (5.0, 5.0), (16.0, 5.0)
    with pytest.raises(ValueError):
        grid_path(poly, start, goal)
    path = grid_path(poly, start, goal, halvings=1)
    assert np.allclose(path[0], start) and np.allclose(path[-1], goal)
    for a, b in zip(path[:-1], path[1:]):
        assert poly.buffer(1e-9).covers(shapely.LineString([a, b]))


def _first_stall(xs, goal, period: float = 50.0, dt: float = 0.5, tol: float = 0.05) -> float | None:
    """Time at which :func:`progress` first reports a stall along the trajectory ``xs`` sampled every dt."""
    anchor = (0.0, *xs[0])
    for k, x in enumerate(xs[1:], start=1):
        anchor, stalled = progress(anchor, k * dt, x, goal, period, tol)
        if stalled:
            return k * dt
    return None


def test_an_exponential_approach_at_the_law_time_constant_never_stalls():
    """The law's descent away from barriers, x − x_d ∝ exp(−2 k1 t), down to the goal tolerance."""
    goal, t = np.array([10.0, 0.0]), np.arange(0.0, 400.0, 0.5)
    xs = goal + np.outer(np.exp(-t / 50.0), [-6.0, 2.0])
    assert _first_stall(xs, goal) is None


def test_a_slow_run_far_from_the_goal_is_progress():
    """5 m of 53 m in a period (a long motion through a squeezed room at 0.1 m/s)."""
    goal, t = np.array([60.0, 0.0]), np.arange(0.0, 300.0, 0.5)
    xs = np.column_stack([0.1 * t, np.zeros_like(t)])
    assert _first_stall(xs, goal) is None


def test_an_entity_that_creeps_to_a_standstill_short_of_its_goal_stalls_within_two_periods():
    """Speed decaying like exp(−t/20 s) to a halt 6.4 m from the goal."""
    goal, t = np.array([0.0, 0.0]), np.arange(0.0, 400.0, 0.5)
    xs = np.column_stack([6.4 + 0.8 * np.exp(-t / 20.0), np.zeros_like(t)])
    t_stall = _first_stall(xs, goal)
    assert t_stall is not None and t_stall <= 100.0
    k = int(t_stall / 0.5)
    assert np.linalg.norm(xs[k] - xs[k - 100]) < STALL_FRACTION * np.linalg.norm(xs[k] - goal)


def test_a_chatter_on_the_spot_stalls_and_a_rest_at_the_goal_does_not():
    t = np.arange(0.0, 200.0, 0.5)
    chatter = np.column_stack([3.0 + 1e-3 * np.sin(7.0 * t), np.zeros_like(t)])
    assert _first_stall(chatter, np.zeros(2)) == 50.0
    at_goal = np.column_stack([0.03 + 0.0 * t, np.zeros_like(t)])
    assert _first_stall(at_goal, np.zeros(2)) is None
