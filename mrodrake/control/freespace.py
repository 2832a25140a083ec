"""Free space of one moving entity and goal points (paper Sec. III-A).

A moving entity (a robot, or a robots-object team with covering radius r_A,j) sees the workspace obstacles,
the other entities (static disks) and the regions of interest other than its start and goal ("avoid
entering other RoIs"), all enlarged by its radius, and the outer boundary shrunk by it:

    F = (W_f \\ O) ⊖ r,    O = ⋃_{other entities} B̄(x^e_ℓ, r^e_ℓ) ∪ ⋃_{k ∉ {start, goal}} π_k.

Shapely approximates arcs by chords whose vertices lie on the circle; every enlargement therefore uses the
radius r / cos(π / (4 q)) (q segments per quarter circle), so that the polygonal Minkowski sums contain the
exact ones and F never over-approximates the true free space.  F is further eroded by ``safety`` (mitre
joins): this opens pinch points where an enlarged obstacle touches the boundary or another obstacle, so
that touching holes merge, and keeps every point of F strictly collision-free.

Numerical margin (our addition).  The guarantee assumes an exact map H.  The panel solution of H is off
by ~1e-4 (median) to ~1e-2 (corners) on the outer boundary, while the barrier of φ acts only where
1 − ‖χ‖² < τ ~ 1e-6: an entity cutting a door jamb can cross ∂F by a few decimetres (0.28 m seen in the
property tests).  Walls, workspace obstacles and the other regions are therefore enlarged by r + margin
(``control.margin``, default 0.5 m; the error scales with the floor, so a small floor can use a
smaller one).  The other entities are enlarged by r only: they are packed ``layout.spacing`` apart
(0.1 m), so a margin would put the start inside their holes, and their small round holes are resolved
finely by the map.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely.geometry import Point, Polygon

from mrodrake.errors import UserError
from mrodrake.geometry import DISK_QUAD_SEGS, disk, free_space_parts, polygon
from mrodrake.packing import place
from mrodrake.scenario import Scenario

#: Default erosion of F beyond the entity radius (m): opens pinch points, keeps clearance strictly positive.
DEFAULT_SAFETY = 1e-3
_CHORD = 1.0 / math.cos(math.pi / (4 * DISK_QUAD_SEGS))


@dataclass(frozen=True)
class Disk:
    """A static disk entity (another robot, object or team) at ``center`` with covering ``radius``."""

    name: str
    center: tuple[float, float]
    radius: float


@dataclass
class EntityFreeSpace:
    """F of one entity for one transition, plus the raw geometry it was made from (for figures/tests).

    ``polygon``: F (one connected Polygon with holes); ``radius``: the entity radius r;
    ``hole_names[ℓ]``: names of the obstacles merged into ``polygon.interiors[ℓ]``;
    ``obstacles``: (name, unbuffered polygon) of everything avoided (workspace obstacles, other entities,
    other regions); ``boundary``: the unbuffered workspace polygon.
    """

    polygon: Polygon
    radius: float
    start: np.ndarray
    goal: np.ndarray
    boundary: Polygon
    obstacles: list[tuple[str, Polygon]] = field(default_factory=list)
    hole_names: list[list[str]] = field(default_factory=list)


def region_index(scenario: Scenario, region: int | str) -> int:
    """Index of a region given by index or name (UserError naming the region otherwise)."""
    names = scenario.region_names
    if isinstance(region, str):
        if region not in names:
            raise UserError(f"region '{region}': unknown (regions: {', '.join(names)})")
        return names.index(region)
    k = int(region)
    if not 0 <= k < len(names):
        raise UserError(f"region index {k}: out of range 0..{len(names) - 1}")
    return k


def entity_free_space(
    scenario: Scenario,
    radius: float,
    start,
    goal,
    src_region: int | str,
    dst_region: int | str,
    others: Sequence[Disk] = (),
    safety: float = DEFAULT_SAFETY,
    margin: float | None = None,
    confine: Polygon | None = None,
) -> EntityFreeSpace:
    """F = (W_f \\ O) ⊖ r for an entity of ``radius`` moving from ``start`` (in ``src_region``) to
    ``goal`` (in ``dst_region``), the ``others`` being static; the component of F containing ``start``
    (of F ∩ ``confine`` if given: the corridor of a concurrent motion, :mod:`mrodrake.execution.schedule`).

    Walls, workspace obstacles and the other regions are enlarged by r + ``margin`` (default: the scenario's
    ``control.margin``; see the module docstring), the other entities by r.  Raises UserError when the start
    is not in F or the goal is not in the same component ("goal unreachable").
    """
    r = float(radius)
    if not (math.isfinite(r) and r > 0.0):
        raise UserError(f"radius: must be a finite positive number, got {radius!r}")
    src, dst = region_index(scenario, src_region), region_index(scenario, dst_region)
    start = np.asarray(start, dtype=float).reshape(2)
    goal = np.asarray(goal, dtype=float).reshape(2)
    margin = scenario.control.margin if margin is None else margin
    if not (math.isfinite(margin) and margin >= 0.0):
        raise UserError(f"margin: must be a finite number >= 0, got {margin!r}")
    boundary = polygon(scenario.workspace.boundary)
    obstacles: list[tuple[str, Polygon]] = [(o.name, polygon(o.polygon)) for o in scenario.workspace.obstacles]
    for k, reg in enumerate(scenario.regions):
        if k not in (src, dst):
            obstacles.append((reg.name, disk(reg.center, reg.radius)))
    parts, enlarged = free_space_parts(boundary, [g for _, g in obstacles], [(d.center, d.radius) for d in others],
                                       r, float(margin), safety)
    if confine is not None:
        cut = [p.intersection(confine) for p in parts]
        parts = [g for c in cut for g in (c.geoms if hasattr(c, "geoms") else [c]) if isinstance(g, Polygon)
                 and not g.is_empty]
    obstacles += [(d.name, disk(d.center, d.radius)) for d in others]
    p_start, p_goal = Point(start), Point(goal)
    comp = next((p for p in parts if p.contains(p_start)), None)
    if comp is None:
        raise UserError(f"start ({start[0]:.3f}, {start[1]:.3f}): not in the free space of an entity of radius "
                        f"{r:g} (collides with an obstacle, a wall, another entity or another region)")
    if not comp.contains(p_goal):
        inside = any(p.contains(p_goal) for p in parts)
        why = "separated from the start by obstacles" if inside else "not in the free space"
        raise UserError(f"goal unreachable: ({goal[0]:.3f}, {goal[1]:.3f}) in region "
                        f"'{scenario.regions[dst].name}' is {why} for an entity of radius {r:g} "
                        f"(+ {margin:g} m margin to walls, obstacles and other regions)")
    comp = shapely.geometry.polygon.orient(comp, 1.0)
    hole_names = []
    for ring in comp.interiors:
        hole = Polygon(ring)
        hole_names.append([name for (name, _), g in zip(obstacles, enlarged) if g.intersects(hole)])
    return EntityFreeSpace(comp, r, start, goal, boundary, obstacles, hole_names)


def goal_point(
    scenario: Scenario,
    region: int | str,
    radius: float,
    occupants: Sequence[Disk] = (),
    seed: int = 0,
    margin: float | None = None,
    future: Sequence[float] = (),
) -> np.ndarray:
    """Goal x_d of an entity of ``radius`` in ``region`` given the entities already there (P_s, paper
    Sec. III-A), keeping ``margin`` (default: the layout spacing) to them and to the region's rim.
    ``future``: radii of entities that will join it there later; the goal is then taken from a joint
    placement of all of them, so that it leaves room for them."""
    k = region_index(scenario, region)
    reg = scenario.regions[k]
    c = np.asarray(reg.center, dtype=float)
    gap = scenario.layout.spacing if margin is None else float(margin)
    fc = np.array([np.asarray(d.center, dtype=float) - c for d in occupants]).reshape(-1, 2)
    fr = [float(d.radius) for d in occupants]
    sol = place(reg.radius, fc, fr, [float(radius)] + [float(f) for f in future], seed=int(seed), margin=gap)
    if sol is None:
        later = f" and later ones of radii {', '.join(f'{f:g}' for f in future)}" if len(future) else ""
        raise UserError(f"region '{reg.name}': no room for an entity of radius {radius:g}{later} next to "
                        f"{', '.join(d.name for d in occupants) or 'nothing'} (P_s found no placement)")
    return c + sol[0]


def clearances(scenario: Scenario, positions, radius: float, others: Sequence[Disk] = (),
               avoid_regions: Sequence[int | str] = ()) -> dict[str, np.ndarray]:
    """Clearance (m) of the ball B̄(x, radius) at each of ``positions`` (n, 2) from the raw scenario
    geometry, per item: ``wall`` (outer boundary), each obstacle name, each other entity name and each
    region in ``avoid_regions`` (by name).  Negative means overlap.  Independent of any map or buffer."""
    pts = np.asarray(positions, dtype=float).reshape(-1, 2)
    r = float(radius)
    geo = shapely.points(pts)
    boundary = polygon(scenario.workspace.boundary)
    inside = shapely.contains_xy(boundary, pts[:, 0], pts[:, 1])
    wall = shapely.distance(boundary.exterior, geo) - r
    out = {"wall": np.where(inside, wall, -np.abs(wall) - 2.0 * r)}
    for o in scenario.workspace.obstacles:
        poly = polygon(o.polygon)
        out[o.name] = shapely.distance(poly, geo) - r
    for d in others:
        out[d.name] = np.hypot(pts[:, 0] - d.center[0], pts[:, 1] - d.center[1]) - d.radius - r
    for reg_id in avoid_regions:
        reg = scenario.regions[region_index(scenario, reg_id)]
        out[reg.name] = np.hypot(pts[:, 0] - reg.center[0], pts[:, 1] - reg.center[1]) - reg.radius - r
    return out


def inside_region(scenario: Scenario, region: int | str, position, radius: float, tol: float = 0.0) -> bool:
    """Whether the ball B̄(position, radius) lies in region π_k (with ``tol`` to spare)."""
    reg = scenario.regions[region_index(scenario, region)]
    p = np.asarray(position, dtype=float)
    return bool(math.hypot(p[0] - reg.center[0], p[1] - reg.center[1]) + radius + tol <= reg.radius)
