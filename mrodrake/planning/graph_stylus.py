"""The STyLuS* strategy of multi-robot graph transition systems (:class:`~mrodrake.planning.graph.GraphTS`).

STyLuS* (:class:`~mrodrake.planning.stylus.Stylus`) shares trees, rewiring, the NBA distances and suffix
search between transition systems; what depends on the TS is a *strategy*: NBA pruning, the word semantics,
the vectorised transition test and costs, the goal a guard cube sets and the successor sampler.

* **Pruning**: a cube is dropped when no placement of the robots satisfies it: the ``all`` predicates it
  requires and the ``any`` predicates it forbids leave some robot no vertex it can reach, an ``any``
  predicate it requires has no clause left, or an ``all`` predicate it forbids is forced.
* **Goal** of a cube: every robot of a required ``all`` predicate heads for its vertex set, a required
  ``any`` predicate sends its nearest robot; closing a suffix, the robots the cube leaves free head for
  their vertex in the root state.
* **Sampler**: with probability ``p_new`` the robots with a goal take one step along a shortest path
  (edge weights) to it and the others stay (or take a random edge without a self-loop); a robot whose step
  makes a predicate the cube forbids true takes a random edge instead (a few repairs).  Otherwise each robot
  takes a uniformly random edge with probability min(1, 4/N) and stays else, so every successor has positive
  probability.  (The MATLAB code moves every robot at random in both modes except the goal's robots; here
  idle robots stay, which keeps the plans' cost down, and 0.8 toward is the same.)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse.csgraph import dijkstra

from mrodrake.logic.nba import NBA
from mrodrake.planning.graph import GraphTS
from mrodrake.planning.semantics import SourceWords
from mrodrake.ts import State


class GraphTransitions:
    """Vectorised transition test and costs between one state and many (rows of an int array)."""

    def __init__(self, ts: GraphTS):
        self.ts = ts

    def _edge(self, U: np.ndarray, V: np.ndarray) -> np.ndarray:
        return self.ts.has_edges(U, V)

    def mask(self, X: np.ndarray, s) -> np.ndarray:
        """``ok[r]``: is ``X[r] → s`` a transition?  Robots are checked one after the other on the rows
        still possible (most rows fail on the first robots)."""
        s = np.asarray(s, dtype=np.int64).ravel()
        rows = np.arange(len(X))
        for i in range(len(s)):
            rows = rows[self._edge(X[rows, i].astype(np.int64), np.full(len(rows), s[i]))]
            if len(rows) == 0:
                break
        ok = np.zeros(len(X), dtype=bool)
        ok[rows] = True
        return ok

    def mask_from(self, s, X: np.ndarray) -> np.ndarray:
        """``ok[r]``: is ``s → X[r]`` a transition?"""
        s = np.asarray(s, dtype=np.int64).ravel()
        rows = np.arange(len(X))
        for i in range(len(s)):
            rows = rows[self._edge(np.full(len(rows), s[i]), X[rows, i].astype(np.int64))]
            if len(rows) == 0:
                break
        ok = np.zeros(len(X), dtype=bool)
        ok[rows] = True
        return ok

    def cost(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """Σ_i w(A[r, i], B[r, i]) (rows broadcast)."""
        A, B = np.broadcast_arrays(np.asarray(A, dtype=np.int64), np.asarray(B, dtype=np.int64))
        return self.ts.weights(A, B).sum(axis=1)


@dataclass
class GraphGoal:
    """Target vertex sets: ``all_of`` robot -> bool mask over vertices; ``any_of``: groups of (robot, mask),
    one of which suffices; ``target``: robot -> vertex (closing a suffix); ``forbidden``: predicate
    indices that must stay false."""

    all_of: dict = field(default_factory=dict)
    any_of: list = field(default_factory=list)
    target: dict = field(default_factory=dict)
    forbidden: list = field(default_factory=list)


class GraphStrategy:
    """TS-specific parts of STyLuS* for a :class:`GraphTS` (module docstring)."""

    symmetric: bool
    #: Probability that STyLuS* expands the closest not yet focused node of its best bucket (see
    #: ``_Tree.select``): a chain of steps toward a goal then takes as many iterations as steps.
    focus = 0.5
    first_plan_focus = 0.5  # the same before the first plan

    def __init__(self, ts: GraphTS, relevant: int):
        self.ts, self.relevant = ts, int(relevant)
        self.p_rand = ts.scenario.planning.p_rand
        self.p_new = ts.scenario.planning.p_new
        self.transitions = GraphTransitions(ts)
        self.symmetric = ts.symmetric
        self.dtype = np.int16 if ts.K < 2**15 else np.int32
        self._reach: dict[int, np.ndarray] = {}
        self._paths: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._goals: dict[tuple, GraphGoal | None] = {}
        self.loops = np.zeros(ts.K, dtype=bool)
        coo = ts.adj.tocoo()
        self.loops[coo.row[coo.row == coo.col]] = True
        self._scale = float(np.nanmax(np.where(np.isfinite(ts.adj.data), ts.adj.data, np.nan), initial=1.0)) * ts.N + 1

    # ------------------------------------------------------------------------------------ NBA side
    def words(self, nba: NBA) -> SourceWords:
        return SourceWords(self.ts, nba, self.relevant)

    def prune(self, nba: NBA) -> NBA:
        edges = [[([c for c in g if self.cube_infeasibility(*c) is None], d) for g, d in row] for row in nba.edges]
        return NBA(nba.ap, nba.initial, nba.accepting, [[(g, d) for g, d in row if g] for row in edges])

    def reach(self, i: int) -> np.ndarray:
        """Vertices robot i can ever be at."""
        v0 = self.ts.initial[i]
        r = self._reach.get(v0)
        if r is None:
            d = dijkstra(self.ts.adj, directed=True, indices=v0, unweighted=True)
            r = self._reach[v0] = np.isfinite(d)
        return r

    def _split(self, pos: int, neg: int):
        ts = self.ts
        preds = ts.predicates
        return ([preds[b] for b in range(len(preds)) if pos >> b & 1],
                [preds[b] for b in range(len(preds)) if neg >> b & 1])

    def _member(self, vs: np.ndarray) -> np.ndarray:
        m = np.zeros(self.ts.K, dtype=bool)
        m[vs] = True
        return m

    def cube_infeasibility(self, pos: int, neg: int) -> str | None:
        """Why no placement of the robots satisfies the cube (None if one might)."""
        if pos & neg:
            return "a proposition is required both true and false"
        ts = self.ts
        yes, no = self._split(pos, neg)
        allowed: dict[int, np.ndarray] = {}

        def restrict(r: int, m: np.ndarray) -> None:
            allowed[r] = (allowed[r] if r in allowed else self.reach(r)) & m

        for p in yes:
            if p.mode == "all":
                for r, vs in p.clauses:
                    restrict(r, self._member(vs))
        for p in no:
            if p.mode == "any":
                for r, vs in p.clauses:
                    restrict(r, ~self._member(vs))
        for r, m in allowed.items():
            if not m.any():
                return f"robot {ts.robot_names[r]} would have no vertex left"
        for p in yes:
            if p.mode == "any" and not any((allowed.get(r, self.reach(r)) & self._member(vs)).any()
                                           for r, vs in p.clauses):
                return f"no clause of {p.name} can hold"
        for p in no:
            if p.mode == "all" and all(not (allowed.get(r, self.reach(r)) & ~self._member(vs)).any()
                                       for r, vs in p.clauses):
                return f"{p.name} would be forced true"
        return None

    # ------------------------------------------------------------------------------------ paths
    def paths(self, member: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(weighted distance, hops, next vertex) toward the vertex set ``member`` from every vertex."""
        key = np.packbits(member).tobytes()
        hit = self._paths.get(key)
        if hit is None:
            ts = self.ts
            src = np.flatnonzero(member)
            rev = ts.adj.T.tocsr()
            dist = dijkstra(rev, directed=True, indices=src, min_only=True)
            hops = dijkstra(rev, directed=True, indices=src, min_only=True, unweighted=True)
            adj = ts.adj
            deg = np.diff(adj.indptr)
            owner = np.repeat(np.arange(ts.K), deg)
            # staying ties with the best edge on the way (dist[v] = w + dist[u]): only stay at the goal
            vals = np.where((adj.indices == owner) & (dist[owner] > 0), np.inf, adj.data + dist[adj.indices])
            nxt = np.arange(ts.K)
            has = deg > 0
            if has.any():
                starts = adj.indptr[:-1][has]
                best = np.minimum.reduceat(vals, starts)
                rows = owner
                hit_best = vals <= best[np.searchsorted(np.flatnonzero(has), rows)] + 1e-12
                first = np.full(ts.K, -1)
                idx = np.flatnonzero(hit_best)
                first[rows[idx][::-1]] = adj.indices[idx][::-1]
                nxt = np.where(first >= 0, first, nxt)
            hit = self._paths[key] = (dist, hops, nxt)
        return hit

    # ------------------------------------------------------------------------------------ goals
    def goal(self, pos: int, neg: int, target: State | None) -> GraphGoal | None:
        key = (pos, neg, target)
        if key in self._goals:
            return self._goals[key]
        yes, no = self._split(pos, neg)
        g = GraphGoal()
        for p in yes:
            if p.mode == "all":
                for r, vs in p.clauses:
                    m = self._member(vs)
                    g.all_of[r] = g.all_of[r] & m if r in g.all_of else m
            else:
                g.any_of.append([(r, self._member(vs)) for r, vs in p.clauses])
        g.forbidden = [self.ts.predicates.index(p) for p in no]
        if target is not None:
            g.target = {i: int(v) for i, v in enumerate(target) if i not in g.all_of}
        if not g.all_of and not g.any_of and not g.target:
            g = None
        self._goals[key] = g
        return g

    def cube_steps(self, s: State, pos: int, neg: int, target: State | None = None) -> float:
        """Largest number of hops a robot needs to satisfy the cube's requirements and, closing a suffix, to
        reach its vertex in ``target`` (ties: total distance)."""
        g = self.goal(pos, neg, target)
        if g is None:
            return 0.0
        hops, dist = 0.0, 0.0
        for r, v in g.target.items():
            if s[r] != v:
                d, h, _ = self.paths(self._member(np.array([v])))
                hops = max(hops, h[s[r]])
                dist += d[s[r]]
        for r, m in g.all_of.items():
            d, h, _ = self.paths(m)
            hops = max(hops, h[s[r]])
            dist += d[s[r]]
        for group in g.any_of:
            best = min(((self.paths(m)[1][s[r]], self.paths(m)[0][s[r]]) for r, m in group))
            hops = max(hops, best[0])
            dist += best[1]
        return hops + dist / self._scale

    def sampler(self, rng: np.random.Generator) -> GraphSampler:
        return GraphSampler(self, rng)

    def no_plan_note(self) -> str:
        return ""

    def can_idle(self, s: State) -> bool:
        """Is s → s a transition (a self-loop at every robot's vertex)?"""
        return bool(self.loops[list(s)].all())


