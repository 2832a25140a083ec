"""A floor 20 times smaller than the case-study office (12 m x 8 m, robots of radius 0.25 m, a 2 m door):
with the default 0.5 m margin a team (covering radius 0.7 m) cannot pass the door (it needs 2 x (0.7 + 0.5) m);
with ``control.margin: 0.1`` it can, and the mission runs without touching walls or other entities."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import shapely
import yaml

from mrodrake import cli
from mrodrake.errors import UserError
from mrodrake.geometry import polygon
from mrodrake.planning.plan import plan_scenario
from mrodrake.scenario import design_range_warnings, scenario_from_dict
from mrodrake.ts import TransitionSystem


def closet(margin: float | None = None) -> dict:
    data = {
        "name": "closet",
        "workspace": {
            "boundary": [[0, 0], [6, 0], [6, 3], [6.2, 3], [6.2, 0], [12, 0], [12, 8], [6.2, 8], [6.2, 5], [6, 5],
                         [6, 8], [0, 8]],
            "obstacles": [{"name": "crate", "polygon": [[2.5, 3.5], [3.5, 3.5], [3.5, 4.5], [2.5, 4.5]]}],
        },
        "regions": [{"name": "p1", "center": [1.5, 1.5], "radius": 1.0},
                    {"name": "p2", "center": [1.5, 6.5], "radius": 1.0},
                    {"name": "p3", "center": [10.5, 6.5], "radius": 1.0},
                    {"name": "p4", "center": [10.5, 1.5], "radius": 1.0}],
        "robots": [{"name": "r1", "mass": 1.0, "radius": 0.25, "power": 2, "initial_region": "p1"},
                   {"name": "r2", "mass": 1.0, "radius": 0.25, "power": 2, "initial_region": "p1"},
                   {"name": "r3", "mass": 1.0, "radius": 0.25, "power": 2, "initial_region": "p2"}],
        "objects": [{"name": "o1", "mass": 0.25, "radius": 0.1, "required_power": 3, "initial_region": "p2"}],
        "task": {"formula": "F o1_p4 & G !(r1_p3 & r2_p3)"},
    }
    if margin is not None:
        data["control"] = {"margin": margin}
    return data


def test_the_margin_decides_which_doors_a_small_floor_has():
    team = 0.7  # o1 (0.1 m) between two robots of 0.25 m, grasp gap included
    for margin, passes in ((None, False), (0.1, True)):
        ts = TransitionSystem(scenario_from_dict(closet(margin)))
        assert ts.smallest_team_radius(0) == pytest.approx(team)
        assert ts.connected(0.25, 0, 3)  # a robot alone: 2 x (0.25 + 0.5) m < 2 m
        assert ts.connected(team, 1, 3) is passes
    with pytest.raises(UserError) as e:
        plan_scenario(scenario_from_dict(closet()), iterations=100)
    assert "grown by the covering radius + slack 0.05 m + control.margin 0.5 m" in str(e.value)


def test_a_margin_below_the_design_range_is_warned_about(tmp_path, capsys):
    diameter = float(np.hypot(12.0, 8.0))
    assert design_range_warnings(scenario_from_dict(closet(0.1))) == []
    low = design_range_warnings(scenario_from_dict(closet(0.01)))
    assert len(low) == 1 and "control.margin: 0.01 m outside the design range" in low[0]
    assert f"{1e-3 * diameter:.3g} m for {diameter:.3g} m" in low[0]
    path = tmp_path / "closet.yaml"
    path.write_text(yaml.safe_dump(closet(-0.1)))
    assert cli.main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "control.margin" in err[0]


def test_a_mission_on_the_small_floor_keeps_clear(tmp_path):
    from mrodrake.run import run_mission

    sc = scenario_from_dict(closet(0.1))
    log = run_mission(sc, suffix_cycles=1, seed=0, out_dir=tmp_path)
    assert log.ok, log.message
    assert log.steps_done == log.steps_total
    tr = pd.read_csv(tmp_path / "trajectory.csv")
    names = sc.robot_names + sc.object_names
    radii = np.array([r.radius for r in sc.robots] + [o.radius for o in sc.objects])
    P = np.stack([tr.pivot(index="t", columns="entity", values=c)[names].to_numpy() for c in ("x", "y")], axis=-1)
    geo = shapely.points(P.reshape(-1, 2))
    r = np.tile(radii, len(P))
    walls = [polygon(sc.workspace.boundary).exterior] + [polygon(o.polygon) for o in sc.workspace.obstacles]
    for w in walls:
        assert (shapely.distance(w, geo) - r).min() > 0.0
    for a in range(len(names)):
        for b in range(a + 1, len(names)):
            assert (np.hypot(*(P[:, a] - P[:, b]).T) - radii[a] - radii[b]).min() > 0.0, (names[a], names[b])
    moved = tr[tr["entity"] == "o1"]
    assert shapely.Point(moved["x"].iloc[-1], moved["y"].iloc[-1]).distance(shapely.Point(10.5, 1.5)) < 1.0
