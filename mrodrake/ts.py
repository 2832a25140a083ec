"""The coupled multi-robot-object transition system TS (paper Definition 4, Sec. III-B).

A state is a flat tuple of ints ``(k_1..k_N, k^o_1..k^o_M, g_1..g_N)``: the region index of every
robot, the region index of every object, and the object each robot grasps (−1 for none).  This is the
paper's (π̄, π̄_o, AG) with AG stored per robot (a robot grasps at most one object).

A state is *valid* iff every grasping robot is in its object's region and, in every region, the
entities fit (P_s): free robots (radius r_i), ungrasped objects (r^o_j) and robots-object teams
(covering radius r_A,j, see :func:`mrodrake.geometry.grasp_layout`).

A transition s → s' is a set of simultaneous actions, one per robot (all idle = self-loop):

* a free robot (free in s and s') stays or navigates to another region (π_k →_i π_k') connected to its own
  for its radius (a passage wide enough, no other region in the way: :meth:`TransitionSystem.connections`);
* grasp i →g j: i free in s, grasping j in s', co-located with j, region unchanged, j not moving;
* release i →r j: i grasping j in s, free in s', region unchanged, j not moving;
* a robot grasping j in s and s' moves iff j moves, to the same region;
* object j moves (π_k →T_{A,j} π_k') only if the same non-empty team A grasps it in s and s', Λ holds:
  Σ_{i∈A} ζ_i ≥ required power of j, and π_k, π_k' are connected for the team's covering radius r_A,j;
  a robot never switches objects in one step;
* both states valid, and the step fits while it is executed one action at a time (:meth:`TransitionSystem.step_fits`:
  where a region loses and gains entities in one step, or a robot grasps or releases there, everything that is
  in it at the start or at the end fits together).

Labels: ``<robot>_<region>`` / ``<object>_<region>`` true where the entity is.  Cost
χ(s, s') = Σ_i ‖p_{k_i} − p_{k'_i}‖ + c_grasp · (number of grasps and releases).
"""

from __future__ import annotations

import array
import copy
import itertools
import math
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order

from mrodrake.geometry import TEAM_TRAVEL_SLACK, RegionGraph, grasp_layout, polygon
from mrodrake.packing import entities_fit
from mrodrake.scenario import Scenario


def _no_passage(margin: float, team: bool = False) -> str:
    """Why a travel is blocked: free space is the workspace minus walls, obstacles and other regions grown by
    the entity's radius (a team's: its covering radius plus the docking slack) plus the controllers' margin
    (``control.margin``)."""
    radius = f"the covering radius + slack {TEAM_TRAVEL_SLACK:g} m" if team else "the radius"
    return (f"no passage wide enough (walls, obstacles and other regions grown by {radius} + control.margin "
            f"{margin:g} m)")

State = tuple

#: Relative slack of the power comparison Λ (Σ_{i ∈ team} power_i ≥ required power, paper Sec. II): powers
#: are real, and a sum of a few decimal powers is off by ~1e-16 relative in floating point; required powers
#: closer than this to a team's power count as met.
POWER_SLACK = 1e-9
#: Entities (robots + objects) up to which region occupancy is handled as int64 bit masks.
_MASK_BITS = 40
#: Largest code table the vectorised checks allocate densely (else they sort the codes).
_DENSE_CODES = 1 << 22
#: Up to this many steps to one state, :meth:`TransitionSystem.steps_fit` tests them one by one (cheaper than the
#: vectorised test's fixed cost).
_FEW_STEPS = 48
#: Largest state-code space :meth:`TransitionSystem.build` indexes with a dense array (else sorted codes).
_DENSE_INDEX = 1 << 24


@dataclass(frozen=True, order=True)
class Navigate:
    """π_src →_robot π_dst."""

    robot: int
    src: int
    dst: int


@dataclass(frozen=True, order=True)
class Grasp:
    """robot →g obj."""

    robot: int
    obj: int


@dataclass(frozen=True, order=True)
class Release:
    """robot →r obj."""

    robot: int
    obj: int


@dataclass(frozen=True, order=True)
class Transport:
    """π_src →T_{team,obj} π_dst."""

    obj: int
    team: tuple[int, ...]
    src: int
    dst: int


Action = Navigate | Grasp | Release | Transport


@dataclass(frozen=True)
class SizeEstimate:
    """Estimated size of the explicit TS (:meth:`TransitionSystem.estimate_size`)."""

    states: float
    transitions: float
    samples: int
    seconds: float



def reachable(C: np.ndarray, k: int) -> set[int]:
    """Regions reachable from region k along the connection matrix C (k included)."""
    seen, todo = {int(k)}, [int(k)]
    while todo:
        u = todo.pop()
        for v in np.flatnonzero(C[u]):
            if int(v) not in seen:
                seen.add(int(v))
                todo.append(int(v))
    return seen


