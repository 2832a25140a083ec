"""Order choice of concurrent actions (soundness beyond the paper): a step that moves r1 into p2 while r2
leaves p2 must run r2 first under the safety formula G !(r1_p2 & r2_p2)."""

from pathlib import Path

import pytest
import yaml

from mrodrake.planning.plan import Plan, task_nba
from mrodrake.scenario import scenario_from_dict
from mrodrake.systems.supervisor import choose_order, label_of, order_letters, run_through
from mrodrake.ts import Navigate, TransitionSystem

ROOT = Path(__file__).resolve().parents[2]
FORMULA = "G !(r1_p2 & r2_p2) & F (r1_p2 & r2_p3)"


def _setup():
    data = yaml.safe_load((ROOT / "scenarios" / "tiny.yaml").read_text())
    data["name"] = "tiny_order"
    data["task"] = {"propositions": {}, "formula": FORMULA}
    scn = scenario_from_dict(data)
    ts = TransitionSystem(scn)
    formula, nba = task_nba(scn, ts)
    s1 = ts.initial  # r1 p1, r2 p2, o1 p1
    r1, r2 = 0, 1
    s2 = ts.make_state([1, 2], list(ts.objects_of(s1)), [-1, -1])
    assert ts.check_transition(s1, s2) is None
    # NBA states of the plan: q0 -L(s1)-> q1 -L(s2)-> qa, qa -L(s2)-> qa accepting (s2 idles)
    L1, L2 = ts.label_mask(s1), ts.label_mask(s2)
    q1, qa = next((q1, qa) for q1 in nba.successors(nba.initial, L1) for qa in nba.successors(q1, L2)
                  if qa in nba.successors(qa, L2) and qa in nba.accepting)
    plan = Plan.from_runs(ts, scn.name, str(formula), "exact", None, [(s1, nba.initial), (s2, q1)], [(s2, qa)])
    plan.verify(ts, nba, formula)
    return scn, ts, nba, plan, s1, s2, q1, (r1, r2)


def test_naive_order_violates_safety_and_choice_fixes_it():
    scn, ts, nba, plan, s1, s2, qa, (r1, r2) = _setup()
    acts = plan.actions[0]
    assert [type(a) for a in acts] == [Navigate, Navigate] and acts[0].robot == r1  # plan order: r1 first
    regions = list(s1[: ts.N + ts.M])
    run0 = frozenset([nba.initial])
    naive = run_through(nba, run0, label_of(regions, ts.K), order_letters(ts, regions, acts))
    assert not naive  # r1 enters p2 while r2 is still there: the run dies
    order, after = choose_order(ts, nba, run0, regions, acts, qa)
    assert order is not None and [a.robot for a in order] == [r2, r1]
    assert qa in after


def test_no_order_reported_when_none_exists():
    scn, ts, nba, plan, s1, s2, qa, _ = _setup()
    regions = list(s1[: ts.N + ts.M])
    # an NBA state the run cannot reach from the initial one in a step: no order is consistent with it
    unreachable = [q for q in range(nba.num_states)
                   if q not in run_through(nba, frozenset([nba.initial]), label_of(regions, ts.K),
                                           order_letters(ts, regions, plan.actions[0]))
                   and q not in run_through(nba, frozenset([nba.initial]), label_of(regions, ts.K),
                                            order_letters(ts, regions, plan.actions[0][::-1]))]
    if not unreachable:
        pytest.skip("every NBA state is reachable in this step")
    order, after = choose_order(ts, nba, frozenset([nba.initial]), regions, plan.actions[0], unreachable[0])
    assert order is None and not after


def test_mission_executes_the_safe_order():
    """Short simulation: the supervisor runs r2 first, the monitored run never dies."""
    from mrodrake.systems.mission import Mission

    scn, ts, nba, plan, s1, s2, qa, (r1, r2) = _setup()
    m = Mission(scn, plan, suffix_cycles=0)
    log = m.run()
    assert log.ok, log.message
    prim = log.primitive_events
    assert list(prim["action"]) == ["navigate r2 p2->p3", "navigate r1 p1->p2"]
    assert (log.events["kind"] == "order").sum() == 1
    labels = log.events[log.events["kind"] == "label"]
    assert labels["ok"].all()
    assert not any("r1_p2" in p.split() and "r2_p2" in p.split() for p in labels["propositions"])
    assert log.final_state == ts.state_dict(s2)
