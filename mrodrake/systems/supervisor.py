"""Mission supervisor (paper Section III-A, sequential execution) and the monitored NBA run.

The :class:`Supervisor` is a Drake LeafSystem whose abstract state is the plan position (step, pending
primitives, phase of the current primitive), the mode of every entity (parked, moving, docked, coupled), the
live :class:`~mrodrake.control.adaptive.NavigationTask` objects, the monitored NBA run and the event log.  A
periodic unrestricted update reads the routed states of all robots and objects and

* checks completion of the current primitive (entity ball inside the target region, near its goal, speed
  below the rest threshold; docking point within tolerance), then starts the next one: goal points from P_s
  given the ACTUAL positions of the entities already in the target region, free space, map and φ;
* drives the controllers' abstract ``task`` inputs, the plants' ``sync`` inputs (:class:`SyncCommand`: a
  state reset with a version counter, a parking brake and, for coupled plants, the grasp offsets) and the
  PortSwitch selectors (own plant or coupled plant);
* monitors the executed trace: whenever the set of true propositions changes, the subset run of the NBA
  reads the label being left (:func:`advance_run`); at each planned state the run must contain the plan's
  NBA state, and the executed discrete state must equal the planned one;
* ends the simulation with ``ReachedTermination`` after the last step, or on a failure (recorded).

Sequencing (one entity moves at a time, the others are parked obstacles): a TS step's releases come first
(disengage, back off), then grasps (docking), then the region-changing actions in an order chosen by
:func:`choose_order` so that the monitored run stays alive and reaches the plan's NBA state.

Local motions (our addition, :mod:`mrodrake.control.local`): docking at a grasp point, backing off after a
release, and the last part of every navigation / transport once the entity's ball is inside its target region
(``SETTLE_DEPTH``) follow straight legs inside the region with the same adaptive law on the identity map.

Parking brake (our addition): an entity that is not moving has zero dynamics; on arrival (speed below
``rest_speed``) its velocity is reset to zero.  The paper's friction term sin(·) can be negative, so an
uncontrolled entity at small speed would otherwise drift.  Positions are continuous across every switch;
velocities jump by at most ``rest_speed`` at a parking.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np
import shapely
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import EventStatus, InputPortIndex, LeafSystem

from mrodrake.control.adaptive import AdaptiveGains
from mrodrake.control.freespace import DEFAULT_MARGIN, Disk, entity_free_space, goal_point
from mrodrake.control.local import PATH_CLEARANCE, disk_obstacles, local_path, local_task
from mrodrake.errors import UserError
from mrodrake.geometry import grasp_layout, polygon, workspace_free_space
from mrodrake.packing import place
from mrodrake.systems.controllers import TaskCommand
from mrodrake.ts import Grasp, Navigate, Release, Transport

#: Speed (m/s) under which an arrived entity counts as at rest (then parked).
REST_SPEED = 0.05
#: Distance (m) to the docking point at which a docking navigation is complete.
DOCK_TOL = 0.03
#: Distance (m) to the goal at which a navigation / transport / back-off is complete.
GOAL_TOL = 0.25
#: Distance (m) to an intermediate waypoint of a local motion at which its next leg starts.
LEG_TOL = 0.25 * PATH_CLEARANCE
#: Width (m) of the approach ring around a region (at most; less where walls, obstacles or other regions are
#: closer than this plus DEFAULT_MARGIN): entering it, a navigation / transport switches to the local law.
APPROACH = 10.0
#: Depth (m) of the entity's ball inside the approach disk of its target region at which a navigation / transport switches to the
#: local law for the rest of the way to its goal (a tenth of it when the entity crawls below REST_SPEED).
SETTLE_DEPTH = 0.05


# ------------------------------------------------------------------------------------------ commands
@dataclass(frozen=True)
class SyncCommand:
    """Command from the supervisor to one plant: when ``version`` changes the plant copies [x, v] into its
    state (per-step update); ``frozen`` (read directly) parks it (zero dynamics); ``offsets`` are the grasp
    offsets x_i − x^o of a coupled plant's members."""

    version: int = 0
    x: tuple = (0.0, 0.0)
    v: tuple = (0.0, 0.0)
    frozen: bool = True
    offsets: tuple = ()

    def __deepcopy__(self, memo):
        return self


# ------------------------------------------------------------------------------------------ labels, run
def entity_regions(centers: np.ndarray, radii: np.ndarray, positions: np.ndarray, region_radii: np.ndarray,
                   tol: float = 1e-9) -> np.ndarray:
    """Region index of every entity whose ball B̄(x_e, r_e) lies in a region (−1: in none)."""
    d = np.hypot(positions[:, None, 0] - centers[None, :, 0], positions[:, None, 1] - centers[None, :, 1])
    inside = d + radii[:, None] <= region_radii[None, :] + tol
    return np.where(inside.any(axis=1), inside.argmax(axis=1), -1)


def label_of(regions: Sequence[int], K: int) -> int:
    """TS label mask of a configuration: bit e·K + k for entity e in region k (none if k = −1)."""
    m = 0
    for e, k in enumerate(regions):
        if k >= 0:
            m |= 1 << (e * K + int(k))
    return m


def advance_run(nba, run: frozenset, letter: int) -> frozenset:
    """Subset run of the NBA reading one letter (the label of the configuration being left)."""
    out = set()
    for q in run:
        out.update(nba.successors(q, letter))
    return frozenset(out)


def mover_entities(ts, a) -> tuple[list[int], int, int]:
    """(entities, src, dst) of a region-changing action (entity e: robots 0..N−1, objects N..N+M−1)."""
    if isinstance(a, Navigate):
        return [a.robot], a.src, a.dst
    return [ts.N + a.obj] + list(a.team), a.src, a.dst


def order_letters(ts, regions: Sequence[int], movers: Sequence) -> list[int]:
    """The labels the configuration passes through when ``movers`` run one after the other: each mover's
    entities leave their region (a configuration where they are in none), then enter the target."""
    cur = list(regions)
    out = []
    for a in movers:
        ents, src, dst = mover_entities(ts, a)
        for e in ents:
            cur[e] = -1
        out.append(label_of(cur, ts.K))
        for e in ents:
            cur[e] = dst
        out.append(label_of(cur, ts.K))
    return out


def run_through(nba, run: frozenset, label: int, letters: Sequence[int]) -> frozenset:
    """The run after a planned step whose configuration labels are ``letters`` (starting from ``label``):
    each change reads the label left; a step without change reads its source label once."""
    changed = False
    for new in letters:
        if new != label:
            run = advance_run(nba, run, label)
            label, changed = new, True
            if not run:
                return run
    if not changed:
        run = advance_run(nba, run, label)
    return run


