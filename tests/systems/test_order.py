"""Order of concurrent actions on the executed-word semantics: a step that moves r1 into p2 while r2 leaves
p2 must run r2 first under the safety formula G !(r1_p2 & r2_p2); the plan stores that order and the mission
executes it without the monitored run ever dying."""

from pathlib import Path

import yaml

from mrodrake.planning.plan import Plan, task_words
from mrodrake.scenario import scenario_from_dict
from mrodrake.systems.mission import Mission
from mrodrake.ts import Navigate, TransitionSystem

ROOT = Path(__file__).resolve().parents[2]
FORMULA = "G !(r1_p2 & r2_p2) & F (r1_p2 & r2_p3)"


def _setup():
    data = yaml.safe_load((ROOT / "scenarios" / "tiny.yaml").read_text())
    data["name"] = "tiny_order"
    data["task"] = {"propositions": {}, "formula": FORMULA}
    scn = scenario_from_dict(data)
    ts = TransitionSystem(scn)
    formula, nba, words = task_words(scn, ts)
    s1 = ts.initial  # r1 p1, r2 p2, o1 p1
    s2 = ts.make_state([1, 2], list(ts.objects_of(s1)), [-1, -1])
    assert ts.check_transition(s1, s2) is None
    q1 = next(iter(words.successors(nba.initial, s1, s2)))
    qa = next(q for q in words.successors(q1, s2, s2) if q in nba.accepting and q in words.successors(q, s2, s2))
    plan = Plan.from_runs(ts, scn.name, str(formula), "exact", None, [(s1, nba.initial), (s2, q1)], [(s2, qa)],
                          words)
    plan.verify(ts, nba, formula)
    return scn, ts, nba, words, plan, s1, s2, q1


def test_plan_stores_the_safe_order_and_the_naive_one_violates_safety():
    scn, ts, nba, words, plan, s1, s2, q1 = _setup()
    acts = plan.actions[0]
    assert [type(a) for a in acts] == [Navigate, Navigate] and [a.robot for a in acts] == [1, 0]  # r2 first
    naive = tuple(reversed(acts))
    assert words.reached(1 << nba.initial, s1, s2, naive) == 0  # r1 enters p2 while r2 is there: the run dies
    both = (1 << ts.propositions.index("r1_p2")) | (1 << ts.propositions.index("r2_p2"))
    assert all(any(letter & both == both for letter in w) for w in words.step_words(s1, s2, naive))
    assert not any(letter & both == both for w in words.step_words(s1, s2, acts) for letter in w)
    assert words.reached(1 << nba.initial, s1, s2, acts) >> q1 & 1


def test_mission_executes_the_safe_order():
    """Short simulation: the supervisor runs r2 first, the monitored run never dies."""
    scn, ts, nba, words, plan, s1, s2, q1 = _setup()
    log = Mission(scn, plan, suffix_cycles=0).run()
    assert log.ok, log.message
    prim = log.primitive_events
    assert list(prim["action"]) == ["navigate r2 p2->p3", "navigate r1 p1->p2"]
    labels = log.events[log.events["kind"] == "label"]
    assert len(labels) > 0 and labels["ok"].all()
    assert not any("r1_p2" in p.split() and "r2_p2" in p.split() for p in labels["propositions"])
    assert log.final_state == ts.state_dict(s2)