class GraphSampler:
    """Successors of a graph TS state (module docstring); ``stats`` counts the kinds of samples."""

    repairs = 3

    def __init__(self, strategy: GraphStrategy, rng: np.random.Generator):
        self.st, self.ts, self.rng = strategy, strategy.ts, rng
        adj = self.ts.adj
        self.indptr, self.indices = adj.indptr, adj.indices
        self.deg = np.diff(adj.indptr)
        self.loop = np.zeros(self.ts.K, dtype=bool)
        coo = adj.tocoo()
        self.loop[coo.row[coo.row == coo.col]] = True
        self.stats = {"toward": 0, "random": 0, "repaired": 0}
        #: probability that a robot moves in a random successor: about four robots per step
        self.p_move = min(1.0, 4.0 / max(1, self.ts.N))

    def random_moves(self, s: np.ndarray, robots: np.ndarray) -> np.ndarray:
        """A uniformly random out-neighbour of each of ``robots`` (its vertex when it has none)."""
        v = s[robots]
        d = self.deg[v]
        pick = (self.rng.random(len(v)) * np.maximum(d, 1)).astype(np.int64)
        return np.where(d > 0, self.indices[self.indptr[v] + np.minimum(pick, np.maximum(d - 1, 0))], v)

    def random(self, s: State) -> State:
        """Each robot takes a uniformly random out-edge with probability ``p_move`` (always when it cannot
        stay), else stays: every successor has positive probability."""
        self.stats["random"] += 1
        x = np.asarray(s, dtype=np.int64)
        who = np.flatnonzero((self.rng.random(len(x)) < self.p_move) | ~self.loop[x])
        t = x.copy()
        t[who] = self.random_moves(x, who)
        return tuple(int(v) for v in t)

    def toward(self, s: State, goal: GraphGoal) -> State:
        self.stats["toward"] += 1
        st = self.st
        x = np.asarray(s, dtype=np.int64)
        t = x.copy()
        moved = np.zeros(len(x), dtype=bool)
        for r, m in goal.all_of.items():
            t[r] = st.paths(m)[2][x[r]]
            moved[r] = True
        for group in goal.any_of:
            r, m = min(group, key=lambda c: st.paths(c[1])[0][x[c[0]]])
            if not moved[r]:
                t[r] = st.paths(m)[2][x[r]]
                moved[r] = True
        for r, v in goal.target.items():
            if not moved[r] and x[r] != v:
                t[r] = st.paths(st._member(np.array([v])))[2][x[r]]
                moved[r] = True
        idle = np.flatnonzero(~moved & ~self.loop[x])
        if len(idle):
            t[idle] = self.random_moves(x, idle)
        for _ in range(self.repairs):
            bad = [p for p in goal.forbidden if self.ts.predicates[p].holds(t)]
            if not bad:
                break
            self.stats["repaired"] += 1
            robots = np.array(sorted({r for p in bad for r, _ in self.ts.predicates[p].clauses}), dtype=np.int64)
            t[robots] = self.random_moves(x, robots)
        return tuple(int(v) for v in t)

    def sample(self, s: State, goal: GraphGoal | None, p_new: float) -> State:
        if goal is not None and self.rng.random() < p_new:
            return self.toward(s, goal)
        return self.random(s)