def choose_order(ts, nba, run: frozenset, regions: Sequence[int], movers: Sequence, expected_q: int,
                 max_permutations: int = 40320):
    """Order of the region-changing actions of one TS step (Sec. "soundness beyond the paper"): the first
    permutation, starting from the plan's order, whose sequential label trace keeps the monitored subset run
    alive and ends with the plan's NBA state ``expected_q`` in it.  Returns (order, run after) or (None, ∅).
    Beyond ``max_permutations`` candidates a greedy order is tried (each next mover keeps the run alive)."""
    movers = list(movers)
    label = label_of(regions, ts.K)
    n_perm = math.factorial(len(movers))
    if n_perm <= max_permutations:
        for perm in itertools.permutations(movers):
            after = run_through(nba, run, label, order_letters(ts, regions, perm))
            if expected_q in after:
                return list(perm), after
        return None, frozenset()
    chosen, rest, cur_run, cur_regions = [], list(movers), run, list(regions)
    while rest:
        for a in rest:
            trial = run_through(nba, cur_run, label_of(cur_regions, ts.K), order_letters(ts, cur_regions, [a]))
            if trial:
                break
        else:
            return None, frozenset()
        chosen.append(a)
        rest.remove(a)
        ents, _, dst = mover_entities(ts, a)
        for e in ents:
            cur_regions[e] = dst
        cur_run = trial
    after = run_through(nba, run, label, order_letters(ts, regions, chosen))
    return (chosen, after) if expected_q in after else (None, frozenset())


# ------------------------------------------------------------------------------------------ plan steps
@dataclass(frozen=True)
class StepSpec:
    """One executed TS step: plan step number, cycle (0 = prefix), source/target state and NBA states."""

    index: int
    plan_step: int
    cycle: int
    src: tuple
    src_q: int
    dst: tuple
    dst_q: int
    actions: tuple


def expand_steps(plan, suffix_cycles: int) -> list[StepSpec]:
    """The plan's prefix steps followed by ``suffix_cycles`` copies of its suffix steps."""
    steps = list(plan.steps())
    P = len(plan.prefix)
    out = []
    for step, part, i, j, a, b, acts, cost in steps[:P]:
        out.append(StepSpec(len(out) + 1, step, 0, a[0], a[1], b[0], b[1], tuple(acts)))
    for c in range(suffix_cycles):
        for step, part, i, j, a, b, acts, cost in steps[P:]:
            out.append(StepSpec(len(out) + 1, step, c + 1, a[0], a[1], b[0], b[1], tuple(acts)))
    return out


# ------------------------------------------------------------------------------------------ supervisor state
@dataclass(frozen=True)
class Op:
    """One primitive in execution: ``kind`` in navigate/grasp/release/transport, the TS action, its step."""

    kind: str
    action: object
    step: StepSpec


@dataclass
class SupState:
    """The supervisor's abstract state (replaced, never mutated once stored: copies share immutables)."""

    step_idx: int = -1
    ops: tuple = ()
    op: Op | None = None
    phase: str = ""
    op_t0: float = 0.0
    op_info: dict = field(default_factory=dict)
    sync: dict = field(default_factory=dict)
    tasks: dict = field(default_factory=dict)
    route: dict = field(default_factory=dict)
    engaged: dict = field(default_factory=dict)
    docked: dict = field(default_factory=dict)
    grasp_open: dict = field(default_factory=dict)
    run: frozenset = frozenset()
    label: int = 0
    changed: bool = False
    events: tuple = ()
    grasps: tuple = ()
    primitives: tuple = ()
    status: str = "running"
    message: str = ""
    version: int = 0
    episode: int = 0

    def copy(self) -> "SupState":
        return replace(self, op_info=dict(self.op_info), sync=dict(self.sync), tasks=dict(self.tasks),
                       route=dict(self.route), engaged=dict(self.engaged), docked=dict(self.docked),
                       grasp_open=dict(self.grasp_open))

    def __deepcopy__(self, memo):
        return self


@dataclass(frozen=True)
class PrimitiveRecord:
    """What the figures need of one executed motion: entity, team, kind, regions, times, F and the task."""

    kind: str
    entity: str
    team: tuple
    src: int
    dst: int
    radius: float
    start: np.ndarray
    goal: np.ndarray
    others: tuple
    free: object
    task: object
    controller: str
    offsets: np.ndarray
    t_start: float
    t_end: float


class _Failure(Exception):
    """A primitive could not be started or finished (recorded, ends the mission with ok=False)."""


class _Defer(Exception):
    """A grasp waits until the transports of its step have left its region (see ``Supervisor._dock_point``)."""


