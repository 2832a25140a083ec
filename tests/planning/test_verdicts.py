"""The three answers of the default planner against an independent oracle on random small scenarios and tasks.

The oracle evaluates LTL directly on lasso words (:func:`~mrodrake.logic.lasso.evaluate_lasso`, no automaton)
and draws the words from the executed-word semantics: one crossing interleaving per step
(:meth:`~mrodrake.planning.semantics.ExecutedWords.step_words`).

* a plan: every drawn word of its lasso (each suffix step's interleaving repeated every cycle) satisfies the
  task, and the plan-wide placement realises the run;
* "unsatisfiable" on an over-approximation (every message but the word-family one): no word of any drawn TS
  lasso, in any region-changing order and interleaving, satisfies the task;
* "unsatisfiable" on the word-family product (deterministic NBA): every TS lasso drawn has some executed word
  that violates the task (model-checked on the lasso's word graph against a fresh NBA of ¬φ).
"""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrodrake.errors import NoPlanFound, UserError
from mrodrake.logic.lasso import evaluate_lasso
from mrodrake.planning.generate import generate_scenario_data
from mrodrake.planning.plan import plan_scenario, task_nba
from mrodrake.planning.semantics import ExecutedWords, check_plan_words, region_changing, relevant_mask
from mrodrake.scenario import scenario_from_dict
from mrodrake.ts import TransitionSystem
from tests.helpers.tasks import region_atoms

FAMILY = "for every plan some executed word violates the task"


@st.composite
def _tasks(draw):
    n, m = draw(st.integers(2, 3)), draw(st.integers(1, 2))
    k = 3
    seed = draw(st.integers(0, 10_000))
    atoms = st.sampled_from(region_atoms(n, m, k))
    lit = st.one_of(atoms, atoms.map(lambda a: f"!{a}"))
    conj = st.builds(lambda a, b: f"({a} & {b})", lit, lit)
    prop = st.one_of(lit, conj)
    clause = st.one_of(
        st.builds(lambda a, b: f"({a} U {b})", prop, prop),
        st.builds(lambda a: f"G {a}", lit),
        st.builds(lambda a: f"F {a}", prop),
        st.builds(lambda a: f"G F {a}", prop),
        st.builds(lambda a: f"F G {a}", prop),
        st.builds(lambda a, b: f"G ({a} -> F {b})", lit, prop))
    clauses = draw(st.lists(clause, min_size=1, max_size=3))
    return n, m, k, seed, " & ".join(clauses)


def _letters(ts, words, s, t, order, rng) -> list[int]:
    options = list(itertools.islice(words.step_words(s, t, order), 64))
    return options[rng.integers(len(options))]


def _drawn_words(ts, words, steps, loop, rng, draws):
    """``draws`` lasso words (prefix letters, cycle letters) of a lasso of TS steps."""
    for _ in range(draws):
        letters = [_letters(ts, words, s, t, o, rng) for s, t, o in steps]
        yield sum(letters[:loop], []), sum(letters[loop:], [])


def _random_lassos(ts, ets, rng, count, length=6):
    """Random TS lassos (steps with a random region-changing order) of at most ``length`` steps."""
    for _ in range(count):
        path = [0]
        while len(path) <= length:
            succ = ets.successors(path[-1])
            v = int(succ[rng.integers(len(succ))])
            if v in path:
                loop = path.index(v)
                break
            path.append(v)
        else:
            continue
        states = [ets.state(u) for u in path]
        steps = []
        for a, b in zip(states, states[1:] + [states[loop]]):
            moving = region_changing(ts.actions(a, b))
            steps.append((a, b, [moving[i] for i in rng.permutation(len(moving))]))
        yield steps, loop


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(task=_tasks())
def test_every_answer_agrees_with_the_lasso_oracle(task):
    n, m, k, seed, formula = task
    data = generate_scenario_data(n, m, k, seed)
    data["task"] = {"formula": formula, "propositions": {}}
    sc = scenario_from_dict(data)
    ts = TransitionSystem(sc)
    f, nba = task_nba(sc, ts)
    words = ExecutedWords(ts, nba, relevant_mask(ts, f))
    rng = np.random.default_rng(seed)
    try:
        plan = plan_scenario(sc, iterations=300, seed=seed, layout_seed=seed)
    except NoPlanFound:
        return
    except UserError as e:
        msg = str(e)
        assert msg.startswith("task is unsatisfiable: "), msg
        if ts.candidate_count(ts.initial) > 5_000:
            return
        ets = ts.build(max_states=20_000)
        for steps, loop in _random_lassos(ts, ets, rng, 30):
            if FAMILY in msg:
                assert not check_plan_words(ts, f, steps, loop), (msg, steps)
            else:
                drawn = _drawn_words(ts, words, steps, loop, rng, 8)
                assert not any(evaluate_lasso(f, u, v, ts.propositions) for u, v in drawn), (msg, steps)
        return
    assert plan.placement is not None
    run = [a[0] for _st, _p, _i, _j, a, _b, _acts, _c in plan.steps()]
    steps = [(a[0], b[0], acts) for _st, _p, _i, _j, a, b, acts, _c in plan.steps()]
    assert run[0] == ts.initial
    for u, v in _drawn_words(ts, words, steps, len(plan.prefix), rng, 16):
        assert evaluate_lasso(f, u, v, ts.propositions), (formula, u, v)
