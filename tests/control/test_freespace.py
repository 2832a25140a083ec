"""Free space of a moving entity F = (W_f \\ O) ⊖ r, goal points from P_s, clearances (paper Sec. III-A)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Polygon

from mrodrake.control.freespace import (
    Disk,
    clearances,
    entity_free_space,
    goal_point,
    inside_region,
)
from mrodrake.errors import UserError
from mrodrake.geometry import polygon
from mrodrake.scenario import load_scenario

SCEN = Path(__file__).resolve().parents[2] / "scenarios"


@pytest.fixture(scope="module")
def case1():
    return load_scenario(SCEN / "case_study_1.yaml")


def _centre(s, k):
    return np.array(s.regions[k].center, dtype=float)


def _others(s):
    """r2 in p3, r3 in p4, o1 in p2, o2 in p1 (case study I's initial regions), off-centre."""
    return [Disk("r2", tuple(_centre(s, 2) + [1.5, 0.0]), 0.75), Disk("r3", tuple(_centre(s, 3)), 0.75),
            Disk("o1", tuple(_centre(s, 1)), 0.2), Disk("o2", tuple(_centre(s, 0) + [2.0, 0.0]), 0.2)]


def _raw_clearance(s, pts, radius, others, avoid):
    cl = clearances(s, pts, radius, others, avoid)
    return np.min(np.vstack(list(cl.values())), axis=0)


def test_free_space_is_one_polygon_with_one_hole_per_obstacle(case1):
    s = case1
    start, goal = _centre(s, 0) + [-1.5, 0.0], _centre(s, 2) + [-1.5, 0.0]
    fs = entity_free_space(s, 0.75, start, goal, "p1", "p3", _others(s))
    assert isinstance(fs.polygon, Polygon) and fs.polygon.is_valid
    assert fs.polygon.contains(shapely.Point(start)) and fs.polygon.contains(shapely.Point(goal))
    # 19 obstacles + r2, o2 (in start/goal regions) + p2 (holding o1) + p4 (holding r3), merged pairwise
    names = sorted(n for h in fs.hole_names for n in h)
    assert len(fs.polygon.interiors) == 23
    assert ["o1", "p2"] in [sorted(h) for h in fs.hole_names] and ["p4", "r3"] in [sorted(h) for h in fs.hole_names]
    assert "p1" not in names and "p3" not in names
    assert {o.name for o in s.workspace.obstacles} <= set(names)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.2, 2.0), st.integers(0, 2**31 - 1))
def test_every_point_of_F_is_collision_free(case1, radius, seed):
    """Points of F (its vertices and random interior points) keep the entity ball clear of everything."""
    s = case1
    start, goal = _centre(s, 0) + [-1.5, 0.0], _centre(s, 2) + [-1.8, 0.0]
    fs = entity_free_space(s, radius, start, goal, 0, 2, _others(s))
    rng = np.random.default_rng(seed)
    minx, miny, maxx, maxy = fs.polygon.bounds
    pts = rng.uniform((minx, miny), (maxx, maxy), size=(3000, 2))
    pts = pts[shapely.contains_xy(fs.polygon, pts[:, 0], pts[:, 1])]
    verts = np.vstack([np.asarray(r.coords) for r in [fs.polygon.exterior, *fs.polygon.interiors]])
    clear = _raw_clearance(s, np.vstack([pts, verts]), radius, _others(s), [1, 3])
    assert clear.min() > 0.0


def test_touching_holes_merge(case1):
    """Two entities 0.5 m apart, enlarged by 0.75 m each, become one hole."""
    s = case1
    c = _centre(s, 1)
    others = [Disk("a", tuple(c + [-0.35, 0.0]), 0.1), Disk("b", tuple(c + [0.35, 0.0]), 0.1)]
    fs = entity_free_space(s, 0.75, _centre(s, 0), _centre(s, 2), 0, 2, others)
    assert any(sorted(h) == ["a", "b", "p2"] for h in fs.hole_names)
    fs2 = entity_free_space(s, 0.75, _centre(s, 0), _centre(s, 1) + [0, 3.0], 0, 1, others)
    assert any(sorted(h) == ["a", "b"] for h in fs2.hole_names)