# ------------------------------------------------------------------------------------------ supervisor system
class Supervisor(LeafSystem):
    """Plan executor (module docstring).  Inputs ``state_<entity>`` ([x, ẋ] routed, robots then objects);
    abstract outputs ``task_<controller>``, ``sync_<plant>`` and ``select_<entity>``."""

    def __init__(self, scenario, ts, nba, plan, *, suffix_cycles: int = 1, seed: int = 0, couplings=(),
                 route_ports: dict | None = None, initial_positions: dict | None = None, period: float = 0.5,
                 rest_speed: float = REST_SPEED, dock_tol: float = DOCK_TOL, goal_tol: float = GOAL_TOL,
                 time_limit: tuple[float, float] = (1500.0, 10.0), build_task=None):
        super().__init__()
        self.set_name("supervisor")
        self.scenario, self.ts, self.nba, self.plan = scenario, ts, nba, plan
        self.seed = int(seed)
        self.steps = expand_steps(plan, suffix_cycles)
        self.robots = list(scenario.robot_names)
        self.objects = list(scenario.object_names)
        self.entities = self.robots + self.objects
        self.N, self.M, self.K = len(self.robots), len(self.objects), len(scenario.regions)
        self.radii = np.array([r.radius for r in scenario.robots] + [o.radius for o in scenario.objects])
        self.centers = np.array([g.center for g in scenario.regions], dtype=float)
        self.region_radii = np.array([g.radius for g in scenario.regions], dtype=float)
        self.couplings = [(int(j), tuple(int(i) for i in team)) for j, team in couplings]
        self.route_ports = dict(route_ports or {})
        self.period = float(period)
        self.rest_speed, self.dock_tol, self.goal_tol = float(rest_speed), float(dock_tol), float(goal_tol)
        self.time_limit = time_limit
        self._build_task = build_task
        self.approach = self._approach_widths()
        self.controllers = [f"nav_{r}" for r in self.robots] + [self.coupling_name(j, t) + "_ctrl"
                                                                  for j, t in self.couplings]
        self.plants = self.entities + [self.coupling_name(j, t) for j, t in self.couplings]
        init_pos = initial_positions or {}
        st = SupState()
        for p in self.plants:
            x = init_pos.get(p, (0.0, 0.0))
            st.sync[p] = SyncCommand(0, tuple(map(float, x)), (0.0, 0.0), True,
                                     tuple() if p in self.entities else tuple((0.0, 0.0) for _ in range(
                                         len(self.couplings[self.plants.index(p) - len(self.entities)][1]))))
        for c in self.controllers:
            st.tasks[c] = None
        for e in self.entities:
            st.route[e] = 1
        for j in range(self.M):
            st.engaged[j] = None
        pos0 = np.array([init_pos.get(e, (0.0, 0.0)) for e in self.entities], dtype=float).reshape(-1, 2)
        st.label = label_of(entity_regions(self.centers, self.radii, pos0, self.region_radii), self.K)
        st.run = frozenset([nba.initial])
        self._initial = st
        self._state_index = self.DeclareAbstractState(AbstractValue.Make(st))
        self.state_ports = [self.DeclareVectorInputPort(f"state_{e}", 4) for e in self.entities]
        tick = {self.abstract_state_ticket(self._state_index)}
        self.task_ports = {c: self.DeclareAbstractOutputPort(
            f"task_{c}", lambda: AbstractValue.Make(None), self._task_calc(c), prerequisites_of_calc=tick)
            for c in self.controllers}
        self.sync_ports = {p: self.DeclareAbstractOutputPort(
            f"sync_{p}", lambda: AbstractValue.Make(SyncCommand()), self._sync_calc(p), prerequisites_of_calc=tick)
            for p in self.plants}
        self.select_ports = {e: self.DeclareAbstractOutputPort(
            f"select_{e}", lambda: AbstractValue.Make(InputPortIndex(1)), self._select_calc(e),
            prerequisites_of_calc=tick) for e in self.entities}
        self.DeclarePeriodicUnrestrictedUpdateEvent(self.period, 0.0, self._Tick)

    # ------------------------------------------------------------------ naming, outputs
    def coupling_name(self, j: int, team: Sequence[int]) -> str:
        return f"{self.objects[j]}_{'+'.join(self.robots[i] for i in team)}"

    def _task_calc(self, c):
        def calc(context, value):
            value.set_value(self.sup_state(context).tasks[c])
        return calc

    def _sync_calc(self, p):
        def calc(context, value):
            value.set_value(self.sup_state(context).sync[p])
        return calc

    def _select_calc(self, e):
        def calc(context, value):
            value.set_value(InputPortIndex(int(self.sup_state(context).route[e])))
        return calc

    def sup_state(self, context) -> SupState:
        """The supervisor's state in its (sub)context."""
        return context.get_abstract_state(int(self._state_index)).get_value()

    # ------------------------------------------------------------------ geometry helpers
    def _positions(self, context) -> np.ndarray:
        return np.array([p.Eval(context) for p in self.state_ports], dtype=float)

    def _disks(self, X: np.ndarray, exclude: set[int], radius_override: dict | None = None) -> list[Disk]:
        ro = radius_override or {}
        return [Disk(self.entities[e], (float(X[e, 0]), float(X[e, 1])), float(ro.get(e, self.radii[e])))
                for e in range(len(self.entities)) if e not in exclude]

    def _in_region(self, X: np.ndarray, k: int, exclude: set[int]) -> list[int]:
        reg = entity_regions(self.centers, self.radii, X[:, :2], self.region_radii, tol=1e-6)
        d = np.hypot(X[:, 0] - self.centers[k, 0], X[:, 1] - self.centers[k, 1])
        return [e for e in range(len(self.entities)) if e not in exclude and (reg[e] == k or d[e] < self.region_radii[k])]

    def _next_team(self, st: SupState, j: int, robot: int) -> tuple[int, ...]:
        """Team of the next Transport of object j from the current step on (default: the robot alone)."""
        for spec in self.steps[max(st.step_idx, 0):]:
            for a in spec.actions:
                if isinstance(a, Transport) and a.obj == j and robot in a.team:
                    return tuple(a.team)
        return (robot,)

    def _team_cover(self, j: int, team: Sequence[int]) -> float:
        return grasp_layout(self.radii[self.N + j], [self.radii[i] for i in team],
                            self.scenario.layout.grasp_gap).covering_radius

    def _reserve(self, st: SupState, X: np.ndarray, k: int) -> dict:
        """Reserved radii of the ungrasped objects in region k whose next transport needs a team layout."""
        out = {}
        for e in self._in_region(X, k, set()):
            if e >= self.N:
                j = e - self.N
                if st.engaged.get(j) is None:
                    team = None
                    for spec in self.steps[max(st.step_idx, 0):]:
                        hit = [a for a in spec.actions if isinstance(a, Transport) and a.obj == j]
                        if hit:
                            team = hit[0].team
                            break
                    if team:
                        out[e] = self._team_cover(j, team)
        return out

    def _future_units(self, st: SupState, X: np.ndarray, k: int, movers: set[int],
                      stay: set[int] | None = None) -> list[float]:
        """Radii of what the plan brings into region k later while ``stay`` (default: the movers; the object
        of a transport, whose position the goal fixes until it is moved again) stays there (single entities,
        or a robots-object team by its covering radius), for the planned state of that stay with the most
        such area; entities now in region k and the movers are not counted."""
        present = set(self._in_region(X, k, set()))
        nm = self.N + self.M
        best, best_area = [], 0.0
        for spec in self.steps[max(st.step_idx, 0):]:
            regions, grasps = spec.dst[:nm], spec.dst[nm:]
            if any(regions[e] != k for e in (movers if stay is None else stay)):
                break
            teams: dict[int, list[int]] = {}
            for i in range(self.N):
                if grasps[i] >= 0:
                    teams.setdefault(int(grasps[i]), []).append(i)
            units = []
            for e in range(nm):
                if regions[e] != k or e in movers or e in present or (e < self.N and grasps[e] >= 0):
                    continue
                j = e - self.N
                units.append(self._team_cover(j, teams[j]) if j in teams else float(self.radii[e]))
            area = sum(u * u for u in units)
            if area > best_area:
                best, best_area = units, area
        return best

    def _foresight(self, st: SupState, X: np.ndarray, k: int, movers: set[int], stay: set[int] | None = None):
        """(reserved radii, future radii) for a goal in region k, from the most foresight to none: the
        reserved team disks (:meth:`_reserve`) with the future units (:meth:`_future_units`), then with fewer
        of them (the smallest dropped first: the large ones are the hard ones to fit later), then nothing."""
        reserve = self._reserve(st, X, k)
        future = sorted(self._future_units(st, X, k, movers, stay), reverse=True)
        for n in range(len(future), -1, -1):
            yield reserve, future[:n]
        yield {}, []

    def _goal(self, st: SupState, X: np.ndarray, k: int, radius: float, movers: set[int],
              stay: set[int] | None = None) -> np.ndarray:
        """P_s goal in region k given the entities there (objects with their reserved team radius) and
        leaving room for what the plan brings there later, with as much foresight as fits (:meth:`_foresight`)."""
        occupants = [e for e in self._in_region(X, k, movers)]
        why = ""
        for override, later in self._foresight(st, X, k, movers, stay):
            disks = self._disks(X, set(range(len(self.entities))) - set(occupants), override)
            try:
                return goal_point(self.scenario, k, radius, disks, seed=self.seed, future=later)
            except UserError as exc:
                why = why or str(exc)
        raise _Failure(why)

    def _arrival_goal(self, st: SupState, t: float, X: np.ndarray, k: int, radius: float,
                      movers: set[int], stay: set[int] | None = None) -> np.ndarray | None:
        """Goal of an arrival in region k (:meth:`_goal`); if P_s finds none, make room (:meth:`_make_room`)
        and return None (the primitive resumes once the free robots have moved, with the joint placement's
        goal)."""
        goal = st.op_info.pop("room_goal", None)
        if goal is not None:
            return np.asarray(goal, dtype=float)
        try:
            return self._goal(st, X, k, radius, movers, stay)
        except _Failure:
            found = None if st.op_info.get("room_done_dst") else self._room_moves(st, X, k, movers, radius)
            if found is None:
                raise
            if not found[1]:  # the joint placement leaves every free robot where it is
                return found[0]
            self._make_room(st, t, X, k, found, "room_done_dst")
            return None

    def _free_robots(self, st: SupState, X: np.ndarray, k: int, movers: set[int]) -> list[int]:
        """Parked robots in region k that may be moved inside it to make room: not docked, not moving, their
        ball inside the region."""
        reg = entity_regions(self.centers, self.radii, X[:, :2], self.region_radii, tol=1e-6)
        return [i for i in range(self.N) if i not in movers and i not in st.docked and reg[i] == k]

    def _room_moves(self, st: SupState, X: np.ndarray, k: int, movers: set[int], radius: float | None = None,
                    keep_out: tuple | None = None):
        """Make room in region k by moving its free robots (:meth:`_free_robots`) inside it: a joint P_s
        placement of a new entity of ``radius`` (an arrival; then the goal is returned too) and the free
        robots, or of the free robots that intrude into the disk ``keep_out`` = (centre, radius) (a departing
        team's start).  The other occupants are fixed, with their reserved team disks when possible.  Returns
        (goal or None, [(robot, spot, legs)]) with collision-free local paths taken one robot after the
        other (no moves only with a goal), or None."""
        free = self._free_robots(st, X, k, movers)
        if keep_out is not None:
            kc, kr = np.asarray(keep_out[0], dtype=float), float(keep_out[1])
            reach = kr + 0.5 * self.scenario.layout.spacing
            free = [i for i in free if math.hypot(*(X[i, :2] - kc)) < reach + self.radii[i]]
        if not free:
            return None
        c = self.centers[k]
        fixed = [e for e in self._in_region(X, k, set()) if e not in free]  # movers inside stay put meanwhile
        new = ([float(radius)] if radius is not None else []) + [float(self.radii[i]) for i in free]
        for override in (self._reserve(st, X, k), {}):
            fc = [X[e, :2] - c for e in fixed]
            fr = [float(override.get(e, self.radii[e])) for e in fixed]
            if keep_out is not None:
                fc.append(kc - c)
                fr.append(kr)
            sol = place(self.region_radii[k], np.array(fc).reshape(-1, 2), fr, new, seed=self.seed,
                        margin=self.scenario.layout.spacing)
            if sol is None:
                continue
            spots = c + sol[len(new) - len(free):]
            goal = c + sol[0] if radius is not None else None
            for order in itertools.islice(itertools.permutations(range(len(free))), 24):
                Xs, moves = X.copy(), []
                try:
                    for m in order:
                        i = free[m]
                        if math.hypot(*(spots[m] - X[i, :2])) > self.dock_tol:
                            moves.append((i, spots[m], self._local_path(Xs, i, k, spots[m])))
                        Xs[i, :2] = spots[m]
                except ValueError:
                    continue
                return (goal, moves) if moves or goal is not None else None
        return None

    def _make_room(self, st: SupState, t: float, X: np.ndarray, k: int, found, flag: str) -> None:
        """Start the moves ``found`` by :meth:`_room_moves` (phase ``room``); the current primitive then resumes
        from the phase it was in, with the joint placement's goal for an arrival and ``flag`` set in its
        op_info (each of departure / arrival makes room at most once)."""
        goal, moves = found
        keep = {key: v for key, v in st.op_info.items() if key.startswith("room_done")}
        st.op_info = keep | {"room": list(moves), "room_goal": goal, "resume": st.phase, "room_k": k, flag: True}
        st.phase = "room"
        self._next_room_move(st, t, X)

    def _next_room_move(self, st: SupState, t: float, X: np.ndarray) -> None:
        info = st.op_info
        robot, spot, legs = info["room"].pop(0)
        k = info["room_k"]
        self._event(st, kind="room", t_start=t, t_end=t, step=st.op.step.index, plan_step=st.op.step.plan_step,
                    action=self.ts.format_action(st.op.action, "names"), entities=self.robots[robot],
                    from_region=self.scenario.region_names[k], to_region=self.scenario.region_names[k], ok=True,
                    propositions="", nba_states="", detail=f"{self.robots[robot]} moves inside "
                    f"{self.scenario.region_names[k]} to ({spot[0]:.2f}, {spot[1]:.2f}) to make room")
        self._start_local_motion(st, t, X, kind="room", robot=robot, k=k, goal=spot, legs=legs)
        st.phase = "room"

    def _room_phase(self, st: SupState, t: float, X: np.ndarray) -> bool:
        """Progress the make-room moves; True once they are done (the primitive then resumes)."""
        if not self._wait_motion(st, t, X):
            return False
        if st.op_info["room"]:
            self._next_room_move(st, t, X)
            return False
        st.phase = st.op_info["resume"]
        st.op_info = {key: v for key, v in st.op_info.items() if key == "room_goal" or key.startswith("room_done")}
        return True

    def _dock_point(self, st: SupState, X: np.ndarray, robot: int, j: int,
                    defer: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
        """Grasp point of ``robot`` next to object j, the local path to it and the growth of the region the
        path may use: the team layout (grasp_layout of the next transport's team) rotated so that the point
        is free, inside the region and reachable inside it (else through the approach ring, if
        :meth:`_excursion_ok`); robots already docked at j fix the rotation when possible.

        Points are taken in tiers: the rotations that leave the slots of the teammates still to dock free
        and are clear of the reserved team disks of the other objects in the region (:meth:`_reserve`), then
        those clear of the covering disks of the teams that still leave the region in this step
        (:meth:`_departing`) with the teammates' slots free, then without them, then any.  With ``defer`` and a later transport of this step departing
        from the region, a point of the last tier raises :class:`_Defer` instead (the grasp waits until
        the team has left: a docked robot inside its covering disk would block its start)."""
        team = self._next_team(st, j, robot)
        lay = grasp_layout(self.radii[self.N + j], [self.radii[i] for i in team], self.scenario.layout.grasp_gap)
        slot = team.index(robot)
        xo = X[self.N + j, :2]
        k = int(self._region_of(X, self.N + j))
        base = math.atan2(lay.offsets[slot, 1], lay.offsets[slot, 0])
        r = self.radii[robot]
        spacing = self.scenario.layout.spacing
        others = [e for e in range(len(self.entities)) if e not in (robot, self.N + j)]
        docked = [i for i, o in st.docked.items() if o == j and i in team and i != robot]
        angles = []
        if docked:
            i0 = docked[0]
            a0 = math.atan2(*(X[i0, 1::-1] - xo[::-1]))
            rot = a0 - math.atan2(lay.offsets[team.index(i0), 1], lay.offsets[team.index(i0), 0])
            angles.append(rot)
        angles += list(np.linspace(0.0, 2.0 * math.pi, 72, endpoint=False))
        why = "no free grasp point inside the region"
        reserved = [(X[e, :2], rad) for e, rad in self._reserve(st, X, k).items() if e != self.N + j]
        departing = [(X[self.N + jj, :2], rad) for jj, rad in self._departing(st, k) if jj != j]
        waiting = [m for m, i in enumerate(team) if i != robot and i not in docked]  # slots still to be taken
        fixed = [e for e in others if e not in team]

        def free_at(p, rad, entities) -> bool:
            return (math.hypot(*(p - self.centers[k])) + rad + 0.5 * spacing <= self.region_radii[k]
                    and all(math.hypot(*(p - X[e, :2])) >= rad + self.radii[e] + spacing for e in entities))

        tiers: list[list[np.ndarray]] = [[], [], [], []]
        for rot in angles:
            q = xo + lay.distance * np.array([math.cos(base + rot), math.sin(base + rot)])
            if not free_at(q, r, others):
                continue
            cr, sr = math.cos(rot), math.sin(rot)
            team_ok = all(free_at(xo + np.array([cr * lay.offsets[m, 0] - sr * lay.offsets[m, 1],
                                                 sr * lay.offsets[m, 0] + cr * lay.offsets[m, 1]]),
                                  self.radii[team[m]], fixed) for m in waiting)
            clear_dep = all(math.hypot(*(q - c)) >= rad + r + spacing for c, rad in departing)
            clear_res = clear_dep and all(math.hypot(*(q - c)) >= rad + r + spacing for c, rad in reserved)
            tiers[(0 if clear_res else 1) if team_ok and clear_dep else (2 if clear_dep else 3)].append(q)
        extras = [0.0] + ([float(self.approach[k])] if self.approach[k] > 0 and self._excursion_ok(st, X, robot)
                          else [])
        for tier, candidates in enumerate(tiers):
            if tier == 3 and defer and departing:
                raise _Defer()
            for extra in extras:
                for q in candidates:
                    try:
                        return q, self._local_path(X, robot, k, q, extra), extra
                    except ValueError as exc:
                        why = str(exc)
        raise _Failure(f"no reachable grasp point for {self.robots[robot]} at {self.objects[j]} ({why})")

    def _departing(self, st: SupState, k: int) -> list[tuple[int, float]]:
        """(object, team covering radius) of the transports still to run in this step that leave region k."""
        return [(op.action.obj, self._team_cover(op.action.obj, op.action.team)) for op in st.ops
                if op.kind == "transport" and op.action.src == k]

    def _excursion_ok(self, st: SupState, X: np.ndarray, robot: int) -> bool:
        """Whether ``robot`` may leave its region for a moment while docking (through the approach ring,
        when the region is too crowded for a path inside it): the monitored NBA run, reading the current
        label and then the label with the robot in no region, must still contain the plan's NBA state of
        the current step."""
        regions = list(entity_regions(self.centers, self.radii, X[:, :2], self.region_radii, tol=1e-6))
        regions[robot] = -1
        run = advance_run(self.nba, advance_run(self.nba, st.run, st.label), label_of(regions, self.K))
        return bool(run) and self.steps[st.step_idx].dst_q in run

    def _approach_widths(self) -> np.ndarray:
        """Width of the approach ring of every region: APPROACH, or the clearance of the region's disk to
        walls, obstacles and other regions minus DEFAULT_MARGIN if smaller (never negative)."""
        ws = self.scenario.workspace
        free = workspace_free_space(polygon(ws.boundary), [polygon(o.polygon) for o in ws.obstacles])
        out = []
        for k, (c, R) in enumerate(zip(self.centers, self.region_radii)):
            clear = free.boundary.distance(shapely.Point(*c)) - R
            for m, (cm, Rm) in enumerate(zip(self.centers, self.region_radii)):
                if m != k:
                    clear = min(clear, math.hypot(*(c - cm)) - R - Rm)
            out.append(max(0.0, min(APPROACH, clear - DEFAULT_MARGIN)))
        return np.array(out)

    def _local_world(self, X: np.ndarray, entity: int, radius: float, k: int, exclude=(), extra: float = 0.0):
        """(rim centre, rim radius, disk centres, grown radii) of local motions of ``entity`` (covering
        ``radius``) in region k, its rim enlarged by ``extra``; ``exclude``: its team, which moves with it."""
        c, R = self.centers[k], float(self.region_radii[k] + extra - radius)
        centers, radii = disk_obstacles(X, self.radii, radius, [entity, *exclude], c, R)
        return c, R, centers, radii

    def _local_path(self, X: np.ndarray, robot: int, k: int, goal: np.ndarray, extra: float = 0.0) -> np.ndarray:
        c, R, centers, radii = self._local_world(X, robot, self.radii[robot], k, (), extra)
        return local_path(X[robot, :2], goal, centers, radii, c, R)

    def _region_of(self, X: np.ndarray, e: int) -> int:
        d = np.hypot(X[e, 0] - self.centers[:, 0], X[e, 1] - self.centers[:, 1])
        return int(np.argmin(d - self.region_radii))

    def _task(self, free, n_members: int, label: str):
        return self._build_task(self.scenario, free, n_members, label=label)

    # ------------------------------------------------------------------ the periodic update
    def _Tick(self, context, state):
        st = self.sup_state(context)
        if st.status != "running":
            return EventStatus.ReachedTermination(self, st.message or st.status)
        t = float(context.get_time())
        X = self._positions(context)
        new = st.copy()
        try:
            if not np.all(np.isfinite(X)):
                raise _Failure(f"non-finite entity state at t={t:.2f}")
            self._monitor(new, t, X)
            self._advance(new, t, X)
        except _Failure as exc:
            self._fail(new, t, str(exc))
        state.get_mutable_abstract_state(int(self._state_index)).set_value(new)
        if new.status == "done":
            return EventStatus.ReachedTermination(self, "mission complete")
        if new.status == "failed":
            return EventStatus.ReachedTermination(self, f"mission failed: {new.message}")
        return EventStatus.Succeeded()

    def _event(self, st: SupState, **row) -> None:
        st.events = st.events + (row,)

    def abort(self, context, reason: str) -> str:
        """End the mission in ``context`` (this system's own context, mutable) as a failure of the primitive in
        execution, from outside the periodic update (a controller fault, an integrator failure, any exception
        inside the simulation); returns the one-line message, which names the primitive, its step and the
        simulated time."""
        st = self.sup_state(context).copy()
        if st.status != "running":
            return st.message
        t = float(context.get_time())
        if st.op is not None:
            where = (f"{self.ts.format_action(st.op.action, 'names')} (step {st.op.step.index}, plan step "
                     f"{st.op.step.plan_step})")
        elif 0 <= st.step_idx < len(self.steps):
            where = f"step {self.steps[st.step_idx].index}"
        else:
            where = "the mission"
        msg = f"{where} failed at t = {t:.2f} s: {reason}"
        self._fail(st, t, msg)
        context.get_mutable_abstract_state(int(self._state_index)).set_value(st)
        return msg

    def _fail(self, st: SupState, t: float, msg: str) -> None:
        if st.op is not None:
            self._primitive_event(st, t, ok=False, detail=msg)
            st.op = None
        st.status, st.message = "failed", msg
        for c in st.tasks:
            st.tasks[c] = None

    def _monitor(self, st: SupState, t: float, X: np.ndarray) -> None:
        """Advance the monitored NBA run when the set of true propositions changes."""
        regions = entity_regions(self.centers, self.radii, X[:, :2], self.region_radii, tol=1e-6)
        lab = label_of(regions, self.K)
        if lab == st.label:
            return
        st.run = advance_run(self.nba, st.run, st.label)
        st.label, st.changed = lab, True
        props = [p for b, p in enumerate(self.ts.propositions) if lab >> b & 1]
        spec = self.steps[st.step_idx] if 0 <= st.step_idx < len(self.steps) else None
        self._event(st, kind="label", t_start=t, t_end=t, step=spec.index if spec else 0,
                    plan_step=spec.plan_step if spec else 0, action="", entities="", from_region="",
                    to_region="", ok=bool(st.run), propositions=" ".join(props),
                    nba_states=" ".join(str(q) for q in sorted(st.run)), detail="")
        if not st.run:
            raise _Failure(f"the monitored NBA run died at t={t:.2f} (propositions: {' '.join(props) or 'none'})")

    def _advance(self, st: SupState, t: float, X: np.ndarray) -> None:
        while st.status == "running":
            if st.op is None:
                if st.ops:
                    st.op, st.ops, st.phase, st.op_t0, st.op_info = st.ops[0], st.ops[1:], "start", t, {}
                else:
                    if st.step_idx >= 0:
                        self._end_step(st, t, X)
                    st.step_idx += 1
                    if st.step_idx >= len(self.steps):
                        st.status, st.message = "done", "mission complete"
                        return
                    self._begin_step(st, t, X)
                    continue
            if not self._run_op(st, t, X):
                return
            st.op = None

    # ------------------------------------------------------------------ steps
    def discrete_state(self, st: SupState, X: np.ndarray) -> tuple:
        """The executed TS state: region of every entity (−1: none) and grasps from the docking record."""
        reg = entity_regions(self.centers, self.radii, X[:, :2], self.region_radii, tol=1e-6)
        grasps = [st.docked.get(i, -1) for i in range(self.N)]
        return tuple(int(k) for k in reg) + tuple(grasps)

    def _begin_step(self, st: SupState, t: float, X: np.ndarray) -> None:
        spec = self.steps[st.step_idx]
        st.changed = False
        releases = [a for a in spec.actions if isinstance(a, Release)]
        grasps = [a for a in spec.actions if isinstance(a, Grasp)]
        movers = [a for a in spec.actions if isinstance(a, (Navigate, Transport))]
        regions = list(spec.src[: self.N + self.M])
        order, _ = choose_order(self.ts, self.nba, st.run, regions, movers, spec.dst_q)
        if order is None:
            raise _Failure(f"step {spec.index} (plan step {spec.plan_step}): no order of the concurrent actions "
                           "keeps the monitored NBA run consistent with the plan")
        ops = [Op("release", a, spec) for a in releases] + [Op("grasp", a, spec) for a in grasps]
        ops += [Op("navigate" if isinstance(a, Navigate) else "transport", a, spec) for a in order]
        st.ops = tuple(ops)
        if movers and order != movers:
            self._event(st, kind="order", t_start=t, t_end=t, step=spec.index, plan_step=spec.plan_step,
                        action="; ".join(self.ts.format_action(a, "names") for a in order), entities="",
                        from_region="", to_region="", ok=True, propositions="", nba_states="",
                        detail="concurrent actions reordered for the monitored NBA run")

    def _end_step(self, st: SupState, t: float, X: np.ndarray) -> None:
        spec = self.steps[st.step_idx]
        if not st.changed:
            st.run = advance_run(self.nba, st.run, st.label)
        if spec.dst_q not in st.run:
            raise _Failure(f"step {spec.index}: the monitored NBA run {sorted(st.run)} does not contain the "
                           f"plan's NBA state {spec.dst_q}")
        got = self.discrete_state(st, X)
        if got != tuple(spec.dst):
            raise _Failure(f"step {spec.index}: executed state {self.ts.state_dict(got) if min(got[:self.N + self.M]) >= 0 else got} "
                           f"differs from the plan's {self.ts.state_dict(spec.dst)}")

    # ------------------------------------------------------------------ primitives
    def _sync(self, st: SupState, plant: str, x, v=(0.0, 0.0), frozen=True, offsets=None, reset=True) -> None:
        old = st.sync[plant]
        if reset:
            st.version += 1
        st.sync[plant] = SyncCommand(st.version if reset else old.version, tuple(map(float, x)),
                                     tuple(map(float, v)), bool(frozen),
                                     old.offsets if offsets is None else tuple(map(tuple, np.asarray(offsets, float))))

    def _unfreeze(self, st: SupState, plant: str) -> None:
        st.sync[plant] = replace(st.sync[plant], frozen=False)

    def _limit(self, dist: float) -> float:
        return self.time_limit[0] + self.time_limit[1] * dist

    def _start_motion(self, st: SupState, t: float, X: np.ndarray, *, kind: str, entity: int, team: tuple,
                      radius: float, src: int, dst: int, goal: np.ndarray, plant: str, controller: str,
                      offsets=np.zeros((0, 2))) -> None:
        movers = {entity} | set(team)
        others = self._disks(X, movers)
        start = X[entity, :2].copy()
        try:
            free = entity_free_space(self.scenario, radius, start, goal, src, dst, others)
            task = self._task(free, max(1, len(team)), f"{self.entities[entity]} {kind}")
        except (UserError, ValueError) as exc:
            raise _Failure(f"{kind} of {self.entities[entity]}: {str(exc).splitlines()[0]}") from None
        st.episode += 1
        st.tasks[controller] = TaskCommand(task, st.episode)
        self._unfreeze(st, plant)
        st.op_info.update(goal=goal, radius=radius, dst=dst, plant=plant, controller=controller, start=start,
                          free=free, task=task, others=tuple(others), src=src, entity=entity, team=team,
                          kind=kind, offsets=np.asarray(offsets), t_motion=t,
                          limit=self._limit(float(np.hypot(*(goal - start)))))
        st.phase = "moving"

    def _local_leg_task(self, st: SupState, X: np.ndarray):
        info = st.op_info
        e, k, team = info["entity"], info["dst"], info["team"]
        extra = self.approach[k] if info["kind"] in ("navigate", "transport") else info.get("extra", 0.0)
        c, R, centers, radii = self._local_world(X, e, info["radius"], k, team, extra)
        ctrl = self.scenario.control
        try:
            # a team of n robots and its object has n + 1 bodies whose friction bounds add up (α_A = Σ α):
            # k_v_local per body keeps the velocity loop damped (tests/control/test_local.py)
            gains = replace(AdaptiveGains.from_scenario(ctrl), k_v=ctrl.k_v_local * (1 + len(team)))
            return local_task(info["legs"][info["leg"]], centers, radii, c, R, gains,
                              k1=ctrl.k1_local, k2=ctrl.k2, start=X[e, :2], cf=max(1, len(team)),
                              label=f"{self.entities[e]} {info['kind']} leg {info['leg'] + 1}/{len(info['legs'])}")
        except ValueError as exc:
            raise _Failure(f"{info['kind']} of {self.entities[e]}: {exc}") from None

    def _start_local_motion(self, st: SupState, t: float, X: np.ndarray, *, kind: str, robot: int, k: int,
                            goal: np.ndarray, legs: np.ndarray, extra: float = 0.0) -> None:
        """Dock / back off inside region k (grown by ``extra``) along ``legs`` with the local law
        (mrodrake.control.local)."""
        name = self.robots[robot]
        start = X[robot, :2].copy()
        st.op_info.update(goal=np.asarray(goal, dtype=float), radius=self.radii[robot], dst=k, src=k, plant=name,
                          controller=f"nav_{name}", start=start, free=None, others=tuple(self._disks(X, {robot})),
                          entity=robot, team=(), kind=kind, offsets=np.zeros((0, 2)), t_motion=t,
                          legs=np.asarray(legs, dtype=float), leg=0, extra=float(extra),
                          limit=self._limit(float(np.sum(np.linalg.norm(np.diff(np.vstack([start, legs]), axis=0),
                                                                       axis=1)))))
        task = self._local_leg_task(st, X)
        st.op_info["task"] = task
        st.episode += 1
        st.tasks[f"nav_{name}"] = TaskCommand(task, st.episode)
        self._unfreeze(st, name)
        st.phase = "moving"

    def _settle(self, st: SupState, X: np.ndarray) -> None:
        """Once a navigating / transported entity's ball is inside the approach disk of its target region
        (the region grown by ``approach[k]``, clear of walls, obstacles and other regions), finish the motion
        to its P_s goal with the local law (mrodrake.control.local): near its goal the paper's point-world law
        with k1 = 0.01 moves at 0.02 (x − x_d) per second and crawls around the saddles behind the other
        entities' holes.  Without a local path the point-world law carries on."""
        info = st.op_info
        if info["kind"] not in ("navigate", "transport") or info.get("legs") is not None or info.get("no_settle"):
            return
        e, k, r = info["entity"], info["dst"], info["radius"]
        x = X[e, :2]
        depth = self.region_radii[k] + self.approach[k] - math.hypot(*(x - self.centers[k])) - r
        slow = math.hypot(*X[e, 2:]) <= self.rest_speed
        if depth < SETTLE_DEPTH and not (slow and depth >= 0.1 * SETTLE_DEPTH):
            return
        c, R, centers, radii = self._local_world(X, e, r, k, info["team"], self.approach[k])
        try:
            legs = local_path(x, info["goal"], centers, radii, c, R)
        except ValueError:
            info["no_settle"] = True
            return
        info.update(legs=legs, leg=0)
        self._swap_task(st, info["controller"], self._local_leg_task(st, X))

    def _next_leg(self, st: SupState, X: np.ndarray) -> None:
        """Start the next leg of a local motion once the entity is within LEG_TOL of the current waypoint."""
        info = st.op_info
        legs = info.get("legs")
        if legs is None or info["leg"] >= len(legs) - 1:
            return
        if math.hypot(*(X[info["entity"], :2] - legs[info["leg"]])) <= LEG_TOL:
            info["leg"] += 1
            task = self._local_leg_task(st, X)
            if info["kind"] in ("dock", "backoff", "room"):
                info["task"] = task
            self._swap_task(st, info["controller"], task)

    @staticmethod
    def _swap_task(st: SupState, controller: str, task) -> None:
        """Give ``controller`` a new task within its episode (the estimates carry over)."""
        st.tasks[controller] = TaskCommand(task, st.tasks[controller].episode)

    def _arrived(self, st: SupState, X: np.ndarray) -> bool:
        """Completion of the current motion: at rest (speed ≤ rest_speed) and, for a docking or a back-off, on
        its last leg and within ``dock_tol`` of its goal; for a navigation / transport, the ball inside the
        target region with half the layout spacing to spare (or inside it and within ``goal_tol`` of the goal)."""
        info = st.op_info
        e, k = info["entity"], info["dst"]
        x, v = X[e, :2], X[e, 2:]
        if math.hypot(*v) > self.rest_speed:
            return False
        if info.get("legs") is not None and info["leg"] < len(info["legs"]) - 1:
            return False
        to_goal = math.hypot(*(x - info["goal"]))
        if info["kind"] == "dock":
            return to_goal <= self.dock_tol
        margin = 0.5 * self.scenario.layout.spacing
        depth = self.region_radii[k] - math.hypot(*(x - self.centers[k])) - info["radius"]
        if info["kind"] in ("backoff", "room"):
            return to_goal <= self.dock_tol
        return depth >= margin or (depth > 0.0 and to_goal <= self.goal_tol)

    def _finish_motion(self, st: SupState, t: float, X: np.ndarray) -> None:
        info = st.op_info
        st.tasks[info["controller"]] = None
        plant = info["plant"]
        self._sync(st, plant, X[info["entity"], :2], (0.0, 0.0), True)
        st.primitives = st.primitives + (PrimitiveRecord(
            info["kind"], self.entities[info["entity"]], tuple(self.robots[i] for i in info["team"]),
            info["src"], info["dst"], info["radius"], info["start"], np.asarray(info["goal"]), info["others"],
            info["free"], info["task"], info["controller"], info["offsets"], info["t_motion"], t),)

    def _wait_motion(self, st: SupState, t: float, X: np.ndarray) -> bool:
        """True once the current motion has arrived (then parked); raises on its time limit."""
        self._settle(st, X)
        self._next_leg(st, X)
        if self._arrived(st, X):
            self._finish_motion(st, t, X)
            return True
        if t - st.op_info["t_motion"] > st.op_info["limit"]:
            raise _Failure(f"{st.op_info['kind']} of {self.entities[st.op_info['entity']]}: time limit "
                           f"{st.op_info['limit']:.0f} s exceeded")
        return False

    def _primitive_event(self, st: SupState, t: float, ok: bool = True, detail: str = "") -> None:
        op = st.op
        a = op.action
        if isinstance(a, Navigate):
            ents, src, dst = [self.robots[a.robot]], a.src, a.dst
        elif isinstance(a, Transport):
            ents, src, dst = [self.objects[a.obj]] + [self.robots[i] for i in a.team], a.src, a.dst
        else:
            k = op.step.src[self.N + a.obj]
            ents, src, dst = [self.robots[a.robot], self.objects[a.obj]], k, k
        names = self.scenario.region_names
        self._event(st, kind="primitive", t_start=st.op_t0, t_end=t, step=op.step.index,
                    plan_step=op.step.plan_step, action=self.ts.format_action(a, "names"), entities=" ".join(ents),
                    from_region=names[src], to_region=names[dst], ok=bool(ok), propositions="",
                    nba_states=" ".join(str(q) for q in sorted(st.run)), detail=detail)

    def _run_op(self, st: SupState, t: float, X: np.ndarray) -> bool:
        """Progress the current primitive; True when it is complete."""
        op, a = st.op, st.op.action
        if st.phase == "room" and not self._room_phase(st, t, X):
            return False
        if op.kind == "navigate":
            if st.phase == "start":
                goal = self._arrival_goal(st, t, X, a.dst, self.radii[a.robot], {a.robot})
                if goal is None:
                    return False
                self._start_motion(st, t, X, kind="navigate", entity=a.robot, team=(), radius=self.radii[a.robot],
                                   src=a.src, dst=a.dst, goal=goal, plant=self.robots[a.robot],
                                   controller=f"nav_{self.robots[a.robot]}")
                return False
            if self._wait_motion(st, t, X):
                self._primitive_event(st, t)
                return True
            return False
        if op.kind == "grasp":
            if st.phase == "start":
                try:
                    q, legs, extra = self._dock_point(st, X, a.robot, a.obj, defer=True)
                except _Defer:
                    st.ops = st.ops + (op,)
                    self._event(st, kind="order", t_start=t, t_end=t, step=op.step.index,
                                plan_step=op.step.plan_step, action=self.ts.format_action(a, "names"),
                                entities="", from_region="", to_region="", ok=True, propositions="",
                                nba_states="", detail="grasp deferred until the transports leaving its region "
                                "have left (no grasp point outside their covering disks)")
                    return True
                except _Failure:
                    # free robots (teammates not docked yet included) inside the covering disk of the team
                    # being formed move away first
                    k = op.step.src[self.N + a.obj]
                    cover = self._team_cover(a.obj, self._next_team(st, a.obj, a.robot))
                    found = None if st.op_info.get("room_done_dock") else self._room_moves(
                        st, X, k, {a.robot, self.N + a.obj}, keep_out=(X[self.N + a.obj, :2], cover))
                    if found is None:
                        raise
                    self._make_room(st, t, X, k, found, "room_done_dock")
                    return False
                k = op.step.src[self.N + a.obj]
                self._start_local_motion(st, t, X, kind="dock", robot=a.robot, k=k, goal=q, legs=legs, extra=extra)
                return False
            if self._wait_motion(st, t, X):
                st.docked[a.robot] = a.obj
                st.grasp_open[a.robot] = t
                self._primitive_event(st, t)
                return True
            return False
        if op.kind == "release":
            if st.phase == "start":
                j = a.obj
                key = st.engaged.get(j)
                if a.robot in st.grasp_open:
                    t0 = st.grasp_open.pop(a.robot)
                    st.grasps = st.grasps + ((t0, t, self.robots[a.robot], self.objects[j]),)
                st.docked.pop(a.robot, None)
                if key is not None:
                    team = self.couplings[key][1]
                    self._sync(st, self.objects[j], X[self.N + j, :2])
                    for i in team:
                        self._sync(st, self.robots[i], X[i, :2])
                    st.phase = "disengage"
                    return False
                st.phase = "backoff"
            if st.phase == "disengage":
                key = st.engaged[a.obj]
                for i in self.couplings[key][1]:
                    st.route[self.robots[i]] = 1
                st.route[self.objects[a.obj]] = 1
                st.engaged[a.obj] = None
                st.phase = "backoff"
            if st.phase == "backoff":
                k = op.step.src[self.N + a.obj]
                found, why = None, "P_s found no placement"
                for override, later in self._foresight(st, X, k, {a.robot}):
                    occupants = self._in_region(X, k, {a.robot})
                    disks = self._disks(X, set(range(len(self.entities))) - set(occupants), override)
                    try:
                        goal = goal_point(self.scenario, k, self.radii[a.robot], disks, seed=self.seed,
                                          future=later)
                        found = (goal, self._local_path(X, a.robot, k, goal))
                        break
                    except (UserError, ValueError) as exc:
                        why = str(exc)
                if found is None:
                    self._primitive_event(st, t, detail=f"no room to back off ({why}): stays at its grasp point")
                    return True
                self._start_local_motion(st, t, X, kind="backoff", robot=a.robot, k=k, goal=found[0], legs=found[1])
                return False
            if self._wait_motion(st, t, X):
                self._primitive_event(st, t)
                return True
            return False
        # transport
        j, team = a.obj, tuple(a.team)
        key = self.couplings.index((j, team))
        name = self.coupling_name(j, team)
        if st.phase == "start":
            if st.engaged.get(j) not in (None, key):
                raise _Failure(f"transport of {self.objects[j]}: still coupled to another team")
            if st.engaged.get(j) is None:
                xo = X[self.N + j, :2]
                offsets = np.array([X[i, :2] - xo for i in team])
                self._sync(st, name, xo, (0.0, 0.0), True, offsets)
                st.phase = "engage"
                return False
            st.phase = "go"
        if st.phase == "engage":
            st.engaged[j] = key
            st.route[self.objects[j]] = self.route_ports[(self.objects[j], name)]
            for i in team:
                st.route[self.robots[i]] = self.route_ports[(self.robots[i], name)]
            st.phase = "go"
        if st.phase == "go":
            offsets = np.asarray(st.sync[name].offsets, dtype=float)
            radius = max(float(self.radii[self.N + j]),
                         max(float(np.hypot(*offsets[m])) + self.radii[i] for m, i in enumerate(team)))
            movers = {self.N + j, *team}
            xo = X[self.N + j, :2]
            found = None if st.op_info.get("room_done_src") else self._room_moves(st, X, a.src, movers,
                                                                                   keep_out=(xo, radius))
            if found is not None:
                self._make_room(st, t, X, a.src, found, "room_done_src")
                return False
            goal = self._arrival_goal(st, t, X, a.dst, radius, movers, stay={self.N + j})
            if goal is None:
                return False
            self._start_motion(st, t, X, kind="transport", entity=self.N + j, team=team, radius=radius, src=a.src,
                               dst=a.dst, goal=goal, plant=name, controller=name + "_ctrl", offsets=offsets)
            return False
        if self._wait_motion(st, t, X):
            self._primitive_event(st, t)
            return True
        return False
