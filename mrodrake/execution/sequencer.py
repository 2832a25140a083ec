"""The sequencer: runs the placed primitives of a plan one at a time (paper Sec. III-A, sequential execution),
pure Python without Drake.

:meth:`Sequencer.tick` takes the sequencer's state, the time and a snapshot of every entity's [x, ẋ] and
returns the next state: which controller has which task (:class:`~mrodrake.execution.commands.TaskCommand`),
which plant is synced, parked or coupled (:class:`~mrodrake.execution.commands.SyncCommand`), which entities
follow a team plant, the monitored run (:class:`~mrodrake.execution.monitor.WordMonitor`) and the event log.
A Drake system only has to carry this state and route it to ports
(:class:`mrodrake.systems.supervisor.Supervisor`).

Each primitive is a small state machine (:class:`Phase`) over an :class:`Active` value: a room move, release
(disengage the team plant, back off), grasp (dock), navigation or transport (engage the team plant, go).  Its
end point comes from the plan-wide placement (:mod:`mrodrake.planning.placement`).  Motions use the paper's
adaptive law on the point-world map of the entity's free space, and the identity-map local law for docking,
backing off, room moves, the last part of every navigation or transport inside the *approach disk* of the
target region and, from a start nearer than the margin (``control.margin``) to another entity, its first part (exit legs
inside the source region's approach disk) (:mod:`mrodrake.control.local`); where the map of the whole free space
does not resolve the entity's position or its goal, the point-world law runs on the maps of receding windows
around the entity (:mod:`mrodrake.control.windows`); the estimates carry over within one primitive (one episode).

Parking brake: an entity that is not moving has zero dynamics; at rest (speed below ``rest_speed``) its
velocity is reset to zero (the paper's friction can be negative, so an uncontrolled entity would drift).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Sequence
from concurrent.futures import Future
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np
import shapely
from shapely.errors import GEOSException

from mrodrake.control.adaptive import AdaptiveGains
from mrodrake.control.freespace import Disk, entity_free_space
from mrodrake.control.local import PATH_CLEARANCE, clear_goal, disk_obstacles, exit_path, local_path, local_task
from mrodrake.control.mapworker import map_worker
from mrodrake.control.tasks import MAP_OPTIONS, build_map, build_task, departure_point, inside_circle
from mrodrake.control.windows import (
    RESOLUTION,
    RESOLUTION_FLOOR,
    STALL_FRACTION,
    STALL_SPEED,
    WINDOW_GROWTH,
    WINDOW_MARGIN,
    WINDOW_RADIUS,
    WINDOW_SWITCH,
    goal_window_free_space,
    grid_path,
    point_resolution,
    progress,
    resolution,
    window_free_space,
)
from mrodrake.errors import UserError
from mrodrake.execution.commands import PrimitiveRecord, SyncCommand, TaskCommand
from mrodrake.execution.monitor import WordMonitor, entity_regions, label_of
from mrodrake.execution.schedule import (
    SPOT_LEG,
    Corridor,
    Execution,
    Job,
    Request,
    assign_corridors,
    dependency_graph,
    redraw_corridors,
    task_order,
)
from mrodrake.geometry import DOCK_TOL, GOAL_TOL, disk, polygon, workspace_free_space
from mrodrake.planning.placement import OpKind, PlacedOp, Placement, layout_slots
from mrodrake.planning.steps import StepSpec
from mrodrake.ts import Transport

#: Speed (m/s) under which an arrived entity counts as at rest (then parked).
REST_SPEED = 0.05
#: Halvings of a local motion's path clearance allowed where no path keeps it (:func:`local_path`): entities
#: dock and stop within DOCK_TOL and GOAL_TOL of their planned points, so a gap that placement checked at the full
#: clearance can be a few cm narrower (a release on a generated office task: a 0.10 m gap beside a member robot).
LOCAL_NARROW = 2
#: Halvings of the grid step a window's grid path may take (:func:`~mrodrake.control.windows.grid_path`) where
#: no other task can be built: the TS lets a team through a door whose centre channel is a few centimetres wide,
#: narrower than the grid step (a finer grid over a whole 80 m floor costs seconds, so only there).
GRID_HALVINGS = 2
#: Distance (m) to a waypoint of a local motion at which its next leg starts.
LEG_TOL = 0.25 * PATH_CLEARANCE
#: Width (m) of the approach ring around a region (less where walls, obstacles or other regions are nearer
#: than this plus the margin): inside it, a navigation or transport finishes with the local law.
APPROACH = 10.0
#: Depth (m) of the entity's ball inside the approach disk at which the local law takes over.
SETTLE_DEPTH = 0.05
#: Point-world maps (and maps asked of the map worker) a sequencer keeps for reuse (:meth:`Sequencer._map`).
MAP_CACHE = 6
#: Navigations and transports ahead whose maps the map worker builds while the current one runs.
PREFETCH_AHEAD = 2
#: Period (s) at which motions waiting for a corridor ask again while no job ends (concurrent execution): the
#: running motions have moved on, and corridors drawn again from where they are may leave room for them.
REGRANT_PERIOD = 10.0
#: Distance (m) to its planned spot within which a parked object is a hole of a motion's map as its planned
#: spot with the radius grown by this much (:meth:`Sequencer._map_disks`): transports end within GOAL_TOL.
PARK_TOL = GOAL_TOL
#: The same for a parked robot: navigations end within GOAL_TOL of their spots and back-offs within DOCK_TOL,
#: and a robot docked to an object sits within DOCK_TOL of its slot next to an object within GOAL_TOL of its
#: own spot.
ROBOT_PARK_TOL = GOAL_TOL + DOCK_TOL


class Phase(Enum):
    """Phases of a primitive."""

    START = "start"
    ENGAGE = "engage"
    DISENGAGE = "disengage"
    MOVING = "moving"


class Status(Enum):
    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"


@dataclass(frozen=True)
class Motion:
    """One controller driving one plant: the moving entity (a robot, or the object of a team), its team,
    regions, covering radius, start and goal; ``legs`` are the straight legs of the local law (None while on
    the point-world law), ``leg`` the current one; ``exiting``: the legs are exit legs in the source region
    (out of another entity's margin, or ``departed``: to a start that maps inside the circle barrier) before
    the point-world law starts; ``window_radius``: the radius of its windows (smaller after each stall),
    ``anchor``: (t, x, y) where the current period of stall detection started on the point-world law."""

    kind: OpKind
    entity: int
    team: tuple[int, ...]
    controller: str
    plant: str
    src: int
    dst: int
    radius: float
    start: tuple[float, float]
    goal: tuple[float, float]
    t_start: float
    limit: float
    episode: int
    task: object
    free: object = None
    others: tuple = ()
    offsets: tuple = ()
    legs: tuple | None = None
    leg: int = 0
    settle_tried: bool = False
    extra: float = 0.0
    exiting: bool = False
    departed: bool = False
    world: tuple = ()
    waypoint: tuple | None = None
    corridor: Corridor | None = None
    spans: tuple = ()
    window_radius: float = WINDOW_RADIUS
    anchor: tuple = ()


@dataclass(frozen=True)
class Active:
    """A primitive in execution: its placed op, its step, its phase and its motion; ``uid``: its job
    (concurrent execution), ``tried``: the corridor version at which it last found no corridor."""

    op: PlacedOp
    step: StepSpec
    phase: Phase
    t0: float
    motion: Motion | None = None
    uid: int = -1
    tried: int = -1


@dataclass(frozen=True)
class ExecState:
    """Everything the sequencer knows between two ticks (replaced, never mutated).  Mappings are keyed by
    system names (controllers, plants) or entity indices and are copied on every change."""

    step_idx: int
    queue: tuple[PlacedOp, ...]
    active: Active | None
    tasks: dict
    syncs: dict
    coupled: dict       # entity index -> team plant name it follows (absent: its own plant)
    engaged: dict       # object index -> team plant name (absent: none)
    docked: dict        # robot index -> object index
    grasp_open: dict    # robot index -> time its grasp started
    monitor: WordMonitor
    events: tuple = ()
    grasps: tuple = ()
    primitives: tuple = ()
    status: Status = Status.RUNNING
    message: str = ""
    version: int = 0
    episode: int = 0
    running: tuple = ()     # concurrent execution: the jobs in execution (Active values)
    done: frozenset = frozenset()
    next_job: int = 0       # concurrent execution: jobs before this uid have started
    word_step: int = 0      # concurrent execution: the executed steps before it are closed on the monitor
    corridors: int = 0      # concurrent execution: bumped whenever a job ends (corridors may have come free)
    regrant: float = 0.0    # concurrent execution: time of the last bump while no job ended (REGRANT_PERIOD)

    def __deepcopy__(self, memo):
        return self


class _Failure(Exception):
    """A primitive cannot go on (recorded; ends the mission with ok=False)."""


@dataclass
class _Edit:
    """Mutable working copy of an :class:`ExecState` during one tick."""

    st: ExecState
    tasks: dict = field(default_factory=dict)
    syncs: dict = field(default_factory=dict)
    events: list = field(default_factory=list)

    def __post_init__(self):
        self.tasks, self.syncs = dict(self.st.tasks), dict(self.st.syncs)
        self.coupled, self.engaged = dict(self.st.coupled), dict(self.st.engaged)
        self.docked, self.grasp_open = dict(self.st.docked), dict(self.st.grasp_open)
        self.monitor = self.st.monitor.copy()
        self.events = list(self.st.events)
        self.grasps, self.primitives = list(self.st.grasps), list(self.st.primitives)
        self.step_idx, self.queue, self.active = self.st.step_idx, self.st.queue, self.st.active
        self.status, self.message = self.st.status, self.st.message
        self.version, self.episode = self.st.version, self.st.episode
        self.running, self.done, self.next_job = list(self.st.running), set(self.st.done), self.st.next_job
        self.word_step, self.corridors, self.regrant = self.st.word_step, self.st.corridors, self.st.regrant
        self.grants: dict[int, Corridor] = {}
        self.t = 0.0

    def unchanged(self) -> bool:
        """True if this tick changed nothing: every field is the one it started from (mappings entry by entry,
        the append-only records by length, the monitor by its run, regions and read flag)."""
        st, mon = self.st, self.st.monitor
        same = (self.step_idx == st.step_idx and self.queue is st.queue and self.active is st.active
                and self.status is st.status and self.message == st.message and self.version == st.version
                and self.episode == st.episode and self.next_job == st.next_job and self.word_step == st.word_step
                and self.corridors == st.corridors and self.regrant == st.regrant
                and len(self.events) == len(st.events)
                and len(self.grasps) == len(st.grasps) and len(self.primitives) == len(st.primitives)
                and self.done == st.done and len(self.running) == len(st.running)
                and all(a is b for a, b in zip(self.running, st.running))
                and self.monitor.run == mon.run and self.monitor.read_in_step == mon.read_in_step
                and self.monitor.regions == mon.regions)
        if not same:
            return False
        for new, old in ((self.tasks, st.tasks), (self.syncs, st.syncs)):
            if new.keys() != old.keys() or any(new[k] is not old[k] for k in new):
                return False
        return (self.coupled == st.coupled and self.engaged == st.engaged and self.docked == st.docked
                and self.grasp_open == st.grasp_open)

    def freeze(self) -> ExecState:
        return ExecState(self.step_idx, self.queue, self.active, self.tasks, self.syncs, self.coupled,
                         self.engaged, self.docked, self.grasp_open, self.monitor, tuple(self.events),
                         tuple(self.grasps), tuple(self.primitives), self.status, self.message, self.version,
                         self.episode, tuple(self.running), frozenset(self.done), self.next_job, self.word_step,
                         self.corridors, self.regrant)


class Sequencer:
    """Executes ``placement`` (the placed steps of ``plan``) for ``scenario``; ``couplings`` are the
    (object, team) pairs of the plan's transports, each with a team plant and controller.  ``execution``:
    one primitive at a time (the paper), or every job of :func:`~mrodrake.execution.schedule.dependency_graph`
    as soon as its predecessors are done, concurrent motions on their corridors.  ``prefetch`` (sequential
    execution): the maps of the next navigations and transports are built by the map worker while the current
    one runs (:meth:`_prefetch`; the same maps either way, only sooner); ``map_sources`` counts where the
    maps came from."""

    def __init__(self, scenario, ts, words, placement: Placement, couplings: Sequence[tuple[int, tuple[int, ...]]],
                 *, rest_speed: float = REST_SPEED, dock_tol: float = DOCK_TOL, goal_tol: float = GOAL_TOL,
                 time_limit: tuple[float, float] = (1500.0, 10.0), execution: Execution = Execution.SEQUENTIAL,
                 prefetch: bool = True):
        self.scenario, self.ts, self.words, self.placement = scenario, ts, words, placement
        # clearance to walls, obstacles and other regions, and to every other entity at which a navigation or
        # transport starts the point-world law (nearer: exit legs of the local law first).  Entities packed
        # closer than their grown radii merge into one hole of the free space, and a start in a pocket of it
        # maps next to that hole's point b_ℓ, where the barrier (kept off the start, Prop. 1) acts only within
        # ~1 cm of the pocket's wall (case II seed 0, step 52: τ = 2.6e-10, 0.12 m gaps, integrator failure)
        self.margin = float(scenario.control.margin)
        self.steps = [p.step for p in placement.steps]
        self.robots, self.objects = list(scenario.robot_names), list(scenario.object_names)
        self.entities = self.robots + self.objects
        self.N, self.M, self.K = len(self.robots), len(self.objects), len(scenario.regions)
        self.radii = np.array([r.radius for r in scenario.robots] + [o.radius for o in scenario.objects])
        self.centers = np.array([g.center for g in scenario.regions], dtype=float)
        self.region_radii = np.array([g.radius for g in scenario.regions], dtype=float)
        self.couplings = [(int(j), tuple(int(i) for i in team)) for j, team in couplings]
        self.rest_speed, self.dock_tol, self.goal_tol = float(rest_speed), float(dock_tol), float(goal_tol)
        # period of stall detection: the time constant 1/(2 k1) of the point-world law (windows.STALL_FRACTION)
        self.stall_period = 1.0 / (2.0 * float(scenario.control.k1))
        self.time_limit = time_limit
        self.approach = self._approach_widths()
        self._maps: OrderedDict = OrderedDict()
        self.prefetch = bool(prefetch)
        self.map_sources = {"built": 0, "worker": 0, "cached": 0}
        self._ops = [op for sp in placement.steps for op in sp.ops]
        self._op_start = np.cumsum([0] + [len(sp.ops) for sp in placement.steps]).tolist()
        self._planned = self._plan_track()
        self.controllers = ([f"nav_{r}" for r in self.robots]
                            + [self.team_name(j, t) + "_ctrl" for j, t in self.couplings])
        self.plants = self.entities + [self.team_name(j, t) for j, t in self.couplings]
        self.execution = Execution(execution)
        self.jobs: tuple[Job, ...] = ()
        self.block_end = tuple(range(len(self.steps)))
        if self.execution is Execution.CONCURRENT:
            order = task_order(words, placement)
            self.jobs, self.block_end = dependency_graph(ts, words, placement, order), order.block_end
        self.block_start = tuple(min(t for t in range(s + 1) if self.block_end[t] == self.block_end[s])
                                 for s in range(len(self.steps)))
        self._floor = polygon(scenario.workspace.boundary)
        if self.prefetch and self.execution is Execution.SEQUENTIAL:
            try:  # the worker starts while the first motion builds its own map
                map_worker()
            except OSError:
                self.prefetch = False

    # ------------------------------------------------------------------ names
    def team_name(self, j: int, team: Sequence[int]) -> str:
        """Name of the team plant of object j and ``team`` (``<object>_<r1>+<r2>...``)."""
        return f"{self.objects[j]}_{'+'.join(self.robots[i] for i in team)}"

    def initial_state(self) -> ExecState:
        init = np.asarray(self.placement.initial, dtype=float).reshape(-1, 2)
        syncs = {}
        for p in self.plants:
            if p in self.entities:
                x = init[self.entities.index(p)]
                syncs[p] = SyncCommand(0, (float(x[0]), float(x[1])), (0.0, 0.0), True, ())
            else:
                j, team = next((j, t) for j, t in self.couplings if self.team_name(j, t) == p)
                syncs[p] = SyncCommand(0, tuple(map(float, init[self.N + j])), (0.0, 0.0), True,
                                       tuple((0.0, 0.0) for _ in team))
        regions = entity_regions(self.centers, self.radii, init, self.region_radii)
        return ExecState(-1, (), None, {c: None for c in self.controllers}, syncs, {}, {}, {}, {},
                         WordMonitor(self.words, regions))

    # ------------------------------------------------------------------ the tick
    def tick(self, st: ExecState, t: float, X: np.ndarray) -> ExecState:
        """The state after one periodic update at time t with the entities' states X (rows [x, y, vx, vy]);
        ``st`` itself if the update changed nothing."""
        if st.status is not Status.RUNNING:
            return st
        ed = _Edit(st)
        ed.t = t
        try:
            if not np.isfinite(X).all():
                raise _Failure(f"non-finite entity state at t={t:.2f}")
            self._monitor(ed, t, X)
            if self.execution is Execution.CONCURRENT:
                self._advance_concurrent(ed, t, X)
            else:
                self._advance(ed, t, X)
        except _Failure as exc:
            self._fail(ed, t, str(exc))
        return st if ed.unchanged() else ed.freeze()

    def abort(self, st: ExecState, t: float, reason: str) -> ExecState:
        """End the mission as a failure of the primitive in execution, from outside the tick (a controller
        fault, an integrator failure, any exception inside the simulation); the message names the
        primitive, its step and the simulated time."""
        if st.status is not Status.RUNNING:
            return st
        ed = _Edit(st)
        if ed.active is None and ed.running:
            ed.active = ed.running[0]
        if ed.active is not None:
            a = ed.active
            where = f"{self._op_text(a.op)} (step {a.step.index}, plan step {a.step.plan_step})"
        elif 0 <= ed.step_idx < len(self.steps):
            where = f"step {self.steps[ed.step_idx].index}"
        else:
            where = "the mission"
        self._fail(ed, t, f"{where} failed at t = {t:.2f} s: {reason}")
        return ed.freeze()

    def discrete_state(self, st: ExecState, X: np.ndarray) -> tuple:
        """The executed TS state: region of every entity (−1: none) and grasps from the docking record."""
        reg = entity_regions(self.centers, self.radii, X[:, :2], self.region_radii, tol=1e-6)
        return tuple(int(k) for k in reg) + tuple(st.docked.get(i, -1) for i in range(self.N))

    def steps_done(self, st: ExecState) -> int:
        """Executed steps complete (concurrent execution: those whose jobs, and all before them, are done)."""
        return len(self.steps) if st.status is Status.DONE else max(0, st.step_idx)

    def in_execution(self, st: ExecState) -> tuple[Active, ...]:
        """The primitives in execution now."""
        return tuple(st.running) if self.execution is Execution.CONCURRENT else (
            () if st.active is None else (st.active,))

    def _advance(self, ed: _Edit, t: float, X: np.ndarray) -> None:
        while ed.status is Status.RUNNING:
            if ed.active is None:
                if ed.queue:
                    op, ed.queue = ed.queue[0], ed.queue[1:]
                    uid = self._op_start[ed.step_idx + 1] - len(ed.queue) - 1
                    ed.active = Active(op, self.steps[ed.step_idx], Phase.START, t, uid=uid)
                else:
                    if ed.step_idx >= 0:
                        self._end_step(ed, X)
                    ed.step_idx += 1
                    if ed.step_idx >= len(self.steps):
                        ed.status, ed.message = Status.DONE, "mission complete"
                        return
                    ed.monitor.begin_step()
                    ed.queue = self.placement.steps[ed.step_idx].ops
                    continue
            if not self._run(ed, t, X):
                return
            ed.active = None

    def _advance_concurrent(self, ed: _Edit, t: float, X: np.ndarray) -> None:
        """Progress every job in execution, then start every job whose predecessors are done (a visible job
        first closes the executed steps before its own on the monitor); repeat until nothing changes."""
        jobs = self.jobs
        while ed.status is Status.RUNNING:
            self._grant(ed, t, X)
            changed, k = False, 0
            while k < len(ed.running):
                ed.active = ed.running[k]
                if self._run(ed, t, X):
                    self._job_done(ed, X, ed.running.pop(k))
                    changed = True
                else:
                    ed.running[k] = ed.active
                    k += 1
                ed.active = None
            started = {a.uid for a in ed.running}
            for job in jobs[ed.next_job:]:
                if job.uid in ed.done or job.uid in started or not all(p in ed.done for p in job.preds):
                    continue
                if job.visible:
                    self._close_steps(ed, X, self.block_start[job.step])
                ed.running.append(Active(job.op, self.steps[job.step], Phase.START, t, uid=job.uid))
                started.add(job.uid)
                changed = True
            while ed.next_job < len(jobs) and (ed.next_job in ed.done or ed.next_job in started):
                ed.next_job += 1
            pending = next((j for j in jobs if j.uid not in ed.done), None)
            ed.step_idx = len(self.steps) if pending is None else pending.step
            if pending is None:
                self._close_steps(ed, X, len(self.steps))
                got = self.discrete_state(ed.freeze(), X)
                if self.steps and got != tuple(self.steps[-1].dst):
                    shown = self.ts.state_dict(got) if min(got[: self.N + self.M]) >= 0 else got
                    raise _Failure(f"step {self.steps[-1].index}: executed state {shown} differs from the plan's "
                                   f"{self.ts.state_dict(self.steps[-1].dst)}")
                ed.status, ed.message = Status.DONE, "mission complete"
                return
            if not changed:
                return

    def _close_steps(self, ed: _Edit, X: np.ndarray, upto: int) -> None:
        """Close the blocks of executed steps before ``upto`` on the monitor: a step without a visible crossing
        reads the label once; the run must admit the planned NBA state at every block's end."""
        while ed.word_step < upto:
            spec = self.steps[self.block_end[ed.word_step]]
            ed.monitor.end_step()
            if not ed.monitor.admits(spec.dst_q):
                raise _Failure(f"step {spec.index}: the monitored NBA run {ed.monitor.states} does not contain "
                               f"the plan's NBA state {spec.dst_q}")
            ed.monitor.begin_step()
            ed.word_step = self.block_end[ed.word_step] + 1

    def _job_done(self, ed: _Edit, X: np.ndarray, a: Active) -> None:
        """Record a finished job; the bodies of a navigation or transport must be in its target region."""
        ed.done.add(a.uid)
        ed.corridors += 1
        if a.op.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT):
            act = a.op.action
            reg = entity_regions(self.centers, self.radii, X[:, :2], self.region_radii, tol=1e-6)
            off = [self.entities[b] for b in self.jobs[a.uid].bodies if reg[b] != act.dst]
            if off:
                raise _Failure(f"{self._op_text(a.op)} (step {a.step.index}): {', '.join(off)} not in "
                               f"{self.scenario.region_names[act.dst]} at its end")

    def _grant(self, ed: _Edit, t: float, X: np.ndarray) -> None:
        """Corridors (:func:`~mrodrake.execution.schedule.assign_corridors`) for every navigation or transport
        in execution that is ready to move and has not asked since a job last ended (or, waiting, for
        :data:`REGRANT_PERIOD`), together; where some get none, the corridors of the running motions drawn
        again from where they are (:meth:`_redraw`) if that lets more start."""
        if any(a.op.kind is OpKind.TRANSPORT and a.phase is Phase.START for a in ed.running):
            return  # a team engaging now asks at the next tick: everyone asks then, together
        if t - ed.regrant >= REGRANT_PERIOD and any(a.tried == ed.corridors for a in ed.running):
            ed.corridors += 1
            ed.regrant = t
        requests, failed = [], set()
        for a in ed.running:
            if a.motion is not None or a.uid in ed.grants or a.tried == ed.corridors:
                continue
            op, act = a.op, a.op.action
            if op.kind is OpKind.NAVIGATE and a.phase is Phase.START:
                entity, team, radius = act.robot, (), float(self.radii[act.robot])
            elif op.kind is OpKind.TRANSPORT and a.phase is Phase.ENGAGE:
                name = self.team_name(act.obj, act.team)
                offsets = np.asarray(ed.syncs[name].offsets, dtype=float)
                entity, team, radius = self.N + act.obj, tuple(act.team), self._team_radius(act.team, offsets,
                                                                                             act.obj)
            else:
                continue
            try:
                requests.append(self._request(a.uid, op, X[entity, :2], radius, self._disks(X, {entity, *team})))
            except UserError:  # waits while another job can clear its way
                failed.add(a.uid)
        held = [self._held(a.motion) for a in ed.running if a.motion is not None and a.motion.corridor is not None]
        busy = shapely.union_all(held) if held else None
        granted = set(ed.grants)
        if requests:
            try:
                ed.grants.update(assign_corridors(requests, self._floor, busy, self.margin))
            except GEOSException:  # degenerate cells: the first asker alone when nothing moves, else all wait
                if busy is None:
                    ed.grants[requests[0].uid] = Corridor(None, self._floor)
            if not granted and any(rq.uid not in ed.grants for rq in requests):
                self._redraw(ed, X, requests)
        if failed and set(ed.grants) == granted and not any(b.motion is not None for b in ed.running):
            ed.grants[min(failed)] = Corridor(None, self._floor)  # nothing else moves: it starts and reports why
        asked = {rq.uid for rq in requests} | failed
        ed.running = [replace(a, tried=ed.corridors) if a.uid in asked and a.uid not in ed.grants else a
                      for a in ed.running]

    def _held(self, m: Motion):
        """The floor the bodies of running motion ``m`` may still cover: its corridor's, or once it settles in
        its destination on local legs, which keep its centre inside their rim, that rim grown by its radius
        (a part of the corridor's body)."""
        if m.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT) and m.legs is not None and not m.exiting:
            spot = m.corridor.spots[1]
            c = np.asarray(m.goal, dtype=float) if spot else self.centers[m.dst]
            R = SPOT_LEG if spot else float(self.region_radii[m.dst] + m.extra - m.radius)
            return disk(c, R + m.radius)
        return m.corridor.body

    @staticmethod
    def _redrawable(m: Motion | None) -> bool:
        """A navigation or transport on the point-world law (not on exit, departure or settle legs)."""
        return (m is not None and m.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT) and m.corridor is not None
                and m.legs is None and bool(m.world))

    def _redraw(self, ed: _Edit, X: np.ndarray, requests: list[Request]) -> None:
        """Corridors of the running motions on the point-world law drawn again from where they are, together
        with the waiting ``requests`` (:func:`~mrodrake.execution.schedule.redraw_corridors`), if that grants
        more of the requests than :func:`~mrodrake.execution.schedule.assign_corridors` did: each running
        motion's law restarts from where it is on F ∩ its new corridor (:meth:`_point_world`, same episode: the
        estimates carry over, as for windows), a static free space again, so Theorem 1 applies to it from there.
        The new corridors are disjoint from each other and from those kept, and each holds its motion's bodies
        where they are, so no two bodies meet at the switch either.  Nothing changes if any motion's law cannot
        restart."""
        movers = [a for a in ed.running if self._redrawable(a.motion)]
        if not movers:
            return
        kept = [self._held(a.motion) for a in ed.running
                if a.motion is not None and a.motion.corridor is not None and not self._redrawable(a.motion)]
        try:
            moving = [self._request(a.uid, a.op, X[a.motion.entity, :2], a.motion.radius,
                                    self._disks(X, {a.motion.entity, *a.motion.team})) for a in movers]
            got = redraw_corridors(moving, requests, self._floor, shapely.union_all(kept) if kept else None,
                                   self.margin)
        except (UserError, GEOSException):
            return
        waiting = {rq.uid for rq in requests}
        if got is None or len(waiting & set(got)) <= len(waiting & set(ed.grants)):
            return
        tasks, moved = dict(ed.tasks), {}
        for a in movers:
            try:
                m = self._point_world(ed, X, replace(a.motion, corridor=got[a.uid], departed=True))
            except _Failure:
                m = None
            if m is None or (m.waypoint is not None and a.motion.waypoint is None):
                ed.tasks = tasks
                return
            moved[a.uid] = m
        ed.running = [replace(a, motion=moved[a.uid]) if a.uid in moved else a for a in ed.running]
        for uid in waiting:
            ed.grants.pop(uid, None)
        ed.grants.update({uid: c for uid, c in got.items() if uid in waiting})

    def _request(self, uid: int, op: PlacedOp, start: np.ndarray, radius: float, others: list[Disk]) -> Request:
        """The corridor request of the navigation or transport ``op`` (job ``uid``) from ``start`` with the
        entities ``others`` parked; raises UserError when its free space does not hold its start and goal."""
        act = op.action
        free = entity_free_space(self.scenario, radius, start, op.goal, act.src, act.dst, others)
        regions = tuple((disk(self.centers[k], self.region_radii[k] + self.approach[k]),
                         disk(self.centers[k], self.region_radii[k])) for k in (act.src, act.dst))
        spots = tuple(disk(p, SPOT_LEG + radius) for p in (start, op.goal))
        return Request(uid, free.polygon, np.array(start, dtype=float), np.asarray(op.goal, dtype=float), radius,
                       regions, spots)

    def _end_step(self, ed: _Edit, X: np.ndarray) -> None:
        spec = self.steps[ed.step_idx]
        ed.monitor.end_step()
        if not ed.monitor.admits(spec.dst_q):
            raise _Failure(f"step {spec.index}: the monitored NBA run {ed.monitor.states} does not contain the "
                           f"plan's NBA state {spec.dst_q}")
        got = self.discrete_state(ed.freeze(), X)
        if got != tuple(spec.dst):
            shown = self.ts.state_dict(got) if min(got[: self.N + self.M]) >= 0 else got
            raise _Failure(f"step {spec.index}: executed state {shown} differs from the plan's "
                           f"{self.ts.state_dict(spec.dst)}")

    def _monitor(self, ed: _Edit, t: float, X: np.ndarray) -> None:
        regions = entity_regions(self.centers, self.radii, X[:, :2], self.region_radii, tol=1e-6)
        if not ed.monitor.observe(regions):
            return
        lab = label_of(ed.monitor.regions, self.K)
        props = [p for b, p in enumerate(self.ts.propositions) if lab >> b & 1]
        k = min(ed.word_step, len(self.steps) - 1) if self.execution is Execution.CONCURRENT else ed.step_idx
        spec = self.steps[k] if 0 <= k < len(self.steps) else None
        self._event(ed, "label", t, spec, ok=bool(ed.monitor.run), propositions=" ".join(props),
                    nba_states=" ".join(map(str, ed.monitor.states)))
        if not ed.monitor.run:
            raise _Failure(f"the monitored NBA run died at t={t:.2f} (propositions: {' '.join(props) or 'none'})")

    def _fail(self, ed: _Edit, t: float, msg: str) -> None:
        if ed.active is not None:
            self._primitive_event(ed, t, ok=False, detail=msg)
            ed.active = None
        ed.status, ed.message = Status.FAILED, msg
        ed.running = []
        for c in ed.tasks:
            ed.tasks[c] = None

    # ------------------------------------------------------------------ events
    def _event(self, ed: _Edit, kind: str, t: float, spec: StepSpec | None, **row) -> None:
        base = {"kind": kind, "t_start": row.pop("t_start", t), "t_end": t, "step": spec.index if spec else 0,
                "plan_step": spec.plan_step if spec else 0, "action": "", "entities": "", "from_region": "",
                "to_region": "", "ok": True, "propositions": "", "nba_states": "", "detail": "", "time_limit": None}
        base.update(row)
        ed.events.append(base)

    def _op_text(self, op: PlacedOp) -> str:
        if op.kind is OpKind.ROOM:
            who = self.entities[op.entity]
            return f"room move of {who} in {self.scenario.region_names[op.region]}"
        return self.ts.format_action(op.action, "names")

    def _primitive_event(self, ed: _Edit, t: float, ok: bool = True, detail: str = "") -> None:
        a = ed.active
        op, names = a.op, self.scenario.region_names
        act = op.action
        if op.kind is OpKind.ROOM:
            ents, src, dst = [self.entities[op.entity]] + [self.robots[i] for i in op.team], op.region, op.region
        elif op.kind is OpKind.NAVIGATE:
            ents, src, dst = [self.robots[act.robot]], act.src, act.dst
        elif op.kind is OpKind.TRANSPORT:
            ents, src, dst = [self.objects[act.obj]] + [self.robots[i] for i in act.team], act.src, act.dst
        else:
            ents, src, dst = [self.robots[act.robot], self.objects[act.obj]], op.region, op.region
        self._event(ed, "room" if op.kind is OpKind.ROOM else "primitive", t, a.step, t_start=a.t0,
                    action=self._op_text(op), entities=" ".join(ents), from_region=names[src], to_region=names[dst],
                    ok=bool(ok), nba_states=" ".join(map(str, ed.monitor.states)), detail=detail,
                    time_limit=None if a.motion is None else float(a.motion.limit))

    # ------------------------------------------------------------------ plant commands
    def _sync(self, ed: _Edit, plant: str, x, v=(0.0, 0.0), frozen: bool = True, offsets=None) -> None:
        old = ed.syncs[plant]
        ed.version += 1
        ed.syncs[plant] = SyncCommand(ed.version, tuple(map(float, x)), tuple(map(float, v)), bool(frozen),
                                      old.offsets if offsets is None else tuple(map(tuple, np.asarray(offsets, float))))

    def _unfreeze(self, ed: _Edit, plant: str) -> None:
        ed.syncs[plant] = replace(ed.syncs[plant], frozen=False)

    def _limit(self, dist: float) -> float:
        return self.time_limit[0] + self.time_limit[1] * dist

    # ------------------------------------------------------------------ geometry
    def _disks(self, X: np.ndarray, exclude: set[int]) -> list[Disk]:
        return [Disk(self.entities[e], (float(X[e, 0]), float(X[e, 1])), float(self.radii[e]))
                for e in range(len(self.entities)) if e not in exclude]

    def _plan_track(self) -> list[np.ndarray]:
        """Planned positions (N + M, 2) of every entity before each primitive of the run in sequential order,
        and after the last one: each primitive puts its entity at its planned end point, a transport or a
        team's room move its members on their slots around it."""
        pos = np.asarray(self.placement.initial, dtype=float).reshape(-1, 2).copy()
        out = []
        for op in self._ops:
            out.append(pos.copy())
            goal = np.asarray(op.goal, dtype=float)
            pos[op.entity] = goal
            if op.entity >= self.N and op.team:
                pos[list(op.team)] = layout_slots(self.ts, op.entity - self.N, op.team, goal, op.rotation)
        out.append(pos.copy())
        return out

    def _map_disks(self, X: np.ndarray, movers: set[int], planned: np.ndarray) -> list[Disk]:
        """The entities other than ``movers`` as holes of a motion's map: one within its parking tolerance
        (ROBOT_PARK_TOL for a robot, PARK_TOL for an object) of its planned spot (``planned``) as that spot with
        its radius grown by the tolerance, a disk that contains it and does not depend on where within that it
        stopped (so the map can be built before it has); any other at its actual disk."""
        out = []
        for e in range(len(self.entities)):
            if e in movers:
                continue
            x, p, r = X[e, :2], planned[e], float(self.radii[e])
            tol = ROBOT_PARK_TOL if e < self.N else PARK_TOL
            near = math.hypot(x[0] - p[0], x[1] - p[1]) <= tol
            c = (float(p[0]), float(p[1])) if near else (float(x[0]), float(x[1]))
            out.append(Disk(self.entities[e], c, r + tol if near else r))
        return out

    def _map_radius(self, entity: int, team: Sequence[int], radius: float) -> float:
        """The covering radius a motion's map uses: a team's from its planned slots grown by dock_tol (its
        members dock within that of their slots, so it covers the actual one), else ``radius``."""
        if not team:
            return radius
        return max(radius, self.ts.covering_radius(entity - self.N, tuple(team)) + self.dock_tol)

    def _approach_widths(self) -> np.ndarray:
        """Width of the approach ring of every region: APPROACH, or the clearance of the region's disk to
        walls, obstacles and other regions minus the margin if smaller (never negative)."""
        ws = self.scenario.workspace
        free = workspace_free_space(polygon(ws.boundary), [polygon(o.polygon) for o in ws.obstacles])
        out = []
        for k, (c, R) in enumerate(zip(self.centers, self.region_radii)):
            clear = free.boundary.distance(shapely.Point(*c)) - R
            for m, (cm, Rm) in enumerate(zip(self.centers, self.region_radii)):
                if m != k:
                    clear = min(clear, math.hypot(*(c - cm)) - R - Rm)
            out.append(max(0.0, min(APPROACH, clear - self.margin)))
        return np.array(out)

    def _local_world(self, X: np.ndarray, entity: int, radius: float, k: int, exclude=(), extra: float = 0.0):
        """(rim centre, rim radius, disk centres, grown radii) of a local motion of ``entity`` (covering
        ``radius``) in region k, its rim grown by ``extra``; ``exclude``: its team, which moves with it."""
        c, R = self.centers[k], float(self.region_radii[k] + extra - radius)
        centers, radii = disk_obstacles(X, self.radii, radius, [entity, *exclude], c, R)
        return c, R, centers, radii

    def _motion_world(self, X: np.ndarray, m: Motion, k: int, extra: float):
        """:meth:`_local_world` of motion ``m`` in its region k (its source or destination) with the rim grown by
        ``extra``; on a corridor that holds only the disk of radius SPOT_LEG around its start (k the source) or
        its goal (the destination), that disk (:class:`~mrodrake.execution.schedule.Corridor`)."""
        if m.corridor is None or not m.corridor.spots[0 if k == m.src else 1]:
            return self._local_world(X, m.entity, m.radius, k, m.team, extra)
        c, R = self._motion_rim(m, k, extra)
        centers, radii = disk_obstacles(X, self.radii, m.radius, [m.entity, *m.team], c, R)
        return c, R, centers, radii

    def _motion_rim(self, m: Motion, k: int, extra: float) -> tuple[np.ndarray, float]:
        """(rim centre, rim radius) of :meth:`_motion_world`, without its obstacles."""
        if m.corridor is None or not m.corridor.spots[0 if k == m.src else 1]:
            return self.centers[k], float(self.region_radii[k] + extra - m.radius)
        return np.asarray(m.start if k == m.src else m.goal, dtype=float), SPOT_LEG

    def _ring(self, m: Motion, k: int) -> float:
        """Width of the approach ring of region k (the source or destination of ``m``) that ``m`` may use."""
        if m.corridor is None or m.corridor.rings[0 if k == m.src else 1]:
            return float(self.approach[k])
        return 0.0

    def _team_radius(self, team: Sequence[int], offsets: np.ndarray, j: int) -> float:
        return max(float(self.radii[self.N + j]),
                   max((float(np.hypot(*offsets[m])) + self.radii[i] for m, i in enumerate(team)), default=0.0))

    # ------------------------------------------------------------------ motions
    def _new_episode(self, ed: _Edit) -> int:
        ed.episode += 1
        return ed.episode

    def _start_point_world(self, ed: _Edit, t: float, X: np.ndarray, op: PlacedOp, *, entity: int, team: tuple,
                           radius: float, src: int, dst: int, plant: str, controller: str, offsets=()) -> Motion:
        start, goal = X[entity, :2].copy(), np.asarray(op.goal, dtype=float)
        offsets = tuple(map(tuple, np.asarray(offsets, dtype=float).reshape(-1, 2)))
        limit = self._limit(float(np.hypot(*(goal - start))))
        corridor = None
        if self.execution is Execution.CONCURRENT:
            corridor = ed.grants.pop(ed.active.uid, None)
            if corridor is None:
                return None
        m = Motion(op.kind, entity, team, controller, plant, src, dst, radius, tuple(start), tuple(goal), t, limit,
                   self._new_episode(ed), None, offsets=offsets, corridor=corridor)
        self._unfreeze(ed, plant)
        return self._exit(ed, X, m) or self._point_world(ed, X, m)

    def _exit(self, ed: _Edit, X: np.ndarray, m: Motion) -> Motion | None:
        """Exit legs of the local law in the source region's approach disk to the nearest point the margin
        clear of every other entity, when the start is nearer than that to one (None: not needed, or no path;
        the point-world law then starts where the entity is)."""
        ring = self._ring(m, m.src)
        c, R, centers, radii = self._motion_world(X, m, m.src, ring)
        x = X[m.entity, :2]
        if not len(centers) or np.min(np.linalg.norm(centers - x, axis=1) - radii) >= self.margin:
            return None
        try:
            legs = exit_path(x, centers, radii, c, R, self.margin, toward=np.asarray(m.goal))
        except ValueError:
            return None
        m = replace(m, legs=tuple(map(tuple, legs)), leg=0, extra=ring, exiting=True)
        ed.tasks[m.controller] = TaskCommand(self._leg_task(X, m), m.episode)
        return m

    def _point_world(self, ed: _Edit, X: np.ndarray, m: Motion) -> Motion:
        """The point-world law from where the entity is (same episode: the estimates carry over); a start that
        maps outside the circle barrier ρ₀ (a spacing from an entity whose grown disk merges with the walls lies
        in the outer boundary's band) first departs on local legs inside the source region to the nearest point
        that maps inside it (:func:`~mrodrake.control.tasks.departure_point`), once."""
        entity, team = m.entity, m.team
        movers = {entity} | set(team)
        others = self._disks(X, movers)
        start, src = X[entity, :2].copy(), m.src
        name = self.entities[entity]
        try:
            free = self._motion_free_space(ed, X, m, start, others)
            if free.polygon.wkb not in self._maps:  # built here: the worker starts on the next maps meanwhile
                self._prefetch(ed, X)
            pw = self._map(free)
            self._prefetch(ed, X)
            if not m.departed and not inside_circle(pw, start)[0]:
                c, R, centers, radii = self._motion_world(X, m, src, 0.0)
                point = departure_point(pw, free, centers, radii, c, R, self.dock_tol)
                if point is not None:  # reachable by a local path (departure_point checked it)
                    legs = local_path(start, point, centers, radii, c, R)
                    m = replace(m, legs=tuple(map(tuple, legs)), leg=0, extra=0.0, exiting=True, departed=True)
                    ed.tasks[m.controller] = TaskCommand(self._leg_task(X, m), m.episode)
                    return m
        except (UserError, ValueError) as exc:
            raise _Failure(f"{m.kind.value} of {name}: {str(exc).splitlines()[0]}") from None
        m = replace(m, others=tuple(others), world=(free, pw), legs=None, leg=0, extra=0.0, exiting=False)
        return self._map_task(ed, X, m, RESOLUTION)

    def _motion_free_space(self, ed: _Edit, X: np.ndarray, m: Motion, start: np.ndarray, others: list[Disk]):
        """F of motion ``m`` from ``start`` for its map.  In sequential execution first with the parked
        entities as :meth:`_map_disks` and the covering radius of :meth:`_map_radius`, plan data wherever the
        entities stopped within their tolerances (so :meth:`_prefetch` can build the map ahead); if that F
        does not hold the start and the goal, and always in concurrent execution (within the motion's
        corridor), with the actual disks ``others`` and radius."""
        goal = np.asarray(m.goal, dtype=float)
        if self.execution is Execution.SEQUENTIAL:
            try:
                return entity_free_space(self.scenario, self._map_radius(m.entity, m.team, m.radius), start, goal,
                                         m.src, m.dst, self._map_disks(X, {m.entity, *m.team},
                                                                       self._planned[ed.active.uid]))
            except UserError:
                pass
        confine = None if m.corridor is None else m.corridor.confine
        return entity_free_space(self.scenario, m.radius, start, goal, m.src, m.dst, others, confine=confine)

    def _prefetch(self, ed: _Edit, X: np.ndarray) -> None:
        """Ask the map worker (:mod:`mrodrake.control.mapworker`) for the maps of the run's next
        :data:`PREFETCH_AHEAD` navigations and transports, each on the free space :meth:`_motion_free_space`
        will give it if every entity that moves before it stops within its parking tolerance of its planned
        spot and docked members make a team radius no larger than planned (those parked now stay where they
        are).  A wrong guess costs a map nobody takes."""
        if not self.prefetch or self.execution is not Execution.SEQUENTIAL:
            return
        uid = ed.active.uid
        ahead = [u for u in range(uid + 1, len(self._ops)) if self._ops[u].kind in (OpKind.NAVIGATE, OpKind.TRANSPORT)]
        for nxt in ahead[:PREFETCH_AHEAD]:
            free = self._predicted_free_space(X, uid, nxt)
            if free is None or free.polygon.wkb in self._maps:
                continue
            try:
                self._maps[free.polygon.wkb] = map_worker().submit(free.polygon, MAP_OPTIONS)
            except OSError:  # no worker process on this machine: every map is built in the mission
                self.prefetch = False
                return
            self._trim_maps()

    def _predicted_free_space(self, X: np.ndarray, uid: int, nxt: int):
        """The free space of the motion ``nxt`` as :meth:`_motion_free_space` will make it, seen before
        primitive ``uid`` runs: the entities that move in between at their planned spots (None: no such F)."""
        op, planned = self._ops[nxt], self._planned[nxt]
        act = op.action
        if op.kind is OpKind.NAVIGATE:
            entity, team, radius = act.robot, (), float(self.radii[act.robot])
        else:
            entity, team = self.N + act.obj, tuple(act.team)
            radius = self._map_radius(entity, team, 0.0)
        at = X[:, :2].copy()
        for u in range(uid, nxt):
            moved = self._ops[u]
            for e in (moved.entity, *(moved.team if moved.entity >= self.N else ())):
                at[e] = planned[e]
        goal = np.asarray(op.goal, dtype=float)
        try:
            return entity_free_space(self.scenario, radius, goal, goal, act.src, act.dst,
                                     self._map_disks(at, {entity, *team}, planned))
        except UserError:
            return None

    def _map_task(self, ed: _Edit, X: np.ndarray, m: Motion, threshold: float) -> Motion:
        """The point-world law from where the entity is: on the map of the whole motion (``m.world``) if it
        resolves the entity's position and its goal (:func:`~mrodrake.control.windows.resolution` at least
        ``threshold``) and maps both inside its circle barrier ρ₀, else on the map of the window around the
        entity toward its waypoint (the map of the whole motion there when no window can be built; a threshold
        of 0 never windows).  A goal deep in a dead end that is narrow for the entity maps next to the unit
        circle, since the outer boundary runs once around it by arc length and the dead end gets a sliver of
        it (corridor map, a team's goal at the corridor's end: ‖χ‖ = 0.99887 > ρ₀ = 0.99523); on a window,
        whose boundary is tens of metres instead of hundreds, the same dead end gets a larger share.  Where no
        task can be built on the map of the whole motion either, the law runs on the window around the goal if
        there is one, else on a window whose grid path takes finer steps (a hall behind a door the team just fits
        through, which the map squeezes against its circle), else the motion fails."""
        free, pw = m.world
        x = X[m.entity, :2].copy()
        free = replace(free, start=x)
        if threshold > 0.0 and (np.min(resolution(pw, [x, m.goal])) < threshold
                                or not np.all(inside_circle(pw, [x, m.goal]))):
            windowed = self._window(ed, x, m, free)
            if windowed is not None:
                return windowed
        name = self.entities[m.entity]
        try:
            task = build_task(self.scenario, free, max(1, len(m.team)), label=f"{name} {m.kind.value}", pw_map=pw)
        except (UserError, ValueError) as exc:
            windowed = (self._window(ed, x, m, free, around_goal=True)
                        or self._window(ed, x, m, free, halvings=GRID_HALVINGS))
            if windowed is not None:
                return windowed
            raise _Failure(f"{m.kind.value} of {name}: {str(exc).splitlines()[0]}") from None
        ed.tasks[m.controller] = TaskCommand(task, m.episode)
        return replace(m, task=task, free=free, waypoint=None, spans=(*m.spans, (ed.t, free)),
                       anchor=(ed.t, float(x[0]), float(x[1])))

    def _window(self, ed: _Edit, x: np.ndarray, m: Motion, free, around_goal: bool = False,
                halvings: int = 0) -> Motion | None:
        """The law on the map of the window around ``x`` toward its waypoint, or (``around_goal``) on the map of
        the window around the goal (:func:`~mrodrake.control.windows.goal_window_free_space`: a goal in a pocket
        that is narrow for the entity, between parked entities and a wall, which neither the map of the whole
        motion nor any window around the entity maps inside its circle barrier; lab, a team arriving next to two
        parked robots: ‖χ_d‖ = 0.99935 > ρ₀ = 0.99556); None without a window."""
        try:
            if around_goal:
                window, pw = goal_window_free_space(free, x, m.goal)
            else:
                window, pw = window_free_space(free, x, grid_path(free.polygon, x, m.goal, halvings=halvings),
                                               radius=m.window_radius)
            task = build_task(self.scenario, window, max(1, len(m.team)),
                              label=f"{self.entities[m.entity]} {m.kind.value} {'goal ' * around_goal}window",
                              pw_map=pw)
        except (UserError, ValueError):
            return None
        ed.tasks[m.controller] = TaskCommand(task, m.episode)
        return replace(m, task=task, free=window, waypoint=tuple(map(float, window.goal)),
                       spans=(*m.spans, (ed.t, window)), anchor=(ed.t, float(x[0]), float(x[1])))

    def _next_window(self, ed: _Edit, X: np.ndarray, m: Motion) -> Motion:
        """Near the waypoint of its window a motion moves on to the next window (never back to the map of the
        whole motion, which drove it into the unresolved part again: warehouse aisle 2, a navigation cycled
        between both for 1 750 s); on the map of the whole motion it moves to a window when it is slower than
        :data:`~mrodrake.control.windows.STALL_SPEED` where that map does not resolve its position, or at any
        speed where the resolution falls below :data:`~mrodrake.control.windows.RESOLUTION_FLOOR`.  On either
        map, a motion that has stalled (:func:`~mrodrake.control.windows.progress`) moves to a smaller window
        (:meth:`_unstall`).  A window whose waypoint is nearer than twice WINDOW_SWITCH (a small window, a
        waypoint short of a pocket) is left halfway to it, not at the next tick.  A motion left on the map of the
        whole motion because no window could be built there (``world`` cleared) fails when it stalls: nothing
        else would move it on (in a channel narrower than its map resolves, the integrator otherwise rejects
        step after step until the map degenerates there)."""
        if m.kind not in (OpKind.NAVIGATE, OpKind.TRANSPORT) or m.legs is not None or not (m.world or m.anchor):
            return m
        x = X[m.entity, :2]
        goal = m.goal if m.waypoint is None else m.waypoint
        anchor, stalled = progress(m.anchor, ed.t, x, goal, self.stall_period, self.goal_tol)
        if stalled and not self._arrived(X, m):
            if not m.world:
                raise _Failure(f"{m.kind.value} of {self.entities[m.entity]}: stalled at ({x[0]:.3f}, {x[1]:.3f}), "
                               f"{math.hypot(*(np.asarray(m.goal) - x)):.2f} m from its goal, where neither its map "
                               f"nor a window around it resolves its position")
            return self._unstall(ed, X, m)
        if anchor is not m.anchor:
            m = replace(m, anchor=anchor)
        if not m.world:
            return m
        if m.waypoint is None:
            res = point_resolution(m.world[1], x)
            if res >= RESOLUTION or (math.hypot(*X[m.entity, 2:]) >= STALL_SPEED and res >= RESOLUTION_FLOOR):
                return m
            return self._window(ed, x.copy(), m, replace(m.world[0], start=x.copy())) or replace(m, world=())
        wp = np.asarray(m.waypoint)
        switch = min(WINDOW_SWITCH, 0.5 * math.hypot(*(wp - np.asarray(m.free.start))))
        if math.hypot(*(x - wp)) > switch or np.allclose(m.waypoint, m.goal):
            return m
        return self._window(ed, x.copy(), m, replace(m.world[0], start=x.copy())) or self._map_task(ed, X, m, 0.0)

    def _unstall(self, ed: _Edit, X: np.ndarray, m: Motion) -> Motion:
        """A stalled motion (:func:`~mrodrake.control.windows.progress`) goes on in a window around the entity
        smaller than the map that held it: radius the motion's window radius, at most the farthest point of that
        map's free space from the entity, over :data:`~mrodrake.control.windows.WINDOW_GROWTH`, smaller again
        until the window's law leads on from where the entity is (its desired velocity would cover
        :data:`~mrodrake.control.windows.STALL_FRACTION` of the distance to the waypoint within a period); later
        windows of the motion keep that radius.  A window is a subset of F, so the law keeps its guarantees.
        Fails when no window of at least twice :data:`~mrodrake.control.windows.WINDOW_MARGIN` does."""
        x = X[m.entity, :2].copy()
        free = replace(m.world[0], start=x)
        radius = min(m.window_radius, _reach(m.free.polygon, x)) / WINDOW_GROWTH
        goal = np.asarray(m.goal if m.waypoint is None else m.waypoint)
        self._event(ed, "stall", ed.t, ed.active.step, action=self._op_text(ed.active.op),
                    entities=self.entities[m.entity],
                    detail=f"stalled at ({x[0]:.3f}, {x[1]:.3f}), {math.hypot(*(goal - x)):.2f} m from its goal: "
                           f"window of radius {radius:.2f} m or less")
        while radius >= 2.0 * WINDOW_MARGIN:
            windowed = self._window(ed, x, replace(m, window_radius=radius), free)
            if windowed is None:
                break
            ev = windowed.task.evaluate(x, np.zeros(2), 1.0, 0.0)
            ahead = math.hypot(*(np.asarray(windowed.waypoint) - x))
            if not ev.fault and math.hypot(*ev.v_d) * self.stall_period >= STALL_FRACTION * ahead:
                return windowed
            radius = _reach(windowed.free.polygon, x) / WINDOW_GROWTH
        raise _Failure(f"{m.kind.value} of {self.entities[m.entity]}: stalled at ({x[0]:.3f}, {x[1]:.3f}), "
                       f"{math.hypot(*(np.asarray(m.goal) - x)):.2f} m from its goal, and no window around it leads "
                       f"on")

    def _map(self, free):
        """The point-world map of ``free``: memoised over the last :data:`MAP_CACHE` free spaces (a departure
        restarts the law in the same free space, whose map then need not be solved again), or taken from the
        map worker if :meth:`_prefetch` asked for it (waiting for it; built here if the worker failed)."""
        key = free.polygon.wkb
        pw = self._maps.get(key)
        source = "cached"
        if isinstance(pw, Future):
            try:
                pw, source = pw.result(), "worker"
            except RuntimeError:
                pw = None
        if pw is None:
            pw, source = build_map(free), "built"
        self.map_sources[source] += 1
        self._maps[key] = pw
        self._maps.move_to_end(key)
        self._trim_maps()
        return pw

    def _trim_maps(self) -> None:
        while len(self._maps) > MAP_CACHE:
            self._maps.popitem(last=False)

    def _leg_task(self, X: np.ndarray, m: Motion):
        if m.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT):
            c, R, centers, radii = self._motion_world(X, m, m.src if m.exiting else m.dst, m.extra)
        else:
            c, R, centers, radii = self._local_world(X, m.entity, m.radius, m.src, m.team, m.extra)
        ctrl = self.scenario.control
        # a team of n robots and its object has n + 1 bodies whose friction bounds add up (α_A = Σ α):
        # k_v_local per body keeps the velocity loop damped (tests/control/test_local.py)
        gains = replace(AdaptiveGains.from_scenario(ctrl), k_v=ctrl.k_v_local * (1 + len(m.team)))
        try:
            return local_task(m.legs[m.leg], centers, radii, c, R, gains, k1=ctrl.k1_local, k2=ctrl.k2,
                              start=X[m.entity, :2], cf=max(1, len(m.team)),
                              label=f"{self.entities[m.entity]} {m.kind.value} leg {m.leg + 1}/{len(m.legs)}")
        except ValueError as exc:
            raise _Failure(f"{m.kind.value} of {self.entities[m.entity]}: {exc}") from None

    def _start_local(self, ed: _Edit, t: float, X: np.ndarray, op: PlacedOp, *, entity: int, team: tuple,
                     radius: float, plant: str, controller: str, goal: np.ndarray, offsets=()) -> Motion:
        """A local motion of ``entity`` (a robot, or a team's object) inside the region of ``op`` to ``goal``."""
        k = op.region
        c, R, centers, radii = self._local_world(X, entity, radius, k, team)
        try:
            if op.kind in (OpKind.ROOM, OpKind.RELEASE):  # planned points: others end within GOAL_TOL of theirs
                goal = clear_goal(goal, centers, radii, c, R, 2.0 * GOAL_TOL)
            legs = local_path(X[entity, :2], goal, centers, radii, c, R, narrow=LOCAL_NARROW)
        except ValueError as exc:
            raise _Failure(f"{self._op_text(op)}: {exc}") from None
        start = X[entity, :2].copy()
        length = float(np.sum(np.linalg.norm(np.diff(np.vstack([start, legs]), axis=0), axis=1)))
        ep = self._new_episode(ed)
        m = Motion(op.kind, entity, team, controller, plant, k, k, radius, tuple(start), tuple(map(float, goal)), t,
                   self._limit(length), ep, None, None, tuple(self._disks(X, {entity, *team})),
                   tuple(map(tuple, np.asarray(offsets, dtype=float).reshape(-1, 2))),
                   tuple(map(tuple, legs)), 0, True)
        task = self._leg_task(X, m)
        ed.tasks[controller] = TaskCommand(task, ep)
        self._unfreeze(ed, plant)
        return replace(m, task=task)

    def _settle(self, ed: _Edit, X: np.ndarray, m: Motion) -> Motion:
        """Inside the approach disk of its target region a navigation or transport finishes with the local law
        (same episode: the estimates carry over).  Without a local path the point-world law carries on."""
        if m.kind not in (OpKind.NAVIGATE, OpKind.TRANSPORT) or m.legs is not None or m.settle_tried:
            return m
        k, x = m.dst, X[m.entity, :2]
        ring = self._ring(m, k)
        c, R = self._motion_rim(m, k, ring)
        depth = R - math.hypot(*(x - c))
        slow = math.hypot(*X[m.entity, 2:]) <= self.rest_speed
        if depth < SETTLE_DEPTH and not (slow and depth >= 0.1 * SETTLE_DEPTH):
            return m
        c, R, centers, radii = self._motion_world(X, m, k, ring)
        try:
            legs = local_path(x, np.asarray(m.goal), centers, radii, c, R)
        except ValueError:
            return replace(m, settle_tried=True)
        m = replace(m, legs=tuple(map(tuple, legs)), leg=0, settle_tried=True, extra=ring)
        ed.tasks[m.controller] = TaskCommand(self._leg_task(X, m), m.episode)
        return m

    def _next_leg(self, ed: _Edit, X: np.ndarray, m: Motion) -> Motion:
        if m.legs is None:
            return m
        if math.hypot(*(X[m.entity, :2] - np.asarray(m.legs[m.leg]))) > LEG_TOL:
            return m
        if m.exiting and m.leg >= len(m.legs) - 1:
            return self._point_world(ed, X, m)
        if m.leg >= len(m.legs) - 1:
            return m
        m = replace(m, leg=m.leg + 1)
        task = self._leg_task(X, m)
        ed.tasks[m.controller] = TaskCommand(task, m.episode)
        return m if m.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT) else replace(m, task=task)

    def _arrived(self, X: np.ndarray, m: Motion) -> bool:
        """At rest on the last leg and near the goal (local motions within dock_tol; navigations and
        transports within goal_tol, or, when no local path finished them, inside the target region with half
        the layout spacing to spare).  A navigation or transport has also arrived only with its whole ball
        (radius ``m.radius``: a team's from its members' actual offsets) inside the target region, so that
        the executed state is the planned one: a goal within goal_tol of the region's rim is not enough (a
        team goal keeps half the spacing to the rim for the nominal covering radius, and docked members are
        up to dock_tol off their slots; the goal is still inside since dock_tol < half the spacing)."""
        x, v = X[m.entity, :2], X[m.entity, 2:]
        if math.hypot(*v) > self.rest_speed:
            return False
        if m.exiting or (m.legs is not None and m.leg < len(m.legs) - 1):
            return False
        to_goal = math.hypot(*(x - np.asarray(m.goal)))
        if m.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT):
            depth = self.region_radii[m.dst] - math.hypot(*(x - self.centers[m.dst])) - m.radius
            if depth < 0.0:
                return False
            return to_goal <= self.goal_tol or (m.legs is None and depth >= 0.5 * self.scenario.layout.spacing)
        return to_goal <= self.dock_tol

    def _wait(self, ed: _Edit, t: float, X: np.ndarray, a: Active) -> bool:
        """Progress the motion of ``a``; True once it has arrived (then parked and recorded)."""
        m = self._next_leg(ed, X, self._settle(ed, X, self._next_window(ed, X, a.motion)))
        if m is not a.motion:
            ed.active = replace(a, motion=m)
        if self._arrived(X, m):
            ed.tasks[m.controller] = None
            self._sync(ed, m.plant, X[m.entity, :2], (0.0, 0.0), True)
            ed.primitives.append(PrimitiveRecord(
                m.kind.value, self.entities[m.entity], tuple(self.robots[i] for i in m.team), m.src, m.dst, m.radius,
                np.asarray(m.start), np.asarray(m.goal), m.others, m.free, m.task, m.controller,
                np.asarray(m.offsets).reshape(-1, 2), m.t_start, t, m.spans))
            return True
        if t - m.t_start > m.limit:
            raise _Failure(f"{m.kind.value} of {self.entities[m.entity]}: time limit {m.limit:.0f} s exceeded")
        return False

    # ------------------------------------------------------------------ primitives
    def _run(self, ed: _Edit, t: float, X: np.ndarray) -> bool:
        """Progress the active primitive; True when it is complete."""
        a = ed.active
        handler = {OpKind.ROOM: self._room, OpKind.RELEASE: self._release, OpKind.GRASP: self._grasp,
                   OpKind.NAVIGATE: self._navigate, OpKind.TRANSPORT: self._transport}[a.op.kind]
        done = handler(ed, t, X, a)
        if done:
            self._primitive_event(ed, t)
        return done

    def _room(self, ed: _Edit, t: float, X: np.ndarray, a: Active) -> bool:
        op = a.op
        if a.phase is Phase.START:
            if op.entity < self.N:
                m = self._start_local(ed, t, X, op, entity=op.entity, team=(), radius=float(self.radii[op.entity]),
                                      plant=self.robots[op.entity], controller=f"nav_{self.robots[op.entity]}",
                                      goal=np.asarray(op.goal))
                ed.active = replace(a, phase=Phase.MOVING, motion=m)
                return False
            j = op.entity - self.N
            if not self._engage(ed, X, j, op.team):
                ed.active = replace(a, phase=Phase.ENGAGE)
                return False
            a = ed.active = replace(a, phase=Phase.ENGAGE)
        if a.phase is Phase.ENGAGE:
            j = op.entity - self.N
            self._route(ed, j, op.team)
            name = self.team_name(j, op.team)
            offsets = np.asarray(ed.syncs[name].offsets, dtype=float)
            m = self._start_local(ed, t, X, op, entity=op.entity, team=op.team,
                                  radius=self._team_radius(op.team, offsets, j), plant=name,
                                  controller=name + "_ctrl", goal=np.asarray(op.goal), offsets=offsets)
            ed.active = replace(a, phase=Phase.MOVING, motion=m)
            return False
        return self._wait(ed, t, X, a)

    def _moving(self, a: Active, m: Motion, t: float) -> Active:
        """``a`` with its motion started at t (concurrent execution: a primitive's time starts when its motion
        got its corridor, not while it waited for one)."""
        t0 = t if self.execution is Execution.CONCURRENT else a.t0
        return replace(a, phase=Phase.MOVING, motion=m, t0=t0)

    def _engage(self, ed: _Edit, X: np.ndarray, j: int, team: tuple) -> bool:
        """Couple object j and ``team`` to their team plant (synced to the object with the members' actual
        offsets, so nothing jumps); True if it already was coupled."""
        name = self.team_name(j, team)
        if ed.engaged.get(j) == name:
            return True
        if ed.engaged.get(j) is not None:
            raise _Failure(f"{self.objects[j]}: still coupled to another team")
        xo = X[self.N + j, :2]
        self._sync(ed, name, xo, (0.0, 0.0), True, [X[i, :2] - xo for i in team])
        return False

    def _route(self, ed: _Edit, j: int, team: tuple) -> None:
        name = self.team_name(j, team)
        ed.engaged[j] = name
        for e in (self.N + j, *team):
            ed.coupled[e] = name

    def _release(self, ed: _Edit, t: float, X: np.ndarray, a: Active) -> bool:
        op, act = a.op, a.op.action
        j, i = act.obj, act.robot
        if a.phase is Phase.START:
            if i in ed.grasp_open:
                ed.grasps.append((ed.grasp_open.pop(i), t, self.robots[i], self.objects[j]))
            ed.docked.pop(i, None)
            name = ed.engaged.get(j)
            if name is not None:  # hand the coupled state back to the object and member plants
                self._sync(ed, self.objects[j], X[self.N + j, :2])
                for r in next(team for jj, team in self.couplings if self.team_name(jj, team) == name):
                    self._sync(ed, self.robots[r], X[r, :2])
                a = ed.active = replace(a, phase=Phase.DISENGAGE)
                return False
            a = ed.active = replace(a, phase=Phase.DISENGAGE)
        if a.phase is Phase.DISENGAGE:
            name = ed.engaged.pop(j, None)
            if name is not None:
                for e in [e for e, n in ed.coupled.items() if n == name]:
                    ed.coupled.pop(e)
            m = self._start_local(ed, t, X, op, entity=i, team=(), radius=float(self.radii[i]), plant=self.robots[i],
                                  controller=f"nav_{self.robots[i]}", goal=np.asarray(op.goal))
            ed.active = replace(a, phase=Phase.MOVING, motion=m)
            return False
        return self._wait(ed, t, X, a)

    def _grasp(self, ed: _Edit, t: float, X: np.ndarray, a: Active) -> bool:
        op, act = a.op, a.op.action
        i, j = act.robot, act.obj
        if a.phase is Phase.START:
            slot = layout_slots(self.ts, j, op.team, X[self.N + j, :2], op.rotation)[op.team.index(i)]
            m = self._start_local(ed, t, X, op, entity=i, team=(), radius=float(self.radii[i]), plant=self.robots[i],
                                  controller=f"nav_{self.robots[i]}", goal=slot)
            ed.active = replace(a, phase=Phase.MOVING, motion=m)
            return False
        if self._wait(ed, t, X, a):
            ed.docked[i] = j
            ed.grasp_open[i] = t
            return True
        return False

    def _navigate(self, ed: _Edit, t: float, X: np.ndarray, a: Active) -> bool:
        op, act = a.op, a.op.action
        if a.phase is Phase.START:
            if a.tried == ed.corridors:
                return False
            r = act.robot
            m = self._start_point_world(ed, t, X, op, entity=r, team=(), radius=float(self.radii[r]), src=act.src,
                                        dst=act.dst, plant=self.robots[r], controller=f"nav_{self.robots[r]}")
            ed.active = a if m is None else self._moving(a, m, t)
            return False
        return self._wait(ed, t, X, a)

    def _transport(self, ed: _Edit, t: float, X: np.ndarray, a: Active) -> bool:
        op, act = a.op, a.op.action
        j, team = act.obj, tuple(act.team)
        if a.phase is Phase.START:
            if not self._engage(ed, X, j, team):
                ed.active = replace(a, phase=Phase.ENGAGE)
                return False
            a = ed.active = replace(a, phase=Phase.ENGAGE)
        if a.phase is Phase.ENGAGE:
            if a.tried == ed.corridors:
                return False
            self._route(ed, j, team)
            name = self.team_name(j, team)
            offsets = np.asarray(ed.syncs[name].offsets, dtype=float)
            m = self._start_point_world(ed, t, X, op, entity=self.N + j, team=team,
                                        radius=self._team_radius(team, offsets, j), src=act.src, dst=act.dst,
                                        plant=name, controller=name + "_ctrl", offsets=offsets)
            ed.active = a if m is None else self._moving(a, m, t)
            return False
        return self._wait(ed, t, X, a)


def _reach(poly, x: np.ndarray) -> float:
    """Distance from x to the farthest vertex of the outer boundary of ``poly``."""
    return float(np.max(np.linalg.norm(np.asarray(poly.exterior.coords) - x, axis=1)))


def couplings_of(plan) -> list[tuple[int, tuple[int, ...]]]:
    """The (object, team) pairs of a plan's transports, in order of first use."""
    out: list[tuple[int, tuple[int, ...]]] = []
    for acts in plan.actions:
        for a in acts:
            if isinstance(a, Transport) and (a.obj, tuple(a.team)) not in out:
                out.append((a.obj, tuple(a.team)))
    return out
