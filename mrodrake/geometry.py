"""Planar geometry helpers (shapely): polygon checks, workspace free space, disks, grasp layouts.

Used by the scenario validator, the transition system (covering radii r_A,j) and the controllers
(free space of one moving entity, paper Section III-A: F_i = (W_f \\ O_i) ⊖ r_i).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import shapely
from shapely.geometry import LinearRing, Point, Polygon
from shapely.validation import explain_validity

#: Segments per quarter circle used when a disk is turned into a polygon.
DISK_QUAD_SEGS = 16


def ring_problem(points: Sequence[Sequence[float]]) -> str | None:
    """Why ``points`` is not a simple polygon (``None`` when it is one)."""
    pts = [tuple(map(float, p)) for p in points]
    if len(pts) >= 2 and pts[0] == pts[-1]:
        pts = pts[:-1]
    if len(pts) < 3:
        return f"a polygon needs at least 3 vertices, got {len(pts)}"
    for k in range(len(pts)):
        if pts[k] == pts[(k + 1) % len(pts)]:
            return f"vertices {k} and {(k + 1) % len(pts)} coincide"
    ring = LinearRing(pts)
    if not ring.is_simple:
        return f"polygon is not simple (self-intersecting): {explain_validity(Polygon(pts))}"
    poly = Polygon(pts)
    if poly.area <= 0.0:
        return "polygon has zero area"
    return None


def polygon(points: Sequence[Sequence[float]]) -> Polygon:
    """A shapely polygon from a vertex list, oriented counter-clockwise."""
    return shapely.geometry.polygon.orient(Polygon([tuple(map(float, p)) for p in points]), 1.0)


def disk(center: Sequence[float], radius: float, quad_segs: int = DISK_QUAD_SEGS) -> Polygon:
    """Polygonal disk circumscribing the true disk (so that it never under-approximates it)."""
    inflate = 1.0 / math.cos(math.pi / (4 * quad_segs))
    return Point(float(center[0]), float(center[1])).buffer(radius * inflate, quad_segs=quad_segs)


def workspace_free_space(boundary: Polygon, obstacles: Sequence[Polygon]) -> Polygon:
    """W_f = W minus the obstacles (paper Section II-B)."""
    free = boundary
    for obs in obstacles:
        free = free.difference(obs)
    return free


def disk_inside(free: Polygon, center: Sequence[float], radius: float) -> bool:
    """Whether the closed ball B̄(center, radius) lies in the (closed) polygon ``free``."""
    p = Point(float(center[0]), float(center[1]))
    if not free.covers(p):
        return False
    return free.boundary.distance(p) >= radius


@dataclass(frozen=True)
class GraspLayout:
    """Where the robots of a team sit around an object while transporting it.

    ``offsets[k]`` is x_i − x^o_j for the k-th robot of the team (the paper's −d^o_ij), measured
    in the team's reference orientation; ``covering_radius`` is r_A,j of the coupled entity (paper
    Section II): the smallest disk centred at the object that covers the object and every robot.
    """

    offsets: np.ndarray
    covering_radius: float
    distance: float


def grasp_layout(object_radius: float, robot_radii: Sequence[float], gap: float) -> GraspLayout:
    """Robots evenly spaced around the object's rim, each ``gap`` away from it (or further out when
    neighbours would otherwise overlap: adjacent centres are at least r_a + r_b + gap apart)."""
    n = len(robot_radii)
    if n == 0:
        return GraspLayout(np.zeros((0, 2)), float(object_radius), 0.0)
    radii = [float(r) for r in robot_radii]
    d = object_radius + max(radii) + gap
    if n >= 2:
        chord = 2.0 * math.sin(math.pi / n)
        for k in range(n):
            need = (radii[k] + radii[(k + 1) % n] + gap) / chord
            d = max(d, need)
    angles = 2.0 * math.pi * np.arange(n) / n
    offsets = d * np.column_stack([np.cos(angles), np.sin(angles)])
    cover = max(d + max(radii), object_radius)
    return GraspLayout(offsets, float(cover), float(d))
