"""STyLuS* (Kantaros & Zavlanos, IJRR 2020): sampling-based prefix-suffix planning on TS ⊗ NBA.

The product is never built.  The algorithm, as implemented here:

1. **NBA pruning and distances.**  Guard cubes that no single TS label satisfies are removed
   (:func:`~mrodrake.planning.product.prune_nba`), kept edges weigh 1, and the prefix tree measures NBA
   states by their hop distance to an accepting state that lies on a cycle.  Refinement: an accepting
   node whose TS state also satisfies a guard of an edge into the accepting state *from its own cycle*
   can close a suffix with the free all-idle step, so the prefix distance counts the edges up to such
   a "closable" entry (a feasible conjunction of the entry cube with a cycle-entry cube), falling back
   to the plain distance for states that cannot reach one.
2. **Prefix tree** rooted at ``(s0, q0)``.  Each iteration selects a node: with probability ``p_rand`` uniformly
   among the expandable nodes of minimum ``h(s, q) = min_{q' ∈ δ(q, L(s))} D(q')``, else uniformly among all
   expandable nodes.  Strategies with a ``focus`` (the graph TS; object systems until the first plan, and beyond
   the case studies' size throughout) first, with that probability, take the node of the minimum bucket with the
   fewest estimated steps to its goal cube that was not taken this way before, so that a chain of steps toward a
   goal takes about as many iterations as it has steps.  Among the next NBA states of minimum distance it takes
   the edges that decrease the distance most and, of their guard cubes, one with the fewest estimated TS steps
   from ``s`` (navigate, grasp, transport); the cube says which entities must (not) be where.  A TS successor of
   ``s`` is sampled toward that cube with probability ``p_new``, else uniformly at random
   (:mod:`~mrodrake.planning.sampler`).  The new TS state is added with every NBA state it can take, each with the
   **cheapest feasible parent** among all tree nodes (a vectorised transition test over all tree states, once per
   new TS state and remembered for both ends), closed under the free idle step, and then tree nodes at
   neighbouring TS states are **rewired** through the new nodes when cheaper (the public MATLAB code has rewiring
   switched off; here the cost keeps improving with more iterations).  Re-sampling a known state rewires too.  The
   TS relation and χ are symmetric, so one vectorised test gives both parents and rewiring targets.
3. **Suffix trees**, one per accepting prefix node ``a = (s_a, q_a)`` being tried, grown the same way
   with distances back to ``q_a`` (at least one edge); on the last NBA edge the goal also asks for
   ``s_a``'s regions and grasps, and a node ``(s, q)`` closes the cycle when ``q_a ∈ δ(q, L(s))`` and
   ``s → s_a`` is a TS transition.
4. The cheapest prefix + suffix found so far is the plan (anytime).  On small object systems
   (:meth:`~mrodrake.planning.legs.LassoImprover.applies`) the best lasso is also re-planned exactly along its
   own NBA-state sequence (:mod:`~mrodrake.planning.legs`) :data:`IMPROVE_PERIOD` iterations after a new best
   cheaper than every re-planned lasso appeared (the best one then) or at the end of the run; the cheapest lasso
   is the plan.

Scheduling: until an accepting prefix node exists every iteration grows the prefix tree; afterwards one
iteration in three does, and the others grow up to ``max_active_suffix`` suffix trees round-robin,
picked by (closable by the idle step first, then lowest prefix cost) among candidates whose prefix cost
is below the best plan.  A suffix tree is set aside after ``suffix_budget`` (1000) iterations; when
all are set aside without a plan, every budget doubles (so no candidate is abandoned for good).
``iterations`` counts all tree iterations; ``time_limit`` stops earlier; without a plan after
``iterations`` the search continues until the first plan (at most ``extend_iterations`` more).
The TS-specific parts (pruning, word semantics, vectorised transition test and costs, goals, estimated steps,
successor sampler) are a *strategy*: :class:`ObjectStrategy` here, :class:`~mrodrake.planning.graph_stylus.
GraphStrategy` for multi-robot graph systems.  All randomness comes from one seeded numpy Generator: the same seed
and iteration budget give the same plan (a time limit makes the result depend on the machine's speed).
"""

from __future__ import annotations

import bisect
import heapq
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from mrodrake.errors import NoPlanFound, UserError
from mrodrake.logic.nba import NBA
from mrodrake.planning.bans import Bans
from mrodrake.planning.exact import blocked_note
from mrodrake.planning.graph_stylus import GraphStrategy
from mrodrake.planning.legs import LassoImprover
from mrodrake.planning.product import (
    CubeGoal,
    accepting_on_cycle,
    cube_goal,
    cube_infeasibility,
    cycle_distances,
    hop_distances,
    hop_distances_from,
    prune_nba,
    useful_states,
)
from mrodrake.planning.sampler import Goal, SuccessorSampler
from mrodrake.planning.semantics import ExecutedWords, GuardTable
from mrodrake.ts import State, TransitionSystem

INF = math.inf
#: Object systems with more robots + objects than this focus STyLuS*'s selection after the first plan too
#: (ObjectStrategy.focus).
FOCUS_ENTITIES = 8
#: Focus of object systems until the first plan (ObjectStrategy.first_plan_focus): a larger one finds most first
#: plans sooner still, but follows chains whose estimated steps mislead (a team that cannot form) far longer.
FIRST_PLAN_FOCUS = 0.3
#: Iterations between a new best lasso and its exact re-planning (the best lasso then is re-planned; the run's
#: last one at its end): the first lassos improve quickly, and re-planning each of them costs more than waiting.
#: Lassos no cheaper than the best re-planned one are not re-planned.
IMPROVE_PERIOD = 200


