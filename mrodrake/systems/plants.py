"""Uncertain plants as Drake LeafSystems (paper Sec. II-B).

Every plant has continuous state [x(2), ẋ(2)] (generalised positions x, velocities ẋ).  The TRUE mass and
friction parameters are numeric parameters ``[mass, friction scale, friction frequency]`` (one parameter
vector per body, ``DeclareNumericParameter``), so a Monte-Carlo run varies them per context without
rebuilding the diagram; controllers never read them.  The friction model kind (``paper`` / ``viscous``,
scenario :class:`~mrodrake.scenario.Friction`) is structural and fixed at construction.

* :class:`RobotPlant`:   m_i ẍ_i + f_i(x_i, ẋ_i) = u_i − h_i        (eq. (1))
* :class:`ObjectPlant`:  m^o_j ẍ^o_j + f^o_j(x^o_j, ẋ^o_j) = h^o_j    (eq. (2))
* :class:`CoupledPlant`: m_A,j ẍ^o_j + f_A,j(x^o_j, ẋ^o_j) = Σ_{i∈A} u_i  (eq. (5)), with
  m_A,j = m^o_j + Σ m_i and f_A,j = f^o_j(x^o_j, ẋ^o_j) + Σ f_i(x^o_j − d^o_ij, ẋ^o_j); robot i sits
  rigidly at x_i = x^o_j + offset_i (offset_i = −d^o_ij).

The contact forces h (robot, object) are optional inputs: zero while unconnected.

In a mission every plant has an abstract ``sync`` input (:class:`~mrodrake.execution.commands.SyncCommand`):
a per-step unrestricted update copies the commanded [x, ẋ] into the plant's own state when the command's
version changes (an event may change only its own system's state), and a parked plant has zero dynamics
(:class:`SyncedRobotPlant`, :class:`SyncedObjectPlant`, :class:`SyncedCoupledPlant`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, ContinuousStateIndex, LeafSystem

from mrodrake.execution.commands import SyncCommand
from mrodrake.scenario import Friction, Scenario

FRICTION_MODELS = ("paper", "viscous")


def friction(model: str, scale: float, frequency: float, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
    """Friction-like term f(x, ẋ) of Assumption 1 (scenario ``Friction``).

    ``paper``: scale · sin(frequency (x₁ + x₂)) · diag(exp(−|ẋ_k|) + 1) ẋ (paper Sec. IV);
    ``viscous``: scale · ẋ.  Both satisfy ‖f‖ ≤ α‖ẋ‖ (α = 2 scale resp. scale).
    """
    if model == "paper":
        s = scale * math.sin(frequency * (x[0] + x[1]))
        return s * (np.exp(-np.abs(xdot)) + 1.0) * xdot
    if model == "viscous":
        return scale * np.asarray(xdot, dtype=float)
    raise ValueError(f"unknown friction model {model!r} (expected one of {FRICTION_MODELS})")


def _friction_spec(fr: Friction | None) -> tuple[str, float, float]:
    fr = fr if fr is not None else Friction()
    if fr.model not in FRICTION_MODELS:
        raise ValueError(f"unknown friction model {fr.model!r}")
    return fr.model, float(fr.scale), float(fr.frequency)


class _PointMassPlant(LeafSystem):
    """Shared machinery: state [x, ẋ], one numeric parameter [m, scale, frequency] per body."""

    def __init__(self, bodies: Sequence[tuple[float, Friction | None]]):
        super().__init__()
        self._models = []
        for mass, fr in bodies:
            model, scale, freq = _friction_spec(fr)
            if not (math.isfinite(mass) and mass > 0):
                raise ValueError(f"mass must be a finite positive number, got {mass!r}")
            self._models.append(model)
            self.DeclareNumericParameter(BasicVector([float(mass), scale, freq]))
        self.DeclareContinuousState(2, 2, 0)

    # ------------------------------------------------------------------ parameters and state
    def set_body_parameters(self, context, body: int, mass: float | None = None, scale: float | None = None,
                            frequency: float | None = None) -> None:
        """Change the true mass / friction scale / frequency of ``body`` in ``context`` (None: keep)."""
        p = context.get_mutable_numeric_parameter(body)
        for k, v in enumerate((mass, scale, frequency)):
            if v is not None:
                p.SetAtIndex(k, float(v))

    def body_parameters(self, context, body: int = 0) -> np.ndarray:
        """[mass, scale, frequency] of ``body`` in ``context``."""
        return context.get_numeric_parameter(body).CopyToVector()

    def set_state(self, context, x, xdot=(0.0, 0.0)) -> None:
        """Set [x, ẋ] of this plant in its (sub)context."""
        context.SetContinuousState(np.concatenate([np.asarray(x, dtype=float), np.asarray(xdot, dtype=float)]))

    def _body_friction(self, context, body: int, x: np.ndarray, xdot: np.ndarray) -> tuple[float, np.ndarray]:
        m, scale, freq = context.get_numeric_parameter(body).value()
        return m, friction(self._models[body], scale, freq, x, xdot)

    def _optional(self, port, context) -> np.ndarray:
        return port.Eval(context) if port.HasValue(context) else np.zeros(2)


class RobotPlant(_PointMassPlant):
    """Robot i: m_i ẍ + f_i(x, ẋ) = u − h (eq. (1)).

    Ports: input ``u`` (2), optional input ``h`` (2, grasp force, zero if unconnected), output ``state``
    [x, ẋ].  Numeric parameter 0: [m_i, friction scale, friction frequency].
    """

    def __init__(self, mass: float, friction_spec: Friction | None = None, name: str = "robot"):
        super().__init__([(mass, friction_spec)])
        self.set_name(name)
        self.u_port = self.DeclareVectorInputPort("u", 2)
        self.h_port = self.DeclareVectorInputPort("h", 2)
        self.state_port = self.DeclareStateOutputPort("state", ContinuousStateIndex(0))

    @classmethod
    def from_scenario(cls, scenario: Scenario, robot: str | int) -> RobotPlant:
        r = scenario.robots[robot if isinstance(robot, int) else scenario.robot_names.index(robot)]
        return cls(r.mass, r.friction, name=r.name)

    def DoCalcTimeDerivatives(self, context, derivatives):
        s = context.get_continuous_state_vector().value()
        x, v = s[:2], s[2:]
        m, f = self._body_friction(context, 0, x, v)
        a = (self.u_port.Eval(context) - self._optional(self.h_port, context) - f) / m
        derivatives.get_mutable_vector().SetFromVector(np.concatenate([v, a]))


class ObjectPlant(_PointMassPlant):
    """Object j: m^o_j ẍ + f^o_j(x, ẋ) = h (eq. (2)).

    Ports: optional input ``h`` (2, total force of the grasping robots, zero if unconnected), output
    ``state``.  Numeric parameter 0: [m^o_j, friction scale, friction frequency].
    """

    def __init__(self, mass: float, friction_spec: Friction | None = None, name: str = "object"):
        super().__init__([(mass, friction_spec)])
        self.set_name(name)
        self.h_port = self.DeclareVectorInputPort("h", 2)
        self.state_port = self.DeclareStateOutputPort("state", ContinuousStateIndex(0))

    @classmethod
    def from_scenario(cls, scenario: Scenario, obj: str | int) -> ObjectPlant:
        o = scenario.objects[obj if isinstance(obj, int) else scenario.object_names.index(obj)]
        return cls(o.mass, o.friction, name=o.name)

    def DoCalcTimeDerivatives(self, context, derivatives):
        s = context.get_continuous_state_vector().value()
        x, v = s[:2], s[2:]
        m, f = self._body_friction(context, 0, x, v)
        a = (self._optional(self.h_port, context) - f) / m
        derivatives.get_mutable_vector().SetFromVector(np.concatenate([v, a]))


class CoupledPlant(_PointMassPlant):
    """Object j rigidly grasped by team A (eq. (5)): m_A,j ẍ^o + f_A,j(x^o, ẋ^o) = Σ u_i.

    State: the object's [x^o, ẋ^o].  Inputs: ``u_<member>`` (2) per team member.  Outputs: ``state`` (the
    object / entity state) and ``state_<member>`` = [x^o + offset_i, ẋ^o] per member.  Numeric parameter 0
    is the object's [m, scale, frequency], parameter 1 + k that of member k.
    """

    def __init__(self, object_mass: float, object_friction: Friction | None, members: Sequence[str],
                 member_masses: Sequence[float], member_frictions: Sequence[Friction | None], offsets,
                 name: str = "team"):
        members = list(members)
        if not members:
            raise ValueError("a coupled plant needs at least one team member")
        if len(set(members)) != len(members):
            raise ValueError(f"duplicate team members: {members}")
        if not (len(member_masses) == len(member_frictions) == len(members)):
            raise ValueError("members, member_masses and member_frictions must have the same length")
        offsets = np.asarray(offsets, dtype=float).reshape(len(members), 2)
        super().__init__([(object_mass, object_friction)] + list(zip(member_masses, member_frictions)))
        self.set_name(name)
        self.members = members
        self.offsets = offsets
        self.u_ports = [self.DeclareVectorInputPort(f"u_{n}", 2) for n in members]
        self.state_port = self.DeclareStateOutputPort("state", ContinuousStateIndex(0))
        xc = {self.xc_ticket()}
        self.member_state_ports = [
            self.DeclareVectorOutputPort(f"state_{n}", 4, self._member_calc(k), prerequisites_of_calc=xc)
            for k, n in enumerate(members)
        ]

    @classmethod
    def from_scenario(cls, scenario: Scenario, obj: str | int, team: Sequence[str | int], offsets=None) -> CoupledPlant:
        """Team plant of object ``obj`` and robots ``team`` (offsets default: ``geometry.grasp_layout``)."""
        from mrodrake.geometry import grasp_layout

        o = scenario.objects[obj if isinstance(obj, int) else scenario.object_names.index(obj)]
        robots = [scenario.robots[i if isinstance(i, int) else scenario.robot_names.index(i)] for i in team]
        if offsets is None:
            offsets = grasp_layout(o.radius, [r.radius for r in robots], scenario.layout.grasp_gap).offsets
        return cls(o.mass, o.friction, [r.name for r in robots], [r.mass for r in robots],
                   [r.friction for r in robots], offsets, name=f"{o.name}_team")

    def _member_calc(self, k: int):
        def calc(context, output):
            s = context.get_continuous_state_vector().value()
            out = s.copy()
            out[:2] += self.offsets[k]
            output.SetFromVector(out)

        return calc

    def total_mass(self, context) -> float:
        """m_A,j = m^o_j + Σ m_i in ``context``."""
        return float(sum(context.get_numeric_parameter(b).GetAtIndex(0) for b in range(len(self.members) + 1)))

    def DoCalcTimeDerivatives(self, context, derivatives):
        s = context.get_continuous_state_vector().value()
        x, v = s[:2], s[2:]
        m_total, f_total = self._body_friction(context, 0, x, v)
        u = np.zeros(2)
        for k, port in enumerate(self.u_ports):
            m_k, f_k = self._body_friction(context, k + 1, x + self.offsets[k], v)
            m_total += m_k
            f_total = f_total + f_k
            u += port.Eval(context)
        derivatives.get_mutable_vector().SetFromVector(np.concatenate([v, (u - f_total) / m_total]))


# ------------------------------------------------------------------------------------------ synced plants (missions)
def _declare_sync(plant) -> None:
    plant.sync_port = plant.DeclareAbstractInputPort("sync", AbstractValue.Make(SyncCommand()))
    plant._version_index = plant.DeclareDiscreteState([-1.0])  # numeric: cheap per-step copies
    plant.DeclarePerStepUnrestrictedUpdateEvent(plant._Sync)


def _apply_sync(plant, context, state) -> None:
    cmd = plant.sync_port.Eval(context)
    if cmd.version == context.get_discrete_state(int(plant._version_index)).GetAtIndex(0):
        return
    state.get_mutable_discrete_state(int(plant._version_index)).SetAtIndex(0, float(cmd.version))
    state.get_mutable_continuous_state().SetFromVector(np.concatenate([cmd.x, cmd.v]))


class _SyncedBody:
    """Mixin for a one-body plant: an abstract ``sync`` input (state reset by version, parking brake)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        _declare_sync(self)

    def _Sync(self, context, state):
        _apply_sync(self, context, state)

    def DoCalcTimeDerivatives(self, context, derivatives):
        if self.sync_port.Eval(context).frozen:
            derivatives.get_mutable_vector().SetZero()
            return
        super().DoCalcTimeDerivatives(context, derivatives)


