"""Regions the task keeps robots out of for good, and what that means for the objects they must carry."""

from __future__ import annotations

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrodrake.errors import NoPlanFound, UserError
from mrodrake.planning.confine import never_true, task_regions
from mrodrake.planning.generate import generate_scenario_data
from mrodrake.planning.plan import plan_scenario, task_nba
from mrodrake.planning.relax import Relaxations
from mrodrake.planning.semantics import relevant_mask
from mrodrake.scenario import scenario_from_dict
from mrodrake.ts import TransitionSystem, Transport
from tests.helpers.tasks import region_atoms
from tests.planning.conftest import SCENARIOS

#: A third robot for tiny.yaml (r1 power 2 in p1, r2 power 3 in p2, o1 needs 4 in p1).
R3 = {"name": "r3", "mass": 1.0, "radius": 0.75, "power": 2, "initial_region": "p2"}


def _tiny(formula: str, extra_robots=()):
    data = yaml.safe_load((SCENARIOS / "tiny.yaml").read_text())
    data["task"] = {"formula": formula}
    data["robots"] += list(extra_robots)
    return scenario_from_dict(data)


def _never(sc) -> set[str]:
    ts = TransitionSystem(sc)
    _f, nba = task_nba(sc, ts)
    mask = never_true(ts, nba) or 0
    return {p for b, p in enumerate(ts.propositions) if mask >> b & 1}


@pytest.mark.parametrize("formula, never", [
    ("F o1_p3 & G !r2_p3", {"r2_p3"}),
    ("G !r1_p2 & G F r1_p3 & G !(r2_p3)", {"r1_p2", "r2_p3"}),
    ("F o1_p3 & (!r2_p3 U r1_p2)", set()),
    ("F o1_p3 & F G !r2_p3", set()),
    ("F o1_p3 & G (o1_p3 -> !r2_p3)", set()),
    ("F o1_p3 & X G !r2_p3", set()),  # r2 may be in p3 only at the start, where it is not: still allowed
    ("G !(r1_p3 & r2_p3) & F o1_p3", set()),
])
def test_only_constraints_that_hold_forever_keep_a_robot_out(formula, never):
    assert _never(_tiny(formula)) == never


def test_a_task_that_the_start_already_violates_keeps_nobody_out():
    ts_sc = _tiny("F o1_p3 & G !r2_p2")  # r2 starts in p2
    ts = TransitionSystem(ts_sc)
    _f, nba = task_nba(ts_sc, ts)
    assert never_true(ts, nba) is None and task_regions(ts, nba) is None


@pytest.mark.parametrize("planner", ["stylus", "exact"])
def test_object_whose_region_only_weak_robots_may_enter_is_unmovable(planner):
    with pytest.raises(UserError) as e:
        plan_scenario(_tiny("F o1_p3 & G !r2_p1"), planner=planner)
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith("task is unsatisfiable: object o1 must leave region p1 but needs power 4")
    assert "the robots the task lets into p1 (r1) reach at most power 2" in msg
    assert "keeps r2 out of p1" in msg


def test_object_stays_movable_when_the_robots_let_in_are_strong_enough():
    sc = _tiny("F o1_p3 & G !r2_p1", [R3])
    plan = plan_scenario(sc, iterations=300)
    carried = [a for acts in plan.actions for a in acts if isinstance(a, Transport)]
    assert carried and all(set(a.team) == {0, 2} for a in carried)
    assert all(s[1] != 0 for s, _ in plan.run)  # r2 never in p1


def test_object_need_not_move_keeps_the_task_satisfiable():
    plan = plan_scenario(_tiny("G F r1_p3 & G !r2_p1 & G o1_p1"), iterations=300)
    assert all(s[plan.ts.N] == 0 for s, _ in plan.run)


def test_relaxation_carries_objects_only_with_robots_let_into_both_regions():
    sc = _tiny("F o1_p3 & G !r2_p3 & G !r3_p3", [R3])  # only r1 (power 2) may enter p3
    ts = TransitionSystem(sc)
    f, nba = task_nba(sc, ts)
    msg = Relaxations(ts, nba, relevant_mask(ts, f)).prove()
    assert msg is not None and "the task lets it into" in msg
    sc = _tiny("F o1_p3 & G !r2_p3", [R3])  # r1 + r3 = 4 may
    ts = TransitionSystem(sc)
    f, nba = task_nba(sc, ts)
    assert Relaxations(ts, nba, relevant_mask(ts, f)).prove() is None


@st.composite
def _kept_out_tasks(draw):
    n, m, k = draw(st.integers(2, 3)), 1, 3
    seed = draw(st.integers(0, 10_000))
    atoms = region_atoms(n, m, k)
    robots = [a for a in atoms if a.startswith("r")]
    kept = draw(st.lists(st.sampled_from(robots), min_size=1, max_size=3, unique=True))
    goal = draw(st.sampled_from([a for a in atoms if a.startswith("o")]))
    extra = draw(st.sampled_from(["", " & G F {}", " & ({} U {})", " & F G !{}"]))
    formula = f"F {goal} & " + " & ".join(f"G !{a}" for a in kept)
    if extra:
        formula += extra.format(*draw(st.lists(st.sampled_from(atoms), min_size=2, max_size=2)))
    return n, m, k, seed, formula


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(task=_kept_out_tasks())
def test_no_planned_run_enters_a_region_the_task_keeps_it_out_of(task):
    """Plans never contradict the derived confinement, and an object declared unmovable for lack of admitted
    power is never carried by any plan the exact planner finds."""
    n, m, k, seed, formula = task
    data = generate_scenario_data(n, m, k, seed)
    data["task"] = {"formula": formula, "propositions": {}}
    sc = scenario_from_dict(data)
    ts = TransitionSystem(sc)
    _f, nba = task_nba(sc, ts)
    never = never_true(ts, nba) or 0
    try:
        plan = plan_scenario(sc, planner="exact", place=False)
    except (UserError, NoPlanFound) as e:
        if "the task lets into" in str(e):
            assert never
        return
    assert all(ts.label_mask(s) & never == 0 for s, _ in plan.run), formula