class _Transitions:
    """Vectorised TS transition tests and costs between one state and many (rows of an int array)."""

    def __init__(self, ts: TransitionSystem):
        self.ts = ts
        self.N, self.M = ts.N, ts.M
        self.power = np.array(ts.power, dtype=float)
        self.required = np.array(ts.required_power, dtype=float)
        self.dist = ts.dist
        self.gc = ts.grasp_cost
        self._flat = np.zeros(0, dtype=bool)  # every robot and object table so far, one after another
        self._offsets: dict[tuple, int] = {}  # table key -> where the table starts in _flat

    def mask(self, X: np.ndarray, s) -> np.ndarray:
        """``ok[r]``: is ``X[r] → s`` a TS transition?  Rows of X and s are valid states.

        The relation is symmetric on valid states (navigate back, release what was grasped, transport
        back with the same team), so this also answers ``s → X[r]``.  Per robot: a grasp change needs
        the robot to stay, the object involved to stay, and never switches objects; a robot that keeps
        grasping an object moves iff the object moves.  These imply that a moving object keeps its team,
        so per object only Λ with s's team remains (required powers are > 0, so the team is non-empty).
        Last, every region change must be travelled (``TransitionSystem.travel`` for the robot's or the
        team's radius) and the step must fit while executed one action at a time
        (``TransitionSystem.steps_fit``); both are symmetric too.
        """
        N, M = self.N, self.M
        n = len(X)
        if M == 0:  # robots only: every move must be travelled, and the step must fit
            s = np.asarray(s, dtype=np.int64).ravel()
            ok = np.ones(n, dtype=bool)
            moves = X[:, :N] != s[:N]
            for i in np.flatnonzero(moves.any(axis=0)):
                C = self.ts.travel(self.ts.robot_radius[i])
                rows = np.flatnonzero(moves[:, i])
                ok[rows] &= C[X[rows, i], s[i]]
            rows = np.flatnonzero(ok)
            if len(rows):
                ok[rows] = self.ts.steps_fit(X[rows], s)
            return ok
        if not isinstance(s, tuple):
            s = tuple(int(x) for x in np.asarray(s).ravel())
        objects, robots = self._tables(s)
        flat = self._flat
        XR, XO, XG = X[:, :N], X[:, N : N + M], X[:, N + M :]
        ok = flat[XO + objects].all(axis=1)
        moved = np.zeros((n, M + 1), dtype=np.int64)  # last column: no object (grasp -1)
        moved[:, :M] = XO != s[N : N + M]
        gs = np.array(s[N + M :])
        cols = np.where(gs >= 0, gs, XG)  # the object in question per robot (−1: the last column)
        flag = moved[np.arange(n)[:, None], cols]
        ok &= flat[(XR * (M + 1) + (XG + 1)) * 2 + flag + robots].all(axis=1)
        rows = np.flatnonzero(ok)
        if len(rows):
            ok[rows] = self.ts.steps_fit(X[rows], s)
        return ok

    def _tables(self, s: State) -> tuple[np.ndarray, np.ndarray]:
        """Where s's object tables (:meth:`_object_table`, per object) and robot tables (:meth:`_robot_table`, per
        robot) start in the flat table array."""
        N, M = self.N, self.M
        objects = [self._place(self._object_table(j, s)) for j in range(M)]
        robots = [self._place(self._robot_table(i, s[i], s[N + M + i])) for i in range(N)]
        return np.array(objects, dtype=np.int64), np.array(robots, dtype=np.int64)

    def _place(self, table: tuple[tuple, Callable[[], np.ndarray]]) -> int:
        """The offset of a table (key, how to build it) in the flat table array, appended when new."""
        key, build = table
        at = self._offsets.get(key)
        if at is None:
            at = self._offsets[key] = len(self._flat)
            self._flat = np.concatenate([self._flat, build()])
        return at

    def _robot_table(self, i: int, r: int, g: int) -> tuple[tuple, Callable[[], np.ndarray]]:
        """Robot i's rules for steps between s (robot in region r, grasping g) and any state: a table over
        (region, grasp + 1, has the object in question moved) of the other state.  The object in question is g
        when s grasps one, else the one the other state grasps."""

        def build() -> np.ndarray:
            ts, M = self.ts, self.M
            C = ts.travel(ts.robot_radius[i])
            T = np.zeros((ts.K, M + 1, 2), dtype=bool)
            for xr in range(ts.K):
                for xg in range(-1, M):
                    for flag in (False, True):
                        moves, changed = xr != r, xg != g
                        if g >= 0:
                            bad = (xg >= 0 or moves or flag) if changed else moves != flag
                        elif changed:
                            bad = moves or flag
                        else:
                            bad = moves and not C[xr, r]
                        T[xr, xg + 1, int(flag)] = not bad
            return T.ravel()

        return ("robot", i, r, g), build

    def _object_table(self, j: int, s: State) -> tuple[tuple, Callable[[], np.ndarray]]:
        """``U[k]``: may object j be in region k in the other state of a step with s?  Only where it is in s,
        or one travel away for s's team if that team is powerful enough (Λ)."""
        N, M = self.N, self.M
        team = tuple(i for i in range(N) if s[N + M + i] == j)
        o = s[N + j]

        def build() -> np.ndarray:
            ts = self.ts
            power = 0.0
            for i in team:
                power += ts.power[i]
            U = np.zeros(ts.K, dtype=bool)
            U[o] = True
            if team and not power < ts.required_power[j]:
                C = ts.travel(ts.travel_radius(j, team))
                U |= C[:, o]
            return U

        return ("object", j, o, team), build

    def cost(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """χ(A[r], B[r]) for all rows (broadcast like :meth:`mask`)."""
        N, M = self.N, self.M
        c = self.dist[A[:, :N], B[:, :N]].sum(axis=1)
        c = c + self.gc * (A[:, N + M :] != B[:, N + M :]).sum(axis=1)
        return c


class ObjectStrategy:
    """TS-specific parts of STyLuS* for the multi-robot-object TS: pruning on executed words, the
    executed-word semantics, the vectorised transition test, guard cubes as region goals
    (:class:`~mrodrake.planning.sampler.Goal`) and the domain-aware sampler
    (:mod:`~mrodrake.planning.sampler`).  :mod:`~mrodrake.planning.graph_stylus` has the graph TS's."""

    symmetric = True  # the TS relation and χ are symmetric on valid states (see _Transitions.mask)
    dtype = np.int16

    def __init__(self, ts: TransitionSystem, relevant: int):
        self.ts, self.relevant = ts, int(relevant)
        self.p_rand = ts.scenario.planning.p_rand
        self.p_new = ts.scenario.planning.p_new
        self.transitions = _Transitions(ts)
        # until the first plan, and beyond the case studies' size throughout (the best bucket then holds hundreds
        # of nodes), uniform picks rarely continue a chain of steps toward a goal: focus on the closest node (see
        # _Tree.select); on small systems the uniform picks after the first plan find the cheaper plans
        self.focus = 0.0 if ts.N + ts.M <= FOCUS_ENTITIES else 0.8
        self.first_plan_focus = max(self.focus, FIRST_PLAN_FOCUS)
        self._cubes: dict[tuple[int, int], CubeGoal] = {}
        self._goals: dict[tuple, Goal | None] = {}
        self._steps: dict[tuple, float] = {}  # cube_steps per (state, cube)
        self._power_of: dict[State, tuple[list[float], list[float]]] = {}
        self._dlist = ts.dist.tolist()
        self._dscale = float(ts.dist.max()) * (ts.N + ts.M) + 1.0

    def prune(self, nba: NBA) -> NBA:
        return prune_nba(nba, self.ts, transit=True)

    def words(self, nba: NBA) -> ExecutedWords:
        return ExecutedWords(self.ts, nba, self.relevant)

    def sampler(self, rng: np.random.Generator) -> SuccessorSampler:
        return SuccessorSampler(self.ts, rng)

    def cube_infeasibility(self, pos: int, neg: int) -> str | None:
        return cube_infeasibility(self.ts, pos, neg, transit=True)

    def no_plan_note(self) -> str:
        return blocked_note(self.ts)

    @staticmethod
    def can_idle(s: State) -> bool:
        """Is the all-idle step s → s a transition?  (Always: every robot may stay.)"""
        return True

    def cube(self, pos: int, neg: int) -> CubeGoal:
        key = (pos, neg)
        cg = self._cubes.get(key)
        if cg is None:
            cg = cube_goal(self.ts, pos, neg)
            self._cubes[key] = cg
        return cg

    def goal(self, pos: int, neg: int, target: State | None) -> Goal | None:
        """The regions the cube asks for (completed by ``target``'s when closing a suffix), or None (cached;
        the sampler only reads goals)."""
        key = (pos, neg, target)
        if key in self._goals:
            return self._goals[key]
        cg = self.cube(pos, neg)
        g = None
        if target is not None or cg.required or cg.forbidden:
            g = Goal.from_cube(cg.required, cg.forbidden, target, self.ts)
        self._goals[key] = g
        return g

    def cube_steps(self, s: State, pos: int, neg: int, target: State | None = None) -> float:
        """Rough number of TS steps until s satisfies the cube (navigate, grasp, transport; the travel
        distance still needed breaks ties), used to choose among the guard cubes to aim at (``target``, the
        root of a suffix tree, is not used; cached per state and cube)."""
        key = (s, pos, neg)
        hit = self._steps.get(key)
        if hit is not None:
            return hit
        cg = self.cube(pos, neg)
        ts = self.ts
        N = ts.N
        d = self._dlist
        steps, dist = 0, 0.0
        powers = None
        for e, k in cg.required.items():
            if e < N:
                if s[e] != k:
                    steps += 1 + (s[ts.N + ts.M + e] >= 0)
                    dist += d[s[e]][k]
            else:
                j = e - N
                r = s[e]
                if r != k:
                    steps += 1
                    dist += d[r][k]
                    if powers is None:
                        powers = self._powers(s)
                    team = powers[0][j]
                    if team < ts.required_power[j]:
                        steps += 1 if team + powers[1][r] >= ts.required_power[j] else 2
        for e, mask in cg.forbidden.items():
            if mask >> s[e] & 1 and e not in cg.required:
                steps += 1 if e < N else 3
        out = self._steps[key] = steps + dist / self._dscale
        return out


    def _powers(self, s: State) -> tuple[list[float], list[float]]:
        """Per object the power of the robots grasping it in s, and per region the power of the free robots
        there (cached per state)."""
        hit = self._power_of.get(s)
        if hit is None:
            ts = self.ts
            N, M = ts.N, ts.M
            team = [sum(ts.power[i] for i in range(N) if s[N + M + i] == j) for j in range(M)]
            near = [sum(ts.power[i] for i in range(N) if s[i] == r and s[N + M + i] < 0) for r in range(ts.K)]
            hit = self._power_of[s] = (team, near)
        return hit


def strategy_for(ts, relevant: int):
    """The STyLuS* strategy of a transition system (graph TS or multi-robot-object TS)."""
    if getattr(ts, "reads_source_label", False):
        return GraphStrategy(ts, relevant)
    return ObjectStrategy(ts, relevant)


class _Labels:
    """NBA moves per TS label, shared by all trees: label id -> bool matrix ``T[q, q']``."""

    def __init__(self, ts: TransitionSystem, nba: NBA):
        self.ts, self.nba = ts, nba
        self.Q = nba.num_states
        self.ids: dict[int, int] = {}
        self.masks: list[int] = []
        self.succ: list[list[tuple[int, ...]]] = []
        self.T = np.zeros((64, self.Q, self.Q), dtype=bool)
        self.guards = GuardTable(nba)  # δ(q, L(s)) for every q at once

    def lid(self, s: State) -> int:
        m = self.ts.label_mask(s)
        k = self.ids.get(m)
        if k is None:
            k = len(self.masks)
            self.ids[m] = k
            self.masks.append(m)
            Q = self.Q
            cols = dict(self.guards.columns(m))
            rows = [tuple(d for d in range(Q) if cols.get(q, 0) >> d & 1) for q in range(Q)]
            self.succ.append(rows)
            if k >= len(self.T):
                self.T = np.concatenate([self.T, np.zeros_like(self.T)])
            self.T[k].reshape(-1)[[q * Q + d for q, r in enumerate(rows) for d in r]] = True
        return k


class _Tree:
    """A STyLuS* tree over product nodes (see the module docstring)."""

    def __init__(self, planner: Stylus, root: State, root_q: int, dist: list[float],
                 close_to: tuple[State, int] | None = None):
        self.p = planner
        ts = planner.ts
        self.D = dist
        self.close_to = close_to
        self.Q = planner.nba.num_states
        self.width = len(ts.initial)
        cap = 256
        self.X = np.zeros((cap, self.width), dtype=planner.strategy.dtype)
        self._at: list[list[int]] = []  # per tree state and NBA state: the node, or -1
        self._qs: list[list[int]] = []  # per tree state: the NBA states of its nodes, in increasing order
        self.lids: list[int] = []  # per tree state: its label id
        self.C: list[float] = []  # per node: its cost from the root
        self.states: list[State] = []
        self.tid_of: dict[State, int] = {}
        self.n_tid: list[int] = []
        self.n_q: list[int] = []
        self.parent: list[int] = []
        self.w: list[float] = []
        self.children: list[list[int]] = []
        self.h: list[float] = []
        self.buckets: dict[float, list[int]] = {}
        self.expandable: list[int] = []
        self.closers: list[int] = []
        self.frontier: dict[float, list[tuple[float, int]]] = {}  # per bucket: (estimated steps, node)
        self._opts: dict[int, list] = {}
        self._adj: list[list[list]] = []  # per tree state: neighbours, χ, visibility (symmetric strategies)
        # per tree state (symmetric strategies): may inserting it again change the tree?  Cleared by its
        # parent search, set when a node at it or at a neighbour is added or gets cheaper (_touch)
        self._stale: list[bool] = []
        self._idle_self: list[bool] = []  # its own nodes as parents are the idle closure's (see _link)
        self._settling = -1  # the tree state whose parent search and idle closure are running
        self.iterations = 0
        self._reparents = 0  # reparentings so far (tells when costs may have fallen)
        tid = self._add_state(root)
        if planner.strategy.symmetric:
            self._link(tid)
        self._new_node(tid, root_q, -1, 0.0)

    # --------------------------------------------------------------------------------- storage
    def _add_state(self, s: State) -> int:
        tid = len(self.states)
        if tid >= len(self.X):
            self.X = np.concatenate([self.X, np.zeros_like(self.X)])
        self.X[tid] = s
        self.lids.append(self.p.labels.lid(s))
        self._at.append([-1] * self.Q)
        self._qs.append([])
        self.states.append(s)
        self.tid_of[s] = tid
        self._stale.append(True)
        return tid

    def _touch(self, tid: int) -> None:
        """A node at tree state tid was added or got cheaper: its neighbours (and tid) may find cheaper parents
        there.  Changes at the state whose parent search is running leave that state clean when its own nodes
        as parents are the idle closure's (the closure settles them)."""
        stale = self._stale
        if tid == self._settling:
            for u in self._adj[tid][0]:
                if u != tid:
                    stale[u] = True
            return
        for u in self._adj[tid][0]:
            stale[u] = True
        stale[tid] = True

    def _new_node(self, tid: int, q: int, parent: int, w: float) -> int:
        v = len(self.n_tid)
        self.n_tid.append(tid)
        self.n_q.append(q)
        self.parent.append(parent)
        self.w.append(w)
        self.children.append([])
        self.C.append((self.C[parent] + w) if parent >= 0 else 0.0)
        if parent >= 0:
            self.children[parent].append(v)
        self._at[tid][q] = v
        bisect.insort(self._qs[tid], q)
        if self.p.strategy.symmetric:
            self._touch(tid)
        succ = self.p.labels.succ[self.lids[tid]][q]
        h = min((self.D[x] for x in succ), default=INF)
        self.h.append(h)
        if h < INF:
            self.buckets.setdefault(h, []).append(v)
            self.expandable.append(v)
            if self.p.focus:
                opts = self.options(v)
                if opts:
                    heapq.heappush(self.frontier.setdefault(h, []), (min(o[0] for o in opts), v))
        if self.close_to is not None and self._closes(v):
            self.closers.append(v)
        self.p._on_new_node(self, v)
        return v

    def _closes(self, v: int) -> bool:
        s_a, q_a = self.close_to
        tid = self.n_tid[v]
        s = self.states[tid]
        if self.p.ts.check_transition(s, s_a) is not None or s_a in self.p.banned.get(s, ()):
            return False
        return bool(self.p.words.rows(s, s_a, [self.n_q[v]])[0, q_a])

    def _reparent(self, v: int, u: int, w: float) -> None:
        self._reparents += 1
        old = self.parent[v]
        if old >= 0:
            self.children[old].remove(v)
        self.parent[v] = u
        self.w[v] = w
        self.children[u].append(v)
        C = self.C
        C[v] = C[u] + w
        stack = list(self.children[v])
        changed = {self.n_tid[v]}
        while stack:
            c = stack.pop()
            C[c] = C[self.parent[c]] + self.w[c]
            changed.add(self.n_tid[c])
            stack.extend(self.children[c])
        if self.p.strategy.symmetric:
            for tid in changed:
                self._touch(tid)

    # --------------------------------------------------------------------------------- growth
    def insert(self, s: State) -> None:
        """Add TS state s with every NBA state it can take (cheapest parents), then rewire."""
        p = self.p
        tid = self.tid_of.get(s)
        if p.strategy.symmetric:
            if tid is None:
                tid = self._add_state(s)
                pred, chi, seen = self._link(tid)
            elif not self._stale[tid]:
                return  # no node at s or next to it has changed since its last parent search
            else:
                pred, chi, seen = self._adj[tid]
            if p.banned and s in p.banned:
                keep = [k for k, u in enumerate(pred) if self.states[u] not in p.banned[s]]
                pred, chi, seen = [pred[k] for k in keep], [chi[k] for k in keep], [seen[k] for k in keep]
        else:
            row = np.asarray(s, dtype=self.X.dtype)[None, :]
            X = self.X[:len(self.states)]  # the earlier tree states
            pa = np.flatnonzero(p.trans.mask(X, s))
            if p.banned and s in p.banned:
                pa = pa[[self.states[u] not in p.banned[s] for u in pa]].astype(np.int64)
            if tid is None:
                tid = self._add_state(s)
            pred, chi, seen = pa.tolist(), p.trans.cost(X[pa], row).tolist(), p.words.visible(X[pa], s).tolist()
        if not pred:
            return
        if p.strategy.symmetric:
            self._stale[tid] = False
            self._settling = tid if self._idle_self[tid] else -1
        # cheapest parent per NBA state among the nodes at the neighbouring states, the first one on ties;
        # steps whose crossings the task sees take executed-word moves instead of the label's
        Q, C, at, lids, qs = self.Q, self.C, self._at, self.lids, self._qs
        succ, words, states = p.labels.succ, p.words, self.states
        best_cost, best = [INF] * Q, [-1] * Q
        cand_u, cand_c = [], []
        for u_state, c, vis in zip(pred, chi, seen):
            nodes, moves, sid = at[u_state], succ[lids[u_state]], -1
            for q in qs[u_state]:
                u = nodes[q]
                if vis:
                    if sid < 0:
                        sid = words.step_id(states[u_state], s)
                    targets = words.step_targets(sid, q)
                else:
                    targets = moves[q]
                b = C[u] + c
                k = len(cand_u)
                cand_u.append(u)
                cand_c.append(c)
                for q2 in targets:
                    if b < best_cost[q2]:
                        best_cost[q2], best[q2] = b, k
        changed = []
        for q in range(Q):
            k = best[q]
            if k < 0:
                continue
            u, c = cand_u[k], cand_c[k]
            v = at[tid][q]
            if v < 0:
                changed.append(self._new_node(tid, q, u, c))
            elif self.C[u] + c < self.C[v] - 1e-9 and u != v:
                self._reparent(v, u, c)
                changed.append(v)
        # idle self-loop closure: (s, q) -> (s, q') costs nothing when q' ∈ δ(q, L(s)) and s -> s exists
        queue = list(changed) if p.strategy.can_idle(s) else []
        succ_rows = p.labels.succ[lids[tid]]
        while queue:
            v = queue.pop()
            for q2 in succ_rows[self.n_q[v]]:
                y = at[tid][q2]
                if y < 0:
                    y = self._new_node(tid, q2, v, 0.0)
                elif y != v and self.C[v] < self.C[y] - 1e-9:
                    self._reparent(y, v, 0.0)
                else:
                    continue
                changed.append(y)
                queue.append(y)
        self._settling = -1
        if not changed:
            return
        if not p.strategy.symmetric:  # else the relation and χ are symmetric: successors of s are its predecessors
            pa = np.flatnonzero(p.trans.mask_from(s, X))
            if p.banned and s in p.banned:
                pa = pa[[self.states[u] not in p.banned[s] for u in pa]].astype(np.int64)
            pred, chi, seen = pa.tolist(), p.trans.cost(row, X[pa]).tolist(), p.words.visible(X[pa], s).tolist()
        self._rewire(list(dict.fromkeys(changed)), pred, chi, seen)

    def _link(self, tid: int) -> tuple[list[int], list[float], list[bool]]:
        """The neighbours of the new tree state ``tid`` among the earlier ones (symmetric strategies): the
        transition test, χ and visibility computed once and remembered for both ends (``_adj``: per tree state
        its neighbours among all tree states in increasing order, what the transition test over them gives)."""
        p = self.p
        s = self.states[tid]
        rows = self.X[:tid + 1]
        nb = np.flatnonzero(p.trans.mask(rows, s))
        near = rows[nb]
        chi = p.trans.cost(near, rows[tid][None, :])
        seen = p.words.visible(near, s)
        nb, chi, seen = nb.tolist(), chi.tolist(), seen.tolist()
        self._adj.append([nb, chi, seen])
        # with a free hidden self-loop, s's nodes as parents of s's nodes are exactly the idle closure
        loop = bool(nb) and nb[-1] == tid
        self._idle_self.append(not loop or (p.strategy.can_idle(s) and chi[-1] == 0.0 and not seen[-1]))
        adj = self._adj
        for u, c, w in zip(nb, chi, seen):
            if u != tid:
                entry = adj[u]
                entry[0].append(tid)
                entry[1].append(c)
                entry[2].append(w)
        k = len(nb) - 1 if nb and nb[-1] == tid else len(nb)
        return nb[:k], chi[:k], seen[:k]

    def _rewire(self, vs: list[int], succ: list[int], chi: list[float], vis: list[bool]) -> None:
        """Reparent the nodes at TS states ``succ`` (costs ``chi`` from the one TS state of the nodes ``vs``;
        ``vis``: the steps whose crossings the task sees) through each node of vs in turn: per node, the
        candidates through hidden steps (NBA state first, as the label's moves are listed, then TS state),
        then through visible ones (TS state first) by the costs after those."""
        p = self.p
        C, at, n_q = self.C, self._at, self.n_q
        tid = self.n_tid[vs[0]]
        s, states = self.states[tid], self.states
        words = p.words
        moves = p.labels.succ[self.lids[tid]]
        hidden = [(at[u], c) for u, c, w in zip(succ, chi, vis) if not w]
        visible = [(k, at[u], c) for k, (u, c, w) in enumerate(zip(succ, chi, vis)) if w]
        sids: dict[int, int] = {}  # step ids of s -> succ[k], filled when needed
        try_reparent = self._try_reparent
        for v in vs:
            q, cv = n_q[v], C[v]
            for q2 in moves[q]:
                for nodes, c in hidden:
                    y = nodes[q2]
                    if y >= 0:
                        try_reparent(y, v, c)
            for k, nodes, c in visible:
                b = cv + c
                if not any(y >= 0 and y != v and b < C[y] - 1e-9 for y in nodes):
                    continue
                sid = sids.get(k)
                if sid is None:
                    sid = sids[k] = words.step_id(s, states[succ[k]])
                targets = words.step_targets(sid, q)
                for q2 in sorted(targets):
                    y = nodes[q2]
                    if y >= 0:
                        try_reparent(y, v, c)

    def _try_reparent(self, y: int, v: int, w: float) -> None:
        if y != v and self.C[v] + w < self.C[y] - 1e-9:
            self._reparent(y, v, w)

    def select(self, rng: np.random.Generator) -> int:
        """With probability ``focus`` (strategies that set it) the node of the minimum-distance bucket with the
        fewest estimated steps to its goal cube that was not focused on before; else with probability p_rand a
        uniform node of that bucket, else any expandable node."""
        if self.p.focus and rng.random() < self.p.focus:
            heap = self.frontier.get(min(self.buckets))
            if heap:
                return heapq.heappop(heap)[1]
        if rng.random() < self.p.p_rand:
            bucket = self.buckets[min(self.buckets)]
            return bucket[int(rng.integers(len(bucket)))]
        return self.expandable[int(rng.integers(len(self.expandable)))]

    def options(self, v: int) -> list[tuple[float, int, int, int]]:
        """Candidate goal cubes of node v: (estimated TS steps, pos, neg, target NBA state); cached."""
        opts = self._opts.get(v)
        if opts is not None:
            return opts
        p = self.p
        tid, q = self.n_tid[v], self.n_q[v]
        s = self.states[tid]
        nexts = p.labels.succ[self.lids[tid]][q]
        D = self.D
        dmin = min(D[x] for x in nexts)
        cands = []
        for q1 in nexts:
            if D[q1] != dmin:
                continue
            for guard, q2 in p.edges[q1]:
                cands.append((guard, q2))
        cubes = {}
        if dmin == 1 and self.close_to is not None:
            for guard, q2 in cands:
                if q2 == self.close_to[1]:
                    for pos, neg in guard:
                        cubes.setdefault((pos, neg, q2), None)
        elif dmin == 1 and p.closable:
            for guard, q2 in cands:
                if q2 in p.acc:
                    for pos, neg in guard:
                        for c in p.closing_cubes(pos, neg, q2):
                            cubes.setdefault(c + (q2,), None)
        else:
            # the NBA step that decreases the distance most (at an accepting state of a prefix tree
            # without closable entries, dmin == 0: the step that heads back toward acceptance)
            want = min((D[c[1]] for c in cands), default=INF)
            for guard, q2 in cands:
                if D[q2] == want:
                    for pos, neg in guard:
                        cubes.setdefault((pos, neg, q2), None)
        close = self.close_to
        opts = [(p.strategy.cube_steps(s, pos, neg, close[0] if close is not None and q2 == close[1] else None),
                 pos, neg, q2) for pos, neg, q2 in cubes]
        self._opts[v] = opts
        return opts

    def goal_for(self, v: int, rng: np.random.Generator) -> Goal | None:
        """The guard cube to aim at from node v (see the module docstring)."""
        p = self.p
        opts = self.options(v)
        if not opts:
            return None
        vmin = min(o[0] for o in opts)
        best = [o for o in opts if o[0] == vmin]
        _, pos, neg, q2 = best[int(rng.integers(len(best)))]
        target = None
        if self.close_to is not None and q2 == self.close_to[1]:
            target = self.close_to[0]
        return p.strategy.goal(pos, neg, target)

    def step(self, rng: np.random.Generator) -> None:
        self.iterations += 1
        v = self.select(rng)
        s = self.states[self.n_tid[v]]
        goal = self.goal_for(v, rng)
        t = self.p.sampler.sample(s, goal, self.p.p_new)
        self.insert(t)

    # --------------------------------------------------------------------------------- paths
    def path(self, v: int) -> list[tuple[State, int]]:
        out = []
        while v >= 0:
            out.append((self.states[self.n_tid[v]], self.n_q[v]))
            v = self.parent[v]
        return out[::-1]

    def best_cycle(self) -> tuple[float, int]:
        """(cost, closing node) of the cheapest cycle back to the root, or (inf, -1)."""
        if not self.closers:
            return INF, -1
        s_a = self.close_to[0]
        best, arg = INF, -1
        for v in self.closers:
            c = self.C[v] + self.p.ts.cost(self.states[self.n_tid[v]], s_a)
            if c < best:
                best, arg = c, v
        return best, arg

    @property
    def num_nodes(self) -> int:
        return len(self.n_tid)


@dataclass
class StylusResult:
    """Best lasso found: product nodes of prefix and suffix, costs, and the run's statistics."""

    prefix: list
    suffix: list
    prefix_cost: float
    suffix_cost: float
    stats: dict = field(default_factory=dict)
    history: list = field(default_factory=list)  # (seconds, iteration, total cost) at each improvement


class Stylus:
    """STyLuS* planner for ``ts`` and an NBA over ``ts.propositions`` on the executed-word semantics
    (``relevant``: the task's AP_φ mask, :func:`~mrodrake.planning.semantics.relevant_mask`)."""

    def __init__(self, ts: TransitionSystem, nba: NBA, relevant: int, seed: int | None = None,
                 p_rand: float | None = None, p_new: float | None = None, max_active_suffix: int = 4,
                 suffix_budget: int = 1000, replan: bool = True, banned=None):
        self.ts = ts
        #: TS transitions the planner must not use (state -> states; both directions of each pair): a
        #: :class:`~mrodrake.planning.bans.Bans` or state pairs.
        self.banned = banned if isinstance(banned, Bans) else Bans(ts, banned or ())
        self.strategy = strategy_for(ts, relevant)
        self.nba = self.strategy.prune(nba)
        self.words = self.strategy.words(self.nba)
        self.p_rand = self.strategy.p_rand if p_rand is None else p_rand
        self.p_new = self.strategy.p_new if p_new is None else p_new
        self.rng = np.random.default_rng(seed)
        self.sampler = self.strategy.sampler(self.rng)
        self.focus = self.strategy.first_plan_focus  # the strategy's ``focus`` once a plan exists
        self.trans = self.strategy.transitions
        self.labels = _Labels(ts, self.nba)
        self.edges = self.nba.edges
        self.acc = accepting_on_cycle(self.nba)
        self._closing: dict[tuple[int, int, int], list[tuple[int, int]]] = {}
        self.return_cubes: dict[int, list[tuple[int, int]]] = {}
        for f in self.acc:
            back = hop_distances_from(self.nba, f)
            self.return_cubes[f] = [c for q, row in enumerate(self.edges) if back[q] < INF
                                    for g, d in row if d == f for c in g]
        # prefix distances: edges up to and including a "closable" entry into an accepting state (one
        # whose cube is consistent with a cycle-entry guard of that state); states that cannot reach
        # such an entry keep their plain distance to acceptance, offset behind all closable ones
        lasts = [q for q, row in enumerate(self.edges)
                 if any(f in self.acc and self.closing_cubes(pos, neg, f) for g, f in row for pos, neg in g)]
        self.closable = bool(lasts) and self.nba.initial in {
            q for q, d in enumerate(hop_distances(self.nba, lasts)) if d < INF}
        d_acc = hop_distances(self.nba, sorted(self.acc))
        if self.closable:
            d_close = [d + 1 for d in hop_distances(self.nba, lasts)]
            off = max(d for d in d_close if d < INF) + 1
            self.d_prefix = [dc if dc < INF else off + da for dc, da in zip(d_close, d_acc)]
        else:
            self.d_prefix = d_acc
        self.max_active = max_active_suffix
        self.suffix_budget = suffix_budget
        self._new_accepting: list[int] = []
        self._reach: dict[int, list[int]] = {}
        self.prefix_tree: _Tree | None = None
        self.improver = LassoImprover(ts, self.words, self.nba) if replan and LassoImprover.applies(ts) else None

    def closing_cubes(self, pos: int, neg: int, f: int) -> list[tuple[int, int]]:
        """Feasible conjunctions of the cube (pos, neg) of an edge into accepting state f with the guard
        cubes of the edges into f from f's own cycle: a TS state satisfying one enters f and can close a
        suffix with the free idle step (cached)."""
        key = (pos, neg, f)
        out = self._closing.get(key)
        if out is None:
            out = []
            for rp, rn in self.return_cubes.get(f, ()):
                c = (pos | rp, neg | rn)
                if c not in out and self.strategy.cube_infeasibility(c[0], c[1]) is None:
                    out.append(c)
            self._closing[key] = out
        return out

    def _uses_banned(self, prefix: list, suffix: list) -> bool:
        run = [s for s, _ in prefix] + [s for s, _ in suffix]
        nxt = run[1:] + [suffix[0][0]]
        return any(b in self.banned.get(a, ()) for a, b in zip(run, nxt))

    def _on_new_node(self, tree: _Tree, v: int) -> None:
        if tree is self.prefix_tree and tree.n_q[v] in self.acc:
            self._new_accepting.append(v)

    def _idle_closable(self, tree: _Tree, a: int) -> bool:
        """Can a cycle through accepting node a = (s_a, q_a) end with the free idle step s_a → s_a, i.e.
        does L(s_a) enable an NBA edge q → q_a from a state q reachable from q_a?  Such roots are tried
        first: the others need a different TS state one step before s_a that satisfies the guard."""
        q_a = tree.n_q[a]
        reach = self._reach.get(q_a)
        if reach is None:
            d = hop_distances_from(self.nba, q_a)
            reach = [q for q in range(self.nba.num_states) if d[q] < INF]
            self._reach[q_a] = reach
        T = self.labels.T[tree.lids[tree.n_tid[a]]]
        return bool(T[reach, q_a].any())

    def run(self, iterations: int, time_limit: float | None = None, stop_at_first: bool = False,
            progress: Callable[[dict], None] | None = None, extend_iterations: int = 0) -> StylusResult:
        """Grow the trees for ``iterations`` iterations or ``time_limit`` seconds, whichever ends first.

        If no plan exists after ``iterations``, keep going until the first plan for at most
        ``extend_iterations`` more (and never past ``time_limit``); then NoPlanFound.  Without a time limit the
        result is a function of the seed and the budget only.  ``progress`` gets a dict (iteration, seconds,
        tree sizes, best cost) about ten times a second.
        """
        t0 = time.perf_counter()
        ts, rng = self.ts, self.rng
        self.focus = self.strategy.first_plan_focus
        useful = useful_states(self.nba)
        if self.nba.initial not in useful:
            raise UserError(f"task is unsatisfiable: the NBA ({self.nba.num_states} states) has no accepting "
                            "cycle whose guards a TS label can satisfy (searched the pruned NBA)")
        self.prefix_tree = None
        self._new_accepting = []
        pre = _Tree(self, ts.initial, self.nba.initial, self.d_prefix)
        self.prefix_tree = pre
        if not pre.expandable:
            mask = ts.label_mask(ts.initial) & self.strategy.relevant
            true = [p for b, p in enumerate(ts.propositions) if mask >> b & 1]
            label = f"{', '.join(true)} true" if true else "no task proposition true"
            raise UserError(f"task is unsatisfiable: from the initial state's label ({label}) the NBA can only move "
                            "to states without a reachable accepting cycle (searched the pruned NBA)")
        if pre.n_q[0] in self.acc:
            self._new_accepting.append(0)
        candidates: list[int] = []  # accepting prefix nodes
        suffix: dict[int, _Tree] = {}
        budget: dict[int, int] = {}  # suffix iterations allowed per candidate before it is set aside
        base_budget = self.suffix_budget
        active: list[int] = []
        best = (INF, -1, -1)  # total, accepting prefix node, closing suffix node
        replanned = None  # (total, prefix, suffix, prefix cost, suffix cost) of the best re-planned lasso
        replans, replan_seconds = 0, 0.0
        pending, last_improve = None, 0  # best lasso not yet re-planned; iteration of the last re-plan
        history = []
        first_seconds = None
        it = rr = 0
        last_report = -1.0

        def current_best():
            b = (INF, -1, -1)
            for a, tree in suffix.items():
                c, v = tree.best_cycle()
                if v >= 0 and pre.C[a] + c < b[0]:
                    b = (pre.C[a] + c, a, v)
            return b

        def improve(lasso):
            """The improver's re-plan of ``lasso`` (total, prefix node, closing node) if cheaper than the best
            re-planned lasso so far, else that one."""
            nonlocal replans, replan_seconds
            _, a, v = lasso
            t1 = time.perf_counter()
            found = self.improver.improve(pre.path(a)[:-1], suffix[a].path(v),
                                          None if time_limit is None else t0 + time_limit)
            replans += 1
            replan_seconds += time.perf_counter() - t1
            top = min(best[0], replanned[0]) if replanned else best[0]
            if found is not None and self.banned and self._uses_banned(found[0], found[1]):
                found = None
            if found is not None and found[2] + found[3] < top - 1e-9:
                history.append((time.perf_counter() - t0, it, found[2] + found[3]))
                return (found[2] + found[3], *found)
            return replanned

        def spent(a: int) -> int:
            return suffix[a].iterations if a in suffix else 0

        def exhausted(a: int) -> bool:
            return spent(a) >= budget.setdefault(a, base_budget) or (a in suffix and suffix[a].best_cycle()[0] == 0.0)

        while True:
            now = time.perf_counter() - t0
            if time_limit is not None and now > time_limit:
                break
            if it >= iterations and (best[1] >= 0 or it >= iterations + extend_iterations):
                break
            it += 1
            if self._new_accepting:
                candidates.extend(self._new_accepting)
                self._new_accepting.clear()
            grow_suffix = bool(candidates) and it % 3 != 0
            if grow_suffix:
                # a few active suffix trees, lowest prefix cost first (idle-closable roots before others)
                top = min(best[0], replanned[0]) if replanned else best[0]
                active = [a for a in active if not exhausted(a) and pre.C[a] < top]
                if len(active) < self.max_active:
                    pool = [a for a in candidates if a not in active and pre.C[a] < top and not exhausted(a)]
                    if not pool and not active and best[1] < 0:
                        for a in candidates:  # everything tried: double the budgets (completeness)
                            budget[a] = 2 * budget.setdefault(a, base_budget)
                        pool = [a for a in candidates if not exhausted(a)]
                    pool.sort(key=lambda a: (not self._idle_closable(pre, a), pre.C[a], a))
                    active.extend(pool[: self.max_active - len(active)])
                grow_suffix = bool(active)
            if grow_suffix:
                a = active[rr % len(active)]
                rr += 1
                tree = suffix.get(a)
                if tree is None:
                    s_a, q_a = pre.states[pre.n_tid[a]], pre.n_q[a]
                    tree = _Tree(self, s_a, q_a, cycle_distances(self.nba, q_a), close_to=(s_a, q_a))
                    suffix[a] = tree
                if tree.expandable and not (tree.closers and tree.best_cycle()[0] == 0.0):
                    tree.step(rng)
                else:
                    budget[a] = 0
            else:
                pre.step(rng)
            b = current_best() if suffix else best
            if b[0] < best[0] - 1e-9:
                best = b
                elapsed = time.perf_counter() - t0
                if first_seconds is None:
                    first_seconds = elapsed
                    self.focus = self.strategy.focus
                lowest = not replanned or best[0] < replanned[0] - 1e-9  # below every re-planned lasso
                if lowest:
                    history.append((elapsed, it, best[0]))
                if stop_at_first:
                    break
                if self.improver is not None and lowest:
                    if pending is None:
                        last_improve = it
                    pending = best
            if pending is not None and it - last_improve >= IMPROVE_PERIOD:
                replanned = improve(pending)
                pending, last_improve = None, it
            if progress is not None and (now - last_report > 0.1 or it == iterations):
                last_report = now
                progress({"iteration": it, "iterations": iterations, "seconds": now,
                          "prefix_nodes": pre.num_nodes, "suffix_trees": len(suffix), "best": best[0]})
        if pending is not None:
            replanned = improve(pending)
        elapsed = time.perf_counter() - t0
        stats = {"iterations": it, "seconds": elapsed, "first_plan_seconds": first_seconds,
                 "prefix_nodes": pre.num_nodes, "prefix_ts_states": len(pre.states),
                 "accepting_prefix_nodes": len(candidates), "suffix_trees": len(suffix),
                 "suffix_nodes": sum(t.num_nodes for t in suffix.values()),
                 "sampler": dict(self.sampler.stats), "replans": replans, "replan_seconds": replan_seconds}
        if best[1] < 0:
            ran_out = (f"the time limit of {time_limit:g} s"
                       if time_limit is not None and it < iterations + extend_iterations
                       else f"the budget of {it} iterations")
            raise NoPlanFound(f"no plan found within {ran_out} ({elapsed:.1f} s); satisfiability unknown "
                              "(STyLuS* is probabilistically complete: raise --iterations or --time-limit)"
                              + self.strategy.no_plan_note())
        if replanned and replanned[0] < best[0]:
            stats["replanned"] = True
            _, prefix_nodes, suffix_nodes, pc, sc = replanned
            return StylusResult(prefix_nodes, suffix_nodes, pc, sc, stats, history)
        _, a, v = best
        prefix_nodes = pre.path(a)[:-1]
        tree = suffix[a]
        suffix_nodes = tree.path(v)
        pc = float(pre.C[a])
        sc = float(tree.best_cycle()[0])
        return StylusResult(prefix_nodes, suffix_nodes, pc, sc, stats, history)
