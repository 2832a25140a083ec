"""Planning on every executed word at once: the word-family product.

The planning product of :mod:`mrodrake.planning.product` asks each step to reach **one** NBA state q' on every
crossing interleaving.  That is sound but misses plans whose interleavings part for a step and meet again
later (an object entering its region before or after its carrier, read by an NBA whose guards tell the two
letters apart).  Here a product node keeps, for the words executing the plan so far may be, a *family* of
members (S0, S1): the NBA states one class of those words can be in without (S0) and with (S1) an accepting
state passed since the last breakpoint.  A step maps every member through every crossing interleaving of its
actions in the chosen order (each interleaving a new member); only the minimal members are kept (a member
whose S0 ∪ S1 and S1 contain another's is implied by it).  A node is dead when a member is empty (some word
has no NBA run).  When every member has S1 ≠ ∅ the node is a *breakpoint* (accepting): every word has a run
that passed an accepting state since the previous one, and the members restart as (S1, ∅), so the runs of
consecutive segments compose (Miyano–Hayashi).  A reachable cycle through a breakpoint is a plan every
executed word of which the NBA accepts: sound by construction.  For a deterministic NBA each word has one run
and the construction is exact, so no such cycle proves that no plan exists (:func:`solve_families`).
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from mrodrake.logic.nba import NBA
from mrodrake.planning.product import optimal_lasso
from mrodrake.planning.semantics import ExecutedWords, _apply, _events, region_changing
from mrodrake.ts import Action, ExplicitTS, Navigate, State, TransitionSystem, Transport

Member = tuple[int, int]


@dataclass(frozen=True)
class Family:
    """A node's NBA side: the minimal members (S0, S1) as bit masks, sorted, and whether the node is a
    breakpoint (the members are then the restarted ones)."""

    members: tuple[Member, ...]
    accepting: bool = False

    @staticmethod
    def of_state(q: int) -> Family:
        return Family(((1 << q, 0),))

    def states(self) -> int:
        """Every NBA state some member holds (bit mask)."""
        out = 0
        for a, b in self.members:
            out |= a | b
        return out

    def admits(self, run: int) -> bool:
        """Is an observed subset run ``run`` (bit mask) one of the words the family stands for (some member's
        states all in it)?"""
        return any((a | b) & ~run == 0 for a, b in self.members)

    def to_dict(self) -> dict:
        def bits(m: int) -> list[int]:
            return [q for q in range(m.bit_length()) if m >> q & 1]

        return {"members": [[bits(a), bits(b)] for a, b in self.members], "accepting": self.accepting}

    @staticmethod
    def from_dict(d: dict) -> Family:
        members = tuple((sum(1 << int(q) for q in a), sum(1 << int(q) for q in b)) for a, b in d["members"])
        return Family(tuple(sorted(members)), bool(d.get("accepting", False)))


def minimal(members) -> tuple[Member, ...]:
    """The minimal members (sorted): (S0, S1) is implied by (T0, T1) when T1 ⊆ S1 and T0 ⊆ S0 ∪ S1."""
    ms = sorted({(a & ~b, b) for a, b in members}, key=lambda m: (bin(m[0] | m[1]).count("1"), m))
    out: list[Member] = []
    for a, b in ms:
        if not any(tb & ~b == 0 and ta & ~(a | b) == 0 for ta, tb in out):
            out.append((a, b))
    return tuple(sorted(out))


class FamilyWords:
    """Family steps (module docstring) on the executed-word semantics ``words``."""

    def __init__(self, words: ExecutedWords):
        self.words = words
        self.acc = sum(1 << f for f in words.nba.accepting)
        self._cache: dict[tuple, Family | None] = {}
        #: Some step had more orders than ``words.max_orders`` (then not every order was tried).
        self.truncated = False

    def _letter(self, m: Member, letter: int) -> Member:
        a, b = m
        t = self.words.delta(a, letter)
        return (t & ~self.acc, (t & self.acc) | self.words.delta(b, letter))

    def _action(self, members: frozenset, mask: int, cross: tuple) -> tuple[frozenset, int]:
        events, pre = _events(cross)
        n = len(events)
        fam = {0: set(members)}
        masks = {0: mask}
        for D in range(1 << n):
            if D not in fam:
                continue
            letter = masks[D]
            images = {self._letter(m, letter) for m in fam[D]}
            for i in range(n):
                if not D >> i & 1 and D & pre[i] == pre[i]:
                    D2 = D | 1 << i
                    fam.setdefault(D2, set()).update(images)
                    masks[D2] = _apply(letter, events[i])
        full = (1 << n) - 1
        return frozenset(minimal(fam[full])), masks[full]

    def step(self, F: Family, mask: int, sig: Sequence[tuple]) -> Family | None:
        """The family after a step whose source label is ``mask`` and whose visible actions have the
        crossing signatures ``sig`` in execution order; None when some word has no NBA run."""
        key = (F.members, mask, tuple(sig))
        if key in self._cache:
            out = self._cache[key]
        else:
            members = frozenset(F.members)
            if not sig:
                members = frozenset(self._letter(m, mask) for m in members)
            else:
                m = mask
                for cross in sig:
                    members, m = self._action(members, m, cross)
            ms = minimal(members)
            if any(a | b == 0 for a, b in ms):
                out = None
            elif all(b for _, b in ms):
                out = Family(minimal((b, 0) for _, b in ms), True)
            else:
                out = Family(ms)
            self._cache[key] = out
        return out

    def orders(self, s: State, t: State) -> list[tuple[tuple[Action, ...], tuple]]:
        """(region-changing actions in execution order, crossing signatures of their visible ones) for every
        order of the visible actions of s → t (at most ``max_orders``, lexicographic)."""
        words = self.words
        mask, sig, vis = words.key(s, t)
        acts = region_changing(words.ts.actions(s, t))
        out = []
        if math.factorial(len(vis)) > words.max_orders:
            self.truncated = True
        for perm in itertools.islice(itertools.permutations(range(len(vis))), words.max_orders):
            out.append((words._full_order(acts, vis, perm), tuple(sig[i] for i in perm)))
        return out

    def execute(self, F: Family, s: State, t: State, order: Sequence[Action]) -> Family | None:
        """The family after s → t with its actions in ``order``."""
        mask = self.words.ts.label_mask(s) & self.words.relevant
        sig = [c for a in region_changing(order) if (c := self.words.crossings(a))]
        return self.step(F, mask, sig)


@dataclass
class FamilyResult:
    """A lasso of (TS state, Family) nodes, the actions of each step in execution order, and costs (an empty
    suffix: no lasso exists)."""

    prefix: list[tuple[State, Family]]
    suffix: list[tuple[State, Family]]
    orders: list[tuple[Action, ...]]
    prefix_cost: float
    suffix_cost: float
    stats: dict


def is_deterministic(nba: NBA) -> bool:
    """Does every letter lead from every state to at most one state (guards to different states disjoint)?"""
    for row in nba.edges:
        cubes = [(p, n, d) for g, d in row for p, n in g]
        for (p1, n1, d1), (p2, n2, d2) in itertools.combinations(cubes, 2):
            if d1 != d2 and not (p1 & n2 or p2 & n1):
                return False
    return True


def solve_families(ts: TransitionSystem, words: ExecutedWords, ets: ExplicitTS,
                   max_nodes: int = 2_000_000) -> FamilyResult | None:
    """The cheapest lasso of the word-family product over ``ets`` (module docstring); without a reachable cycle
    through a breakpoint the result has an empty suffix (its stats say whether every order of every step was
    tried).  Raises MemoryError beyond ``max_nodes`` product nodes."""
    t0 = time.perf_counter()
    fw = FamilyWords(words)
    nba = words.nba
    F0 = Family.of_state(nba.initial)
    index: dict[tuple[int, Family], int] = {(0, F0): 0}
    nodes: list[tuple[int, Family]] = [(0, F0)]
    rows, cols, costs, order_of = [], [], [], []
    per_edge: dict[tuple[int, int], list] = {}
    k = 0
    while k < len(nodes):
        u, F = nodes[k]
        s = ets.state(u)
        for e in range(ets.indptr[u], ets.indptr[u + 1]):
            v = int(ets.targets[e])
            opts = per_edge.get((u, v))
            if opts is None:
                opts = per_edge[(u, v)] = fw.orders(s, ets.state(v))
            mask = ts.label_mask(s) & words.relevant
            seen: set[Family] = set()
            for order, sig in opts:
                G = fw.step(F, mask, sig)
                if G is None or G in seen:
                    continue
                seen.add(G)
                key = (v, G)
                j = index.get(key)
                if j is None:
                    j = index[key] = len(nodes)
                    nodes.append(key)
                    if len(nodes) > max_nodes:
                        raise MemoryError(f"word-family product beyond {max_nodes} nodes")
                rows.append(k)
                cols.append(j)
                costs.append(float(ets.costs[e]))
                order_of.append(order)
        k += 1
    n = len(nodes)
    g = sp.csr_matrix((np.array(costs), (np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64))),
                      shape=(n, n))
    edge_order = {}
    for r, c, o in zip(rows, cols, order_of):
        edge_order.setdefault((r, c), o)
    accepting = np.array([F.accepting for _, F in nodes], dtype=bool)
    stats = {"family_nodes": n, "family_edges": len(rows), "family_orders_truncated": fw.truncated}
    found = optimal_lasso(g, 0, accepting, stats)
    stats["family_seconds"] = time.perf_counter() - t0
    if found is None:
        return FamilyResult([], [], [], math.inf, math.inf, stats)
    prefix_ids, cycle_ids = found
    run = list(prefix_ids) + list(cycle_ids)
    nxt = run[1:] + [cycle_ids[0]]
    orders = []
    for a, b in zip(run, nxt):
        fixed = tuple(x for x in ts.actions(ets.state(nodes[a][0]), ets.state(nodes[b][0]))
                      if not isinstance(x, (Navigate, Transport)))
        orders.append(fixed + edge_order[(a, b)])
    node = [(ets.state(nodes[i][0]), nodes[i][1]) for i in run]
    P = len(prefix_ids)
    step_cost = [ts.cost(node[i][0], (node[i + 1] if i + 1 < len(node) else node[P])[0]) for i in range(len(node))]
    return FamilyResult(node[:P], node[P:], orders, float(sum(step_cost[:P])), float(sum(step_cost[P:])), stats)
