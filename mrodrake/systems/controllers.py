"""Adaptive navigation / transport controllers as Drake LeafSystems (paper Sec. III-A).

Continuous state: the adaptation estimates [m̂, α̂] (eq. (11)).  Inputs: ``state`` ([x, ẋ] of the
moving entity: the robot, or the object of a robots-object team) and an optional abstract ``task``.
Outputs: ``u`` (navigation) or ``u_<member>`` per team member (transport, u_ℓ = cf_ℓ u), and ``estimates``.

Reuse in a full mission diagram (design choice).  Everything that depends on one transition — the
point-world map of the entity's free space, φ with its b_ℓ, r̄ and τ, the goal and the load sharing — is
bundled in a precomputed :class:`~mrodrake.control.adaptive.NavigationTask`.  A controller takes the task
either at construction (single-transition use: the ``task`` port stays unconnected) or per context from its
abstract ``task`` input (a :class:`TaskCommand`), which a supervisor drives: ``None`` disables the
controller (zero inputs, frozen estimates, so idle controllers do not drift), and a new *episode* resets the
estimates to the task's m̂(0), α̂(0) (``gains.initial_estimates(bodies)``: α̂(0) at the design bound of the
entity's bodies, 1 for a robot, 1 + members for a team) at the start of the next step (a per-step
unrestricted update on the controller's own state), while a new task within the same episode keeps them.  So one
controller per robot (and per team used by a plan) can stay wired for a whole mission while the supervisor only
swaps tasks.

One cache entry evaluates the law (map, φ, v_d, v̇_d) once per context change; the outputs and the
estimate derivatives all read it (one map evaluation per derivative evaluation of the closed loop).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, ContinuousStateIndex, EventStatus, LeafSystem, ValueProducer

from mrodrake.control.adaptive import AdaptiveGains, ControlEval, NavigationTask
from mrodrake.execution.commands import TaskCommand

_ZERO = ControlEval(np.zeros(2), 0.0, 0.0, np.zeros(2), np.zeros(2), np.zeros(2))


#: Episode value of an idle controller (its numeric ``episode`` state; episodes count from 0).
_IDLE = -1


class _AdaptiveController(LeafSystem):
    """Shared part: estimates state, ``state``/``task`` inputs, cached law, ``estimates`` output."""

    def __init__(self, task: NavigationTask | None, gains: AdaptiveGains | None, name: str, bodies: int = 1):
        super().__init__()
        self.set_name(name)
        self._task = task
        self.bodies = int(bodies)
        g = gains if gains is not None else (task.gains if task is not None else AdaptiveGains())
        self.DeclareContinuousState(BasicVector(list(g.initial_estimates(self.bodies))))
        self.state_port = self.DeclareVectorInputPort("state", 4)
        self._command = None if task is None else TaskCommand(task, 0)
        self.task_port = self.DeclareAbstractInputPort("task", AbstractValue.Make(self._command))
        # numeric state (not abstract): the per-step update copies it in C++, not by a Python deepcopy
        self._episode_index = self.DeclareDiscreteState([float(_IDLE if task is None else 0)])
        self._law = self.DeclareCacheEntry(
            "adaptive law",
            ValueProducer(allocate=lambda: AbstractValue.Make(_ZERO), calc=self._CalcLaw),
            prerequisites_of_calc={self.state_port.ticket(), self.task_port.ticket(), self.xc_ticket()},
        )
        self.estimates_port = self.DeclareStateOutputPort("estimates", ContinuousStateIndex(0))
        self.DeclarePerStepUnrestrictedUpdateEvent(self._ResetOnNewTask)
        self._u_prereqs = {self._law.ticket(), self.task_port.ticket()}

    # ------------------------------------------------------------------ task handling
    def command(self, context) -> TaskCommand | None:
        """The command in force: the ``task`` input if connected, else the construction-time task."""
        if self.task_port.HasValue(context):
            return self.task_port.Eval(context)
        return self._command

    def active_task(self, context) -> NavigationTask | None:
        """The task in force (None: the controller is idle)."""
        cmd = self.command(context)
        return None if cmd is None else cmd.task

    def _ResetOnNewTask(self, context, state):
        cmd = self.command(context)
        episode = _IDLE if cmd is None else int(cmd.episode)
        if episode == context.get_discrete_state(int(self._episode_index)).GetAtIndex(0):
            return EventStatus.DidNothing()  # leaves the context (and its caches) untouched
        state.get_mutable_discrete_state(int(self._episode_index)).SetAtIndex(0, float(episode))
        if cmd is not None:
            state.get_mutable_continuous_state().SetFromVector(list(cmd.task.gains.initial_estimates(self.bodies)))
        return EventStatus.Succeeded()

    def set_estimates(self, context, m_hat: float, alpha_hat: float) -> None:
        """Set [m̂, α̂] in this controller's (sub)context."""
        context.SetContinuousState([float(m_hat), float(alpha_hat)])

    # ------------------------------------------------------------------ evaluation
    def _CalcLaw(self, context, value):
        task = self.active_task(context)
        if task is None:
            value.set_value(_ZERO)
            return
        s = self.state_port.Eval(context)
        est = context.get_continuous_state_vector().value()
        value.set_value(task.evaluate(s[:2], s[2:], est[0], est[1]))

    def law(self, context) -> ControlEval:
        """The cached evaluation of the law in ``context``."""
        return self._law.Eval(context)

    def fault(self, context) -> str:
        """Why the law is undefined at the current state (empty while it is defined or the controller idles)."""
        return self._law.Eval(context).fault if self.active_task(context) is not None else ""

    def DoCalcTimeDerivatives(self, context, derivatives):
        if self.command(context) is None:  # idle: frozen estimates, without going through the law's cache
            derivatives.get_mutable_vector().SetZero()
            return
        ev = self._law.Eval(context)
        derivatives.get_mutable_vector().SetFromVector([ev.m_hat_dot, ev.alpha_hat_dot])


