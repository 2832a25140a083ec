"""Departure points (no Drake): a start that maps outside the point-world map's circle barrier leaves from a
nearby point inside the region that maps inside it."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from mrodrake.control.freespace import Disk, entity_free_space
from mrodrake.control.local import disk_obstacles, local_path
from mrodrake.control.tasks import build_map, build_task, departure_point, inside_circle
from mrodrake.scenario import scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]
TOL = 0.03  # the sequencer's dock_tol: the local law ends within it of the departure point


def test_a_start_beside_an_entity_merged_with_the_walls_departs_from_inside_the_circle_barrier():
    """Lab p4 (the campaign's gen_lab_n3_m1_k3_s1 at the start of "navigate r1 p4->p3"): r1 (radius 0.5 m)
    is parked 0.1 m from r3, whose disk grown by r1's radius merges with the east wall grown by r1's radius
    and the 0.5 m margin, so r1 stands 0.086 m from the outer boundary of its free space, where the discrete
    map falls short of the unit circle: |H(start)| > ρ₀ = 1 − κ δ_max and the law cannot start there."""
    data = yaml.safe_load((ROOT / "scenarios" / "maps" / "lab.yaml").read_text())
    data["regions"] = [g for g in data["regions"] if g["name"] in ("p2", "p3", "p4")]
    data["robots"] = [{"name": f"r{i}", "mass": 1.0, "radius": 0.5, "power": 4, "initial_region": "p4"}
                      for i in (1, 2, 3)]
    data["objects"] = [{"name": "o1", "mass": 0.25, "radius": 0.21, "required_power": 4, "initial_region": "p3"}]
    data["task"] = {"formula": "F r1_p3"}
    sc = scenario_from_dict(data)
    start = np.array([14.70989518, 9.780888927])
    pos = {"r1": start, "r2": (12.99309371, 10.23013245), "r3": (14.56408766, 8.702544126),
           "o1": (12.80630154, 9.435910048)}
    others = [Disk(n, tuple(map(float, pos[n])), r) for n, r in (("r2", 0.5), ("r3", 0.5), ("o1", 0.21))]
    free = entity_free_space(sc, 0.5, start, (2.3, 9.7), "p4", "p3", others)
    assert len(free.polygon.interiors) == 0  # every other entity is part of the outer boundary
    pw = build_map(free)
    assert not inside_circle(pw, start)[0]
    with pytest.raises(ValueError, match="not inside the circle barrier"):
        build_task(sc, free, pw_map=pw)
    c, R = np.array([13.4, 9.4]), 2.0 - 0.5
    X = np.array([pos[n] for n in ("r1", "r2", "r3", "o1")], dtype=float)
    centers, radii = disk_obstacles(X, [0.5, 0.5, 0.5, 0.21], 0.5, [0], c, R)
    p = departure_point(pw, free, centers, radii, c, R, TOL)
    assert p is not None
    assert np.linalg.norm(p - start) <= 0.6 + 1e-9
    ring = p + TOL * np.column_stack([np.cos(np.arange(8) * np.pi / 4), np.sin(np.arange(8) * np.pi / 4)])
    assert inside_circle(pw, np.vstack([p, ring])).all()
    assert np.linalg.norm(p - c) <= R  # still inside p4: the local move changes no label
    local_path(start, p, centers, radii, c, R)
    build_task(sc, dataclasses.replace(free, start=p), pw_map=pw)  # the law starts from there