class SyncedRobotPlant(_SyncedBody, RobotPlant):
    """RobotPlant with an abstract ``sync`` input (state reset by version, parking brake)."""


class SyncedObjectPlant(_SyncedBody, ObjectPlant):
    """ObjectPlant with an abstract ``sync`` input (state reset by version, parking brake)."""


class SyncedCoupledPlant(CoupledPlant):
    """CoupledPlant whose grasp offsets come from the ``sync`` command (the members' actual offsets at
    engagement); outputs ``member_<name>`` = [x^o + offset_i, ẋ^o] (eq. (5))."""

    def __init__(self, object_mass, object_friction, members, member_masses, member_frictions, name="team"):
        super().__init__(object_mass, object_friction, members, member_masses, member_frictions,
                         np.zeros((len(members), 2)), name=name)
        _declare_sync(self)
        pre = {self.xc_ticket(), self.sync_port.ticket()}
        self.member_ports = [self.DeclareVectorOutputPort(f"member_{n}", 4, self._member_out(k),
                                                          prerequisites_of_calc=pre)
                             for k, n in enumerate(self.members)]

    def _offsets(self, context) -> np.ndarray:
        off = self.sync_port.Eval(context).offsets
        n = len(self.members)
        return np.asarray(off, dtype=float).reshape(n, 2) if len(off) else np.zeros((n, 2))

    def _member_out(self, k: int):
        def calc(context, output):
            s = context.get_continuous_state_vector().CopyToVector()
            s[:2] += self._offsets(context)[k]
            output.SetFromVector(s)
        return calc

    def _Sync(self, context, state):
        _apply_sync(self, context, state)

    def DoCalcTimeDerivatives(self, context, derivatives):
        cmd = self.sync_port.Eval(context)
        if cmd.frozen:
            derivatives.get_mutable_vector().SetZero()
            return
        s = context.get_continuous_state_vector().value()
        x, v = s[:2], s[2:]
        offsets = self._offsets(context)
        m_total, f_total = self._body_friction(context, 0, x, v)
        u = np.zeros(2)
        for k, port in enumerate(self.u_ports):
            m_k, f_k = self._body_friction(context, k + 1, x + offsets[k], v)
            m_total += m_k
            f_total = f_total + f_k
            u += port.Eval(context)
        derivatives.get_mutable_vector().SetFromVector(np.concatenate([v, (u - f_total) / m_total]))