def test_an_entity_parked_in_an_avoided_region_leaves_F_as_it_is(case1):
    """An entity inside p2 (avoided on a p1 -> p3 motion) lies inside p2's enlarged disk: F is the same
    polygon, vertex for vertex, wherever in p2 it stands and without it; one on the open floor changes F."""
    s = case1
    start, goal = _centre(s, 0) + [-1.5, 0.0], _centre(s, 2) + [-1.5, 0.0]
    base = entity_free_space(s, 0.75, start, goal, 0, 2, []).polygon.wkb
    for offset in ([0.0, 0.0], [1.2, -0.9], [-2.0, 1.3]):  # the 0.2 m ball stays inside the 4 m region
        fs = entity_free_space(s, 0.75, start, goal, 0, 2, [Disk("o1", tuple(_centre(s, 1) + offset), 0.2)])
        assert fs.polygon.wkb == base
        assert any("o1" in h for h in fs.hole_names)  # still named with the hole it lies in
    midway = tuple(0.5 * (_centre(s, 0) + _centre(s, 2)))
    outside = entity_free_space(s, 0.75, start, goal, 0, 2, [Disk("o1", midway, 0.2)]).polygon
    assert outside.wkb != base and outside.area < shapely.from_wkb(base).area


def test_goal_unreachable_when_a_door_is_blocked(case1):
    s = case1
    door = (103.5, -224.5)  # room A's 7 m door
    blocker = [Disk("blocker", door, 3.0)]
    with pytest.raises(UserError, match="goal unreachable"):
        entity_free_space(s, 0.75, _centre(s, 0), _centre(s, 2), 0, 2, blocker)


def test_start_in_collision_is_a_user_error(case1):
    s = case1
    with pytest.raises(UserError, match="start"):
        entity_free_space(s, 0.75, _centre(s, 0), _centre(s, 2), 0, 2, [Disk("x", tuple(_centre(s, 0)), 0.5)])
    with pytest.raises(UserError, match="region 'p9'"):
        entity_free_space(s, 0.75, _centre(s, 0), _centre(s, 2), "p9", 2)


def test_goal_point_from_P_s(case1):
    s = case1
    occ = [Disk("r3", tuple(_centre(s, 3) + [-2.4, 0.0]), 0.75)]
    g = goal_point(s, "p4", 1.8, occ, seed=0)
    assert inside_region(s, "p4", g, 1.8, tol=s.layout.spacing - 1e-9)
    assert np.hypot(*(g - occ[0].center)) >= 0.75 + 1.8 + s.layout.spacing - 1e-9
    assert np.array_equal(g, goal_point(s, "p4", 1.8, occ, seed=0))
    with pytest.raises(UserError, match="no room"):
        goal_point(s, "p4", 1.8, [Disk("r3", tuple(_centre(s, 3)), 0.75)])


def test_clearances_on_simple_geometry(case1):
    s = case1
    c = _centre(s, 1)
    pts = np.array([c, c + [0.0, 10.0], [59.0, -150.0]])
    cl = clearances(s, pts, 0.5, [Disk("d", tuple(c + [3.0, 0.0]), 1.0)], ["p2"])
    np.testing.assert_allclose(cl["d"], [1.5, np.hypot(3, 10) - 1.5, np.hypot(c[0] + 3 - 59, c[1] + 150) - 1.5])
    assert cl["p2"][0] == pytest.approx(-4.5) and cl["p2"][1] == pytest.approx(10 - 4.5)
    assert cl["wall"][2] < 0  # outside the building
    boundary = polygon(s.workspace.boundary)
    assert cl["wall"][0] == pytest.approx(boundary.exterior.distance(shapely.Point(c)) - 0.5)
