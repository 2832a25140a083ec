"""Only realisable transitions: two rooms joined by a 3.2 m passage that a robot (radius 0.75 m + 0.5 m margin
to walls: 2.5 m) passes and a robots-object team (covering radius 1.9 m: 4.8 m) does not."""

from __future__ import annotations

import pytest
import yaml

from mrodrake import cli
from mrodrake.errors import UserError
from mrodrake.planning.plan import plan_scenario
from mrodrake.scenario import scenario_from_dict
from mrodrake.ts import Navigate, TransitionSystem, Transport


def two_rooms(formula: str, passage: float = 3.2) -> dict:
    h = passage / 2
    boundary = [[0, 0], [20, 0], [20, 10 - h], [24, 10 - h], [24, 0], [44, 0], [44, 20], [24, 20], [24, 10 + h],
                [20, 10 + h], [20, 20], [0, 20]]
    return {
        "name": "two_rooms",
        "workspace": {"boundary": boundary},
        "regions": [{"name": "p1", "center": [8.0, 10.0], "radius": 4.0},
                    {"name": "p2", "center": [36.0, 10.0], "radius": 4.0}],
        "robots": [{"name": "r1", "mass": 1.0, "radius": 0.75, "power": 2, "initial_region": "p1"},
                   {"name": "r2", "mass": 1.0, "radius": 0.75, "power": 2, "initial_region": "p1"}],
        "objects": [{"name": "o1", "mass": 0.3, "radius": 0.3, "required_power": 3, "initial_region": "p1"}],
        "task": {"formula": formula},
    }


def test_the_ts_offers_the_robot_the_passage_but_not_the_team():
    ts = TransitionSystem(scenario_from_dict(two_rooms("F r1_p2")))
    team = ts.covering_radius(0, (0, 1))
    assert team == pytest.approx(1.9)
    assert ts.connected(0.75, 0, 1) and not ts.connected(team, 0, 1)
    s = ts.make_state([0, 0], [0], [0, 0])  # r1, r2 grasp o1 in p1
    acts = [a for t in ts.successor_states(s) for a in ts.actions(s, t)]
    assert not any(isinstance(a, Transport) for a in acts)
    free = ts.initial
    assert any(isinstance(a, Navigate) and a.dst == 1 for t in ts.successor_states(free) for a in ts.actions(free, t))
    moved = ts.make_state([1, 1], [1], [0, 0])
    assert "cannot travel from p1 to p2" in ts.check_transition(s, moved)


def test_a_task_that_needs_the_blocked_transport_is_unsatisfiable_naming_it():
    sc = scenario_from_dict(two_rooms("F o1_p2"))
    for planner in ("exact", "stylus"):
        with pytest.raises(UserError) as e:
            plan_scenario(sc, planner=planner, iterations=200)
        msg = str(e.value)
        assert "\n" not in msg
        assert "object o1 can never be carried to p2 from p1" in msg and "covering radius 1.90 m" in msg
    plan = plan_scenario(scenario_from_dict(two_rooms("F G r1_p2")), planner="exact")
    assert plan.suffix[0][0][0] == 1  # the robot alone goes through


def test_validate_reports_the_blocked_travel(tmp_path, capsys):
    path = tmp_path / "two_rooms.yaml"
    path.write_text(yaml.safe_dump(two_rooms("F r1_p2")))
    assert cli.main(["validate", str(path)]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert out[0].startswith(f"{path}: ok")
    assert out[1:] == [f"{path}: object o1 can never be carried to p2 from p1: no passage wide enough (walls, "
                       "obstacles and other regions grown by the radius + 0.5 m) for its smallest team (covering "
                       "radius 1.90 m)"]
