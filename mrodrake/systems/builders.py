"""``AddX(builder, ...)`` helpers that put the systems of a mission into a DiagramBuilder and return typed
handles (Drake idiom: RussTedrake/manipulation's ``AddIiwa`` & co.).

* :func:`AddEntityPlants`: a synced plant per robot and per object (true masses and frictions);
* :func:`AddNavigationControllers`: an adaptive navigation controller per robot, wired to its plant;
* :func:`AddTeams`: a team plant and a transport controller per (object, team) of the plan's transports;
* :func:`AddStateSwitches`: a PortSwitch per robot and object choosing its authoritative [x, ẋ] (its own
  plant, or the team plant it is coupled to), with the index of every input;
* :func:`AddSupervisor`: the supervisor with every task, sync and select connection.
"""

from __future__ import annotations

from dataclasses import dataclass

from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import PortSwitch

from mrodrake.control.adaptive import AdaptiveGains
from mrodrake.execution.sequencer import Sequencer
from mrodrake.scenario import Scenario
from mrodrake.systems.controllers import NavigationController, TransportController
from mrodrake.systems.plants import SyncedCoupledPlant, SyncedObjectPlant, SyncedRobotPlant
from mrodrake.systems.supervisor import Supervisor


@dataclass(frozen=True)
class EntityPlants:
    """The synced plant of every robot and object, by name."""

    robots: dict[str, SyncedRobotPlant]
    objects: dict[str, SyncedObjectPlant]

    def all(self) -> dict:
        return {**self.robots, **self.objects}


@dataclass(frozen=True)
class Team:
    """A team plant of object ``obj`` (index) grasped by robots ``team`` (indices), with its controller."""

    name: str
    obj: int
    team: tuple[int, ...]
    plant: SyncedCoupledPlant
    controller: TransportController


@dataclass(frozen=True)
class StateSwitches:
    """One PortSwitch per entity; ``route_ports[(entity, team name)]`` is the switch input carrying the
    entity's state from that team plant (input 1 is the entity's own plant)."""

    switches: dict[str, PortSwitch]
    route_ports: dict[tuple[str, str], int]


def AddEntityPlants(builder: DiagramBuilder, scenario: Scenario) -> EntityPlants:
    robots = {r.name: builder.AddSystem(SyncedRobotPlant(r.mass, r.friction, name=r.name)) for r in scenario.robots}
    objects = {o.name: builder.AddSystem(SyncedObjectPlant(o.mass, o.friction, name=o.name))
               for o in scenario.objects}
    return EntityPlants(robots, objects)


def AddNavigationControllers(builder: DiagramBuilder, scenario: Scenario, plants: EntityPlants,
                             gains: AdaptiveGains) -> dict[str, NavigationController]:
    """A navigation controller ``nav_<robot>`` per robot driving its plant (its state input is connected by
    :func:`AddStateSwitches`)."""
    out = {}
    for r in scenario.robot_names:
        c = builder.AddSystem(NavigationController(None, gains, name=f"nav_{r}"))
        builder.Connect(c.u_port, plants.robots[r].u_port)
        out[r] = c
    return out


def AddTeams(builder: DiagramBuilder, scenario: Scenario, sequencer: Sequencer, gains: AdaptiveGains) -> list[Team]:
    """A team plant and a transport controller ``<name>_ctrl`` per coupling of ``sequencer``."""
    out = []
    for j, team in sequencer.couplings:
        o, rs = scenario.objects[j], [scenario.robots[i] for i in team]
        name = sequencer.team_name(j, team)
        plant = builder.AddSystem(SyncedCoupledPlant(o.mass, o.friction, [r.name for r in rs], [r.mass for r in rs],
                                                     [r.friction for r in rs], name=name))
        ctrl = builder.AddSystem(TransportController([r.name for r in rs], None, gains, name=name + "_ctrl"))
        for u_out, u_in in zip(ctrl.member_u_ports, plant.u_ports):
            builder.Connect(u_out, u_in)
        builder.Connect(plant.state_port, ctrl.state_port)
        out.append(Team(name, j, team, plant, ctrl))
    return out


def AddStateSwitches(builder: DiagramBuilder, scenario: Scenario, plants: EntityPlants, teams: list[Team],
                     navs: dict[str, NavigationController]) -> StateSwitches:
    """The switches, their inputs (own plant first, then every team plant the entity belongs to) and the
    robots' controller state inputs."""
    switches, route = {}, {}
    for e, plant in plants.all().items():
        sw = builder.AddSystem(PortSwitch(4))
        sw.set_name(f"switch_{e}")
        builder.Connect(plant.state_port, sw.DeclareInputPort(f"{e}_own"))
        switches[e] = sw
    for t in teams:
        obj = scenario.object_names[t.obj]
        port = switches[obj].DeclareInputPort(t.name)
        builder.Connect(t.plant.state_port, port)
        route[(obj, t.name)] = int(port.get_index())
        for k, i in enumerate(t.team):
            r = scenario.robot_names[i]
            port = switches[r].DeclareInputPort(t.name)
            builder.Connect(t.plant.member_ports[k], port)
            route[(r, t.name)] = int(port.get_index())
    for r, c in navs.items():
        builder.Connect(switches[r].get_output_port(), c.state_port)
    return StateSwitches(switches, route)


def AddSupervisor(builder: DiagramBuilder, sequencer: Sequencer, plants: EntityPlants, teams: list[Team],
                  navs: dict[str, NavigationController], switches: StateSwitches, period: float) -> Supervisor:
    """The supervisor reading every switch output and driving every task, sync and selector."""
    sup = builder.AddSystem(Supervisor(sequencer, switches.route_ports, period))
    for k, e in enumerate(sequencer.entities):
        builder.Connect(switches.switches[e].get_output_port(), sup.state_ports[k])
        builder.Connect(sup.select_ports[e], switches.switches[e].get_port_selector_input_port())
    for e, p in plants.all().items():
        builder.Connect(sup.sync_ports[e], p.sync_port)
    for t in teams:
        builder.Connect(sup.sync_ports[t.name], t.plant.sync_port)
        builder.Connect(sup.task_ports[t.name + "_ctrl"], t.controller.task_port)
    for r, c in navs.items():
        builder.Connect(sup.task_ports[f"nav_{r}"], c.task_port)
    return sup
