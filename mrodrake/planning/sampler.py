"""Domain-aware TS successor sampler for STyLuS* (the "q_P^new" step, Kantaros & Zavlanos 2020).

The TS of paper Def. 4 is not a product of independent robot graphs: an object moves only when a team
that grasps it in both states has enough power (Λ), grasping robots move with their object, and every
region must fit its entities (P_s).  A state of N robots has up to ~(K + M)^N successors, so the sampler
never enumerates them; it builds one successor from per-robot / per-object choices that respect the
rules by construction and then checks the packing with ``ts.is_valid``, resampling on failure.

**Biased successor** (:meth:`SuccessorSampler.toward`) for a goal (:class:`Goal`: the regions the
target NBA guard cube requires, the regions it forbids, and, when closing a suffix cycle, the target
state's regions and grasps).  One call advances every sub-task by one TS step:

1. *objects that must move* (required elsewhere, or forbidden where they are) are visited in random
   order; if the robots grasping object j already satisfy Λ, the team transports j toward its target
   (there directly when the two regions are connected for the team's covering radius, else to the next
   region of a shortest route of connected regions; navigations likewise);
   otherwise a team is completed greedily by the marginal cost of each candidate robot,
   ``d(robot, object) + d(object, target) + detour to the robot's own required region`` per unit of
   useful power, perturbed by log-normal noise (so alternative teams get explored) and stripped of
   redundant members; recruits co-located with the object grasp it now, the others navigate to it
   (a navigation is one TS step), and recruits grasping an object that need not move release it first;
2. robots grasping an object that need not move release it when they are needed elsewhere (a required
   region, a forbidden region, or a target grasp of −1) and otherwise hold;
3. free robots navigate to their required region (or to a random allowed region when their current
   one is forbidden), grasp their target object when closing a cycle, and otherwise stay idle (idling
   costs nothing, χ counts travel and grasp changes only).

Every step is a set of independent "units" (a transport with its team, a grasp, a release, a
navigation).  Any subset of the units is still rule-consistent, so when the packing check fails the
sampler retries with each unit kept with probability 1/2 (progress on a subset is still progress).

**Random successor** (:meth:`SuccessorSampler.random`): each object whose team satisfies Λ is
transported with probability 1/2 to a uniformly chosen other region; each grasping robot of an object
that stays releases it with probability 1/2; each free robot stays with probability ``p_idle`` and
otherwise picks uniformly among navigating to another region and grasping a co-located object that
stays.  Every successor of the TS has positive probability (resampled until valid; the all-idle
self-loop is the fallback), which keeps STyLuS* probabilistically complete; ``toward`` is used with
probability ``p_new`` and ``random`` otherwise (:meth:`SuccessorSampler.sample`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from mrodrake.ts import State, TransitionSystem


@dataclass
class Goal:
    """Where entities should be: ``region[e]`` (robots 0..N−1 then objects N..N+M−1), ``forbidden[e]``
    (bitmask of regions), and optionally ``grasp[i]`` (object or −1) for robots of a target state."""

    region: Mapping[int, int] = field(default_factory=dict)
    forbidden: Mapping[int, int] = field(default_factory=dict)
    grasp: Mapping[int, int] = field(default_factory=dict)

    @staticmethod
    def from_cube(required: Mapping[int, int], forbidden: Mapping[int, int], target: State | None = None,
                  ts: TransitionSystem | None = None) -> Goal:
        """A cube's requirements, completed by the regions and grasps of ``target`` (a TS state) for the
        entities the cube leaves free (suffix trees aim at their root state)."""
        region = dict(required)
        grasp: dict[int, int] = {}
        if target is not None and ts is not None:
            N, M = ts.N, ts.M
            for e in range(N + M):
                if e not in region and not (forbidden.get(e, 0) >> target[e] & 1):
                    region[e] = target[e]
            for i in range(N):
                grasp[i] = target[N + M + i]
        return Goal(region, dict(forbidden), grasp)


class SuccessorSampler:
    """Samples TS successors (see the module docstring); ``rng`` is a numpy Generator."""

    def __init__(self, ts: TransitionSystem, rng: np.random.Generator, p_idle: float = 0.5,
                 team_noise: float = 0.3, tries: int = 8):
        self.ts, self.rng = ts, rng
        self.p_idle, self.team_noise, self.tries = p_idle, team_noise, tries
        self.N, self.M, self.K = ts.N, ts.M, ts.K
        self.dist = ts.dist.tolist()
        self.power = list(ts.power)
        self.required_power = list(ts.required_power)
        self.stats = {"toward": 0, "toward_fail": 0, "random": 0, "random_fail": 0}
        self._next: dict[tuple[int, int], tuple[np.ndarray, list[int]]] = {}
        self._checked: dict[tuple[State, State], bool] = {}  # _successor per step

    # ------------------------------------------------------------------------------------------- public
    def sample(self, s: State, goal: Goal | None, p_new: float) -> State:
        """A successor of s: biased toward ``goal`` with probability ``p_new``, else random."""
        if goal is not None and self.rng.random() < p_new:
            t = self.toward(s, goal)
            if t is not None:
                return t
        return self.random(s)

    def random(self, s: State) -> State:
        """A random admissible successor (every successor has positive probability)."""
        self.stats["random"] += 1
        for _ in range(self.tries):
            t = self._random_once(s)
            if self._successor(s, t):
                return t
        self.stats["random_fail"] += 1
        return s

    def toward(self, s: State, goal: Goal) -> State | None:
        """A successor that makes progress toward ``goal`` (None when no valid one was found)."""
        self.stats["toward"] += 1
        units = self._plan_units(s, goal)
        if not units:
            return None
        t = self._apply(s, units)
        if self._successor(s, t):
            return t
        rng = self.rng
        for _ in range(self.tries):
            keep = [u for u in units if rng.random() < 0.5]
            if not keep:
                continue
            t = self._apply(s, keep)
            if self._successor(s, t):
                return t
        self.stats["toward_fail"] += 1
        return None

    # ------------------------------------------------------------------------------------------ helpers
    def _successor(self, s: State, t: State) -> bool:
        """t is valid, its region changes can be travelled and the step fits (the action rules hold by
        construction of the units; cached per step)."""
        key = (s, t)
        ok = self._checked.get(key)
        if ok is None:
            ts = self.ts
            ok = self._checked[key] = ts.is_valid(t) and ts.step_fits(s, t) and ts.blocked(s, t) is None
        return ok

    def _apply(self, s: State, units: list[tuple]) -> State:
        """Apply units: ('T', j, dst, team), ('G', i, j), ('R', i), ('N', i, dst)."""
        N, M = self.N, self.M
        t = list(s)
        for u in units:
            kind = u[0]
            if kind == "T":
                _, j, dst, team = u
                t[N + j] = dst
                for i in team:
                    t[i] = dst
            elif kind == "G":
                t[N + M + u[1]] = u[2]
            elif kind == "R":
                t[N + M + u[1]] = -1
            else:
                t[u[1]] = u[2]
        return tuple(t)

    def _hop(self, radius: float, src: int, dst: int) -> int:
        """The region to travel to from ``src`` toward ``dst``: ``dst`` itself when they are connected for
        ``radius``, else the next region on a shortest route of connected regions (``dst`` if none)."""
        C = self.ts.travel(radius)
        if C[src, dst]:
            return dst
        key = (id(C), dst)
        hit = self._next.get(key)
        nxt = hit[1] if hit is not None and hit[0] is C else None
        if nxt is None:
            W = np.where(C, self.ts.dist, 0.0)
            np.fill_diagonal(W, 0.0)
            _, pred = dijkstra(csr_matrix(W.T), directed=True, indices=dst, return_predecessors=True)
            nxt = [int(p) if p >= 0 else dst for p in pred]
            self._next[key] = (C, nxt)
        return nxt[src]

    def _allowed_region(self, e: int, forbidden_mask: int, current: int) -> int:
        """A uniformly random region other than ``current`` that is not forbidden (or ``current``)."""
        choices = [k for k in range(self.K) if k != current and not forbidden_mask >> k & 1]
        if not choices:
            return current
        return choices[int(self.rng.integers(len(choices)))]

    def _plan_units(self, s: State, goal: Goal) -> list[tuple]:
        N, M = self.N, self.M
        rng = self.rng
        R, O, G = s[:N], s[N : N + M], s[N + M :]
        region, forbidden, gtarget = goal.region, goal.forbidden, goal.grasp
        # targets of objects and robots
        obj_tgt: list[int | None] = [None] * M
        for j in range(M):
            e = N + j
            if e in region:
                obj_tgt[j] = region[e]
            elif forbidden.get(e, 0) >> O[j] & 1:
                obj_tgt[j] = self._allowed_region(e, forbidden[e], O[j])
        rob_tgt: list[int | None] = [None] * N
        for i in range(N):
            if i in region:
                rob_tgt[i] = region[i]
            elif forbidden.get(i, 0) >> R[i] & 1:
                rob_tgt[i] = self._allowed_region(i, forbidden[i], R[i])
        must_move = [j for j in range(M) if obj_tgt[j] is not None and obj_tgt[j] != O[j]]
        moving = set(must_move)
        teams: list[list[int]] = [[] for _ in range(M)]
        for i in range(N):
            if G[i] >= 0:
                teams[G[i]].append(i)
        decided = [False] * N
        units: list[tuple] = []
        stays = [True] * M  # objects that do not move in this step
        order = list(must_move)
        rng.shuffle(order)
        for j in order:
            k, k2 = O[j], obj_tgt[j]
            team = teams[j]
            have = sum(self.power[i] for i in team)
            if team and have >= self.required_power[j]:
                units.append(("T", j, self._hop(self.ts.travel_radius(j, tuple(team)), k, k2), tuple(team)))
                stays[j] = False
                for i in team:
                    decided[i] = True
                continue
            for i in team:
                decided[i] = True
            recruits = self._recruit(j, k, k2, have, R, G, decided, moving, rob_tgt)
            if recruits is None:
                if team and rng.random() < 0.5:
                    units.extend(("R", i) for i in team)  # free the robots for other objects
                continue
            for i in recruits:
                decided[i] = True
                if G[i] >= 0:
                    units.append(("R", i))
                elif R[i] == k:
                    units.append(("G", i, j))
                else:
                    units.append(("N", i, self._hop(self.ts.robot_radius[i], R[i], k)))
        for i in range(N):
            if decided[i]:
                continue
            g = G[i]
            want = gtarget.get(i)
            if g >= 0:
                tgt = rob_tgt[i]
                if want == g:
                    continue
                if (want is not None) or (tgt is not None and tgt != R[i]):
                    units.append(("R", i))
                continue
            if want is not None and want >= 0 and stays[want]:
                if O[want] == R[i] and (obj_tgt[want] is None or obj_tgt[want] == O[want]):
                    units.append(("G", i, want))
                    continue
                if obj_tgt[want] is None or obj_tgt[want] == O[want]:
                    units.append(("N", i, self._hop(self.ts.robot_radius[i], R[i], O[want])))
                    continue
            tgt = rob_tgt[i]
            if tgt is not None and tgt != R[i]:
                units.append(("N", i, self._hop(self.ts.robot_radius[i], R[i], tgt)))
        return units

    def _recruit(self, j: int, k: int, k2: int, have: float, R, G, decided, moving, rob_tgt) -> list[int] | None:
        """Robots to add to object j's team (at region k, going to k2) so that Λ holds, or None."""
        d, rng = self.dist, self.rng
        need = self.required_power[j] - have
        cands = []
        for i in range(self.N):
            if decided[i]:
                continue
            g = G[i]
            if g >= 0 and (g in moving or g == j):
                continue
            c = d[R[i]][k] + d[k][k2]
            tgt = rob_tgt[i]
            if tgt is not None:
                c += d[k2][tgt] - d[R[i]][tgt]
            if g >= 0:
                c += 2.0 * self.ts.grasp_cost
            c += 2.0 * self.ts.grasp_cost
            cands.append((i, max(c, 0.0) + 1e-6))
        if sum(self.power[i] for i, _ in cands) < need:
            return None
        chosen: list[int] = []
        got = 0.0
        noise = self.team_noise
        while got < need:
            best, best_score = -1, math.inf
            for idx, (i, c) in enumerate(cands):
                useful = min(self.power[i], need - got)
                score = c / useful * math.exp(noise * rng.standard_normal())
                if score < best_score:
                    best, best_score = idx, score
            i, _ = cands.pop(best)
            chosen.append(i)
            got += self.power[i]
        # drop redundant members, most expensive first
        cost = {i: c for i, c in cands}
        chosen.sort(key=lambda i: -(cost.get(i, 0.0)))
        for i in list(chosen):
            if got - self.power[i] >= need:
                chosen.remove(i)
                got -= self.power[i]
        return chosen

    def _random_once(self, s: State) -> State:
        N, M, K = self.N, self.M, self.K
        rng = self.rng
        R, O, G = s[:N], s[N : N + M], s[N + M :]
        t = list(s)
        teams: list[list[int]] = [[] for _ in range(M)]
        for i in range(N):
            if G[i] >= 0:
                teams[G[i]].append(i)
        stays = [True] * M
        for j in range(M):
            team = teams[j]
            if team and sum(self.power[i] for i in team) >= self.required_power[j] and rng.random() < 0.5:
                C = self.ts.travel(self.ts.travel_radius(j, tuple(team)))[O[j]]
                dests = [k for k in range(K) if k != O[j] and C[k]]
                if not dests:
                    continue
                k2 = dests[int(rng.integers(len(dests)))]
                t[N + j] = k2
                stays[j] = False
                for i in team:
                    t[i] = k2
        for i in range(N):
            g = G[i]
            if g >= 0:
                if stays[g] and rng.random() < 0.5:
                    t[N + M + i] = -1
                continue
            if rng.random() < self.p_idle:
                continue
            grasps = [j for j in range(M) if O[j] == R[i] and stays[j]]
            C = self.ts.travel(self.ts.robot_radius[i])[R[i]]
            dests = [k for k in range(K) if k != R[i] and C[k]]
            n_opts = len(dests) + len(grasps)
            if n_opts == 0:
                continue
            c = int(rng.integers(n_opts))
            if c < len(dests):
                t[i] = dests[c]
            else:
                t[N + M + i] = grasps[c - len(dests)]
        return tuple(t)
