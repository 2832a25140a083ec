"""Deciding satisfiability: letters between regions, each relaxation's proof (one line, naming it), soundness
against the exact planner (hypothesis), the exact decision on small products, and the three answers of the
default planner (plan, unsatisfiable, unknown with exit status 3)."""

from __future__ import annotations

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrodrake import cli
from mrodrake.errors import NoPlanFound, UserError
from mrodrake.planning.decide import decide
from mrodrake.planning.exact import solve_exact
from mrodrake.planning.generate import generate_scenario
from mrodrake.planning.plan import plan_scenario, task_nba
from mrodrake.planning.relax import Relaxations
from mrodrake.planning.semantics import relevant_mask
from mrodrake.scenario import scenario_from_dict
from mrodrake.ts import TransitionSystem
from tests.planning.conftest import SCENARIOS


def _with_task(name: str, formula: str):
    data = yaml.safe_load((SCENARIOS / f"{name}.yaml").read_text())
    data["task"] = {"formula": formula, "propositions": {}}
    return scenario_from_dict(data)


def _relax(sc):
    ts = TransitionSystem(sc)
    f, nba = task_nba(sc, ts)
    return ts, f, nba, Relaxations(ts, nba, relevant_mask(ts, f))


def test_a_letter_between_regions_satisfies_a_task():
    """r1 in no region holds while r1 travels: the planners used to prune that cube as infeasible."""
    sc = _with_task("tiny", "F (!r1_p1 & !r1_p2 & !r1_p3)")
    for planner in ("exact", "stylus"):
        plan = plan_scenario(sc, planner=planner, iterations=200)
        assert plan.total_cost > 0


# case study I: r1 starts in p1, r2 in p3, r3 in p4; its explicit product is above the exact threshold
@pytest.mark.parametrize("formula, kind, words", [
    ("F (o1_p1 & o1_p2) & G F r1_p2", "labels", "no accepting cycle of the NBA"),
    ("G (r1_p1 | r1_p2) & G F r1_p2", "entity", "robot r1 cannot produce a word"),
    ("r2_p1 & G F r1_p2", "entity", "robot r2 cannot produce a word"),
    ("G (r1_p1 <-> r2_p3) & F r1_p2", "pair", "robot r1, robot r2 moving independently"),
    ("G (r1_p1 <-> (r2_p3 <-> r3_p4)) & F !r1_p1", "joint", "robot r1, robot r2, robot r3 moving independently"),
])
def test_each_relaxation_proves_its_task_unsatisfiable(case1, formula, kind, words):
    sc = _with_task("case_study_1", formula)
    ts, f, nba, relax = _relax(sc)
    msg = relax.prove()
    assert relax.stats["relaxation"] == kind
    assert msg.startswith("task is unsatisfiable: ") and words in msg and "\n" not in msg
    with pytest.raises(UserError) as e:
        plan_scenario(sc, iterations=300)
    assert str(e.value).startswith("task is unsatisfiable: ") and not isinstance(e.value, NoPlanFound)


def test_a_blocked_passage_is_a_confinement_proof():
    from tests.test_passages import two_rooms

    sc = scenario_from_dict(two_rooms("F o1_p2 & G F r1_p1"))
    ts, f, nba, relax = _relax(sc)
    assert relax.prove() is not None and relax.stats["relaxation"] == "labels"


ATOMS = ["r1_p1", "r1_p2", "r1_p3", "r2_p1", "r2_p2", "o1_p1", "o1_p3"]


def _formulas():
    leaf = st.sampled_from(ATOMS)
    return st.recursive(leaf, lambda sub: st.one_of(
        st.builds(lambda a: f"!({a})", sub), st.builds(lambda a: f"G ({a})", sub), st.builds(lambda a: f"F ({a})", sub),
        st.builds(lambda a: f"X ({a})", sub), st.builds(lambda a, b: f"({a}) & ({b})", sub, sub),
        st.builds(lambda a, b: f"({a}) | ({b})", sub, sub), st.builds(lambda a, b: f"({a}) U ({b})", sub, sub)),
        max_leaves=5)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(formula=_formulas(), loop=st.sampled_from(["G F r1_p2", "G F (r2_p1 | o1_p3)", "true"]))
def test_relaxations_never_prove_a_satisfiable_task_unsatisfiable(formula, loop):
    sc = _with_task("tiny", f"({formula}) & {loop}")
    ts, f, nba, relax = _relax(sc)
    proof = relax.prove()
    try:
        solve_exact(ts, nba, relevant_mask(ts, f))
        sat = True
    except UserError as e:
        assert str(e).startswith("task is unsatisfiable")
        sat = False
    assert not (sat and proof), proof