class TransitionSystem:
    """TS of a scenario with implicit successors; see :meth:`build` for the explicit reachable graph."""

    def __init__(self, scenario: Scenario):
        self.scenario = scenario
        self.bind_home = False  # see bound_at_home
        self.N, self.M, self.K = len(scenario.robots), len(scenario.objects), len(scenario.regions)
        self.robot_names = scenario.robot_names
        self.object_names = scenario.object_names
        self.region_names = scenario.region_names
        self.robot_radius = [r.radius for r in scenario.robots]
        self.power = [r.power for r in scenario.robots]
        self.object_radius = [o.radius for o in scenario.objects]
        # the threshold of Λ: sums of decimal powers round in binary (0.7 + 0.1 < 0.8), so a team counts as
        # strong enough from (1 − POWER_SLACK) × the required power on
        self.required_power = [o.required_power * (1.0 - POWER_SLACK) for o in scenario.objects]
        self.region_radius = [g.radius for g in scenario.regions]
        self.margin = float(scenario.control.margin)
        self.centers = np.array([g.center for g in scenario.regions], dtype=float)
        diff = self.centers[:, None, :] - self.centers[None, :, :]
        self.dist = np.sqrt((diff**2).sum(-1))
        self._dist = self.dist.tolist()
        self.spacing = scenario.layout.spacing
        self.grasp_gap = scenario.layout.grasp_gap
        self.grasp_cost = scenario.planning.grasp_cost
        self.propositions = scenario.propositions()
        self._prop_index = {p: b for b, p in enumerate(self.propositions)}
        self._region_index = {g: k for k, g in enumerate(self.region_names)}
        self._cover: dict[tuple, float | None] = {}
        self._carry: dict[int, np.ndarray | None] = {}
        self._robot_regions: list[set[int]] | None = None
        self._fits: dict[tuple[int, tuple], bool] = {}
        self._valid: dict[State, bool] = {}
        self._label: dict[State, int] = {}
        self._pairs: dict[tuple, list[tuple[int, int]]] = {}
        self._radius_ids: dict = {}
        self._radius_values: list[float] = [0.0]
        self._fit_tables: dict[int, np.ndarray] = {}
        self._fit_memo: dict[int, dict[int, int]] = {}
        self._union_memo: dict[tuple[int, tuple[int, ...], int], bool] = {}  # _entities_fit per (k, grasps, mask)
        self._graph: RegionGraph | None = None
        self._conn: dict[float, np.ndarray] = {}
        self._travel: dict[float, np.ndarray] = {}
        self.initial = tuple(
            [self._region_index[r.initial_region] for r in scenario.robots]
            + [self._region_index[o.initial_region] for o in scenario.objects]
            + [-1] * self.N
        )

    # ------------------------------------------------------------------ state accessors
    def robots_of(self, s: State) -> tuple[int, ...]:
        return s[: self.N]

    def objects_of(self, s: State) -> tuple[int, ...]:
        return s[self.N : self.N + self.M]

    def grasps_of(self, s: State) -> tuple[int, ...]:
        return s[self.N + self.M :]

    def make_state(self, robots: Sequence[int], objects: Sequence[int], grasps: Sequence[int]) -> State:
        return tuple(robots) + tuple(objects) + tuple(grasps)

    def team(self, s: State, j: int) -> tuple[int, ...]:
        """Robots grasping object j in s (the paper's AG_j)."""
        g = self.grasps_of(s)
        return tuple(i for i in range(self.N) if g[i] == j)

    def team_power_ok(self, team: Sequence[int], j: int) -> bool:
        """Λ(j, ζ_A): the team is powerful enough to transport object j."""
        return len(team) > 0 and sum(self.power[i] for i in team) >= self.required_power[j]

    def covering_radius(self, j: int, team: tuple[int, ...]) -> float:
        """r_A,j of object j grasped by ``team`` (r^o_j when the team is empty)."""
        key = (j, team)
        r = self._cover.get(key)
        if r is None:
            radii = [self.robot_radius[i] for i in team]
            r = grasp_layout(self.object_radius[j], radii, self.grasp_gap).covering_radius
            self._cover[key] = r
        return r

    def travel_radius(self, j: int, team: tuple[int, ...]) -> float:
        """Radius of object j carried by ``team`` wherever its travel between regions is checked: the covering
        radius plus :data:`~mrodrake.geometry.TEAM_TRAVEL_SLACK` (the members dock within a tolerance of their
        slots)."""
        return self.covering_radius(j, team) + TEAM_TRAVEL_SLACK

    @property
    def region_graph(self) -> RegionGraph:
        if self._graph is None:
            ws = self.scenario.workspace
            self._graph = RegionGraph(polygon(ws.boundary), [polygon(o.polygon) for o in ws.obstacles],
                                      [(g.center, g.radius) for g in self.scenario.regions], margin=self.margin)
        return self._graph

    def connections(self, radius: float) -> np.ndarray:
        """``C[k, k']``: can an entity of ``radius`` travel between regions k and k'
        (:class:`~mrodrake.geometry.RegionGraph`: narrow passages and regions in the way block it)."""
        C = self._conn.get(radius)
        if C is None:
            C = self._conn[radius] = self.region_graph.matrix(radius)
        return C

    def travel(self, radius: float) -> np.ndarray:
        """``C[k, k']`` of :meth:`connections` for k ≠ k' (the diagonal is True and not computed: staying in a
        region needs no travel)."""
        C = self._travel.get(radius)
        if C is None:
            C = self._travel[radius] = self.region_graph.travel_matrix(radius)
        return C

    def connected(self, radius: float, k: int, k2: int) -> bool:
        return self.region_graph.connected(radius, k, k2)

    def blocked(self, s: State, t: State) -> str | None:
        """Why a region change of s → t cannot be travelled (None when every one can)."""
        for a in self.actions(s, t):
            if isinstance(a, Navigate):
                r = self.robot_radius[a.robot]
            elif isinstance(a, Transport):
                r = self.travel_radius(a.obj, a.team)
            else:
                continue
            if not self.connected(r, a.src, a.dst):
                if isinstance(a, Navigate):
                    who = f"robot {self.robot_names[a.robot]}"
                else:
                    who = (f"object {self.object_names[a.obj]} with team "
                           f"{'+'.join(self.robot_names[i] for i in a.team)}")
                size = f"radius {r:.2f} m" if isinstance(a, Navigate) else \
                    f"covering radius {self.covering_radius(a.obj, a.team):.2f} m"
                return (f"{who} ({size}) cannot travel from {self.region_names[a.src]} to "
                        f"{self.region_names[a.dst]}: {_no_passage(self.margin, isinstance(a, Transport))}")
        return None

    def reach(self, radius: float, k: int) -> list[int]:
        """Regions an entity of ``radius`` can ever get to from region k (travelling region to region)."""
        return sorted(reachable(self.connections(radius), k))

    def smallest_team(self, j: int) -> tuple[tuple[int, ...], float] | None:
        """The team powerful enough to carry object j with the smallest covering radius, and that radius
        (None: no team is); teams of up to 12 robots are enumerated, of up to 4 beyond 12 robots."""
        largest = self.N if self.N <= 12 else 4
        teams = [t for n in range(1, largest + 1) for t in itertools.combinations(range(self.N), n)
                 if self.team_power_ok(t, j)]
        if not teams:
            return None
        best = min(teams, key=lambda t: (self.covering_radius(j, t), len(t)))
        return best, self.covering_radius(j, best)

    def smallest_team_radius(self, j: int, among: Sequence[int] | None = None) -> float | None:
        """A lower bound on the covering radius of every team powerful enough to carry object j (None when
        no team is), its members drawn from ``among`` (default: every robot): exact over all teams up to 12
        robots; beyond, the smallest c such that the robots whose one-robot covering radius is at most c are
        together strong enough (a team's covering radius is at least each of its members' one-robot radii,
        :func:`~mrodrake.geometry.grasp_layout`)."""
        robots = tuple(range(self.N)) if among is None else tuple(sorted(among))
        key = ("team", j, robots)
        if key in self._cover:
            return self._cover[key]
        r = None
        if self.N <= 12:
            radii = [self.covering_radius(j, t) for n in range(1, len(robots) + 1)
                     for t in itertools.combinations(robots, n) if self.team_power_ok(t, j)]
            r = min(radii, default=None)
        else:
            power = 0.0
            for c, i in sorted((self.covering_radius(j, (i,)), i) for i in robots):
                power += self.power[i]
                if power >= self.required_power[j]:
                    r = c
                    break
        self._cover[key] = r
        return r

    def robot_regions(self) -> list[set[int]]:
        """The regions each robot can ever be in (its own travels; a team's larger radius only removes
        connections, so carrying an object takes it nowhere else)."""
        if self._robot_regions is None:
            self._robot_regions = [set(self.reach(self.robot_radius[i], self.initial[i])) for i in range(self.N)]
        return self._robot_regions

    def carry_connections(self, j: int, where: Sequence[set[int]] | None = None) -> np.ndarray | None:
        """``C[k, k']``: can object j ever be carried from region k to k' (None: no team is strong enough)?  A
        team that carries it stands in k and then in k', so its members are robots that can reach both, and
        it fits in both; with r the smallest covering radius of a strong-enough team of such robots
        (:meth:`smallest_team_radius`), the regions must hold a disk of radius r and be connected for r + the
        docking slack (a larger radius only removes connections).  ``where``: the regions each robot can be
        in, when narrower than :meth:`robot_regions` (not cached)."""
        if where is None and j in self._carry:
            return self._carry[j]
        C = None
        if self.smallest_team_radius(j) is not None:
            regions = self.robot_regions() if where is None else where
            C = np.zeros((self.K, self.K), dtype=bool)
            for k in range(self.K):
                for k2 in range(self.K):
                    crew = [i for i in range(self.N) if k in regions[i] and k2 in regions[i]]
                    r = self.smallest_team_radius(j, crew)
                    if r is not None and self.region_fits(k, [r]) and self.region_fits(k2, [r]):
                        C[k, k2] = self.connected(r + TEAM_TRAVEL_SLACK, k, k2)
        if where is None:
            self._carry[j] = C
        return C

    def team_size_note(self, r: float) -> str:
        """What a team of smallest covering radius ``r`` needs of a region, for messages."""
        return (f"smallest covering radius {r:.2f} m; with the {self.spacing:g} m spacing to the rim it needs a "
                f"region radius above {r + self.spacing:.2f} m")

    def unreachable(self) -> list[str]:
        """One line per entity that can never reach some region from where it starts: robots by their
        radius, objects by :meth:`carry_connections` (regions where no strong-enough team fits first)."""
        out = []
        names = self.region_names
        for i in range(self.N):
            k = self.initial[i]
            miss = [names[m] for m in range(self.K) if m not in self.reach(self.robot_radius[i], k)]
            if miss:
                out.append(f"robot {self.robot_names[i]} (radius {self.robot_radius[i]:.2f} m) can never reach "
                           f"{', '.join(miss)} from {names[k]}: {_no_passage(self.margin)}")
        for j in range(self.M):
            k = self.initial[self.N + j]
            r = self.smallest_team_radius(j)
            if r is None:
                continue
            size = self.team_size_note(r)
            if not any(self.region_fits(m, [r]) for m in range(self.K)):
                out.append(f"object {self.object_names[j]} can never be carried: no team strong enough fits "
                           f"in any region ({size}, largest region radius {max(self.region_radius):.2f} m)")
                continue
            unfit = [m for m in range(self.K) if not self.region_fits(m, [r])]
            if k in unfit:
                out.append(f"object {self.object_names[j]} can never be carried: no team strong enough fits in "
                           f"its region {names[k]} ({size}, region radius {self.region_radius[k]:.2f} m)")
                continue
            if unfit:
                out.append(f"object {self.object_names[j]} can never be carried to "
                           f"{', '.join(names[m] for m in unfit)}: no team strong enough fits there ({size}, "
                           f"region radi{'us' if len(unfit) == 1 else 'i'} "
                           f"{', '.join(f'{self.region_radius[m]:.2f}' for m in unfit)} m)")
            crew = [i for i in range(self.N) if k in self.robot_regions()[i]]
            if self.smallest_team_radius(j, crew) is None:
                who = "+".join(self.robot_names[i] for i in crew) or "none"
                out.append(f"object {self.object_names[j]} can never be carried: the robots that can reach its "
                           f"region {names[k]} ({who}) are not strong enough together (power "
                           f"{sum(self.power[i] for i in crew):g}, needs {self.required_power[j]:g})")
                continue
            fits = np.array([m not in unfit for m in range(self.K)])
            travel = r + TEAM_TRAVEL_SLACK
            passable = reachable(self.connections(travel) & fits[:, None] & fits[None, :], k)
            tight = [m for m in range(self.K)
                     if m not in passable and m not in unfit and self.region_radius[m] <= travel]
            if tight:  # the region holds the team's disk but not its travel disk: no seat to arrive at
                out.append(f"object {self.object_names[j]} can never be carried to "
                           f"{', '.join(names[m] for m in tight)} from {names[k]}: its smallest team's travel disk "
                           f"(covering radius {r:.2f} m + slack {TEAM_TRAVEL_SLACK:g} m = {travel:.2f} m) is not "
                           f"smaller than the region (radi{'us' if len(tight) == 1 else 'i'} "
                           f"{', '.join(f'{self.region_radius[m]:.2f}' for m in tight)} m)")
            miss = [names[m] for m in range(self.K) if m not in passable and m not in unfit and m not in tight]
            if miss:
                out.append(f"object {self.object_names[j]} can never be carried to {', '.join(miss)} from "
                           f"{names[k]}: {_no_passage(self.margin, True)} for its smallest team (covering radius "
                           f"{r:.2f} m)")
            near = reachable(self.carry_connections(j), k)
            weak = [names[m] for m in sorted(passable - near)]
            if weak:
                out.append(f"object {self.object_names[j]} can never be carried to {', '.join(weak)} from "
                           f"{names[k]}: no team strong enough of robots that can reach the regions on the way "
                           "gets it there")
        return out

    def estimate_size(self, samples: int = 300, per_state: int = 24, seed: int = 0) -> SizeEstimate:
        """Estimate the explicit TS's states and transitions without building it (Monte Carlo, seeded).

        Every entity stays in the regions it can reach from its start (objects: for their smallest team),
        and a robot is free in one of its regions or grasps an object there.  States are drawn from that
        product space; a drawn valid state counts with the space's size and with its candidate count
        (:meth:`candidate_count`) times the valid fraction of ``per_state`` drawn candidates.
        Reachability is not checked, so the estimate tends to exceed :meth:`build`'s counts."""
        t0 = time.perf_counter()
        rng = np.random.default_rng(seed)
        N, M = self.N, self.M
        robot_dom = [self.reach(self.robot_radius[i], self.initial[i]) for i in range(N)]
        obj_dom = []
        for j in range(M):
            best = self.smallest_team(j)
            k = self.initial[N + j]
            obj_dom.append(sorted(reachable(self.carry_connections(j), k)) if best is not None else [k])
        obj_weight = math.prod(len(d) for d in obj_dom)
        states = transitions = 0.0
        for _ in range(samples):
            O = [d[rng.integers(len(d))] for d in obj_dom]
            R, G, weight = [], [], float(obj_weight)
            for i in range(N):
                grasp = [j for j in range(M) if O[j] in robot_dom[i]]
                n = len(robot_dom[i]) + len(grasp)
                weight *= n
                c = int(rng.integers(n))
                if c < len(robot_dom[i]):
                    R.append(robot_dom[i][c])
                    G.append(-1)
                else:
                    R.append(O[grasp[c - len(robot_dom[i])]])
                    G.append(grasp[c - len(robot_dom[i])])
            s = self.make_state(R, O, G)
            if not self.is_valid(s):
                continue
            states += weight
            transitions += weight * self._degree(s, per_state, rng)
        return SizeEstimate(states / samples, transitions / samples, samples, time.perf_counter() - t0)

    def _degree(self, s: State, draws: int, rng: np.random.Generator) -> float:
        """Estimated number of transitions out of s: its candidates times the valid fraction of ``draws``."""
        rules = [(dests, opts, math.prod(len(p) for p in opts)) for dests, opts in self.options(s)]
        counts = np.array([c for _, _, c in rules], dtype=float)
        total = float(counts.sum())
        if total <= draws:
            return float(sum(1 for _ in self.successor_states(s)))
        ok = 0
        for r in rng.choice(len(rules), size=draws, p=counts / total):
            dests, opts, _ = rules[r]
            regions, grasps = zip(*(p[rng.integers(len(p))] for p in opts))
            t = tuple(regions) + tuple(dests) + tuple(grasps)
            ok += self.is_valid(t) and self.step_fits(s, t)
        return total * ok / draws

    # ------------------------------------------------------------------ validity
    def region_fits(self, k: int, radii: Sequence) -> bool:
        """P_{s,0} for region k with the layout spacing (cached on the sorted units): each unit a radius, or
        (radius, bound) for an object whose centre a team of covering radius ``bound`` put down
        (:meth:`parked_unit`)."""
        units = tuple(sorted(((u, 0.0) if not isinstance(u, tuple) else u for u in radii), reverse=True))
        key = (k, units)
        ok = self._fits.get(key)
        if ok is None:
            bounds = [b or None for _, b in units]
            ok = entities_fit(self.region_radius[k], [r for r, _ in units], self.spacing, bounds)
            self._fits[key] = ok
        return ok

    def bound_at_home(self) -> TransitionSystem:
        """This TS with ``bind_home`` (:meth:`parked_unit`), sharing every cache packing does not decide
        (region graph and connections, labels, option pairs, team radii, P_s answers per unit multiset)."""
        self.region_graph  # noqa: B018 (built here, so that both share it)
        self.robot_regions()
        sub = copy.copy(self)
        sub.bind_home = True
        sub._valid, sub._fit_tables, sub._fit_memo, sub._union_memo = {}, {}, {}, {}
        return sub

    def parked_unit(self, j: int, k: int):
        """The P_s unit of object j lying ungrasped in region k: its radius in its initial region, elsewhere
        (radius, bound) with bound the smallest covering radius of a team that can carry it
        (:meth:`smallest_team_radius`).  Objects move only with a team, which puts each one down where the
        team's covering disk fits in the region (the placement's team spots keep spacing/2 to the rim), so
        outside its initial region the object's centre is at most R_k − bound − spacing/2 from the region's
        centre: a sound bound whichever team carried it.  With ``bind_home`` the bound holds in the initial
        region too (where it holds only once a team grasps the object there): a sub-TS whose runs leave every
        object room for a team wherever it lies."""
        r = self.object_radius[j]
        if k == self.initial[self.N + j] and not self.bind_home:
            return r
        bound = self.smallest_team_radius(j)
        return r if bound is None else (r, bound)

    def region_entities(self, s: State) -> list[list[float]]:
        """P_s units of the entities in each region (free robots, ungrasped objects, teams; :meth:`region_fits`)."""
        N, M = self.N, self.M
        R, O, G = s[:N], s[N : N + M], s[N + M :]
        per: list[list[float]] = [[] for _ in range(self.K)]
        teams: list[list[int]] = [[] for _ in range(M)]
        for i in range(N):
            if G[i] < 0:
                per[R[i]].append(self.robot_radius[i])
            else:
                teams[G[i]].append(i)
        for j in range(M):
            per[O[j]].append(self.covering_radius(j, tuple(teams[j])) if teams[j] else self.parked_unit(j, O[j]))
        return per

    def is_valid(self, s: State) -> bool:
        """Grasping robots co-located with their objects, and every region's entities fit (P_s)."""
        ok = self._valid.get(s)
        if ok is None:
            ok = self._compute_valid(s)
            self._valid[s] = ok
        return ok

    def _compute_valid(self, s: State) -> bool:
        N, M, K = self.N, self.M, self.K
        if len(s) != 2 * N + M:
            return False
        R, O, G = s[:N], s[N : N + M], s[N + M :]
        if any(not 0 <= k < K for k in s[: N + M]) or any(not -1 <= g < M for g in G):
            return False
        if any(g >= 0 and R[i] != O[g] for i, g in enumerate(G)):
            return False
        return self._regions_fit(s)

    def _regions_fit(self, s: State) -> bool:
        """Every region's entities fit (P_s); assumes grasping robots are co-located."""
        fits = self.region_fits
        return all(not radii or fits(k, radii) for k, radii in enumerate(self.region_entities(s)))

    def step_fits(self, s: State, t: State) -> bool:
        """Capacity of sequential execution: in every region that some entity leaves and some entity enters
        in the step s → t, and in every region where a robot grasps or releases, the units that are there at
        its start or at its end fit together (P_s), under the grasps of s and under those of t.  The executor
        may then run the step's actions in any order without overfilling a region (occupancy of a region
        during the step is a subset of that union; a grasp that runs before the others leave its region forms
        its team among them)."""
        N, M = self.N, self.M
        n = N + M
        dep = arr = 0  # regions as bit masks
        for e in range(n):
            if s[e] != t[e]:
                dep |= 1 << s[e]
                arr |= 1 << t[e]
        check = dep & arr
        changes = False
        for i in range(N):
            if s[n + i] != t[n + i]:
                check |= 1 << s[i] | 1 << t[i]
                changes = True
        if not check:
            return True
        here = [0] * self.K  # per region: the entities there in s or t (bit e: entity e)
        for e in range(n):
            here[s[e]] |= 1 << e
            here[t[e]] |= 1 << e
        # under the grasps of s and those of t (the same when the step changes no grasp)
        grasps = (tuple(s[n:]), tuple(t[n:])) if changes else (tuple(s[n:]),)
        memo = self._union_memo
        k = 0
        while check:
            if check & 1:
                for G in grasps:
                    key = (k, G, here[k])
                    ok = memo.get(key)
                    if ok is None:
                        ok = memo[key] = self._entities_fit(k, G, here[k])
                    if not ok:
                        return False
            check >>= 1
            k += 1
        return True

    def _entities_fit(self, k: int, G: tuple[int, ...], here: int) -> bool:
        """P_s for region k of the entities in the mask ``here`` (bit e: entity e) under the grasps G: free
        robots alone, objects with their teams."""
        N, M = self.N, self.M
        teams: dict[int, list[int]] = {}
        radii = []
        for i in range(N):
            if G[i] >= 0:
                teams.setdefault(G[i], []).append(i)
            elif here >> i & 1:
                radii.append(self.robot_radius[i])
        for j in range(M):
            if here >> (N + j) & 1:
                radii.append(self.covering_radius(j, tuple(teams[j])) if j in teams else self.parked_unit(j, k))
        return self.region_fits(k, radii)

    def steps_fit(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """:meth:`step_fits` of the steps A[r] → B[r] (rows of state arrays; B may be one state), vectorised
        (:meth:`steps_fit_index`); a few steps to one state are tested one by one."""
        A = np.asarray(A)
        B = np.asarray(B)
        if B.ndim == 1 and len(A) <= _FEW_STEPS:
            t = B.tolist()
            return np.array([self.step_fits(a, t) for a in A.reshape(-1, 2 * self.N + self.M).tolist()], dtype=bool)
        if B.ndim == 1 and self._masks_apply():
            return self._steps_fit_one(A.reshape(-1, 2 * self.N + self.M), [int(x) for x in B])
        if B.ndim == 1:
            states = np.concatenate([A.reshape(-1, 2 * self.N + self.M), B[None, :].astype(A.dtype)])
            dst = np.full(len(A), len(A), dtype=np.int64)
        else:
            states = np.concatenate([A, B.astype(A.dtype)])
            dst = np.arange(len(A), 2 * len(A), dtype=np.int64)
        return self.steps_fit_index(states, np.arange(len(A), dtype=np.int64), dst)

    def steps_fit_index(self, states: np.ndarray, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
        """:meth:`step_fits` of the steps states[src[r]] → states[dst[r]].  Per state and region, the entities
        there form a bit mask; a region loses and gains entities where the two masks differ both ways, and
        the union of the masks (free robots under the grasps considered, every object with its team) is
        decided once per distinct (grasps, union) (:meth:`_masks_fit`)."""
        K = self.K
        S = np.asarray(states)
        src, dst = np.asarray(src, dtype=np.int64), np.asarray(dst, dtype=np.int64)
        if not self._masks_apply():
            return np.array([self.step_fits(tuple(int(x) for x in S[a]), tuple(int(x) for x in S[b]))
                             for a, b in zip(src, dst)], dtype=bool)
        ok = np.ones(len(src), dtype=bool)
        if len(src) == 0:
            return ok
        here, grasps, free = self._region_masks(S)
        held = self._grasp_changes(S[src], S[dst])
        for k in range(K):
            pa, pb = here[k][src], here[k][dst]
            rows = np.flatnonzero((((pa & ~pb) != 0) & ((pb & ~pa) != 0)) | (((pa | pb) & held) != 0))
            if len(rows) == 0:
                continue
            union = pa[rows] | pb[rows]
            for side in (src, dst):
                st = side[rows]
                ok[rows[~self._masks_fit(k, grasps[st], union & free[st])]] = False
        return ok

    def _steps_fit_one(self, A: np.ndarray, s: list[int]) -> np.ndarray:
        """:meth:`steps_fit` of the steps A[r] → s for one state s."""
        N, M = self.N, self.M
        n = N + M
        ok = np.ones(len(A), dtype=bool)
        if len(A) == 0:
            return ok
        here, grasps, free = self._region_masks(A)
        held = self._grasp_changes(A, np.asarray(s, dtype=A.dtype)[None, :])
        g_s = sum((s[n + i] + 1) * (M + 1) ** i for i in range(N))
        f_s = sum(1 << i for i in range(N) if s[n + i] < 0) | (((1 << M) - 1) << N)
        for k in range(self.K):
            h = sum(1 << e for e in range(n) if s[e] == k)
            pa = here[k]
            rows = np.flatnonzero((((pa & ~h) != 0) & ((pa | h) != pa)) | (((pa | h) & held) != 0))
            if len(rows) == 0:
                continue
            union = pa[rows] | h
            fit = self._masks_fit(k, grasps[rows], union & free[rows])
            fit &= self._masks_fit(k, np.full(len(rows), g_s, dtype=np.int64), union & f_s)
            ok[rows[~fit]] = False
        return ok

    def _grasp_changes(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """Per step A[r] → B[r] (B may be one row), the robots that grasp or release as a bit mask (robot i:
        bit i), in the dtype of :meth:`_region_masks`' masks."""
        N, n = self.N, self.N + self.M
        dtype = np.int16 if n < 16 else np.int32 if n < 32 else np.int64
        pow_r = (np.int64(1) << np.arange(N, dtype=np.int64)).astype(dtype)
        return ((A[:, n:] != B[:, n:]) @ pow_r).astype(dtype)

    def _masks_apply(self) -> bool:
        """Do (grasp vector, entity mask) codes fit in int64 (else the checks run state by state)?"""
        N, M = self.N, self.M
        return N + M <= _MASK_BITS and (M + 1) ** N << (N + M) < 1 << 62

    def _region_masks(self, S: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per state (rows of S): ``here[k]``, the entities in region k as a bit mask (robot i: bit i, object j:
        bit N + j); the grasp vector's code Σ_i (g_i + 1)(M + 1)^i; the mask of the entities that count alone
        under the state's grasps (free robots and every object)."""
        N, M, K = self.N, self.M, self.K
        n = N + M
        dtype = np.int16 if n < 16 else np.int32 if n < 32 else np.int64
        pow_e = (np.int64(1) << np.arange(n, dtype=np.int64)).astype(dtype)
        here = (S[None, :, :n] == np.arange(K)[:, None, None]) @ pow_e
        G = S[:, n:]
        grasps = (G.astype(np.int64) + 1) @ (np.int64(M + 1) ** np.arange(N, dtype=np.int64))
        objects = int(pow_e[N:].astype(np.int64).sum()) if M else 0
        free = (((G < 0) @ pow_e[:N].astype(np.int64)) | objects).astype(dtype)
        return here, grasps, free

    def _masks_fit(self, k: int, grasps: np.ndarray, masks: np.ndarray) -> np.ndarray:
        """P_s for region k of the entities in ``masks[r]`` (bit i: free robot i; bit N + j: object j with its
        team under the grasps coded ``grasps[r]``, see :meth:`_region_masks`); an empty mask fits.  Decided
        once per distinct code and remembered (a table over all codes when it is small)."""
        n = self.N + self.M
        code = (grasps.astype(np.int64) << n) | masks
        space = (self.M + 1) ** self.N << n
        if space <= _DENSE_CODES:
            table = self._fit_tables.get(k)
            if table is None:
                table = self._fit_tables[k] = np.full(space, -1, dtype=np.int8)
            got = table[code]
            unknown = np.flatnonzero(got < 0)
            if len(unknown):
                seen = np.zeros(space, dtype=bool)
                seen[code[unknown]] = True
                new = np.flatnonzero(seen)
                table[new] = self._codes_fit(k, new)
                got = table[code]
            return got.astype(bool)
        codes, inv = np.unique(code, return_inverse=True)
        memo = self._fit_memo.setdefault(k, {})
        got = np.array([memo.get(c, -1) for c in codes.tolist()], dtype=np.int8)
        miss = np.flatnonzero(got < 0)
        if len(miss):
            got[miss] = self._codes_fit(k, codes[miss])
            memo.update(zip(codes[miss].tolist(), got[miss].tolist()))
        return got[inv.ravel()].astype(bool)

    def _codes_fit(self, k: int, codes: np.ndarray) -> np.ndarray:
        """P_s for region k of each code ``grasps << (N + M) | mask`` (:meth:`_masks_fit`): the entities' radii
        as sorted ids of distinct radius values, P_s decided once per distinct multiset."""
        N, M = self.N, self.M
        n = N + M
        g, m = codes >> n, codes & ((1 << n) - 1)
        ids = np.zeros((len(codes), n), dtype=np.int64)
        for i in range(N):
            ids[:, i] = np.where(m >> i & 1, self._radius_id(self.robot_radius[i]), 0)
        G = np.empty((len(codes), N), dtype=np.int64)
        for i in range(N):
            g, d = np.divmod(g, M + 1)
            G[:, i] = d - 1
        for j in range(M):
            team = (G == j) @ (np.int64(1) << np.arange(N, dtype=np.int64))
            teams, inv = np.unique(team, return_inverse=True)
            rid = np.array([self._radius_id(self.covering_radius(j, tuple(i for i in range(N) if t >> i & 1))
                                            if t else self.parked_unit(j, k)) for t in teams.tolist()], dtype=np.int64)
            ids[:, N + j] = np.where(m >> (N + j) & 1, rid[inv.ravel()], 0)
        ids.sort(axis=1)
        values = self._radius_values
        if len(values) ** n < 1 << 62:
            _, first, inv = np.unique(ids @ (np.int64(len(values)) ** np.arange(n, dtype=np.int64)),
                                      return_index=True, return_inverse=True)
            rows = ids[first]
        else:
            rows, inv = np.unique(ids, axis=0, return_inverse=True)
        fit = np.array([not any(row) or self.region_fits(k, [values[x] for x in row if x]) for row in rows.tolist()],
                       dtype=bool)
        return fit[inv.ravel()]

    def _radius_id(self, r) -> int:
        """A number ≥ 1 per distinct P_s unit (a radius, or :meth:`parked_unit`'s pair; exact float equality:
        same value, same P_s key)."""
        x = self._radius_ids.get(r)
        if x is None:
            x = self._radius_ids[r] = len(self._radius_values)
            self._radius_values.append(r)
        return x

    def _mask_fits(self, k: int, G: np.ndarray, mask: int) -> bool:
        """P_s for region k of the entities in ``mask`` (bit i: free robot i; bit N + j: object j with its
        team under the grasps G)."""
        N = self.N
        radii = [self.robot_radius[i] for i in range(N) if mask >> i & 1]
        for j in range(self.M):
            if mask >> (N + j) & 1:
                team = tuple(i for i in range(N) if G[i] == j)
                radii.append(self.covering_radius(j, team) if team else self.parked_unit(j, k))
        return self.region_fits(k, radii)

    # ------------------------------------------------------------------ labels and cost
    def label_mask(self, s: State) -> int:
        """L(s) as a bitmask over :attr:`propositions` (bit e·K + k: entity e is in region k)."""
        m = self._label.get(s)
        if m is None:
            K = self.K
            m = 0
            for e, k in enumerate(s[: self.N + self.M]):
                m |= 1 << (e * K + k)
            self._label[s] = m
        return m

    def label(self, s: State) -> frozenset[str]:
        """L(s): the true atomic propositions."""
        names = self.robot_names + self.object_names
        return frozenset(f"{names[e]}_{self.region_names[k]}" for e, k in enumerate(s[: self.N + self.M]))

    def cost(self, s: State, t: State) -> float:
        """χ(s, t): robots' region-centre travel distance plus c_grasp per grasp and release."""
        N, M, d = self.N, self.M, self._dist
        c = 0.0
        for i in range(N):
            if s[i] != t[i]:
                c += d[s[i]][t[i]]
            gs, gt = s[N + M + i], t[N + M + i]
            if gs != gt:
                c += self.grasp_cost
        return c

    # ------------------------------------------------------------------ transitions
    def check_transition(self, s: State, t: State) -> str | None:
        """Why s → t violates a TS rule (``None`` if it is a transition); derived from the rules only."""
        N, M = self.N, self.M
        if not self.is_valid(s):
            return "source state is not valid"
        if not self.is_valid(t):
            return "target state is not valid (entities do not fit or a grasp is not co-located)"
        R, O, G = s[:N], s[N : N + M], s[N + M :]
        R2, O2, G2 = t[:N], t[N : N + M], t[N + M :]
        for i in range(N):
            if G[i] != G2[i]:
                if G[i] >= 0 and G2[i] >= 0:
                    return f"robot {self.robot_names[i]} switches objects in one step"
                if R[i] != R2[i]:
                    return f"robot {self.robot_names[i]} grasps/releases while moving"
                j = G[i] if G[i] >= 0 else G2[i]
                if O[j] != O2[j]:
                    return f"object {self.object_names[j]} moves while robot {self.robot_names[i]} grasps/releases it"
            elif G[i] >= 0:
                j = G[i]
                if (R[i] != R2[i]) != (O[j] != O2[j]) or R2[i] != O2[j]:
                    return f"robot {self.robot_names[i]} grasping {self.object_names[j]} does not move with it"
        for j in range(M):
            if O[j] != O2[j]:
                team = tuple(i for i in range(N) if G[i] == j)
                team2 = tuple(i for i in range(N) if G2[i] == j)
                if not team or team != team2:
                    return f"object {self.object_names[j]} moves without the same non-empty team grasping it"
                if not self.team_power_ok(team, j):
                    members = ", ".join(self.robot_names[i] for i in team)
                    return f"team {{{members}}} lacks the power to move {self.object_names[j]} (Λ)"
        if not self.step_fits(s, t):
            return "the step's arrivals do not fit next to the entities that leave the same region (P_s)"
        return self.blocked(s, t)

    def actions(self, s: State, t: State) -> tuple[Action, ...]:
        """The actions of s → t (recovered from the two states; empty for the self-loop)."""
        N, M = self.N, self.M
        R, O, G = s[:N], s[N : N + M], s[N + M :]
        R2, O2, G2 = t[:N], t[N : N + M], t[N + M :]
        out: list[Action] = []
        for j in range(M):
            if O[j] != O2[j]:
                out.append(Transport(j, tuple(i for i in range(N) if G[i] == j), O[j], O2[j]))
        for i in range(N):
            if G[i] != G2[i]:
                out.append(Grasp(i, G2[i]) if G2[i] >= 0 else Release(i, G[i]))
            elif G[i] < 0 and R[i] != R2[i]:
                out.append(Navigate(i, R[i], R2[i]))
        return tuple(out)

    def option_keys(self, s: State) -> Iterator[tuple[tuple[int, ...], list[tuple]]]:
        """The action rules: for every admissible combination of object destinations, one key per robot
        naming its admissible (region', grasp') choices (see :meth:`option_pairs`):

        * ``(region, -1, graspable, i)`` free robot i: stay, navigate to any region connected to its own for
          its radius (:meth:`connected`), or grasp a co-located object in ``graspable`` (objects that do not
          move in this step);
        * ``(region, j, None)`` robot grasping j while j stays: keep grasping or release;
        * ``(region', j, True)`` robot grasping j while j moves to region' with the team.
        """
        N, M, K = self.N, self.M, self.K
        R, O, G = s[:N], s[N : N + M], s[N + M :]
        team_power = [0.0] * M
        teams: list[tuple[int, ...]] = [()] * M
        for i in range(N):
            if G[i] >= 0:
                team_power[G[i]] += self.power[i]
                teams[G[i]] += (i,)
        obj_opts = []
        for j in range(M):
            if team_power[j] > 0 and team_power[j] >= self.required_power[j]:
                C = self.connections(self.travel_radius(j, teams[j]))
                obj_opts.append([O[j]] + [k for k in range(K) if k != O[j] and C[O[j], k]])
            else:
                obj_opts.append([O[j]])
        for dests in itertools.product(*obj_opts):
            staying: list[tuple[int, ...]] = [()] * K
            for j in range(M):
                if dests[j] == O[j]:
                    staying[O[j]] += (j,)
            keys = []
            for i in range(N):
                g = G[i]
                if g < 0:
                    keys.append((R[i], -1, staying[R[i]], i))
                else:
                    keys.append((dests[g], g, True) if dests[g] != O[g] else (R[i], g, None))
            yield dests, keys

    def option_pairs(self, key: tuple) -> list[tuple[int, int]]:
        """The admissible (region', grasp') pairs of an option key (cached)."""
        pairs = self._pairs.get(key)
        if pairs is None:
            r, g, extra = key[:3]
            if g < 0:
                C = self.connections(self.robot_radius[key[3]])
                pairs = [(r, -1)] + [(k, -1) for k in range(self.K) if k != r and C[r, k]] + [(r, j) for j in extra]
            elif extra is None:
                pairs = [(r, g), (r, -1)]
            else:
                pairs = [(r, g)]
            self._pairs[key] = pairs
        return pairs

    def options(self, s: State) -> Iterator[tuple[tuple[int, ...], list[list[tuple[int, int]]]]]:
        """The action rules as option lists: for every admissible combination of object destinations,
        each robot's admissible (region', grasp') pairs.  Every product of the lists is a candidate
        successor; it is a transition iff it is valid."""
        pairs = self.option_pairs
        for dests, keys in self.option_keys(s):
            yield dests, [pairs(k) for k in keys]

    def candidate_count(self, s: State) -> int:
        """How many candidate successors :meth:`build` enumerates at s (valid or not), without enumerating them."""
        return sum(math.prod(len(p) for p in opts) for _, opts in self.options(s))

    def successor_states(self, s: State) -> Iterator[State]:
        """All s' with s → s' (implicit; never enumerates the whole TS)."""
        valid, fits = self.is_valid, self.step_fits
        for dests, robot_opts in self.options(s):
            for choice in itertools.product(*robot_opts):
                regions, grasps = zip(*choice)
                t = regions + dests + grasps
                if valid(t) and fits(s, t):
                    yield t

    def successors(self, s: State) -> Iterator[tuple[State, tuple[Action, ...], float]]:
        """Implicit successor function: (next state, actions, cost χ) for every s → s'."""
        for t in self.successor_states(s):
            yield t, self.actions(s, t), self.cost(s, t)

    # ------------------------------------------------------------------ explicit construction
    def _radix(self) -> tuple[list[int], list[int], list[int]]:
        """Mixed-radix weights of the integer state code used by :meth:`build`."""
        N, M, K = self.N, self.M, self.K
        w_r = [K**i for i in range(N)]
        w_o = [K ** (N + j) for j in range(M)]
        base = K ** (N + M)
        w_g = [base * (M + 1) ** i for i in range(N)]
        return w_r, w_o, w_g

    def encode(self, s: State) -> int:
        """Integer code of a state (mixed radix; grasp −1 ↦ digit 0)."""
        w_r, w_o, w_g = self._radix()
        N, M = self.N, self.M
        return (sum(s[i] * w_r[i] for i in range(N)) + sum(s[N + j] * w_o[j] for j in range(M))
                + sum((s[N + M + i] + 1) * w_g[i] for i in range(N)))

    def decode(self, code: int) -> State:
        """Inverse of :meth:`encode`."""
        N, M, K = self.N, self.M, self.K
        digits = []
        for _ in range(N + M):
            code, d = divmod(code, K)
            digits.append(d)
        for _ in range(N):
            code, d = divmod(code, M + 1)
            digits.append(d - 1)
        return tuple(digits)

    def build(self, max_states: int | None = None, progress=None, max_transitions: int | None = None) -> ExplicitTS:
        """Reachable TS from the initial state as a CSR graph (see :class:`ExplicitTS`); RuntimeError beyond
        ``max_states`` states or ``max_transitions`` valid candidate transitions.

        Breadth-first over integer state codes (:meth:`encode`): the successor codes of a state are the
        sums of per-robot code deltas over the product of its option lists (:meth:`option_keys`), so no
        state tuple is built per transition; only codes never seen before are decoded and checked.  Batches
        of states are expanded at once with numpy (:meth:`_expand`) when the codes fit in 64 bits.
        """
        t0 = time.perf_counter()
        N, M, K = self.N, self.M, self.K
        if K ** (N + M) * (M + 1) ** N < 1 << 62 and self._masks_apply():
            arr, counts, tg, costs = self._explore(max_states, progress, max_transitions)
        else:
            arr, counts, tg, costs = self._explore_codes(max_states, progress, max_transitions)
        n_states = len(arr)
        keep = tg >= 0
        src_all = np.repeat(np.arange(n_states, dtype=np.int64), counts)
        cand = np.flatnonzero(keep)
        fit = self.steps_fit_index(arr, src_all[cand], tg[cand])
        keep[cand] = fit
        src, tg = src_all[keep], tg[keep].astype(np.int64)
        if costs is not None:
            costs = costs[keep]
        ip = np.zeros(n_states + 1, dtype=np.int64)
        np.cumsum(np.bincount(src, minlength=n_states), out=ip[1:])
        if not fit.all():
            # steps that do not fit may have been the only way to some states: keep what the initial state reaches
            g = csr_matrix((np.ones(len(src), dtype=np.int8), tg, ip), shape=(n_states, n_states))
            order = np.sort(breadth_first_order(g, 0, directed=True, return_predecessors=False))
        else:  # every state was found along kept steps
            order = np.arange(n_states)
        if len(order) < n_states:
            new = np.full(n_states, -1, dtype=np.int64)
            new[order] = np.arange(len(order))
            ok = (new[src] >= 0) & (new[tg] >= 0)
            src, tg = new[src[ok]], new[tg[ok]]
            if costs is not None:
                costs = costs[ok]
            arr = arr[order]
            n_states = len(order)
            ip = np.zeros(n_states + 1, dtype=np.int64)
            np.cumsum(np.bincount(src, minlength=n_states), out=ip[1:])
        src, tg = src.astype(np.int32), tg.astype(np.int32)
        if costs is None:
            costs = self._edge_costs(arr, src, tg)
        return ExplicitTS(self, arr, ip, tg, costs, time.perf_counter() - t0)

    def _explore_codes(self, max_states: int | None, progress,
                       max_transitions: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, None]:
        """Breadth-first search one state at a time on Python integer codes: (states, candidates per state,
        candidate targets (−1: invalid state), None)."""
        N, M = self.N, self.M
        w_r, w_o, w_g = self._radix()
        init = self.encode(self.initial)
        index = {init: 0}  # code -> state index, or -1 for an invalid code
        states = [self.initial]
        ends = [0]
        targets = array.array("i")
        decode, valid = self.decode, self._regions_fit  # candidates are co-located by construction
        deltas: dict[tuple, list[int]] = {}
        u = n_valid = 0
        while u < len(states):
            s = states[u]
            for dests, keys in self.option_keys(s):
                cand = [sum(dests[j] * w_o[j] for j in range(M))]
                for i in range(N):
                    d = deltas.get((i, keys[i]))
                    if d is None:
                        d = deltas[(i, keys[i])] = [r * w_r[i] + (g + 1) * w_g[i]
                                                    for r, g in self.option_pairs(keys[i])]
                    cand = [a + b for a in cand for b in d] if len(d) > 1 else [a + d[0] for a in cand]
                found = list(map(index.get, cand))
                if None in found:
                    for k, idx in enumerate(found):
                        if idx is None:
                            t = decode(cand[k])
                            if valid(t):
                                idx = len(states)
                                if max_states is not None and idx >= max_states:
                                    raise RuntimeError(f"more than {max_states} reachable states")
                                states.append(t)
                            else:
                                idx = -1
                            index[cand[k]] = found[k] = idx
                targets.extend(found)
                n_valid += len(found) - found.count(-1)
            if max_transitions is not None and n_valid > max_transitions:
                raise RuntimeError(f"more than {max_transitions} transitions")
            ends.append(len(targets))
            u += 1
            if progress is not None and u % 1000 == 0:
                progress(u, len(states))
        arr = np.array(states, dtype=np.int16).reshape(len(states), 2 * N + M)
        tg = np.frombuffer(targets, dtype=np.int32).copy() if len(targets) else np.zeros(0, np.int32)
        return arr, np.diff(np.array(ends, dtype=np.int64)), tg, None

    #: States expanded together by :meth:`_explore`.
    batch = 2048

    def _explore(self, max_states: int | None, progress,
                 max_transitions: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_explore_codes` on numpy int64 codes, a batch of known states at a time: new states are
        numbered in the order the one-at-a-time search meets them (first occurrence in the batch's candidates,
        sources in order), so both give the same graph; also returns every candidate's cost χ."""
        N, M, K = self.N, self.M, self.K
        width = 2 * N + M
        w_r, w_o, w_g = self._radix()
        space = K ** (N + M) * (M + 1) ** N
        init = self.encode(self.initial)
        dense = space <= _DENSE_INDEX
        if dense:
            index = np.full(space, -2, dtype=np.int32)  # -2 unseen, -1 invalid, else the state's number
            index[init] = 0
        else:
            known, known_ids = np.array([init], dtype=np.int64), np.zeros(1, dtype=np.int64)

        def lookup(code: np.ndarray) -> np.ndarray:
            if dense:
                return index[code].astype(np.int64)
            pos = np.minimum(np.searchsorted(known, code), len(known) - 1)
            return np.where(known[pos] == code, known_ids[pos], -2)

        tables = self._expand_tables()
        states = np.zeros((1024, width), dtype=np.int64)
        states[0] = self.initial
        n_states = 1
        parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        lo = n_valid = 0
        while lo < n_states:
            hi = min(lo + self.batch, n_states)
            per, code, cost = self._expand(states[lo:hi], tables)
            found = lookup(code)
            unseen = np.flatnonzero(found == -2)
            if len(unseen):
                codes, first = np.unique(code[unseen], return_index=True)
                codes = codes[np.argsort(first, kind="stable")]
                T = self._decode_codes(codes)
                ok = self._states_fit(T)
                nv = int(ok.sum())
                if max_states is not None and n_states + nv > max_states:
                    raise RuntimeError(f"more than {max_states} reachable states")
                ids = np.full(len(codes), -1, dtype=np.int64)
                ids[ok] = np.arange(n_states, n_states + nv)
                while n_states + nv > len(states):
                    states = np.concatenate([states, np.zeros_like(states)])
                states[n_states:n_states + nv] = T[ok]
                n_states += nv
                if dense:
                    index[codes] = ids
                else:
                    allc, allid = np.concatenate([known, codes]), np.concatenate([known_ids, ids])
                    o = np.argsort(allc, kind="stable")
                    known, known_ids = allc[o], allid[o]
                found[unseen] = lookup(code[unseen])
            parts.append((per, found.astype(np.int32), cost))
            n_valid += int((found >= 0).sum())
            if max_transitions is not None and n_valid > max_transitions:
                raise RuntimeError(f"more than {max_transitions} transitions")
            lo = hi
            if progress is not None:
                progress(lo, n_states)
        counts = np.concatenate([p[0] for p in parts])
        tg = np.concatenate([p[1] for p in parts])
        costs = np.concatenate([p[2] for p in parts])
        return states[:n_states].astype(np.int16), counts, tg, costs

    def _decode_codes(self, codes: np.ndarray) -> np.ndarray:
        """:meth:`decode` of an array of codes (one state per row)."""
        N, M, K = self.N, self.M, self.K
        out = np.empty((len(codes), 2 * N + M), dtype=np.int64)
        c = codes
        for e in range(N + M):
            c, out[:, e] = np.divmod(c, K)
        for i in range(N):
            c, d = np.divmod(c, M + 1)
            out[:, N + M + i] = d - 1
        return out

    def _states_fit(self, S: np.ndarray) -> np.ndarray:
        """:meth:`_regions_fit` of every row of S (co-located states)."""
        here, grasps, free = self._region_masks(S)
        ok = np.ones(len(S), dtype=bool)
        for k in range(self.K):
            ok &= self._masks_fit(k, grasps, here[k] & free)
        return ok

    def _expand_tables(self) -> dict:
        """Per robot and region, the codes and costs of its navigation options (staying first), for
        :meth:`_expand`."""
        N, K = self.N, self.K
        w_r, w_o, w_g = self._radix()
        lists = [[[r] + [k for k in range(K) if k != r and self.connections(self.robot_radius[i])[r, k]]
                  for r in range(K)] for i in range(N)]
        width = max((len(x) for row in lists for x in row), default=1)
        code = np.zeros((N, K, width), dtype=np.int64)
        cost = np.zeros((N, K, width))
        length = np.zeros((N, K), dtype=np.int64)
        for i in range(N):
            for r in range(K):
                ks = lists[i][r]
                code[i, r, :len(ks)] = np.array(ks, dtype=np.int64) * w_r[i]
                cost[i, r, :len(ks)] = self.dist[r, ks]
                length[i, r] = len(ks)
        return {"w_r": np.array(w_r, dtype=np.int64), "w_o": np.array(w_o, dtype=np.int64),
                "w_g": np.array(w_g, dtype=np.int64), "nav_code": code, "nav_cost": cost, "nav_len": length,
                "nav_width": width, "carry": {}}

    def _expand(self, X: np.ndarray, tables: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The candidate successors of the states X (rows) in :meth:`option_keys` × :meth:`option_pairs`
        order: (candidates per state, their codes, their costs χ)."""
        N, M, K = self.N, self.M, self.K
        w_r, w_o, w_g = tables["w_r"], tables["w_o"], tables["w_g"]
        gc = self.grasp_cost
        b = len(X)
        R, O, G = X[:, :N], X[:, N:N + M], X[:, N + M:]
        # objects: stay, or move with a powerful enough team to a region connected for its covering radius
        power = np.zeros((b, M))
        team = np.zeros((b, M), dtype=np.int64)
        for i in range(N):
            h = np.flatnonzero(G[:, i] >= 0)
            power[h, G[h, i]] += self.power[i]
            team[h, G[h, i]] |= 1 << i
        opts = np.zeros((b, M, K), dtype=np.int64)
        opts[:, :, 0] = O
        nopt = np.ones((b, M), dtype=np.int64)
        movable = (power > 0) & (power >= np.array(self.required_power, dtype=float))
        carry = tables["carry"]
        for j in range(M):
            h = np.flatnonzero(movable[:, j])
            if len(h) == 0:
                continue
            keys, inv = np.unique(team[h, j] * K + O[h, j], return_inverse=True)
            inv = inv.ravel()
            for u, key in enumerate(keys.tolist()):
                dests = carry.get((j, key))
                if dests is None:
                    members, o = divmod(key, K)
                    C = self.connections(self.travel_radius(j, tuple(i for i in range(N) if members >> i & 1)))
                    dests = carry[(j, key)] = [o] + [k for k in range(K) if k != o and C[o, k]]
                sel = h[inv == u]
                opts[sel, j, :len(dests)] = dests
                nopt[sel, j] = len(dests)
        # combinations of object destinations, the first object's slowest
        ncomb = nopt.prod(axis=1)
        cs = np.repeat(np.arange(b), ncomb)
        rest = np.arange(len(cs)) - np.repeat(np.cumsum(ncomb) - ncomb, ncomb)
        dests = np.empty((len(cs), M), dtype=np.int64)
        for j in reversed(range(M)):
            nj = nopt[cs, j]
            rest, d = np.divmod(rest, nj)
            dests[:, j] = opts[cs, j, d]
        base = dests @ w_o if M else np.zeros(len(cs), dtype=np.int64)
        Rc, Oc, Gc = R[cs], O[cs], G[cs]
        stay = dests == Oc
        # every robot's options: code deltas and costs in option_pairs order
        nav_code, nav_cost, nav_len, nav_width = tables["nav_code"], tables["nav_cost"], tables["nav_len"], \
            tables["nav_width"]
        W = max(nav_width + M, 2)
        C = len(cs)
        ocode = np.zeros((C, N, W), dtype=np.int64)
        ocost = np.zeros((C, N, W))
        cnt = np.zeros((C, N), dtype=np.int64)
        for i in range(N):
            g, r = Gc[:, i], Rc[:, i]
            f = np.flatnonzero(g < 0)
            rf = r[f]
            ocode[f, i, :nav_width] = nav_code[i, rf]
            ocost[f, i, :nav_width] = nav_cost[i, rf]
            pos = nav_len[i, rf]
            for j in range(M):
                c = stay[f, j] & (Oc[f, j] == rf)
                fc, pc = f[c], pos[c]
                ocode[fc, i, pc] = rf[c] * w_r[i] + (j + 1) * w_g[i]
                ocost[fc, i, pc] = gc
                pos = pos + c
            cnt[f, i] = pos
            h = np.flatnonzero(g >= 0)
            gh, rh = g[h], r[h]
            dg = dests[h, gh]
            mv = dg != Oc[h, gh]
            hm, hs = h[mv], h[~mv]
            ocode[hm, i, 0] = dg[mv] * w_r[i] + (gh[mv] + 1) * w_g[i]
            ocost[hm, i, 0] = self.dist[rh[mv], dg[mv]]
            cnt[hm, i] = 1
            ocode[hs, i, 0] = rh[~mv] * w_r[i] + (gh[~mv] + 1) * w_g[i]
            ocode[hs, i, 1] = rh[~mv] * w_r[i]
            ocost[hs, i, 1] = gc
            cnt[hs, i] = 2
        # the product of the robots' options, the first robot's slowest
        ncand = cnt.prod(axis=1)
        cc = np.repeat(np.arange(C), ncand)
        rest = np.arange(len(cc)) - np.repeat(np.cumsum(ncand) - ncand, ncand)
        at = [None] * N
        for i in reversed(range(N)):
            ni = cnt[cc, i]
            rest, d = np.divmod(rest, ni)
            at[i] = (cc * N + i) * W + d
        code = base[cc]
        cost = np.zeros(len(cc))
        flat_code, flat_cost = ocode.reshape(-1), ocost.reshape(-1)
        for i in range(N):
            code += flat_code[at[i]]
            cost += flat_cost[at[i]]
        per = np.add.reduceat(ncand, np.cumsum(ncomb) - ncomb) if b else np.zeros(0, dtype=np.int64)
        return per, code, cost

    def _edge_costs(self, arr: np.ndarray, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
        N, M, K = self.N, self.M, self.K
        flat = self.dist.ravel()
        cols = np.ascontiguousarray(arr.T)
        c = np.zeros(len(src))
        for i in range(N):
            r = cols[i]
            c += flat[r[src] * K + r[dst]]
            g = cols[N + M + i]
            c += self.grasp_cost * (g[src] != g[dst])
        return c

    # ------------------------------------------------------------------ presentation
    def state_dict(self, s: State) -> dict:
        """A state by names: ``{"robots": {...}, "objects": {...}, "grasps": {...}}``."""
        N, M = self.N, self.M
        return {
            "robots": {self.robot_names[i]: self.region_names[s[i]] for i in range(N)},
            "objects": {self.object_names[j]: self.region_names[s[N + j]] for j in range(M)},
            "grasps": {
                self.robot_names[i]: (self.object_names[s[N + M + i]] if s[N + M + i] >= 0 else None)
                for i in range(N)
            },
        }

    def state_from_dict(self, d: dict) -> State:
        """Inverse of :meth:`state_dict` (names must be known)."""
        reg, obj = self._region_index, {o: j for j, o in enumerate(self.object_names)}
        return self.make_state(
            [reg[d["robots"][n]] for n in self.robot_names],
            [reg[d["objects"][n]] for n in self.object_names],
            [obj[d["grasps"][n]] if d["grasps"][n] is not None else -1 for n in self.robot_names],
        )

    def format_action(self, a: Action, style: str = "text") -> str:
        """An action in the paper's Table I notation (``style='text'``) using 1-based numbers,
        e.g. ``1 →g 2``, ``π4 →3 π1``, ``π1 →T_{1,3},2 π4``; ``style='names'`` uses scenario names."""
        rn, on, gn = self.robot_names, self.object_names, self.region_names
        if style == "names":
            if isinstance(a, Navigate):
                return f"navigate {rn[a.robot]} {gn[a.src]}->{gn[a.dst]}"
            if isinstance(a, Grasp):
                return f"grasp {rn[a.robot]} {on[a.obj]}"
            if isinstance(a, Release):
                return f"release {rn[a.robot]} {on[a.obj]}"
            return f"transport {on[a.obj]} by {'+'.join(rn[i] for i in a.team)} {gn[a.src]}->{gn[a.dst]}"
        if isinstance(a, Navigate):
            return f"π{a.src + 1} →{a.robot + 1} π{a.dst + 1}"
        if isinstance(a, Grasp):
            return f"{a.robot + 1} →g {a.obj + 1}"
        if isinstance(a, Release):
            return f"{a.robot + 1} →r {a.obj + 1}"
        team = ",".join(str(i + 1) for i in a.team)
        return f"π{a.src + 1} →T_{{{team}}},{a.obj + 1} π{a.dst + 1}"


@dataclass
class ExplicitTS:
    """Reachable part of TS as CSR arrays: successors of state ``u`` are
    ``targets[indptr[u]:indptr[u+1]]`` with costs ``costs[...]``; ``states[u]`` is the state tuple."""

    ts: TransitionSystem
    states: np.ndarray
    indptr: np.ndarray
    targets: np.ndarray
    costs: np.ndarray
    build_seconds: float
    _index: dict | None = field(default=None, repr=False, compare=False)

    @property
    def index(self) -> dict:
        """state tuple -> state number."""
        if self._index is None:
            self._index = {s: k for k, s in enumerate(map(tuple, self.states.tolist()))}
        return self._index

    @property
    def num_states(self) -> int:
        return len(self.states)

    @property
    def num_transitions(self) -> int:
        return len(self.targets)

    def state(self, u: int) -> State:
        return tuple(int(x) for x in self.states[u])

    def successors(self, u: int) -> np.ndarray:
        return self.targets[self.indptr[u] : self.indptr[u + 1]]

    def without(self, pairs) -> ExplicitTS:
        """This TS without the transitions between the state pairs ``pairs`` (both directions)."""
        drop = set()
        for a, b in pairs:
            u, v = self.index.get(tuple(a)), self.index.get(tuple(b))
            if u is not None and v is not None:
                drop.update([(u, v), (v, u)])
        if not drop:
            return self
        src = np.repeat(np.arange(self.num_states), np.diff(self.indptr))
        keep = np.array([(int(u), int(v)) not in drop for u, v in zip(src, self.targets)], dtype=bool)
        indptr = np.concatenate([[0], np.cumsum(np.bincount(src[keep], minlength=self.num_states))])
        return ExplicitTS(self.ts, self.states, indptr.astype(self.indptr.dtype), self.targets[keep],
                          self.costs[keep], self.build_seconds, self._index)

    def label_masks(self) -> np.ndarray:
        """L(s) bitmask for every state (Python ints may exceed 64 bits: object array)."""
        return np.array([self.ts.label_mask(self.state(u)) for u in range(self.num_states)], dtype=object)

    def to_networkx(self):
        """A networkx DiGraph with ``state``, ``label`` node attributes and ``cost``, ``actions`` edges."""
        import networkx as nx

        g = nx.DiGraph()
        for u in range(self.num_states):
            s = self.state(u)
            g.add_node(u, state=s, label=sorted(self.ts.label(s)))
        for u in range(self.num_states):
            s = self.state(u)
            for e in range(self.indptr[u], self.indptr[u + 1]):
                v = int(self.targets[e])
                g.add_edge(u, v, cost=float(self.costs[e]), actions=self.ts.actions(s, self.state(v)))
        return g

    def summary(self) -> dict:
        return {
            "scenario": self.ts.scenario.name,
            "states": self.num_states,
            "transitions": self.num_transitions,
            "build_seconds": round(self.build_seconds, 4),
        }

