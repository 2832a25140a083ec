"""The shipped maps (scenarios/maps/): valid scenarios whose regions keep the control margin to walls,
obstacles and each other, connected for robots and teams, except the narrow map, which robots cross and
robots-object teams cannot."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest
import shapely

from mrodrake.control.freespace import entity_free_space
from mrodrake.errors import UserError
from mrodrake.geometry import CONTROL_MARGIN, grasp_layout, polygon
from mrodrake.scenario import load_scenario

MAPS = Path(__file__).resolve().parents[1] / "scenarios" / "maps"
MAP_FILES = sorted(MAPS.glob("*.yaml"))


def _connected(sc, radius: float, a: int, b: int) -> bool:
    try:
        entity_free_space(sc, radius, sc.regions[a].center, sc.regions[b].center, a, b)
    except UserError as exc:
        assert "separated from the start" in str(exc)
        return False
    return True


def _radii(sc) -> tuple[float, float]:
    """Robot radius and the largest covering radius of a generated team on this map (3 robots, object
    of 0.4 m scaled like the robots)."""
    r = max(x.radius for x in sc.robots)
    return r, grasp_layout(0.4 * r / 0.75, [r] * 3, sc.layout.grasp_gap).covering_radius


@pytest.mark.parametrize("path", MAP_FILES, ids=lambda p: p.stem)
def test_regions_keep_the_control_margin(path):
    sc = load_scenario(path)
    walls = polygon(sc.workspace.boundary).exterior
    obstacles = [polygon(o.polygon) for o in sc.workspace.obstacles]
    assert len(sc.regions) >= 5
    for i, g in enumerate(sc.regions):
        c = shapely.Point(g.center)
        gaps = [walls.distance(c)] + [o.distance(c) for o in obstacles]
        gaps += [math.dist(g.center, h.center) - h.radius for j, h in enumerate(sc.regions) if j != i]
        assert min(gaps) - g.radius >= CONTROL_MARGIN, g.name


@pytest.mark.parametrize("path", [p for p in MAP_FILES if p.stem != "narrow"], ids=lambda p: p.stem)
def test_every_region_pair_is_connected(path):
    sc = load_scenario(path)
    for radius in _radii(sc):
        for a, b in itertools.combinations(range(len(sc.regions)), 2):
            assert _connected(sc, radius, a, b), (radius, sc.regions[a].name, sc.regions[b].name)


def test_narrow_passage_lets_robots_through_and_blocks_teams():
    sc = load_scenario(MAPS / "narrow.yaml")
    robot, team = _radii(sc)
    smallest_team = grasp_layout(0.2, [robot], sc.layout.grasp_gap).covering_radius
    west = [k for k, g in enumerate(sc.regions) if g.center[0] < 20.0]
    east = [k for k, g in enumerate(sc.regions) if g.center[0] > 21.0]
    assert len(west) == len(east) == 3
    for a, b in itertools.product(west, east):
        assert _connected(sc, robot, a, b)
        assert not _connected(sc, smallest_team, a, b)
    for side in (west, east):
        for a, b in itertools.combinations(side, 2):
            assert _connected(sc, team, a, b)
