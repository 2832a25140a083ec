"""The executed-word semantics against the lasso evaluator: on random small plans (random TS lassos with
random action orders) and random formulas over the plan's propositions, the plan's word model check agrees
with evaluating every executed word lasso directly, and the product successors with brute-force words."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrodrake.logic.formula import And, Ap, F, G, Implies, Not, Or, R, U, X
from mrodrake.logic.lasso import evaluate_lasso
from mrodrake.logic.translate import translate
from mrodrake.planning.semantics import ExecutedWords, check_plan_words, region_changing, relevant_mask

UNARY = (Not, X, F, G)
BINARY = (And, Or, Implies, U, R)
PROPS = ("r1_p1", "r1_p2", "r2_p1", "r2_p3", "o1_p1", "o1_p3")


def small_formulas(max_depth: int = 3):
    leaves = st.sampled_from([Ap(p) for p in PROPS])

    def level(depth):
        if depth == 0:
            return leaves
        sub = level(depth - 1)
        return st.one_of(leaves, st.builds(lambda op, x: op(x), st.sampled_from(UNARY), sub),
                         st.builds(lambda op, x, y: op(x, y), st.sampled_from(BINARY), sub, sub))

    return level(max_depth)


def random_lasso(ts, rng, prefix_len: int, cycle_len: int):
    """A prefix walk and a cycle that returns to its first state (by walking back the way it came)."""
    s = ts.initial
    prefix = []
    for _ in range(prefix_len):
        succ = [t for t in ts.successor_states(s) if t != s]
        prefix.append(s)
        s = succ[int(rng.integers(len(succ)))]
    out = [s]
    for _ in range(cycle_len):
        succ = [t for t in ts.successor_states(out[-1]) if t != out[-1]]
        out.append(succ[int(rng.integers(len(succ)))])
    back = out[-2:0:-1]  # the TS relation is symmetric: walk back to the start of the cycle
    return prefix, out + back


def words_of(ts, words: ExecutedWords, steps, loop_start: int):
    """Every (prefix word, cycle word) where each step keeps one crossing interleaving in every cycle."""
    per_step = [list(words.step_words(s, t, order)) for s, t, order in steps]
    for choice in itertools.product(*per_step):
        pre = [m for w in choice[:loop_start] for m in w]
        cyc = [m for w in choice[loop_start:] for m in w]
        yield pre, cyc


def letters(ts, masks):
    return [frozenset(p for b, p in enumerate(ts.propositions) if m >> b & 1) for m in masks]


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(small_formulas(), st.integers(0, 10**6), st.integers(0, 3), st.integers(1, 3))
def test_plan_word_check_agrees_with_the_lasso_evaluator(tiny, f, seed, n_prefix, n_cycle):
    ts = tiny.ts
    rng = np.random.default_rng(seed)
    prefix, cycle = random_lasso(ts, rng, n_prefix, n_cycle)
    run = prefix + cycle
    nxt = run[1:] + [cycle[0]]
    steps = []
    for s, t in zip(run, nxt):
        acts = list(ts.actions(s, t))
        moving = region_changing(acts)
        fixed = [a for a in acts if a not in moving]
        order = [moving[k] for k in rng.permutation(len(moving))]
        steps.append((s, t, tuple(fixed + order)))
    words = ExecutedWords(ts, translate(f).with_ap(ts.propositions), relevant_mask(ts, f))
    lassos = list(itertools.islice(words_of(ts, words, steps, len(prefix)), 64))
    every = all(evaluate_lasso(f, letters(ts, p), letters(ts, c)) for p, c in lassos)
    verdict = check_plan_words(ts, f, steps, len(prefix))
    if verdict:
        assert every  # sound: no executed word the check accepted violates the formula
    if not every:
        assert not verdict  # a violating executed lasso is found by the model check


@settings(max_examples=30, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(small_formulas(), st.integers(0, 10**6))
def test_successors_hold_for_every_interleaving_of_their_order(tiny, f, seed):
    """For every product successor q' and its order, each word of that order reaches q' from q (directly,
    letter by letter); a state not listed is missed by every order (checked by enumerating all orders)."""
    ts = tiny.ts
    nba = translate(f).with_ap(ts.propositions)
    words = ExecutedWords(ts, nba, relevant_mask(ts, f))
    rng = np.random.default_rng(seed)
    s = ts.initial
    for _ in range(int(rng.integers(0, 3))):
        succ = list(ts.successor_states(s))
        s = succ[int(rng.integers(len(succ)))]
    succ = list(ts.successor_states(s))
    t = succ[int(rng.integers(len(succ)))]
    for q in range(nba.num_states):
        got = words.successors(q, s, t)
        for q2, order in got.items():
            for w in words.step_words(s, t, order):
                S = {q}
                for m in w:
                    S = {d for x in S for d in nba.successors(x, m)}
                assert q2 in S
        moving = region_changing(ts.actions(s, t))
        if len(moving) <= 3:
            for perm in itertools.permutations(moving):
                common = None
                for w in words.step_words(s, t, perm):
                    S = {q}
                    for m in w:
                        S = {d for x in S for d in nba.successors(x, m)}
                    common = S if common is None else common & S
                assert common <= set(got)


def test_signature_and_rows_agree_with_the_step_key(case1):
    """The signature read off two states is the key's; rows asked one at a time are the matrix's rows."""
    ts, words = case1.ts, case1.words
    ets = ts.build()
    rng = np.random.default_rng(3)
    fresh = ExecutedWords(ts, case1.nba, case1.relevant)
    for u in rng.integers(0, ets.num_states, size=60):
        s = ets.state(int(u))
        for v in ets.successors(int(u))[:: 7]:
            t = ets.state(int(v))
            assert words.signature(s, t) == words.key(s, t)[:2]
            qs = list(range(words.Q))[:: 2]
            assert (fresh.rows(s, t, qs) == words.matrix(s, t)[qs]).all()


CASE1_PROPS = ("r1_p1", "r1_p2", "r1_p4", "r3_p1", "r3_p4", "o1_p1", "o1_p2", "o1_p4", "o2_p1", "o2_p4")


def _joint_search_agrees(ts, f, steps) -> int:
    """Assert that the joint search gives every start state its own search's rows; the steps compared."""
    words = ExecutedWords(ts, translate(f).with_ap(ts.propositions), relevant_mask(ts, f))
    n = 0
    for s, t in steps:
        mask, sig = words.signature(s, t)
        if sig and words._unbudgeted(len(sig)):
            joint = words._search_all(mask, sig)
            for q in range(words.Q):
                assert list(words._search(q, mask, sig).items()) == list(joint[q].items())
            n += 1
    return n


