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

In a mission all plants, the team plants included, are one :class:`MissionPlants` system: every plant
has an abstract ``sync`` input (:class:`~mrodrake.execution.commands.SyncCommand`); a per-step unrestricted
update copies the commanded [x, ẋ] into the plant's state when the command's version changes, and a parked
plant has zero dynamics (one derivative call computes the moving plants only).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, ContinuousStateIndex, EventStatus, LeafSystem, ValueProducer

from mrodrake.execution.commands import SyncCommand
from mrodrake.scenario import Friction, Scenario

FRICTION_MODELS = ("paper", "viscous")


def friction(model: str, scale: float, frequency: float, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
    """Friction-like term f(x, ẋ) of Assumption 1 (scenario ``Friction``).

    ``paper``: scale · sin(frequency (x₁ + x₂)) · diag(exp(−|ẋ_k|) + 1) ẋ (paper Sec. IV);
    ``viscous``: scale · ẋ.  Both satisfy ‖f‖ ≤ α‖ẋ‖ (α = 2 scale resp. scale).
    """
    (x0, x1), (v0, v1) = np.asarray(x, dtype=float).tolist(), np.asarray(xdot, dtype=float).tolist()
    return np.array(friction_xy(model, scale, frequency, x0, x1, v0, v1))


def friction_xy(model: str, scale: float, frequency: float, x0: float, x1: float, v0: float, v1: float
                ) -> tuple[float, float]:
    """:func:`friction` of one body on Python floats (the mission's derivative path)."""
    if model == "paper":
        s = scale * math.sin(frequency * (x0 + x1))
        return s * (math.exp(-abs(v0)) + 1.0) * v0, s * (math.exp(-abs(v1)) + 1.0) * v1
    if model == "viscous":
        return scale * v0, scale * v1
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


# ------------------------------------------------------------------------------------------ the plants of a mission
class _Syncs(NamedTuple):
    """What :class:`MissionPlants` reads from its sync commands and parameters (one cache entry)."""

    moving: tuple[int, ...]  # plants not parked
    versions: np.ndarray  # every plant's command version
    commands: list  # every plant's SyncCommand
    offsets: list  # per team plant: its members' grasp offsets [[dx, dy], ...]
    params: tuple  # per body: (mass, friction scale, friction frequency)


class MissionPlants(LeafSystem):
    """Every plant of a mission in one LeafSystem: a body per robot and per object (eqs. (1), (2), without
    contact forces) and a team plant per (object, team) of the plan's transports (eq. (5)).

    Continuous state: [x, ẋ] of every plant in :attr:`names` order (robots, objects, teams), 4 entries each;
    output ``state`` is all of it (a Demultiplexer gives each plant its own port).  Inputs: ``forces``, u of
    every robot and then u_ℓ of every member of every team (2 entries each; :attr:`force_slots` names them,
    robots as (robot, None) and members as (team, robot)), and an abstract ``sync_<plant>``
    (:class:`~mrodrake.execution.commands.SyncCommand`) per plant; all must be connected.  Outputs
    ``member_<team>_<robot>`` = [x^o + offset_i, ẋ^o] per team member, with the grasp offsets of the team's
    sync command (the members' actual offsets at engagement).  Numeric parameter b is the true
    [mass, friction scale, friction frequency] of robot b, then of each object; a team plant uses those of
    its object and members.

    A plant whose sync command is ``frozen`` is parked: zero dynamics, so a derivative evaluation costs one
    call for all plants and computes only the moving ones (``forces`` is read only while a plant moves).  A
    per-step unrestricted update copies the commanded [x, ẋ] into a plant's state when its command's version
    changes.
    """

    def __init__(self, scenario: Scenario, teams: Sequence[tuple[str, int, Sequence[int]]] = (),
                 name: str = "plants"):
        """``teams``: (name, object index, robot indices) of every team plant."""
        super().__init__()
        self.set_name(name)
        bodies = list(scenario.robots) + list(scenario.objects)
        self.robot_names = [r.name for r in scenario.robots]
        self.object_names = [o.name for o in scenario.objects]
        n_r = len(self.robot_names)
        self.teams = [(str(t), int(j), tuple(int(i) for i in team)) for t, j, team in teams]
        self.names = self.robot_names + self.object_names + [t for t, _, _ in self.teams]
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"duplicate plant names: {self.names}")
        self._models = []
        for b in bodies:
            model, scale, freq = _friction_spec(b.friction)
            if not (math.isfinite(b.mass) and b.mass > 0):
                raise ValueError(f"mass must be a finite positive number, got {b.mass!r}")
            self._models.append(model)
            self.DeclareNumericParameter(BasicVector([float(b.mass), scale, freq]))
        # a team plant's bodies: its object's parameter index, then its members'
        self._team_bodies = [(n_r + j, team) for _, j, team in self.teams]
        for _, _, team in self.teams:
            if not team or len(set(team)) != len(team):
                raise ValueError(f"a team needs distinct members, got {team}")
        self.force_slots = [(r, None) for r in self.robot_names] + [
            (t, self.robot_names[i]) for t, _, team in self.teams for i in team]
        self._team_force_at, at = [], 2 * n_r
        for _, _, team in self.teams:
            self._team_force_at.append(at)
            at += 2 * len(team)
        self.DeclareContinuousState(4 * len(self.names))
        self.state_port = self.DeclareStateOutputPort("state", ContinuousStateIndex(0))
        self.forces_port = self.DeclareVectorInputPort("forces", 2 * len(self.force_slots))
        self.sync_ports = {p: self.DeclareAbstractInputPort(f"sync_{p}", AbstractValue.Make(SyncCommand()))
                           for p in self.names}
        self._sync_list = [self.sync_ports[p] for p in self.names]
        self._version_index = self.DeclareDiscreteState(np.full(len(self.names), -1.0))
        self._syncs = self.DeclareCacheEntry(
            "sync commands", ValueProducer(allocate=lambda: AbstractValue.Make(None), calc=self._CalcSyncs),
            prerequisites_of_calc={p.ticket() for p in self._sync_list} | {self.all_parameters_ticket()})
        self._new_versions = self.DeclareCacheEntry(
            "new versions", ValueProducer(allocate=lambda: AbstractValue.Make(None), calc=self._CalcNewVersions),
            prerequisites_of_calc={self._syncs.ticket(), self.discrete_state_ticket(self._version_index)})
        pre = {self.xc_ticket(), self._syncs.ticket()}
        self.member_ports = {t: [self.DeclareVectorOutputPort(f"member_{t}_{self.robot_names[i]}", 4,
                                                              self._member_out(q, k), prerequisites_of_calc=pre)
                                 for k, i in enumerate(team)]
                             for q, (t, _, team) in enumerate(self.teams)}
        self.DeclarePerStepUnrestrictedUpdateEvent(self._Sync)

    # ------------------------------------------------------------------ names and state
    def index(self, plant: str) -> int:
        """Position of ``plant`` (a robot, object or team name) in :attr:`names`."""
        return self.names.index(plant)

    def set_state(self, context, plant: str, x, xdot=(0.0, 0.0)) -> None:
        """Set [x, ẋ] of ``plant`` in this system's (sub)context."""
        k = 4 * self.index(plant)
        s = context.get_continuous_state_vector().CopyToVector()
        s[k : k + 2] = np.asarray(x, dtype=float)
        s[k + 2 : k + 4] = np.asarray(xdot, dtype=float)
        context.SetContinuousState(s)

    def plant_state(self, context, plant: str) -> np.ndarray:
        """[x, ẋ] of ``plant`` in this system's (sub)context."""
        k = 4 * self.index(plant)
        return context.get_continuous_state_vector().CopyToVector()[k : k + 4]

    def body_parameters(self, context, body: int) -> np.ndarray:
        """[mass, scale, frequency] of body ``body`` (robots, then objects) in ``context``."""
        return context.get_numeric_parameter(body).CopyToVector()

    def moving(self, context) -> list[str]:
        """The plants whose sync command does not park them."""
        return [self.names[k] for k in self._syncs.Eval(context).moving]

    # ------------------------------------------------------------------ sync commands
    def _CalcSyncs(self, context, value):
        cmds = [p.Eval(context) for p in self._sync_list]
        moving = tuple(k for k, c in enumerate(cmds) if not c.frozen)
        versions = np.array([c.version for c in cmds], dtype=float)
        n_e = len(self.robot_names) + len(self.object_names)
        offsets = []
        for q, (_, team) in enumerate(self._team_bodies):
            off = cmds[n_e + q].offsets
            offsets.append(np.asarray(off, dtype=float).reshape(len(team), 2).tolist() if len(off)
                           else [[0.0, 0.0]] * len(team))
        params = tuple(tuple(context.get_numeric_parameter(b).value().tolist()) for b in range(len(self._models)))
        value.set_value(_Syncs(moving, versions, cmds, offsets, params))

    def _CalcNewVersions(self, context, value):
        versions = self._syncs.Eval(context).versions
        value.set_value(tuple(np.flatnonzero(versions != context.get_discrete_state(
            int(self._version_index)).value()).tolist()))

    def _Sync(self, context, state):
        changed = self._new_versions.Eval(context)
        if not changed:
            return EventStatus.DidNothing()
        syncs = self._syncs.Eval(context)
        versions, cmds = syncs.versions, syncs.commands
        s = context.get_continuous_state_vector().CopyToVector()
        for k in changed:
            s[4 * k : 4 * k + 4] = np.concatenate([cmds[k].x, cmds[k].v])
        state.get_mutable_continuous_state().SetFromVector(s)
        state.get_mutable_discrete_state(int(self._version_index)).SetFromVector(versions)
        return EventStatus.Succeeded()

    # ------------------------------------------------------------------ dynamics
    def _body_friction(self, params, body: int, x0: float, x1: float, v0: float, v1: float
                       ) -> tuple[float, float, float]:
        m, scale, freq = params[body]
        return (m, *friction_xy(self._models[body], scale, freq, x0, x1, v0, v1))

    def _acceleration(self, params, k: int, x0: float, x1: float, v0: float, v1: float, offsets, forces
                      ) -> tuple[float, float]:
        """ẍ of plant k on Python floats (the hot path of a mission); ``params``: [m, scale, frequency] per body,
        ``forces``: the ``forces`` input as a list."""
        n_r, n_e = len(self.robot_names), len(self.robot_names) + len(self.object_names)
        if k < n_r:  # robot: m ẍ + f = u
            m, f0, f1 = self._body_friction(params, k, x0, x1, v0, v1)
            return (forces[2 * k] - f0) / m, (forces[2 * k + 1] - f1) / m
        if k < n_e:  # object without contact: m ẍ + f = 0
            m, f0, f1 = self._body_friction(params, k, x0, x1, v0, v1)
            return -f0 / m, -f1 / m
        q = k - n_e  # team: m_A ẍ + f_A = Σ u_i
        obj, team = self._team_bodies[q]
        m_total, f0, f1 = self._body_friction(params, obj, x0, x1, v0, v1)
        u0 = u1 = 0.0
        at = self._team_force_at[q]
        for (d0, d1), i in zip(offsets[q], team):
            m_k, g0, g1 = self._body_friction(params, i, x0 + d0, x1 + d1, v0, v1)
            m_total += m_k
            f0 += g0
            f1 += g1
            u0 += forces[at]
            u1 += forces[at + 1]
            at += 2
        return (u0 - f0) / m_total, (u1 - f1) / m_total

    def DoCalcTimeDerivatives(self, context, derivatives):
        moving, _, _, offsets, params = self._syncs.Eval(context)
        out = np.zeros(4 * len(self.names))  # SetFromVector takes an array faster than a list
        if moving:
            s = self.state_port.Eval(context)
            forces = self.forces_port.Eval(context).tolist()
            for k in moving:
                x0, x1, v0, v1 = s[4 * k : 4 * k + 4].tolist()
                out[4 * k : 4 * k + 4] = (v0, v1, *self._acceleration(params, k, x0, x1, v0, v1, offsets, forces))
        derivatives.SetFromVector(out)

    def _member_out(self, q: int, k: int):
        b = 4 * (len(self.robot_names) + len(self.object_names) + q)

        def calc(context, output):
            s = context.get_continuous_state_vector().CopyToVector()[b : b + 4]
            s[:2] += self._syncs.Eval(context).offsets[q][k]
            output.SetFromVector(s)
        return calc