class NavigationController(_AdaptiveController):
    """Adaptive navigation law of one robot (paper Sec. III-A, 1) Robot Navigation): output ``u`` (2)."""

    def __init__(self, task: NavigationTask | None = None, gains: AdaptiveGains | None = None,
                 name: str = "navigation_controller"):
        super().__init__(task, gains, name)
        self.u_port = self.DeclareVectorOutputPort("u", 2, self.CalcU, prerequisites_of_calc=self._u_prereqs)

    def CalcU(self, context, output):
        output.SetFromVector(self._law.Eval(context).u)


class TransportController(_AdaptiveController):
    """Adaptive transport law of a robots-object team (paper Sec. III-A, 2) Cooperative Object
    Transportation): the navigation law of the coupled entity with estimates m̂_A,j, α̂_A,j, split as
    u_ℓ = cf_ℓ u to outputs ``u_<member>``; the total entity input is also available as ``u``.  ``task.cf`` must
    have one entry per member."""

    def __init__(self, members: Sequence[str], task: NavigationTask | None = None,
                 gains: AdaptiveGains | None = None, name: str = "transport_controller"):
        members = list(members)
        if not members or len(set(members)) != len(members):
            raise ValueError(f"members must be distinct and non-empty, got {members}")
        if task is not None and len(task.cf) != len(members):
            raise ValueError(f"task has {len(task.cf)} load-sharing coefficients for {len(members)} members")
        super().__init__(task, gains, name, bodies=1 + len(members))
        self.members = members
        self.u_port = self.DeclareVectorOutputPort("u", 2, self.CalcU, prerequisites_of_calc=self._u_prereqs)
        self.member_u_ports = [
            self.DeclareVectorOutputPort(f"u_{n}", 2, self._member_calc(k), prerequisites_of_calc=self._u_prereqs)
            for k, n in enumerate(members)
        ]

    def CalcU(self, context, output):
        output.SetFromVector(self._law.Eval(context).u)

    def _member_calc(self, k: int):
        def CalcMemberU(context, output):
            task = self.active_task(context)
            cf = task.cf[k] if task is not None else 0.0
            output.SetFromVector(cf * self._law.Eval(context).u)

        return CalcMemberU


