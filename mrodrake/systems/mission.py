"""Mission execution in ONE Drake diagram (paper Sec. III-A, sequential execution of the plan).

:class:`Mission` places the whole executed run (:mod:`mrodrake.planning.placement`), builds the diagram with
the ``AddX`` helpers of :mod:`mrodrake.systems.builders` (plants, controllers, team plants, state switches,
the supervisor that carries the sequencer of :mod:`mrodrake.execution.sequencer`) and a :class:`MissionLogger`,
and advances the whole mission with one ``AdvanceTo``; the supervisor ends it.  Engaging a team syncs the
team plant to the object's state with the ACTUAL member offsets (robots stay where they docked: no jump);
releasing syncs the object and member plants to the team plant's outputs.  :class:`MissionLog` holds what was
recorded and writes the outputs (CSV logs, ``replay.html``, figures).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from pydrake.common.value import AbstractValue
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import DiagramBuilder, EventStatus, LeafSystem
from threadpoolctl import threadpool_limits

from mrodrake.control.adaptive import AdaptiveGains
from mrodrake.errors import UserError
from mrodrake.execution.schedule import Execution
from mrodrake.execution.sequencer import ExecState, Sequencer, Status, couplings_of
from mrodrake.planning.placement import place_run
from mrodrake.planning.plan import Plan, PlanVerificationError, task_nba, task_words
from mrodrake.planning.steps import expand_steps
from mrodrake.scenario import Scenario
from mrodrake.systems.builders import (
    AddControllers,
    AddEntityPlants,
    AddStateSwitches,
    AddSupervisor,
    teams_of,
)
from mrodrake.systems.transition import TransitionResult
from mrodrake.ts import TransitionSystem


# ------------------------------------------------------------------------------------------ logger
class MissionLogger(LeafSystem):
    """Samples every entity's routed [x, ẋ] and every active controller's u, m̂, α̂ every ``period`` s
    (periodic publish; the samples are kept in Python lists on this system, cleared by :meth:`clear`).

    ``controllers``: name -> (entity, members) in the controllers' order.  Inputs: ``states``, ``u`` and
    ``estimates`` (u and [m̂, α̂] of every controller in that order, 2 entries each) and ``tasks`` (every
    controller's :class:`~mrodrake.execution.commands.TaskCommand` by name, None while idle)."""

    def __init__(self, entities, controllers, period: float):
        super().__init__()
        self.set_name("mission_logger")
        self.entities = list(entities)
        self.controllers = dict(controllers)  # name -> (entity, members)
        n = len(self.controllers)
        self.states_port = self.DeclareVectorInputPort("states", 4 * len(self.entities))
        self.u_port = self.DeclareVectorInputPort("u", 2 * n)
        self.estimates_port = self.DeclareVectorInputPort("estimates", 2 * n)
        self.tasks_port = self.DeclareAbstractInputPort("tasks", AbstractValue.Make({}))
        self.DeclarePeriodicPublishEvent(float(period), 0.0, self.Sample)
        self.clear()

    def clear(self) -> None:
        self.times: list[float] = []
        self.states: list[np.ndarray] = []
        self.signals: list[tuple] = []

    def Sample(self, context):
        """Record one sample at the context's time (the periodic publish; also called once at an abort)."""
        t = float(context.get_time())
        if self.times and t <= self.times[-1]:
            return EventStatus.DidNothing()
        self.times.append(t)
        self.states.append(np.array(self.states_port.Eval(context)))
        tasks = self.tasks_port.Eval(context)
        u = est = None
        for q, (c, (entity, members)) in enumerate(self.controllers.items()):
            cmd = tasks.get(c)
            if cmd is None:
                continue
            if u is None:
                u, est = self.u_port.Eval(context).tolist(), self.estimates_port.Eval(context).tolist()
            u0, u1, m, a = u[2 * q], u[2 * q + 1], est[2 * q], est[2 * q + 1]
            self.signals.append((t, c, entity, u0, u1, m, a))
            for k, r in enumerate(members):
                self.signals.append((t, c, r, float(cmd.task.cf[k] * u0), float(cmd.task.cf[k] * u1), m, a))
        return EventStatus.Succeeded()


# ------------------------------------------------------------------------------------------ log
@dataclass
class MissionLog:
    """Everything recorded by a mission run (pandas DataFrames) and its outcome.

    ``trajectory``: t, entity, x, y, vx, vy (every robot and object, uniform sampling);
    ``signals``: t, controller, entity, ux, uy, m_hat, alpha_hat (active controllers; a transport has one
    row for the object (entity input u) and one per member (u_ℓ = cf_ℓ u));
    ``events``: kind (primitive / label / order / stall: a stalled motion moved to a smaller window), t_start,
    t_end, step, plan_step, action, entities, from_region, to_region, ok, propositions, nba_states, detail,
    time_limit (a primitive's motion bound, s);
    ``grasps``: t_start, t_end, robot, object (docked intervals, for the replay).
    """

    scenario: Scenario
    plan: object
    trajectory: pd.DataFrame
    signals: pd.DataFrame
    events: pd.DataFrame
    grasps: pd.DataFrame
    ok: bool
    message: str
    final_state: dict | None
    expected_final_state: dict
    steps_done: int
    steps_total: int
    sim_seconds: float
    wall_seconds: float
    primitives: list = field(default_factory=list)
    nba_run: list = field(default_factory=list)

    @property
    def primitive_events(self) -> pd.DataFrame:
        return self.events[self.events["kind"] == "primitive"]

    def summary(self) -> str:
        prim = self.primitive_events
        state = "ok" if self.ok else ("stopped" if self.message == "not finished" else "FAILED")
        return (f"{state}: {int(prim['ok'].sum())}/{len(prim)} primitives ok, "
                f"{self.steps_done}/{self.steps_total} plan steps, simulated {self.sim_seconds:.1f} s in "
                f"{self.wall_seconds:.1f} s wall" + ("" if self.ok else f" ({self.message})"))

    # ------------------------------------------------------------------ figures
    def transition_result(self, record):
        """A :class:`~mrodrake.systems.transition.TransitionResult` of one executed motion (for viz.figures)."""
        tr = self.trajectory
        seg = tr[(tr["entity"] == record.entity) & (tr["t"] >= record.t_start) & (tr["t"] <= record.t_end)]
        sig = self.signals[(self.signals["controller"] == record.controller)
                           & (self.signals["entity"] == record.entity)]
        log = seg[["t", "x", "y", "vx", "vy"]].merge(sig[["t", "ux", "uy", "m_hat", "alpha_hat"]], on="t",
                                                     how="inner").reset_index(drop=True)
        kind = "transport" if record.kind == "transport" else "navigate"
        return TransitionResult(scenario=self.scenario, kind=kind, entity=record.entity, team=list(record.team),
                                src=record.src, dst=record.dst, radius=record.radius, start=record.start,
                                goal=record.goal, others=list(record.others), free=record.free, task=record.task,
                                log=log, reached=True, status="", t_final=record.t_end, offsets=record.offsets)

# ------------------------------------------------------------------------------------------ mission
class Mission:
    """One Drake diagram executing ``plan`` (prefix + ``suffix_cycles`` suffix cycles) on ``scenario``.

    Before anything is built, the whole executed run is placed (:func:`~mrodrake.planning.placement.place_run`;
    a geometry that cannot be realised raises a one-line :class:`~mrodrake.planning.placement.PlacementError`
    naming the step and region).  The diagram (:mod:`mrodrake.systems.builders`): one
    :class:`~mrodrake.systems.plants.MissionPlants` system with a plant per robot and object and a team plant
    per (object, team) of the plan's transports, one :class:`~mrodrake.systems.controllers.MissionControllers`
    system with a navigation controller per robot and a transport controller per team plant, a state switch
    per entity, the :class:`~mrodrake.systems.supervisor.Supervisor` (the
    sequencer's ports) and a :class:`MissionLogger`.  ``prefetch``: the maps of the next motions are built by
    a map worker process on another core while the current one runs (the same mission either way; off where
    every core already runs a mission, as in campaigns).

    Integration: Drake's error-controlled RK3 with ``accuracy`` 3e-3.  Drake weights every state component
    by 1, so this bounds the local error per step to about 3 mm (m/s) on positions (velocities): over 30 times
    below the 0.1 m layout spacing and the 0.5 m margin to walls that the clearance tests check, while the
    closed loop corrects drift.  On case I, 1e-3 took 11 % more derivative evaluations and 1e-4 2.3x the steps,
    each for the same plan steps, simulated time (to 0.1 s) and smallest gap and clearance (to 0.1 mm).  Steps
    are capped at ``max_step`` = 0.25 s: half the supervisor and logger period, so every 0.5 s interval takes
    whole steps, and near RK3's real-axis stability limit 2.51/|λ| (|λ| up to 11 s⁻¹ for a team with α̂ at its
    design bound).  Uncapped, the step controller grew past that limit and 12.6 % of the attempted steps on
    case I were rejected (6.6 % capped: 6 % fewer derivative evaluations, the same outcome).
    """

    def __init__(self, scenario: Scenario, plan, suffix_cycles: int = 1, seed: int | None = None, *,
                 log_period: float = 0.5,
                 check_period: float = 0.5, accuracy: float = 3e-3, max_step: float = 0.25,
                 integrator: str = "runge_kutta3", rest_speed: float | None = None,
                 execution: Execution | str = Execution.SEQUENTIAL, prefetch: bool = True):
        if suffix_cycles < 0:
            raise UserError(f"--suffix-cycles: must be >= 0, got {suffix_cycles}")
        if plan.scenario != scenario.name:
            raise UserError(f"plan: made for scenario '{plan.scenario}', not '{scenario.name}'")
        placed = plan.stats.get("placement", {}) if plan.placement is not None else {}
        if seed is None:  # the plan's own layout
            seed = placed.get("seed", plan.seed if plan.seed is not None else 0)
        if int(seed) < 0:
            raise UserError(f"--seed: must be >= 0, got {seed}")
        self.scenario, self.plan, self.seed = scenario, plan, int(seed)
        self.ts = plan.ts if plan.ts is not None else TransitionSystem(scenario)
        self.formula, self.nba, self.words = task_words(scenario, self.ts)
        t0 = time.perf_counter()
        if placed.get("seed") == self.seed and placed.get("suffix_cycles") == suffix_cycles:
            self.placement = plan.placement  # the planner placed this very run (place_run is deterministic)
        else:
            with threadpool_limits(limits=1, user_api="blas"):  # as in run(): the same layout on every core count
                self.placement = place_run(self.ts, expand_steps(plan, suffix_cycles), seed=self.seed)
        self.placement_seconds = time.perf_counter() - t0
        kw = {} if rest_speed is None else {"rest_speed": rest_speed}
        self.execution = _execution(execution)
        self.sequencer = Sequencer(scenario, self.ts, self.words, self.placement, couplings_of(plan),
                                   execution=self.execution, prefetch=prefetch, **kw)

        b = DiagramBuilder()
        gains = AdaptiveGains.from_scenario(scenario.control)
        self.plants = AddEntityPlants(b, scenario, self.sequencer)
        self.teams = teams_of(scenario, self.sequencer)
        self.controllers = AddControllers(b, scenario, self.plants, self.teams, gains)
        self.switches = AddStateSwitches(b, scenario, self.plants, self.teams, self.controllers)
        self.supervisor = AddSupervisor(b, self.sequencer, self.plants, self.controllers, self.switches,
                                        check_period)
        entities = scenario.robot_names + scenario.object_names
        ctrl_info = {f"nav_{r}": (r, ()) for r in scenario.robot_names}
        ctrl_info.update({t.controller: (scenario.object_names[t.obj], t.members) for t in self.teams})
        self.logger = b.AddSystem(MissionLogger(entities, {c: ctrl_info[c] for c in self.controllers.names},
                                                log_period))
        b.Connect(self.switches.states_port, self.logger.states_port)
        b.Connect(self.controllers.u_port, self.logger.u_port)
        b.Connect(self.controllers.estimates_port, self.logger.estimates_port)
        b.Connect(self.supervisor.tasks_port, self.logger.tasks_port)
        self.diagram = b.Build()
        self.diagram.set_name("mission")

        self.simulator = Simulator(self.diagram)
        ApplySimulatorConfig(SimulatorConfig(integration_scheme=integrator, accuracy=accuracy,
                                             max_step_size=max_step, use_error_control=True), self.simulator)
        ctx = self.simulator.get_mutable_context()
        init = np.asarray(self.placement.initial, dtype=float).reshape(-1, 2)
        plants = self.plants.system
        pctx = plants.GetMyMutableContextFromRoot(ctx)
        for k, e in enumerate(entities):
            plants.set_state(pctx, e, init[k], (0.0, 0.0))
        for t in self.teams:
            plants.set_state(pctx, t.name, init[len(scenario.robots) + t.obj], (0.0, 0.0))
        self.initial_positions = {e: tuple(init[k]) for k, e in enumerate(entities)}
        self.sim_seconds = 0.0
        self.wall_seconds = 0.0
        self._stop = False
        self._fault = ""
        self._progress, self._last_done = None, -1
        self.simulator.set_monitor(self._Monitor)

    # ------------------------------------------------------------------ running
    @property
    def total_steps(self) -> int:
        return len(self.sequencer.steps)

    def exec_state(self) -> ExecState:
        """The sequencer's state now."""
        return self.supervisor.exec_state(self.supervisor.GetMyContextFromRoot(self.simulator.get_context()))

    def steps_done(self) -> int:
        return self.sequencer.steps_done(self.exec_state())

    def status_line(self) -> str:
        """What the mission is doing now, in one line (notebooks, progress)."""
        st = self.exec_state()
        t = self.simulator.get_context().get_time()
        doing = st.status.value
        running = self.sequencer.in_execution(st)
        if running:
            doing = "; ".join(f"{self.sequencer._op_text(a.op)} ({a.phase.value})" for a in running)
        return (f"t = {t:7.1f} s | steps {self.steps_done():2d}/{self.total_steps} | wall {self.wall_seconds:6.1f} s"
                f" | {doing}")

    def request_stop(self) -> None:
        """Ask a running :meth:`run` to stop at the next integration step (e.g. from a SIGINT handler)."""
        self._stop = True

    def run(self, progress: Callable[[int, int], None] | None = None, t_max: float = 1e7) -> MissionLog:
        """Simulate until the supervisor ends the mission or ``t_max`` (one ``AdvanceTo``; call again to go
        on); ``progress(done, total)`` is called whenever a plan step completes.  Returns :meth:`log`.
        BLAS runs single-threaded meanwhile: a multithreaded BLAS sums in an order that depends on the
        machine's core count, and the mission would too.

        A controller fault (:meth:`_Monitor`), an integrator failure or any other exception inside the
        simulation ends the mission as a failed primitive with a one-line reason
        (:meth:`~mrodrake.systems.supervisor.Supervisor.abort`); the log keeps everything recorded so far."""
        self._progress, self._last_done = progress, -1
        t0 = time.perf_counter()
        try:
            with threadpool_limits(limits=1, user_api="blas"):  # same rounding on every core count
                self.simulator.AdvanceTo(float(t_max))
        except Exception as exc:  # noqa: BLE001 - any failure inside the simulation ends the mission cleanly
            self._abort(_simulation_failure(exc))
        finally:
            self.wall_seconds += time.perf_counter() - t0
            self._progress = None
        if self._fault:
            self._abort(self._fault)
        if progress is not None:
            progress(self.steps_done(), self.total_steps)
        return self.log()

    def _Monitor(self, root_context):
        """Simulator monitor, after every integration step: a stop request, or a fault of an active controller
        (its state left the free set or the map's domain, where the law only damps the entity's velocity),
        ends ``AdvanceTo``; progress is reported per completed plan step.  The laws are evaluated at the step's
        end only after an evaluation during the step found one undefined
        (:attr:`~mrodrake.systems.controllers.MissionControllers.fault_seen`): every step starts with an
        evaluation at the state the last one ended in, so a faulty state ends the mission one step later at the
        latest, and steps without a fault cost no extra evaluation."""
        if self._stop:
            return EventStatus.ReachedTermination(self.diagram, "stopped by the user")
        if self.controllers.fault_seen:
            self.controllers.fault_seen = False
            fault = self.controllers.first_fault(self.controllers.GetMyContextFromRoot(root_context))
            if fault is not None:
                self._fault = f"controller fault of {fault[0]}: {fault[1]}"
                return EventStatus.ReachedTermination(self.diagram, self._fault)
        if self._progress is not None:
            st = self.supervisor.exec_state(self.supervisor.GetMyContextFromRoot(root_context))
            done = self.sequencer.steps_done(st)
            if done != self._last_done:
                self._last_done = done
                self._progress(done, self.total_steps)
        return EventStatus.Succeeded()

    def _abort(self, reason: str) -> None:
        """Record ``reason`` as the failure of the primitive in execution and sample the final state."""
        self._fault = ""
        ctx = self.simulator.get_mutable_context()
        self.supervisor.abort(self.supervisor.GetMyMutableContextFromRoot(ctx), reason)
        self.logger.Sample(self.logger.GetMyContextFromRoot(ctx))

    # ------------------------------------------------------------------ log
    def log(self) -> MissionLog:
        """The recorded trajectory, signals and events so far (pandas DataFrames)."""
        st = self.exec_state()
        lg = self.logger
        ents = lg.entities
        if lg.times:
            T = np.asarray(lg.times)
            S = np.asarray(lg.states).reshape(len(T), len(ents), 4)
            traj = pd.DataFrame({"t": np.repeat(T, len(ents)), "entity": np.tile(ents, len(T)),
                                 "x": S[:, :, 0].ravel(), "y": S[:, :, 1].ravel(), "vx": S[:, :, 2].ravel(),
                                 "vy": S[:, :, 3].ravel()})
        else:
            traj = pd.DataFrame(columns=["t", "entity", "x", "y", "vx", "vy"])
        sig = pd.DataFrame(lg.signals, columns=["t", "controller", "entity", "ux", "uy", "m_hat", "alpha_hat"])
        ev_cols = ["kind", "t_start", "t_end", "step", "plan_step", "action", "entities", "from_region", "to_region",
                   "ok", "propositions", "nba_states", "detail", "time_limit"]
        events = pd.DataFrame(list(st.events), columns=ev_cols)
        t_now = float(self.simulator.get_context().get_time())
        names = self.scenario.robot_names, self.scenario.object_names
        grasps = list(st.grasps) + [(t0, t_now, names[0][i], names[1][st.docked[i]]) for i, t0 in st.grasp_open.items()]
        grasps = pd.DataFrame(grasps, columns=["t_start", "t_end", "robot", "object"])
        final = None
        if lg.times:
            X = np.asarray(lg.states[-1]).reshape(len(ents), 4)
            s = self.sequencer.discrete_state(st, X)
            final = self.ts.state_dict(s) if min(s[: len(ents)]) >= 0 else {"raw": list(s)}
        steps = self.sequencer.steps
        expected = self.ts.state_dict(steps[-1].dst) if steps else self.ts.state_dict(self.ts.initial)
        ok = st.status is Status.DONE
        message = st.message if st.status is not Status.RUNNING else "not finished"
        return MissionLog(self.scenario, self.plan, traj, sig, events, grasps, ok, message, final, expected,
                          self.steps_done(), self.total_steps, t_now, self.wall_seconds, list(st.primitives),
                          st.monitor.states)


def _execution(value) -> Execution:
    if isinstance(value, Execution):
        return value
    try:
        return Execution(value)
    except ValueError:
        raise UserError(f"--execution: unknown mode '{value}' (expected 'sequential' or 'concurrent')") from None


def _simulation_failure(exc: BaseException) -> str:
    """One line for an exception raised inside the simulation (Drake's integrator failures included)."""
    text = str(exc).strip().splitlines()
    first = text[0] if text else type(exc).__name__
    if "step smaller than minimum" in first or "Integrator" in first or "integrator" in first:
        return f"integrator failure ({first})"
    return f"{type(exc).__name__} inside the simulation: {first}"


def load_plan(scenario: Scenario, path):
    """A plan.json for ``scenario``, verified (TS rules, NBA acceptance); user errors name the file."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"--plan: file '{path}' not found")
    ts = TransitionSystem(scenario)
    plan = Plan.from_json(path.read_text(encoding="utf-8"), ts, source=str(path))
    formula, nba = task_nba(scenario, ts)
    try:
        plan.verify(ts, nba, formula)
    except PlanVerificationError as exc:
        raise UserError(f"{path}: plan does not verify: {exc}") from None
    return plan
