"""Degeneralization of a GBA into a state-based Büchi automaton by a level counter, after Gastin &
Oddoux, "Fast LTL to Büchi automata translation", CAV 2001, LNCS 2102, Sec. 5; optionally SCC-aware with
a level cache, as in Spot's ``degeneralize()`` (``spot/twaalgos/degen.cc``)."""

from __future__ import annotations

from collections.abc import Sequence

from mrodrake.logic.bdd import BDD
from mrodrake.logic.graph import sccs
from mrodrake.logic.translate.ba import BA

__all__ = ["degeneralize"]


def degeneralize(trans: list[list[tuple]], nacc: int, order: Sequence[int], bdd: BDD,
                 scc_aware: bool = False) -> BA:
    """Counter-based degeneralization to a state-based BA (Gastin & Oddoux, Sec. 5): BA states are pairs
    (GBA state, level ``0..nacc``); level ``nacc`` is accepting; acceptance sets are visited in ``order``.

    With ``scc_aware`` (as in Spot's degeneralization), levels only matter inside an SCC: a transition
    entering another SCC goes to the level with which its target was first created ("level cache"),
    and states of SCCs that cannot be accepting keep level 0."""
    if nacc == 0:
        edges = []
        for ts in trans:
            row: dict[int, int] = {}
            for g, d, _ in ts:
                row[d] = bdd.disj(row.get(d, 0), g)
            edges.append(row)
        return BA(edges, [True] * len(trans), 0, bdd)
    comp_of: list[int] = [0] * len(trans)
    live_comp: list[bool] = []
    if scc_aware:
        succ = [[d for _, d, _ in ts] for ts in trans]
        full = (1 << nacc) - 1
        for ci, comp in enumerate(sccs(list(range(len(trans))), succ)):
            marks = 0
            for s in comp:
                comp_of[s] = ci
            inside = set(comp)
            for s in comp:
                for _, d, a in trans[s]:
                    if d in inside:
                        marks |= a
            live_comp.append(marks == full and (len(comp) > 1 or any(d == comp[0] for d in succ[comp[0]])))

    def nxt(j: int, a: int) -> int:
        if j == nacc:
            j = 0
        while j < nacc and a >> order[j] & 1:
            j += 1
        return j

    ids = {(0, 0): 0}
    states = [(0, 0)]
    first_level: dict[int, int] = {0: 0}
    edges = []
    head = 0
    while head < len(states):
        s, j = states[head]
        head += 1
        row = {}
        for g, d, a in trans[s]:
            if not scc_aware:
                key = (d, nxt(j, a))
            elif not live_comp[comp_of[d]]:
                key = (d, 0)
            elif comp_of[d] != comp_of[s]:
                key = (d, first_level.setdefault(d, nxt(0, a)))
            else:
                key = (d, nxt(j, a))
            first_level.setdefault(d, key[1])
            q = ids.get(key)
            if q is None:
                q = ids[key] = len(states)
                states.append(key)
            row[q] = bdd.disj(row.get(q, 0), g)
        edges.append(row)
    return BA(edges, [j == nacc for _, j in states], 0, bdd)
