"""Product TS ⊗ NBA: NBA pruning keeps the TS language, distances, explicit vs on-the-fly product,
and the vectorised transition test used by STyLuS* against the TS's own rule checker."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrodrake.logic.nba import NBA
from mrodrake.planning.product import (
    Product,
    accepting_on_cycle,
    cube_infeasibility,
    cycle_distances,
    hop_distances,
    prune_nba,
    useful_states,
)
from mrodrake.planning.stylus import _Transitions


def bit(ts, name: str) -> int:
    return 1 << ts.propositions.index(name)


@pytest.fixture(scope="module")
def tiny_ets(tiny):
    return tiny.ts.build()


@pytest.fixture(scope="module")
def case1_ets(case1):
    return case1.ts.build()


def test_cube_infeasibility_names_the_reason(tiny):
    ts = tiny.ts
    two = bit(ts, "r1_p1") | bit(ts, "r1_p2")
    assert "two regions" in cube_infeasibility(ts, two, 0)
    nowhere = bit(ts, "o1_p1") | bit(ts, "o1_p2") | bit(ts, "o1_p3")
    assert "no region" in cube_infeasibility(ts, 0, nowhere)
    assert cube_infeasibility(ts, bit(ts, "r1_p1"), bit(ts, "r2_p3")) is None
    # an object fixed in p1 (index 2 = o1) can satisfy o1_p1 but not o1_p3 or !o1_p1
    fixed = {2: 0}
    assert cube_infeasibility(ts, bit(ts, "o1_p1"), 0, fixed) is None
    assert "cannot leave" in cube_infeasibility(ts, bit(ts, "o1_p3"), 0, fixed)
    assert "cannot leave" in cube_infeasibility(ts, 0, bit(ts, "o1_p1"), fixed)


def test_cube_infeasibility_region_capacity(tiny):
    # a region of radius 3 m (spacing 0.1) cannot hold disks whose squared radii sum beyond 2.95²:
    # two robots (0.75) and the object fit by area, so the area bound must not reject them
    ts = tiny.ts
    cube = bit(ts, "r1_p1") | bit(ts, "r2_p1") | bit(ts, "o1_p1")
    assert cube_infeasibility(ts, cube, 0) is None


def test_prune_keeps_successors_on_every_ts_label(tiny, tiny_ets):
    ts = tiny.ts
    edges = [
        [([(bit(ts, "r1_p1") | bit(ts, "r1_p2"), 0), (bit(ts, "r1_p1"), bit(ts, "r2_p3"))], 1),
         ([(0, bit(ts, "o1_p1") | bit(ts, "o1_p2") | bit(ts, "o1_p3"))], 0)],
        [([(0, 0)], 1)],
    ]
    nba = NBA(ts.propositions, 0, [1], edges)
    pruned = prune_nba(nba, ts)
    assert pruned.num_edges == 2  # the "o1 nowhere" edge is gone, the mixed guard lost one cube
    assert len(pruned.edges[0][0][0]) == 1
    for u in range(tiny_ets.num_states):
        lab = ts.label_mask(tiny_ets.state(u))
        for q in range(nba.num_states):
            assert nba.successors(q, lab) == pruned.successors(q, lab)


@pytest.mark.parametrize("which", ["tiny", "case1"])
def test_prune_task_nba_keeps_language_on_ts_labels(which, request):
    case = request.getfixturevalue(which)
    ets = request.getfixturevalue(f"{which}_ets")
    pruned = prune_nba(case.nba, case.ts)
    labels = {case.ts.label_mask(ets.state(u)) for u in range(ets.num_states)}
    for lab in labels:
        for q in range(case.nba.num_states):
            assert case.nba.successors(q, lab) == pruned.successors(q, lab)


def test_distances_on_a_handmade_nba(tiny):
    ap = tiny.ts.propositions
    t = [(0, 0)]
    # 0 -> 1 -> 2 -> 3 ; 3 -> 2 ; 4 accepting but only reachable, not on a cycle: 0 -> 4
    nba = NBA(ap, 0, [3, 4], [[(t, 1), (t, 4)], [(t, 2)], [(t, 3)], [(t, 2)], []])
    assert accepting_on_cycle(nba) == frozenset({3})
    assert hop_distances(nba, [3]) == [3, 2, 1, 0, float("inf")]
    assert cycle_distances(nba, 3) == [3, 2, 1, 2, float("inf")]
    assert useful_states(nba) == frozenset({0, 1, 2, 3})


def _reachable_on_the_fly(product):
    start = product.initial
    seen = {start: None}
    todo = deque([start])
    rows = {}
    while todo:
        node = todo.popleft()
        row = sorted(set(product.successors(node)))
        rows[node] = row
        for nxt, _ in row:
            if nxt not in seen:
                seen[nxt] = None
                todo.append(nxt)
    return rows


def test_explicit_product_matches_on_the_fly(tiny, tiny_ets):
    product = Product(tiny.ts, tiny.nba, tiny.relevant)
    ep = product.build(tiny_ets)
    rows = _reachable_on_the_fly(product)
    reach = np.flatnonzero(ep.reachable())
    assert {ep.node(v) for v in reach} == set(rows)
    g = ep.graph
    for v in reach:
        node = ep.node(v)
        lo, hi = g.indptr[v], g.indptr[v + 1]
        explicit = sorted({(ep.node(int(w)), float(c)) for w, c in zip(g.indices[lo:hi], g.data[lo:hi])})
        assert explicit == sorted((n, float(c)) for n, c in rows[node])
    assert ep.node(ep.initial) == product.initial


@settings(max_examples=60)
@given(st.data())
def test_vectorised_transition_test_matches_rule_checker(case1, case1_ets, data):
    ts = case1.ts
    ets = case1_ets
    tr = _Transitions(ts)
    u = data.draw(st.integers(0, ets.num_states - 1))
    # half the rows: real successors of u (transitions), half: arbitrary states (mostly not)
    succ = ets.successors(u)
    picks = [int(succ[data.draw(st.integers(0, len(succ) - 1))]) for _ in range(20)]
    picks += [data.draw(st.integers(0, ets.num_states - 1)) for _ in range(20)]
    A = ets.states[u]
    B = ets.states[picks]
    want = np.array([ts.check_transition(ets.state(v), ets.state(u)) is None for v in picks])
    assert (tr.mask(B, A) == want).all()
    # the relation is symmetric on valid states, which the planner's rewiring relies on
    back = np.array([ts.check_transition(ets.state(u), ets.state(v)) is None for v in picks])
    assert (back == want).all()
    cost = tr.cost(A[None, :], B)
    assert np.allclose(cost, [ts.cost(ets.state(u), ets.state(v)) for v in picks])
    assert np.allclose(cost, [ts.cost(ets.state(v), ets.state(u)) for v in picks])