class MissionControllers(LeafSystem):
    """Every adaptive controller of a mission in one LeafSystem: for each ``(name, members)`` of
    ``controllers`` the navigation law of one robot (``members`` empty) or the transport law of a team
    (``members`` its robots), as :class:`NavigationController` and :class:`TransportController` compute them.

    Continuous state: [m̂, α̂] of every controller in :attr:`names` order (output ``estimates``).  Inputs per
    controller ``c``: ``state_<c>`` ([x, ẋ] of its entity) and ``task_<c>`` (a :class:`TaskCommand` or None:
    idle; must be connected).  Outputs: ``forces``, the input of every plant the controllers drive in
    :attr:`names` order (u of a navigation controller, u_ℓ = cf_ℓ u of each member of a team, 2 entries
    each; :attr:`force_slots` names them), and ``u``, the entity input u of every controller (2 entries each).

    One cache entry evaluates the laws of all active controllers per context change (an idle controller's law
    is not evaluated and its state input is never read); the outputs, the estimate derivatives and the faults
    all read it, so a derivative evaluation of the closed loop evaluates each active law once.  Every
    evaluation that finds a law undefined also raises :attr:`fault_seen` (on the system, not in a context),
    so a monitor need not evaluate the laws again after every step to notice a fault.  A new episode
    resets a controller's estimates to its task's m̂(0), α̂(0) at the start of the next step (one per-step
    unrestricted update for all controllers, which leaves the context untouched when no episode changed).
    """

    def __init__(self, controllers: Sequence[tuple[str, Sequence[str]]], gains: AdaptiveGains,
                 name: str = "controllers"):
        super().__init__()
        self.set_name(name)
        self.names = [str(c) for c, _ in controllers]
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"duplicate controller names: {self.names}")
        self.members = {str(c): list(m) for c, m in controllers}
        for c, m in self.members.items():
            if len(set(m)) != len(m):
                raise ValueError(f"members of {c} must be distinct, got {m}")
        self.bodies = [1 + len(self.members[c]) for c in self.names]
        #: Set by every evaluation of the laws that finds one undefined (cleared by whoever reads it).
        self.fault_seen = False
        #: (controller, member or None) of every 2-entry slot of ``forces``
        self.force_slots = [(c, n) for c in self.names for n in (self.members[c] or [None])]
        self._force_at, at = [], 0
        for c in self.names:
            self._force_at.append(at)
            at += 2 * max(1, len(self.members[c]))
        self._is_team = [bool(self.members[c]) for c in self.names]
        init = [v for b in self.bodies for v in gains.initial_estimates(b)]
        self.DeclareContinuousState(BasicVector(init))
        self.state_ports = {c: self.DeclareVectorInputPort(f"state_{c}", 4) for c in self.names}
        self.task_ports = {c: self.DeclareAbstractInputPort(f"task_{c}", AbstractValue.Make(None))
                           for c in self.names}
        self._task_list = [self.task_ports[c] for c in self.names]
        self._state_list = [self.state_ports[c] for c in self.names]
        self._episode_index = self.DeclareDiscreteState(np.full(len(self.names), float(_IDLE)))
        self._tasks = self.DeclareCacheEntry(
            "task commands", ValueProducer(allocate=lambda: AbstractValue.Make(None), calc=self._CalcTasks),
            prerequisites_of_calc={p.ticket() for p in self._task_list})
        self._new_episodes = self.DeclareCacheEntry(
            "new episodes", ValueProducer(allocate=lambda: AbstractValue.Make(None), calc=self._CalcNewEpisodes),
            prerequisites_of_calc={self._tasks.ticket(), self.discrete_state_ticket(self._episode_index)})
        self._laws = self.DeclareCacheEntry(
            "adaptive laws", ValueProducer(allocate=lambda: AbstractValue.Make(None), calc=self._CalcLaws),
            prerequisites_of_calc={self._tasks.ticket(), self.xc_ticket()} | {p.ticket() for p in self._state_list})
        laws = {self._laws.ticket()}
        self.forces_port = self.DeclareVectorOutputPort("forces", 2 * len(self.force_slots), self.CalcForces,
                                                        prerequisites_of_calc=laws)
        self.u_port = self.DeclareVectorOutputPort("u", 2 * len(self.names), self.CalcU, prerequisites_of_calc=laws)
        self.estimates_port = self.DeclareStateOutputPort("estimates", ContinuousStateIndex(0))
        self.DeclarePerStepUnrestrictedUpdateEvent(self._ResetOnNewTask)

    # ------------------------------------------------------------------ tasks
    def _CalcTasks(self, context, value):
        cmds = tuple(p.Eval(context) for p in self._task_list)
        active = tuple(q for q, cmd in enumerate(cmds) if cmd is not None)
        episodes = np.array([_IDLE if cmd is None else int(cmd.episode) for cmd in cmds], dtype=float)
        value.set_value((cmds, active, episodes))

    def command(self, context, controller: str) -> TaskCommand | None:
        """The command in force for ``controller`` (None: idle)."""
        return self._tasks.Eval(context)[0][self.names.index(controller)]

    def active_task(self, context, controller: str) -> NavigationTask | None:
        cmd = self.command(context, controller)
        return None if cmd is None else cmd.task

    def _CalcNewEpisodes(self, context, value):
        episodes = self._tasks.Eval(context)[2]
        changed = np.flatnonzero(episodes != context.get_discrete_state(int(self._episode_index)).value())
        value.set_value(tuple(changed.tolist()))

    def _ResetOnNewTask(self, context, state):
        changed = self._new_episodes.Eval(context)
        if not changed:
            return EventStatus.DidNothing()  # leaves the context (and its caches) untouched
        cmds, _, episodes = self._tasks.Eval(context)
        est = context.get_continuous_state_vector().CopyToVector()
        for q in changed:
            if cmds[q] is not None:
                est[2 * q : 2 * q + 2] = cmds[q].task.gains.initial_estimates(self.bodies[q])
        state.get_mutable_discrete_state(int(self._episode_index)).SetFromVector(episodes)
        state.get_mutable_continuous_state().SetFromVector(est)
        return EventStatus.Succeeded()

    def estimates(self, context, controller: str) -> np.ndarray:
        """[m̂, α̂] of ``controller`` in this system's (sub)context."""
        q = self.names.index(controller)
        return context.get_continuous_state_vector().CopyToVector()[2 * q : 2 * q + 2]

    def set_estimates(self, context, controller: str, m_hat: float, alpha_hat: float) -> None:
        """Set [m̂, α̂] of ``controller`` in this system's (sub)context."""
        q = self.names.index(controller)
        est = context.get_continuous_state_vector().CopyToVector()
        est[2 * q : 2 * q + 2] = float(m_hat), float(alpha_hat)
        context.SetContinuousState(est)

    # ------------------------------------------------------------------ evaluation
    def _CalcLaws(self, context, value):
        cmds, active, _ = self._tasks.Eval(context)
        laws = [_ZERO] * len(self.names)
        if active:
            est = context.get_continuous_state_vector().value()
            for q in active:
                x0, x1, w0, w1 = self._state_list[q].Eval(context).tolist()
                m_hat, alpha_hat = est[2 * q : 2 * q + 2].tolist()
                laws[q] = ev = cmds[q].task.evaluate_floats(x0, x1, w0, w1, m_hat, alpha_hat)
                if ev.fault:
                    self.fault_seen = True
        value.set_value((cmds, active, laws))

    def law(self, context, controller: str) -> ControlEval:
        """The cached evaluation of ``controller``'s law in ``context``."""
        return self._laws.Eval(context)[2][self.names.index(controller)]

    def fault(self, context, controller: str) -> str:
        """Why ``controller``'s law is undefined at the current state (empty while it is defined or idle)."""
        return self.law(context, controller).fault

    def first_fault(self, context) -> tuple[str, str] | None:
        """(controller, why) of the first active controller, in :attr:`names` order, whose law is undefined at
        the current state; None if there is none."""
        _, active, laws = self._laws.Eval(context)
        for q in active:
            if laws[q].fault:
                return self.names[q], laws[q].fault
        return None

    def DoCalcTimeDerivatives(self, context, derivatives):
        _, active, laws = self._laws.Eval(context)
        out = np.zeros(2 * len(self.names))
        for q in active:
            ev = laws[q]
            out[2 * q : 2 * q + 2] = ev.m_hat_dot, ev.alpha_hat_dot
        derivatives.SetFromVector(out)

    def CalcForces(self, context, output):
        cmds, active, laws = self._laws.Eval(context)
        out = np.zeros(2 * len(self.force_slots))
        for q in active:
            u, at = laws[q].u, self._force_at[q]
            if self._is_team[q]:
                for k, cf in enumerate(cmds[q].task.cf.tolist()):
                    out[at + 2 * k : at + 2 * k + 2] = cf * u
            else:
                out[at : at + 2] = u
        output.SetFromVector(out)

    def CalcU(self, context, output):
        _, active, laws = self._laws.Eval(context)
        out = np.zeros(2 * len(self.names))
        for q in active:
            out[2 * q : 2 * q + 2] = laws[q].u
        output.SetFromVector(out)
