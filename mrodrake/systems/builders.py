"""``AddX(builder, ...)`` helpers that put the systems of a mission into a DiagramBuilder and return typed
handles (Drake idiom: RussTedrake/manipulation's ``AddIiwa`` & co.).

* :func:`AddEntityPlants`: the plants of every robot, object and (object, team) of the plan's transports
  (true masses and frictions), one :class:`~mrodrake.systems.plants.MissionPlants` system with a
  Demultiplexer giving each plant's [x, ẋ] its own port;
* :func:`teams_of`: the team plants of the plan's transports;
* :func:`AddControllers`: an adaptive navigation controller per robot and a transport controller per team
  plant, one :class:`~mrodrake.systems.controllers.MissionControllers` system whose ``forces`` output drives
  the plants' ``forces`` input (every robot's u and every team member's u_ℓ, one vector);
* :func:`AddStateSwitches`: a PortSwitch per robot and object choosing its authoritative [x, ẋ] (its own
  plant, or the team plant it is coupled to), with the index of every input, and a Multiplexer stacking them;
* :func:`AddSupervisor`: the supervisor with every task, sync and select connection.
"""

from __future__ import annotations

from dataclasses import dataclass

from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Demultiplexer, Multiplexer, PortSwitch

from mrodrake.control.adaptive import AdaptiveGains
from mrodrake.execution.sequencer import Sequencer
from mrodrake.scenario import Scenario
from mrodrake.systems.controllers import MissionControllers
from mrodrake.systems.plants import MissionPlants
from mrodrake.systems.supervisor import Supervisor


@dataclass(frozen=True)
class EntityPlants:
    """The plants of a mission: ``system`` (every robot, object and team plant) and ``demux`` (one [x, ẋ]
    output per plant, in ``system.names`` order)."""

    system: MissionPlants
    demux: Demultiplexer

    @property
    def names(self) -> list[str]:
        return list(self.system.names)

    @property
    def entities(self) -> list[str]:
        """The robots, then the objects."""
        return self.system.robot_names + self.system.object_names

    def state_port(self, plant: str):
        """The output port carrying [x, ẋ] of ``plant`` (a robot, object or team name)."""
        return self.demux.get_output_port(self.system.index(plant))


@dataclass(frozen=True)
class Team:
    """A team plant of object ``obj`` (index) grasped by robots ``team`` (indices, names ``members``), driven
    by the transport controller named ``controller``."""

    name: str
    obj: int
    team: tuple[int, ...]
    members: tuple[str, ...]
    controller: str


@dataclass(frozen=True)
class StateSwitches:
    """One PortSwitch per entity; ``route_ports[(entity, team name)]`` is the switch input carrying the
    entity's state from that team plant (input 1 is the entity's own plant); ``mux`` stacks the switch outputs
    in entity order (robots, then objects)."""

    switches: dict[str, PortSwitch]
    route_ports: dict[tuple[str, str], int]
    mux: Multiplexer

    @property
    def states_port(self):
        """The output port carrying the routed [x, ẋ] of every entity, 4 entries each."""
        return self.mux.get_output_port(0)


def AddEntityPlants(builder: DiagramBuilder, scenario: Scenario, sequencer: Sequencer) -> EntityPlants:
    """The plants of every robot and object and a team plant per coupling of ``sequencer``."""
    teams = [(sequencer.team_name(j, team), j, team) for j, team in sequencer.couplings]
    system = builder.AddSystem(MissionPlants(scenario, teams))
    demux = builder.AddSystem(Demultiplexer(4 * len(system.names), 4))
    demux.set_name("plant_states")
    builder.Connect(system.state_port, demux.get_input_port(0))
    return EntityPlants(system, demux)


def teams_of(scenario: Scenario, sequencer: Sequencer) -> list[Team]:
    """The team plants of ``sequencer``'s couplings, with the name of each one's transport controller."""
    return [Team(sequencer.team_name(j, team), j, tuple(team), tuple(scenario.robots[i].name for i in team),
                 sequencer.team_name(j, team) + "_ctrl") for j, team in sequencer.couplings]


def AddControllers(builder: DiagramBuilder, scenario: Scenario, plants: EntityPlants, teams: list[Team],
                   gains: AdaptiveGains) -> MissionControllers:
    """A navigation controller ``nav_<robot>`` per robot and a transport controller per team plant, in one
    :class:`~mrodrake.systems.controllers.MissionControllers` system driving their plants (the robots' state
    inputs are connected by :func:`AddStateSwitches`)."""
    specs = [(f"nav_{r}", ()) for r in scenario.robot_names] + [(t.controller, t.members) for t in teams]
    ctrl = builder.AddSystem(MissionControllers(specs, gains))
    driven = {f"nav_{r}": r for r in scenario.robot_names} | {t.controller: t.name for t in teams}
    if [(driven[c], n) for c, n in ctrl.force_slots] != plants.system.force_slots:
        raise ValueError("the controllers' forces are not laid out as the plants' force input")
    builder.Connect(ctrl.forces_port, plants.system.forces_port)
    for t in teams:
        builder.Connect(plants.state_port(t.name), ctrl.state_ports[t.controller])
    return ctrl


def AddStateSwitches(builder: DiagramBuilder, scenario: Scenario, plants: EntityPlants, teams: list[Team],
                     controllers: MissionControllers) -> StateSwitches:
    """The switches, their inputs (own plant first, then every team plant the entity belongs to), the
    robots' controller state inputs and the Multiplexer of all routed states."""
    switches, route = {}, {}
    for e in plants.entities:
        sw = builder.AddSystem(PortSwitch(4))
        sw.set_name(f"switch_{e}")
        builder.Connect(plants.state_port(e), sw.DeclareInputPort(f"{e}_own"))
        switches[e] = sw
    for t in teams:
        obj = scenario.object_names[t.obj]
        port = switches[obj].DeclareInputPort(t.name)
        builder.Connect(plants.state_port(t.name), port)
        route[(obj, t.name)] = int(port.get_index())
        for k, r in enumerate(t.members):
            port = switches[r].DeclareInputPort(t.name)
            builder.Connect(plants.system.member_ports[t.name][k], port)
            route[(r, t.name)] = int(port.get_index())
    for r in scenario.robot_names:
        builder.Connect(switches[r].get_output_port(), controllers.state_ports[f"nav_{r}"])
    mux = builder.AddSystem(Multiplexer([4] * len(plants.entities)))
    mux.set_name("routed_states")
    for k, e in enumerate(plants.entities):
        builder.Connect(switches[e].get_output_port(), mux.get_input_port(k))
    return StateSwitches(switches, route, mux)


def AddSupervisor(builder: DiagramBuilder, sequencer: Sequencer, plants: EntityPlants,
                  controllers: MissionControllers, switches: StateSwitches, period: float) -> Supervisor:
    """The supervisor reading the routed states and driving every task, sync and selector."""
    sup = builder.AddSystem(Supervisor(sequencer, switches.route_ports, period))
    builder.Connect(switches.states_port, sup.states_port)
    for e in sequencer.entities:
        builder.Connect(sup.select_ports[e], switches.switches[e].get_port_selector_input_port())
    for p in plants.names:
        builder.Connect(sup.sync_ports[p], plants.system.sync_ports[p])
    for c in sequencer.controllers:
        builder.Connect(sup.task_ports[c], controllers.task_ports[c])
    return sup
