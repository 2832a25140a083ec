"""Control data of one primitive, shared by the single-transition builder and the mission: the point-world
navigation task of an entity's free space (paper Sec. III-A) and static P_s layouts of entities."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from mrodrake.control.adaptive import AdaptiveGains, NavigationTask
from mrodrake.control.freespace import Disk, EntityFreeSpace, region_index
from mrodrake.control.pointworld import PointWorldMap
from mrodrake.errors import UserError
from mrodrake.geometry import grasp_layout
from mrodrake.packing import place
from mrodrake.scenario import Scenario

#: Point-world map options used by :func:`build_task`: panels on curved boundaries (the enlarged door
#: jambs, obstacle corners and disks) at most 0.1 x the radius of curvature.  With the default 0.5 the map
#: missed the unit circle by up to 2e-2 along door-jamb arcs and entities slipped through jambs in the
#: property tests (2 of 25 still did with 0.2, none with 0.1); 0.1 divides the error by ~10.  Holes get
#: the same fraction (``hole_refinement`` 1: the map's own blob refinement still applies).
MAP_OPTIONS = {"curvature_fraction": 0.1, "hole_refinement": 1.0}


def build_task(scenario: Scenario, free: EntityFreeSpace, n_members: int = 1, cf: Sequence[float] | None = None,
               label: str = "", **map_options) -> NavigationTask:
    """The map H of ``free.polygon`` (options: :data:`MAP_OPTIONS` updated by ``map_options``) and φ for
    ``free.goal`` with the scenario's gains (caps r̄, τ; the start is kept out of every barrier region,
    see :meth:`NavigationTask.build`)."""
    c = scenario.control
    pw = PointWorldMap.build(free.polygon, **{**MAP_OPTIONS, **map_options})
    return NavigationTask.build(pw, free.goal, AdaptiveGains.from_scenario(c), k1=c.k1, k2=c.k2, r_bar_cap=c.r_bar,
                                tau_cap=c.tau, cf=n_members if cf is None else cf, start=free.start, label=label)


def entity_layout(scenario: Scenario, regions: Mapping[str, int | str] | None = None,
                  teams: Mapping[str, Sequence[str]] | None = None, seed: int = 0,
                  reserve: Mapping[int | str, Sequence[tuple[str, float]]] | None = None) -> dict[str, Disk]:
    """Static disks of every entity placed in its region by P_s (``place`` of all entities of a region
    together: spread out, every gap between them and to the rim at least the layout spacing).

    ``regions`` maps entity names to regions (default: the initial regions); ``teams`` maps an object to the
    robots grasping it: the team is one entity at the object's centre with covering radius r_A,j and its
    robots get no disk of their own.  ``reserve`` adds extra named disks {region: [(name, radius)]} to the
    packing (e.g. the goal spot of an entity about to arrive) and returns them too.
    """
    teams = {o: list(t) for o, t in (teams or {}).items()}
    in_team = {r for t in teams.values() for r in t}
    where = {r.name: r.initial_region for r in scenario.robots}
    where.update({o.name: o.initial_region for o in scenario.objects})
    if regions:
        where.update(regions)
    radius = {}
    for r in scenario.robots:
        if r.name not in in_team:
            radius[r.name] = r.radius
    for o in scenario.objects:
        members = teams.get(o.name, [])
        radius[o.name] = team_radius(scenario, o.name, members) if members else o.radius
    by_region: dict[int, list[str]] = {}
    for name in radius:
        by_region.setdefault(region_index(scenario, where[name]), []).append(name)
    for reg_id, extra in (reserve or {}).items():
        for name, rad in extra:
            radius[name] = float(rad)
            by_region.setdefault(region_index(scenario, reg_id), []).append(name)
    out = {}
    for k, names in sorted(by_region.items()):
        reg = scenario.regions[k]
        sol = place(reg.radius, np.empty((0, 2)), [], [radius[n] for n in names], seed=seed,
                    margin=scenario.layout.spacing)
        if sol is None:
            raise UserError(f"region '{reg.name}': entities {', '.join(names)} do not fit (P_s found no packing)")
        for n, c in zip(names, sol):
            out[n] = Disk(n, (float(reg.center[0] + c[0]), float(reg.center[1] + c[1])), radius[n])
    return out


def team_radius(scenario: Scenario, obj: str, team: Sequence[str]) -> float:
    """Covering radius r_A,j of object ``obj`` grasped by the robots ``team`` (names)."""
    o = scenario.objects[scenario.object_names.index(obj)]
    radii = [scenario.robots[scenario.robot_names.index(r)].radius for r in team]
    return grasp_layout(o.radius, radii, scenario.layout.grasp_gap).covering_radius