@settings(max_examples=30, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(small_formulas())
def test_the_search_from_all_start_states_at_once_is_the_search_from_each(tiny, f):
    """Searching a step's orders on relations (every start state at once) gives each start state the
    successors and orders, in the same sequence, that searching from that state alone gives (every step of
    the tiny TS; interleavings of a team's crossings can end in different NBA states)."""
    ets = tiny.ts.build()
    steps = [(ets.state(u), ets.state(int(v))) for u in range(ets.num_states) for v in ets.successors(u)]
    _joint_search_agrees(tiny.ts, f, steps)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(st.data(), st.integers(0, 10**6))
def test_the_joint_search_agrees_on_steps_with_several_actions(case1, data, seed):
    """The same on case I steps with several visible actions (families of subsets passed on)."""
    ts = case1.ts
    leaves = st.sampled_from([Ap(p) for p in CASE1_PROPS])
    f = data.draw(st.recursive(leaves, lambda sub: st.one_of(
        st.builds(lambda op, x: op(x), st.sampled_from(UNARY), sub),
        st.builds(lambda op, x, y: op(x, y), st.sampled_from(BINARY), sub, sub)), max_leaves=6))
    rng = np.random.default_rng(seed)
    s, steps = ts.initial, []
    for _ in range(6):
        succ = list(ts.successor_states(s))
        steps += [(s, succ[int(k)]) for k in rng.integers(0, len(succ), size=8)]
        s = succ[int(rng.integers(len(succ)))]
    _joint_search_agrees(ts, f, steps)
