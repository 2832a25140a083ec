"""Control data of one primitive, shared by the single-transition builder and the mission: the point-world
navigation task of an entity's free space (paper Sec. III-A) and static P_s layouts of entities."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import shapely

from mrodrake.control.adaptive import AdaptiveGains, NavigationTask, circle_radius
from mrodrake.control.freespace import Disk, EntityFreeSpace, region_index
from mrodrake.control.local import local_path
from mrodrake.control.pointworld import PointWorldMap
from mrodrake.errors import UserError
from mrodrake.geometry import grasp_layout
from mrodrake.packing import place
from mrodrake.scenario import Scenario

#: Point-world map options used by :func:`build_task`: panels on the curved parts of the outer boundary (the
#: enlarged door jambs) at most 0.1 x the radius of curvature.  With the default 0.5 the map missed the unit
#: circle by up to 2e-2 along door-jamb arcs and entities slipped through jambs in the property tests (2 of
#: 25 still did with 0.2, none with 0.1); 0.1 divides the error by ~10.  Holes (obstacle corners, disks)
#: collapse to points instead and the map's blob refinement re-solves any whose image is too large, so their
#: curved parts take 0.2 where that is at most 0.1 x their gap to the nearest other boundary (``PointWorldMap.
#: build``'s ``curved_gap_fraction``; on case study I: ~20 % fewer panels, half the build time of a navigation
#: map, images ≤ 0.07 of their separation against the 0.08 that triggers a re-solve).
MAP_OPTIONS = {"curvature_fraction": 0.1, "hole_curvature_fraction": 0.2, "hole_refinement": 1.0}


def build_map(free: EntityFreeSpace, **map_options) -> PointWorldMap:
    """The point-world map H of ``free.polygon`` (options: :data:`MAP_OPTIONS` updated by ``map_options``)."""
    return PointWorldMap.build(free.polygon, **{**MAP_OPTIONS, **map_options})


def inside_circle(pw_map: PointWorldMap, points) -> np.ndarray:
    """Whether each of ``points`` (n, 2) maps strictly inside the circle barrier ρ₀ of ``pw_map``."""
    chi = np.asarray(pw_map(np.asarray(points, dtype=float).reshape(-1, 2)), dtype=float).reshape(-1, 2)
    return np.linalg.norm(chi, axis=1) < circle_radius(pw_map)


def build_task(scenario: Scenario, free: EntityFreeSpace, n_members: int = 1, cf: Sequence[float] | None = None,
               label: str = "", pw_map: PointWorldMap | None = None, **map_options) -> NavigationTask:
    """The map H of ``free.polygon`` (``pw_map``, or built by :func:`build_map` with ``map_options``) and φ for
    ``free.goal`` with the scenario's gains (caps r̄, τ; the start is kept out of every barrier region,
    see :meth:`NavigationTask.build`)."""
    c = scenario.control
    pw = build_map(free, **map_options) if pw_map is None else pw_map
    return NavigationTask.build(pw, free.goal, AdaptiveGains.from_scenario(c), k1=c.k1, k2=c.k2, r_bar_cap=c.r_bar,
                                tau_cap=c.tau, cf=n_members if cf is None else cf, start=free.start, label=label)


#: Distances (m) from the start searched for a departure point (:func:`departure_point`).
DEPARTURE_STEPS = np.arange(1, 13) * 0.05
_DEPARTURE_ANGLES = 32


def departure_point(pw_map: PointWorldMap, free: EntityFreeSpace, centers, radii, rim_center, rim_radius: float,
                    tol: float) -> np.ndarray | None:
    """A point near ``free.start`` from which the point-world law can start when the start itself maps
    outside the circle barrier ρ₀ = 1 − κ δ_max (a start a spacing away from another entity whose grown disk
    merges with the walls lies on the outer boundary's band, where the discrete map falls short of the unit
    circle): the nearest point (rings every 0.05 m up to 0.6 m) that is reachable from the start by a
    straight-leg local path inside the disk (rim_center, rim_radius) around the grown disks (centers, radii)
    and that maps inside ρ₀ together with every point ``tol`` around it (the local law ends within ``tol``
    of its goal); None if there is none."""
    s = np.asarray(free.start, dtype=float)
    ang = np.arange(_DEPARTURE_ANGLES) * (2.0 * math.pi / _DEPARTURE_ANGLES)
    ring = np.column_stack([np.cos(ang), np.sin(ang)])
    around = np.vstack([[0.0, 0.0], tol * ring[::4]])
    c = np.asarray(centers, dtype=float).reshape(-1, 2)
    rho = np.asarray(radii, dtype=float).reshape(-1)
    rc = np.asarray(rim_center, dtype=float).reshape(2)
    for d in DEPARTURE_STEPS:
        pts = s + d * ring
        ok = np.linalg.norm(pts - rc, axis=1) <= rim_radius - tol
        if len(c):
            ok &= np.all(np.linalg.norm(pts[:, None, :] - c[None, :, :], axis=-1) - rho[None, :] >= tol, axis=1)
        ok &= shapely.contains_xy(free.polygon, pts[:, 0], pts[:, 1])
        if not ok.any():
            continue
        cand = pts[ok]
        good = inside_circle(pw_map, (cand[:, None, :] + around[None, :, :]).reshape(-1, 2))
        for p in cand[good.reshape(len(cand), len(around)).all(axis=1)]:
            try:
                local_path(s, p, c, rho, rc, rim_radius)
            except ValueError:
                continue
            return p
    return None


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