def test_small_products_are_decided_exactly():
    """STyLuS* finds nothing; the interval product on the explicit TS proves the task unsatisfiable."""
    sc = generate_scenario(2, 2, 3, 96)
    with pytest.raises(UserError) as e:
        plan_scenario(sc, iterations=300)
    msg = str(e.value)
    assert msg.startswith("task is unsatisfiable: no accepting cycle is reachable in the interval product of the "
                          "TS (219 states")
    assert not isinstance(e.value, NoPlanFound)


def test_the_exact_plan_is_returned_when_sampling_finds_none(tiny):
    plan = plan_scenario(tiny.scenario, iterations=1)
    assert plan.planner == "exact" and "no plan found" in plan.stats["stylus"]
    plan.verify(tiny.ts, tiny.nba, tiny.formula)


def test_undecided_budget_is_unknown_with_exit_status_3(case2, capsys):
    """Case II with one STyLuS* iteration (and ten more after the decision): no plan, and its explicit product
    is too large for the exact decision."""
    assert cli.main(["plan", str(case2.path), "--iterations", "1"]) == 3
    msg = capsys.readouterr().err.strip().splitlines()[-1]
    assert msg.startswith("error: no plan found within") and "satisfiability unknown" in msg
    assert "too large to decide" in msg


@pytest.mark.parametrize("size", [(8, 4, 6), (12, 6, 8)])
def test_large_satisfiable_tasks_are_not_refuted(size):
    sc = generate_scenario(*size, 0, full=True)
    ts = TransitionSystem(sc)
    f, nba = task_nba(sc, ts)
    d = decide(ts, nba, relevant_mask(ts, f))
    assert d.exact is None and "too large to decide" in d.undecided


def _two_objects(formula: str):
    """Two robots (radius 0.5 m) must team up (covering radius 1.25 m) to carry either object out of p1: in p2
    (radius 1.45 m) each object put down lies within 0.15 m of the centre, too close for both; in p4 (1.8 m) within
    0.5 m, where both fit but the second team's disk leaves no room for the first object; p3 holds both."""
    return scenario_from_dict({
        "name": "two_objects",
        "workspace": {"boundary": [[0, 0], [24, 0], [24, 14], [0, 14]], "obstacles": []},
        "regions": [{"name": "p1", "center": [5, 7], "radius": 3.5},
                    {"name": "p2", "center": [14, 3.5], "radius": 1.45},
                    {"name": "p3", "center": [18, 10], "radius": 3.0},
                    {"name": "p4", "center": [11, 11.5], "radius": 1.8}],
        "robots": [{"name": f"r{i}", "mass": 1.0, "radius": 0.5, "power": 2, "initial_region": "p1"} for i in (1, 2)],
        "objects": [{"name": f"o{j}", "mass": 0.25, "radius": 0.15, "required_power": 4, "initial_region": "p1"}
                    for j in (1, 2)],
        "task": {"formula": formula}})


@pytest.mark.parametrize("region", ["p2", "p4"])
def test_a_guard_that_needs_two_objects_where_they_never_fit_together_is_unusable(region):
    sc = _two_objects(f"F (o1_{region} & o2_{region})")
    ts, f, nba, relax = _relax(sc)
    msg = relax.prove()
    assert relax.stats["relaxation"] == "labels" and "fit there together" in msg
    with pytest.raises(UserError) as e:
        solve_exact(ts, nba, relevant_mask(ts, f))
    assert str(e.value).startswith("task is unsatisfiable")


def test_a_guard_that_needs_two_objects_where_they_fit_is_kept():
    sc = _two_objects("F (o1_p3 & o2_p3)")
    ts, f, nba, relax = _relax(sc)
    assert relax.prove() is None
    assert solve_exact(ts, nba, relevant_mask(ts, f)) is not None


TWO = ["o1_p1", "o2_p1", "o1_p2", "o2_p2", "o1_p3", "o2_p3", "o1_p4", "o2_p4", "r1_p4", "r2_p3"]


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(a=st.sampled_from(TWO), b=st.sampled_from(TWO), c=st.sampled_from(TWO),
       shape=st.sampled_from(["F ({a} & {b})", "F ({a} & {b}) & G F {c}", "(!{c} U ({a} & {b}))",
                              "G F ({a} & {b}) & G F !{c}", "F ({a} & {b} & X {c})"]))
def test_packing_guards_never_prove_a_satisfiable_task_unsatisfiable(a, b, c, shape):
    sc = _two_objects(shape.format(a=a, b=b, c=c))
    ts, f, nba, relax = _relax(sc)
    proof = relax.prove()
    try:
        solve_exact(ts, nba, relevant_mask(ts, f))
        sat = True
    except UserError:
        sat = False
    assert not (sat and proof), proof
