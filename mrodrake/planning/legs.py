"""Exact re-planning of a lasso along its own NBA-state sequence (STyLuS*'s anytime improvement, small systems).

A lasso of the product visits NBA states q_0, q_1, ..., q_m (consecutive repeats merged).  With that sequence
and the lasso's accepting TS state s_a fixed, the cheapest prefix (from the initial state to (s_a, q_m)) and
the cheapest cycle (from (s_a, q_a) back to it) are shortest paths in a *layered* product: node (s, k) is TS
state s with NBA state q_k, an edge (s, k) → (t, k) or (s, k) → (t, k + 1) is a TS transition s → t (the idle
step s → s included) whose executed word takes the NBA from q_k to q_k or q_{k+1}
(:meth:`~mrodrake.planning.semantics.ExecutedWords.rows`).  :func:`replan` runs A* on it from the implicit TS
successors, so the result is the exact optimum over all lassos with that NBA sequence and accepting TS state.

The heuristic is exact on a relaxation, :class:`PositionGraph`: the regions of all entities only (grasps,
packing, passages and the NBA's self-loops dropped), one robot navigation or one transport by a minimal team
with enough power per move, costing the robots' travel.  Every TS step maps to a sequence of such moves of at
most its cost, and every executed letter of a step is the label of a position on that sequence with some
entities absent, so the layered distance h_k(p) (to finish layers k..m from positions p) is a lower bound.
The relaxation has K^(N+M) positions; :data:`MAX_POSITIONS` bounds where it is used.
"""

from __future__ import annotations

import heapq
import itertools
import math
import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from mrodrake.logic.nba import NBA
from mrodrake.ts import State, TransitionSystem

#: The relaxation is built only for systems with at most this many position vectors K^(N+M).
MAX_POSITIONS = 20_000

INF = math.inf


