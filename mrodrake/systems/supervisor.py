"""The mission supervisor: the Drake side of the sequencer (paper Sec. III-A, sequential execution).

:class:`Supervisor` keeps the :class:`~mrodrake.execution.sequencer.ExecState` as its abstract state.  One
periodic unrestricted update snapshots the routed [x, ẋ] of every robot and object and calls
:meth:`~mrodrake.execution.sequencer.Sequencer.tick`; the outputs route the result: ``task_<controller>``
(a :class:`~mrodrake.execution.commands.TaskCommand` or None), ``sync_<plant>``
(:class:`~mrodrake.execution.commands.SyncCommand`) and ``select_<entity>`` (the PortSwitch input carrying the
entity's state: its own plant, or the team plant it is coupled to).  A tick that changes nothing (most ticks
of a motion) returns ``DidNothing``, which leaves the context and every cache downstream untouched.  The
simulation ends with ``ReachedTermination`` when the sequencer is done or has failed.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import EventStatus, InputPortIndex, LeafSystem

from mrodrake.execution.commands import SyncCommand
from mrodrake.execution.sequencer import ExecState, Sequencer, Status


class Supervisor(LeafSystem):
    """Input ``states`` ([x, ẋ] of every entity, robots then objects, 4 entries each); abstract outputs
    ``task_<controller>``, ``tasks`` (all of them, by controller name), ``sync_<plant>`` and
    ``select_<entity>``.  ``route_ports[(entity, team plant)]`` is
    the index of the switch input that carries the entity's state from that team plant (1: its own plant)."""

    def __init__(self, sequencer: Sequencer, route_ports: Mapping[tuple[str, str], int], period: float = 0.5):
        super().__init__()
        self.set_name("supervisor")
        self.sequencer = sequencer
        self.route_ports = dict(route_ports)
        self.period = float(period)
        self._state_index = self.DeclareAbstractState(AbstractValue.Make(sequencer.initial_state()))
        self.states_port = self.DeclareVectorInputPort("states", 4 * len(sequencer.entities))
        tick = {self.abstract_state_ticket(self._state_index)}
        self.task_ports = {c: self.DeclareAbstractOutputPort(
            f"task_{c}", lambda: AbstractValue.Make(None), self._TaskCalc(c), prerequisites_of_calc=tick)
            for c in sequencer.controllers}
        self.tasks_port = self.DeclareAbstractOutputPort("tasks", lambda: AbstractValue.Make({}), self._TasksCalc,
                                                         prerequisites_of_calc=tick)
        self.sync_ports = {p: self.DeclareAbstractOutputPort(
            f"sync_{p}", lambda: AbstractValue.Make(SyncCommand()), self._SyncCalc(p), prerequisites_of_calc=tick)
            for p in sequencer.plants}
        self.select_ports = {e: self.DeclareAbstractOutputPort(
            f"select_{e}", lambda: AbstractValue.Make(InputPortIndex(1)), self._SelectCalc(k),
            prerequisites_of_calc=tick) for k, e in enumerate(sequencer.entities)}
        self.DeclarePeriodicUnrestrictedUpdateEvent(self.period, 0.0, self._Tick)

    def exec_state(self, context) -> ExecState:
        """The sequencer's state in this system's (sub)context."""
        return context.get_abstract_state(int(self._state_index)).get_value()

    def _TaskCalc(self, c: str):
        def calc(context, value):
            value.set_value(self.exec_state(context).tasks[c])
        return calc

    def _TasksCalc(self, context, value):
        value.set_value(self.exec_state(context).tasks)

    def _SyncCalc(self, p: str):
        def calc(context, value):
            value.set_value(self.exec_state(context).syncs[p])
        return calc

    def _SelectCalc(self, e: int):
        name = self.sequencer.entities[e]

        def calc(context, value):
            team = self.exec_state(context).coupled.get(e)
            value.set_value(InputPortIndex(1 if team is None else self.route_ports[(name, team)]))
        return calc

    def _Tick(self, context, state):
        st = self.exec_state(context)
        if st.status is not Status.RUNNING:
            return EventStatus.ReachedTermination(self, st.message)
        X = np.array(self.states_port.Eval(context), dtype=float).reshape(-1, 4)
        new = self.sequencer.tick(st, float(context.get_time()), X)
        if new is st:
            return EventStatus.DidNothing()  # leaves the context (and every cache downstream) untouched
        state.get_mutable_abstract_state(int(self._state_index)).set_value(new)
        if new.status is Status.DONE:
            return EventStatus.ReachedTermination(self, "mission complete")
        if new.status is Status.FAILED:
            return EventStatus.ReachedTermination(self, f"mission failed: {new.message}")
        return EventStatus.Succeeded()

    def abort(self, context, reason: str) -> str:
        """End the mission in ``context`` (this system's own context, mutable) as a failure of the primitive
        in execution (:meth:`~mrodrake.execution.sequencer.Sequencer.abort`); returns the message."""
        st = self.sequencer.abort(self.exec_state(context), float(context.get_time()), reason)
        context.get_mutable_abstract_state(int(self._state_index)).set_value(st)
        return st.message
