"""Simulate one transition (navigation π_k →_i π_k' or transport π_k →T_{A,j} π_k', paper Sec. III-A) in Drake.

:func:`simulate_transition` builds the entity's free space F, its point-world map H and φ (a
:class:`~mrodrake.control.adaptive.NavigationTask`), wires one plant (``RobotPlant`` or ``CoupledPlant``) with
one controller (``NavigationController`` or ``TransportController``) and an :class:`ArrivalMonitor`, runs
the Simulator with error-controlled integrators (:func:`advance_with_stiffness_switch`: RK3, and implicit
Euler for the short stiff episodes where the entity slides along a barrier) and returns a
:class:`TransitionResult` with the logs (one row per integration step).  The monitor ends the run when the
entity's ball lies inside the target region and the entity is nearly at rest (periodic check,
``EventStatus.ReachedTermination``).

Reuse by a mission diagram: the plants, the controllers (tasks swappable per context through their ``task``
input, see :mod:`mrodrake.systems.controllers`), :class:`ArrivalMonitor`, :func:`build_task`,
:func:`entity_layout` and :func:`advance_with_stiffness_switch` are independent of this builder.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
from pydrake.systems.framework import DiagramBuilder, EventStatus, LeafSystem
from pydrake.systems.primitives import LogVectorOutput, Multiplexer

from mrodrake.control.adaptive import NavigationTask
from mrodrake.control.freespace import Disk, EntityFreeSpace, entity_free_space, goal_point, region_index
from mrodrake.control.tasks import build_task, entity_layout
from mrodrake.errors import UserError
from mrodrake.geometry import grasp_layout
from mrodrake.scenario import Scenario
from mrodrake.systems.controllers import NavigationController, TransportController
from mrodrake.systems.plants import CoupledPlant, RobotPlant

#: Default speed (m/s) under which an entity inside its target region counts as at rest.
REST_SPEED = 0.05


class ArrivalMonitor(LeafSystem):
    """Ends a simulation when B̄(x, radius) ⊂ B̄(center, region_radius) and ‖ẋ‖ ≤ rest_speed.

    Input ``state`` [x, ẋ]; a periodic publish event (every ``period`` s) returns
    ``EventStatus.ReachedTermination`` on arrival and ``EventStatus.Failed`` on a non-finite state.
    """

    def __init__(self, center, region_radius: float, radius: float, rest_speed: float = REST_SPEED,
                 period: float = 0.5, name: str = "arrival_monitor"):
        super().__init__()
        self.set_name(name)
        self.center = np.asarray(center, dtype=float)
        self.slack = float(region_radius) - float(radius)
        self.rest_speed = float(rest_speed)
        self.state_port = self.DeclareVectorInputPort("state", 4)
        self.DeclarePeriodicPublishEvent(float(period), 0.0, self._Check)

    def arrived(self, state: np.ndarray) -> bool:
        """Whether ``state`` = [x, ẋ] is an arrival (ball inside the region, speed ≤ rest_speed)."""
        return bool(math.hypot(*(state[:2] - self.center)) <= self.slack and math.hypot(*state[2:]) <= self.rest_speed)

    def _Check(self, context):
        s = self.state_port.Eval(context)
        if not np.all(np.isfinite(s)):
            return EventStatus.Failed(self, f"non-finite entity state {s.tolist()}")
        if self.arrived(s):
            return EventStatus.ReachedTermination(self, "entity at rest inside the target region")
        return EventStatus.DidNothing()


@dataclass
class TransitionResult:
    """Outcome and logs of one simulated transition.

    ``log``: one row per integration step with columns t, x, y, vx, vy (entity state), ux, uy (entity
    input u; a team member's input is cf_ℓ u, see :meth:`member_input`), m_hat, alpha_hat.
    """

    scenario: Scenario
    kind: str
    entity: str
    team: list[str]
    src: int
    dst: int
    radius: float
    start: np.ndarray
    goal: np.ndarray
    others: list[Disk]
    free: EntityFreeSpace
    task: NavigationTask
    log: pd.DataFrame
    reached: bool
    status: str
    t_final: float
    offsets: np.ndarray
    true_params: dict = field(default_factory=dict)
    map_seconds: float = 0.0
    sim_seconds: float = 0.0
    steps: int = 0
    implicit_seconds: float = 0.0

    @property
    def positions(self) -> np.ndarray:
        return self.log[["x", "y"]].to_numpy()

    @property
    def velocities(self) -> np.ndarray:
        return self.log[["vx", "vy"]].to_numpy()

    @property
    def inputs(self) -> np.ndarray:
        return self.log[["ux", "uy"]].to_numpy()

    def member_input(self, member: str) -> np.ndarray:
        """u_ℓ(t) = cf_ℓ u(t) of a team member (n, 2)."""
        return self.task.cf[self.team.index(member)] * self.inputs

    def member_positions(self, member: str) -> np.ndarray:
        """x_ℓ(t) = x^o(t) + offset_ℓ of a team member (n, 2)."""
        return self.positions + self.offsets[self.team.index(member)]

    def point_world(self) -> np.ndarray:
        """χ(t) = H(x(t)) (n, 2)."""
        return self.task.pw_map(self.positions)

    @property
    def wall_seconds(self) -> float:
        return self.map_seconds + self.sim_seconds


@dataclass
class RunStatus:
    """Outcome of :func:`advance_with_stiffness_switch`: reached (a termination event fired), message,
    simulated time spent with the implicit integrator, number of switches to it."""

    reached: bool
    message: str
    implicit_seconds: float = 0.0
    switches: int = 0


#: Target accuracy of the implicit-Euler spans of :func:`advance_with_stiffness_switch`.
IMPLICIT_ACCURACY = 1e-3


def advance_with_stiffness_switch(sim: Simulator, t_final: float, *, accuracy: float = 1e-4, max_step: float = 2.0,
                                  explicit: str = "runge_kutta3", implicit: str = "implicit_euler",
                                  window: int = 100, min_step: float = 1e-3, implicit_span: float = 2.0,
                                  implicit_accuracy: float = IMPLICIT_ACCURACY, fault=None) -> RunStatus:
    """Advance ``sim`` to ``t_final`` with an explicit error-controlled integrator, switching to an implicit
    one for ``implicit_span`` simulated seconds whenever the last ``window`` steps averaged less than
    ``min_step`` (stiffness).

    Why: with the tiny barrier regions τ forced by the point world (Prop. 1), an entity that slides along a
    barrier's edge sees a stiff, smooth vector field (∇²φ ~ k2/τ); explicit RK3 then needs ~1e-4 s steps
    (thousands per simulated second) while implicit Euler takes ~0.1 s steps.  Elsewhere RK3 is several
    times cheaper per simulated second.  Ends early (``reached``) when a termination event fires; a
    failure event, a controller fault (``fault(context)`` non-empty after a step) or an integrator error gives
    ``reached=False`` with its message.
    """
    times: deque[float] = deque(maxlen=window + 1)
    mode = {"stiff": False, "fault": ""}
    diagram = sim.get_system()

    def watch(context):
        why = fault(context) if fault is not None else ""
        if why:
            mode["fault"] = why
            return EventStatus.ReachedTermination(diagram, why)
        if mode["stiff"]:
            return EventStatus.DidNothing()
        times.append(context.get_time())
        if len(times) > window:
            if times[-1] - times[0] < window * min_step:
                mode["stiff"] = True
                return EventStatus.ReachedTermination(diagram, "stiff")
        return EventStatus.DidNothing()

    def use(scheme: str, acc: float) -> None:
        integ = ResetIntegratorFromFlags(sim, scheme, max_step)
        integ.set_target_accuracy(acc)
        integ.set_fixed_step_mode(False)
        integ.Initialize()

    use(explicit, accuracy)
    sim.set_monitor(watch)
    sim.Initialize()
    implicit_time, switches = 0.0, 0
    context = sim.get_context()
    try:
        while True:
            t0 = context.get_time()
            if mode["stiff"]:
                status = sim.AdvanceTo(min(t_final, t0 + implicit_span))
                implicit_time += context.get_time() - t0
                if mode["fault"]:
                    return RunStatus(False, f"controller fault: {mode['fault']}", implicit_time, switches)
                if status.reason() == status.ReturnReason.kReachedTerminationCondition:
                    return RunStatus(True, status.message(), implicit_time, switches)
                if context.get_time() >= t_final:
                    return RunStatus(False, "t_max reached", implicit_time, switches)
                mode["stiff"] = False
                times.clear()
                use(explicit, accuracy)
                continue
            status = sim.AdvanceTo(t_final)
            if mode["fault"]:
                return RunStatus(False, f"controller fault: {mode['fault']}", implicit_time, switches)
            if status.reason() != status.ReturnReason.kReachedTerminationCondition:
                return RunStatus(False, "t_max reached", implicit_time, switches)
            if not mode["stiff"]:
                return RunStatus(True, status.message(), implicit_time, switches)
            switches += 1
            use(implicit, implicit_accuracy)
    except RuntimeError as exc:
        return RunStatus(False, f"simulation failed: {str(exc).splitlines()[0]}", implicit_time, switches)
    finally:
        sim.clear_monitor()


def _check_names(scenario: Scenario, kind: str, entity: str, team: Sequence[str]) -> None:
    if kind == "navigate":
        if entity not in scenario.robot_names:
            raise UserError(f"entity '{entity}': not a robot (robots: {', '.join(scenario.robot_names)})")
        if team:
            raise UserError("team: a navigation has no team (use kind='transport')")
    elif kind == "transport":
        if entity not in scenario.object_names:
            raise UserError(f"entity '{entity}': not an object (objects: {', '.join(scenario.object_names)})")
        if not team:
            raise UserError("team: a transport needs at least one robot")
        for r in team:
            if r not in scenario.robot_names:
                raise UserError(f"team: '{r}' is not a robot")
        if len(set(team)) != len(team):
            raise UserError(f"team: duplicate robots in {list(team)}")
    else:
        raise UserError(f"kind '{kind}': expected 'navigate' or 'transport'")


def simulate_transition(
    scenario: Scenario,
    kind: str = "navigate",
    entity: str = "",
    team: Sequence[str] = (),
    src_region: int | str = 0,
    dst_region: int | str = 1,
    others: Sequence[Disk] | None = None,
    true_params_override: Mapping[str, Mapping[str, float]] | None = None,
    t_max: float = 3000.0,
    seed: int = 0,
    start=None,
    goal=None,
    cf: Sequence[float] | None = None,
    accuracy: float = 1e-4,
    integrator: str = "runge_kutta3",
    max_step: float = 2.0,
    rest_speed: float = REST_SPEED,
    check_period: float = 0.5,
) -> TransitionResult:
    """Simulate one navigation (``entity`` a robot) or transport (``entity`` an object grasped by ``team``)
    from ``src_region`` to ``dst_region``.

    ``others``: the other entities as static disks (default: :func:`entity_layout` of every other entity in
    its initial region, packed together with the moving entity's start in ``src_region`` and its goal spot
    in ``dst_region``, which is then the default goal); ``start``: the entity's initial centre (default: its
    P_s spot in the source region); ``goal``: x_d (default with given ``others``: P_s given the entities
    already in the target region, :func:`~mrodrake.control.freespace.goal_point`, with ``seed``).
    ``true_params_override``: {body name: {"mass"|"scale"|"frequency": value}} changes the plant's true
    parameters (never the controller's).  Integration: Drake's error-controlled RK3 with ``accuracy``.
    """
    team = list(team)
    _check_names(scenario, kind, entity, team)
    src, dst = region_index(scenario, src_region), region_index(scenario, dst_region)
    if src == dst:
        raise UserError(f"dst_region '{scenario.regions[dst].name}': same as the source region")
    bodies = [entity] + team
    for name, over in (true_params_override or {}).items():
        if name not in bodies:
            raise UserError(f"true_params_override.{name}: not a body of this transition ({', '.join(bodies)})")
        unknown = set(over) - {"mass", "scale", "frequency"}
        if unknown:
            raise UserError(f"true_params_override.{name}: unknown keys {sorted(unknown)}")
    if kind == "navigate":
        radius = scenario.robots[scenario.robot_names.index(entity)].radius
        offsets = np.zeros((0, 2))
    else:
        o = scenario.objects[scenario.object_names.index(entity)]
        layout = grasp_layout(o.radius, [scenario.robots[scenario.robot_names.index(r)].radius for r in team],
                              scenario.layout.grasp_gap)
        radius, offsets = layout.covering_radius, layout.offsets
    if others is None or start is None:
        teams = {entity: team} if kind == "transport" else {}
        spot = f"{entity}@goal"
        placed = entity_layout(scenario, {entity: src}, teams, seed=seed,
                               reserve={dst: [(spot, radius)]} if goal is None and others is None else None)
        if start is None:
            start = placed[entity].center
        if others is None:
            others = [d for n, d in placed.items() if n not in (entity, spot)]
            if goal is None:
                goal = placed[spot].center
    others = [d for d in others if d.name != entity and d.name not in team]
    start = np.asarray(start, dtype=float).reshape(2)
    if goal is None:
        dst_reg = scenario.regions[dst]
        occupants = [d for d in others
                     if math.hypot(d.center[0] - dst_reg.center[0], d.center[1] - dst_reg.center[1]) < dst_reg.radius]
        goal = goal_point(scenario, dst, radius, occupants, seed=seed)
    goal = np.asarray(goal, dtype=float).reshape(2)

    t0 = time.perf_counter()
    free = entity_free_space(scenario, radius, start, goal, src, dst, others)
    label = f"{entity}: {scenario.regions[src].name} -> {scenario.regions[dst].name}"
    task = build_task(scenario, free, max(1, len(team)), cf, label=label)
    map_seconds = time.perf_counter() - t0

    builder = DiagramBuilder()
    if kind == "navigate":
        plant = builder.AddSystem(RobotPlant.from_scenario(scenario, entity))
        ctrl = builder.AddSystem(NavigationController(task, name=f"{entity}_controller"))
        builder.Connect(ctrl.u_port, plant.u_port)
    else:
        plant = builder.AddSystem(CoupledPlant.from_scenario(scenario, entity, team, offsets))
        ctrl = builder.AddSystem(TransportController(team, task, name=f"{entity}_team_controller"))
        for u_out, u_in in zip(ctrl.member_u_ports, plant.u_ports):
            builder.Connect(u_out, u_in)
    builder.Connect(plant.state_port, ctrl.state_port)
    reg = scenario.regions[dst]
    monitor = builder.AddSystem(ArrivalMonitor(reg.center, reg.radius, radius, rest_speed, check_period))
    builder.Connect(plant.state_port, monitor.state_port)
    mux = builder.AddSystem(Multiplexer([4, 2, 2]))
    builder.Connect(plant.state_port, mux.get_input_port(0))
    builder.Connect(ctrl.estimates_port, mux.get_input_port(1))
    builder.Connect(ctrl.u_port, mux.get_input_port(2))
    logger = LogVectorOutput(mux.get_output_port(0), builder, publish_period=0.0)
    diagram = builder.Build()

    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    pctx = plant.GetMyMutableContextFromRoot(ctx)
    plant.set_state(pctx, start, (0.0, 0.0))
    true_params = {}
    for b, name in enumerate(bodies):
        plant.set_body_parameters(pctx, b, **dict((true_params_override or {}).get(name, {})))
        m, sc, fq = plant.body_parameters(pctx, b)
        true_params[name] = {"mass": m, "scale": sc, "frequency": fq}

    t1 = time.perf_counter()
    run = advance_with_stiffness_switch(sim, float(t_max), accuracy=accuracy, max_step=max_step,
                                        explicit=integrator,
                                        fault=lambda c: ctrl.fault(ctrl.GetMyContextFromRoot(c)))
    sim_seconds = time.perf_counter() - t1
    data = logger.FindLog(ctx)
    t = data.sample_times()
    d = data.data()
    log = pd.DataFrame({"t": t, "x": d[0], "y": d[1], "vx": d[2], "vy": d[3], "m_hat": d[4], "alpha_hat": d[5],
                        "ux": d[6], "uy": d[7]})
    return TransitionResult(
        scenario=scenario, kind=kind, entity=entity, team=team, src=src, dst=dst, radius=float(radius),
        start=start, goal=goal, others=list(others), free=free, task=task, log=log, reached=run.reached,
        status=run.message, t_final=float(ctx.get_time()), offsets=np.asarray(offsets), true_params=true_params,
        map_seconds=map_seconds, sim_seconds=sim_seconds, steps=len(t), implicit_seconds=run.implicit_seconds,
    )