class PositionGraph:
    """The position relaxation of an object TS (module docstring): nodes are position vectors coded in radix K."""

    def __init__(self, ts: TransitionSystem):
        self.ts = ts
        N, M, K = ts.N, ts.M, ts.K
        self.n_ent = n_ent = N + M
        self.size = K ** n_ent
        self.radix = np.array([K ** (n_ent - 1 - e) for e in range(n_ent)], dtype=np.int64)
        codes = np.arange(self.size, dtype=np.int64)
        self.pos = (codes[:, None] // self.radix[None, :]) % K
        teams = [self._minimal_teams(j) for j in range(M)]
        dist = ts.dist
        rows, cols, data = [], [], []
        P = self.pos
        for i in range(N):
            for k in range(K):
                src = codes[P[:, i] != k]
                rows.append(src)
                cols.append(src + (k - P[src, i]) * self.radix[i])
                data.append(dist[P[src, i], k])
        for j in range(M):
            for team in teams[j]:
                together = np.all(P[:, list(team)] == P[:, [N + j]], axis=1)
                for k in range(K):
                    src = codes[together & (P[:, N + j] != k)]
                    shift = (k - P[src, N + j]) * (self.radix[N + j] + self.radix[list(team)].sum())
                    rows.append(src)
                    cols.append(src + shift)
                    data.append(len(team) * dist[P[src, N + j], k])
        # every move is reversible at the same cost, so distances from a set of positions are distances to it
        self._edges = (np.concatenate(rows), np.concatenate(cols), np.concatenate(data) + 0.0)

    def _minimal_teams(self, j: int) -> list[tuple[int, ...]]:
        """Teams whose power meets object j's requirement and that lose it without any one member."""
        ts = self.ts
        need = ts.required_power[j]
        out = []
        for n in range(1, ts.N + 1):
            for team in itertools.combinations(range(ts.N), n):
                power = sum(ts.power[i] for i in team)
                if power >= need and all(power - ts.power[i] < need for i in team):
                    out.append(team)
        return out

    def code(self, s: State) -> int:
        return int(np.dot(np.asarray(s[: self.n_ent], dtype=np.int64), self.radix))

    def cube_mask(self, pos: int, neg: int) -> np.ndarray:
        """Positions whose label, with some entities absent (in transit), satisfies the cube (pos, neg): every
        entity pos mentions is where pos asks, and every neg bit that holds belongs to an entity pos leaves free."""
        K = self.ts.K
        ok = np.ones(self.size, dtype=bool)
        fixed = set()
        for e in range(self.n_ent):
            for k in range(K):
                if pos >> (e * K + k) & 1:
                    ok &= self.pos[:, e] == k
                    fixed.add(e)
        for e in fixed:
            for k in range(K):
                if neg >> (e * K + k) & 1:
                    ok &= self.pos[:, e] != k
        return ok

    def layered(self, nba: NBA, seq: list[int], target: State) -> list[np.ndarray]:
        """h_k for k = 0..m: relaxed cost to go from positions p in layer k to ``target``'s positions in layer m,
        changing layer k → k + 1 at a position that allows a cube of :func:`change_cubes` (the first letter by
        which the NBA leaves q_k on its way to q_{k+1} within one step)."""
        m = len(seq) - 1
        h = [np.full(self.size, INF) for _ in range(m + 1)]
        h[m] = self._from_sources({self.code(target): 0.0})
        for k in range(m - 1, -1, -1):
            allow = np.zeros(self.size, dtype=bool)
            for pos, neg in change_cubes(nba, seq[k], seq[k + 1]):
                allow |= self.cube_mask(pos, neg)
            src = np.flatnonzero(allow & np.isfinite(h[k + 1]))
            h[k] = self._from_sources(dict(zip(src.tolist(), h[k + 1][src].tolist())))
        return h

    def _from_sources(self, offsets: dict[int, float]) -> np.ndarray:
        """min over sources p' of offsets[p'] + d(p, p') for every position p (one Dijkstra from the super node)."""
        if not offsets:
            return np.full(self.size, INF)
        r, c, d = self._edges
        n = len(offsets)
        # super node ``size``: its edges carry the offsets, shifted by 1 so that none has weight 0
        g = sp.csr_matrix((np.concatenate([d, np.fromiter(offsets.values(), float, n) + 1.0]),
                           (np.concatenate([r, np.full(n, self.size)]),
                            np.concatenate([c, np.fromiter(offsets, np.int64, n)]))),
                          shape=(self.size + 1, self.size + 1))
        return dijkstra(g, directed=True, indices=self.size)[: self.size] - 1.0


def nba_sequence(nodes: list[tuple[State, int]]) -> list[int]:
    """The NBA states of a run with consecutive repeats merged."""
    out: list[int] = []
    for _, q in nodes:
        if not out or out[-1] != q:
            out.append(q)
    return out


def change_cubes(nba: NBA, q: int, q2: int) -> list[tuple[int, int]]:
    """Cubes of the NBA edges q → x, x ≠ q, from which q2 is reachable: a step whose executed word takes q to q2
    reads a letter satisfying one of them."""
    succ = [{d for _, d in row} for row in nba.edges]
    reach = {q2}
    grew = True
    while grew:
        grew = False
        for x in range(nba.num_states):
            if x not in reach and succ[x] & reach:
                reach.add(x)
                grew = True
    return [c for guard, d in nba.edges[q] if d != q and d in reach for c in guard]


def _positive_literals(ts: TransitionSystem, cubes: list[tuple[int, int]]) -> list[tuple[np.ndarray, np.ndarray]]:
    """(entities, regions) of the positive literals of each cube."""
    K = ts.K
    out = []
    for pos, _ in cubes:
        bits = [b for b in range(pos.bit_length()) if pos >> b & 1]
        out.append((np.array([b // K for b in bits], dtype=np.int64), np.array([b % K for b in bits], dtype=np.int64)))
    return out


def replan(ts: TransitionSystem, words, graph: PositionGraph, nba: NBA, start: State, seq: list[int],
           target: State, bound: float, max_expansions: int = 4000,
           successors: dict[State, list[State]] | None = None, deadline: float | None = None,
           any_grasps: bool = False) -> tuple[float, list[tuple[State, int]]] | None:
    """Cheapest run from (start, seq[0]) to (target, seq[-1]) through the NBA states ``seq`` in order (layered
    product, module docstring) if it costs less than ``bound``: (cost, product nodes from start to target), else
    None (also after ``max_expansions`` expanded nodes or at ``deadline``, a :func:`time.perf_counter` value).  A
    run of a cycle (start == target) has at least one step.  ``successors`` caches TS successors between calls.
    With ``any_grasps`` the run may end at any state with ``target``'s regions (the first such state reached).

    Edges are checked when their head is taken from the queue.  A layer change s → t is queued only when every
    positive literal of some cube of :func:`change_cubes` holds in s or in t (else no letter of the step satisfies
    it)."""
    m = len(seq) - 1
    h = graph.layered(nba, seq, target)
    cubes = [_positive_literals(ts, change_cubes(nba, seq[k], seq[k + 1])) for k in range(m)]
    N, n_ent = ts.N, graph.n_ent
    dist, gc, radix = ts.dist, ts.grasp_cost, graph.radix
    tie = itertools.count()
    h0 = h[0][graph.code(start)]
    if not h0 < bound:
        return None
    heap = [(h0, -0.0, next(tie), start, 0, None)]
    done: dict[tuple[State, int], float] = {}
    parent: dict[tuple[State, int], tuple[State, int] | None] = {}
    expansions = 0
    while heap:
        _, neg_g, _, s, k, par = heapq.heappop(heap)
        g = -neg_g
        key = (s, k)
        if g >= done.get(key, INF) - 1e-9:
            continue
        if par is not None and not words.rows(par[0], s, [seq[par[1]]])[0, seq[k]]:
            continue
        done[key] = g
        parent[key] = par
        if k == m and par is not None and (s[:n_ent] == target[:n_ent] if any_grasps else s == target):
            out = [(s, seq[k])]
            node = par
            while node is not None:
                out.append((node[0], seq[node[1]]))
                node = parent[node]
            return g, out[::-1]
        expansions += 1
        if expansions > max_expansions or deadline is not None and time.perf_counter() > deadline:
            return None
        succ = successors.get(s) if successors is not None else None
        if succ is None:
            succ = [s, *ts.successor_states(s)]
            if successors is not None:
                successors[s] = succ
        T = np.array(succ, dtype=np.int64)
        S = T[0]
        c = g + dist[S[None, :N], T[:, :N]].sum(axis=1) + gc * (T[:, n_ent:] != S[None, n_ent:]).sum(axis=1)
        ct = T[:, :n_ent] @ radix
        layers = [(k, h[k][ct])]
        if k < m:
            near = np.zeros(len(T), dtype=bool)
            for ent, reg in cubes[k]:
                near |= np.all((S[ent] == reg)[None, :] | (T[:, ent] == reg[None, :]), axis=1)
            layers.append((k + 1, np.where(near, h[k + 1][ct], INF)))
        for k2, hk in layers:
            f = c + hk
            for r in np.flatnonzero(f < bound - 1e-9):
                if r == 0 and k2 == k:
                    continue
                t = succ[r]
                cr = float(c[r])
                if cr < done.get((t, k2), INF) - 1e-9:
                    heapq.heappush(heap, (float(f[r]), -cr, next(tie), t, k2, key))
    return None


class LassoImprover:
    """Re-plans STyLuS* lassos with :func:`replan` (prefix and cycle apart, each along its own NBA sequence and
    through the lasso's accepting TS state); caches TS successors across calls.  A lasso with the same start,
    NBA sequences and accepting TS state as one re-planned before is not re-planned again: the searches along
    those sequences found the cheapest legs then (None)."""

    def __init__(self, ts: TransitionSystem, words, nba: NBA, max_expansions: int = 6000):
        self.ts, self.words, self.nba = ts, words, nba
        self.graph = PositionGraph(ts)
        self.max_expansions = max_expansions
        self._succ: dict[State, list[State]] = {}
        self._done: set[tuple] = set()

    @staticmethod
    def applies(ts: TransitionSystem) -> bool:
        """Object TS small enough for the position relaxation (:data:`MAX_POSITIONS`)."""
        return not getattr(ts, "reads_source_label", False) and ts.K ** (ts.N + ts.M) <= MAX_POSITIONS

    def _cost(self, nodes: list[tuple[State, int]], closing: State) -> float:
        states = [s for s, _ in nodes] + [closing]
        return float(sum(self.ts.cost(a, b) for a, b in zip(states, states[1:])))

    def improve(self, prefix: list, suffix: list,
                deadline: float | None = None) -> tuple[list, list, float, float] | None:
        """(prefix, suffix, prefix cost, suffix cost) of a cheaper lasso, or None; each search stops at ``deadline``.

        Same format as STyLuS*'s (prefix nodes before the accepting node, cycle nodes from it).  The prefix is
        re-planned to the accepting NBA state at any state with the regions of the accepting TS state s_a (grasps
        free: the cheapest such state s') and the cycle through s'; when that gives no cheaper lasso, prefix and
        cycle through s_a itself."""
        a = suffix[0]
        prefix_seq, cycle_seq = nba_sequence(prefix + [a]), nba_sequence(suffix + [a])
        key = (prefix[0][0] if prefix else None, tuple(prefix_seq), tuple(cycle_seq), a[0])
        if key in self._done:
            return None
        self._done.add(key)
        pc, sc = self._cost(prefix, a[0]), self._cost(suffix, a[0])
        run = (self.ts, self.words, self.graph, self.nba)
        limits = (self.max_expansions, self._succ, deadline)

        def prefixes():
            if not prefix:
                yield 0.0, [a]
                return
            free = replan(*run, prefix[0][0], prefix_seq, a[0], pc, *limits, any_grasps=True)
            if free is not None:
                yield free
            if free is None or free[1][-1][0] != a[0]:
                fixed = replan(*run, prefix[0][0], prefix_seq, a[0], pc, *limits)
                yield fixed if fixed is not None else (pc, prefix + [a])

        for new_pc, path in prefixes():
            s_a = path[-1][0]
            bound = pc + sc - new_pc
            found = replan(*run, s_a, cycle_seq, s_a, min(bound, sc) if s_a == a[0] else bound, *limits)
            if found is not None:
                new_prefix, new_suffix = path[:-1], found[1][:-1]
            elif s_a == a[0]:
                new_prefix, new_suffix = path[:-1], suffix
            else:
                continue
            total_pc, total_sc = self._cost(new_prefix, s_a), self._cost(new_suffix, s_a)
            if total_pc + total_sc < pc + sc - 1e-9:
                return new_prefix, new_suffix, total_pc, total_sc
        return None
