"""Planar geometry helpers (shapely): polygon checks, workspace free space, disks, grasp layouts.

Used by the scenario validator, the transition system (covering radii r_A,j) and the controllers
(free space of one moving entity, paper Sec. III-A: F_i = (W_f \\ O_i) ⊖ r_i).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from scipy.sparse.csgraph import dijkstra
from shapely.geometry import LinearRing, Point, Polygon
from shapely.ops import unary_union
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
    """W_f = W minus the obstacles (paper Sec. II-B)."""
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
    Sec. II-B): the smallest disk centred at the object that covers the object and every robot.
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


#: Clearance (m) a moving entity keeps from walls, workspace obstacles and other regions beyond its radius
#: (the controllers' numerical margin, see :mod:`mrodrake.control.freespace`).
CONTROL_MARGIN = 0.5
#: Distance (m) to its goal at which the sequencer completes a docking, back-off or room move.
DOCK_TOL = 0.03
#: Distance (m) to its planned spot at which the sequencer completes a navigation or transport.
GOAL_TOL = 0.05
#: Slack (m) on a robots-object team's covering radius wherever its travel between regions is checked: its
#: members dock within :data:`DOCK_TOL` of their slots, so the disk that travels is up to that much larger
#: than the planned covering radius; the rest covers rounding.
TEAM_TRAVEL_SLACK = 0.05
#: Erosion (m) of a free space beyond radius and margin: opens pinch points where enlarged obstacles touch.
FREE_SPACE_SAFETY = 1e-3
_CHORD = 1.0 / math.cos(math.pi / (4 * DISK_QUAD_SEGS))


class RegionGraph:
    """Which regions an entity of a given radius can travel between.

    The travel space of a trip from region k to k' is where the entity's centre may be: the workspace shrunk
    by r + margin, minus the obstacles and the regions other than k and k' grown by r + margin (the
    controllers avoid other regions), eroded by ``safety``; other entities are ignored (they can be moved).
    k and k' are connected when one component of it meets the seats of both (the centres whose ball lies in
    the region).  A narrow passage, or another region in the way, separates them.

    Queries are answered per pair and cached: radii are rounded up to :data:`RADIUS_STEP` (a larger radius
    only removes connections, so this is conservative), and since connectivity can only be lost as the
    radius grows, every answer bounds the others (connected at r ⇒ connected below r)."""

    RADIUS_STEP = 0.01

    def __init__(self, boundary: Polygon, obstacles: Sequence[Polygon],
                 regions: Sequence[tuple[Sequence[float], float]], margin: float = CONTROL_MARGIN,
                 safety: float = FREE_SPACE_SAFETY):
        self.boundary, self.obstacles = boundary, list(obstacles)
        self.regions = [(tuple(map(float, c)), float(R)) for c, R in regions]
        self.margin, self.safety = float(margin), float(safety)
        K = len(self.regions)
        self._yes = np.zeros((K, K))           # largest radius known connected
        self._no = np.full((K, K), np.inf)     # smallest radius known separated
        self._base: dict[float, tuple] = {}
        self._matrix: dict[float, np.ndarray] = {}
        self._travel: dict[float, np.ndarray] = {}
        self._spaces: dict[tuple, object] = {}  # travel_space answers

    def _key(self, radius: float) -> float:
        return math.ceil(float(radius) / self.RADIUS_STEP - 1e-9) * self.RADIUS_STEP

    def connected(self, radius: float, k: int, k2: int) -> bool:
        r = self._key(radius)
        if r <= self._yes[k, k2]:
            return True
        if r >= self._no[k, k2]:
            return False
        ok = self._compute(r, k, k2)
        if ok:
            self._yes[k, k2] = self._yes[k2, k] = max(self._yes[k, k2], r)
        else:
            self._no[k, k2] = self._no[k2, k] = min(self._no[k, k2], r)
        return ok

    def matrix(self, radius: float) -> np.ndarray:
        """``C[k, k']``: are regions k and k' connected for an entity of ``radius`` (C[k, k]: the region
        has a seat)?"""
        r = self._key(radius)
        C = self._matrix.get(r)
        if C is None:
            K = len(self.regions)
            C = np.array([[self.connected(r, k, k2) for k2 in range(K)] for k in range(K)], dtype=bool)
            self._matrix[r] = C
        return C

    def travel_matrix(self, radius: float) -> np.ndarray:
        """``C[k, k']`` of :meth:`matrix` for k ≠ k' (travel from one region to another); the diagonal, which
        staying in a region does not need, is True and not computed."""
        r = self._key(radius)
        C = self._travel.get(r)
        if C is None:
            full = self._matrix.get(r)
            if full is not None:
                C = full.copy()
            else:
                K = len(self.regions)
                C = np.array([[k == k2 or self.connected(r, k, k2) for k2 in range(K)] for k in range(K)], dtype=bool)
            np.fill_diagonal(C, True)
            self._travel[r] = C
        return C

    def _geometry(self, r: float) -> tuple:
        hit = self._base.get(r)
        if hit is None:
            grow = (r + self.margin) * _CHORD
            base = self.boundary.buffer(-grow, quad_segs=DISK_QUAD_SEGS)
            if self.obstacles:
                base = base.difference(unary_union([o.buffer(grow, quad_segs=DISK_QUAD_SEGS) for o in self.obstacles]))
            grown = [disk(c, R).buffer(grow, quad_segs=DISK_QUAD_SEGS) for c, R in self.regions]
            hit = (base, grown)
            self._base[r] = hit
        return hit

    def clearance_space(self, radius: float):
        """Where the centre of an entity of ``radius`` may be, regions ignored: the workspace shrunk and the
        obstacles grown by the radius plus the margin."""
        return self._geometry(self._key(radius))[0]

    def travel_space(self, radius: float, k: int, k2: int):
        """The component of the travel space of a trip k → k' for ``radius`` that meets the seats of both
        (None: they are not connected)."""
        key = (self._key(radius), k, k2)
        if key not in self._spaces:
            self._spaces[key] = self._component(*key)
        return self._spaces[key]

    def _component(self, r: float, k: int, k2: int):
        (c1, R1), (c2, R2) = self.regions[k], self.regions[k2]
        if R1 <= r or R2 <= r:
            return None
        base, grown = self._geometry(r)
        others = [grown[m] for m in range(len(self.regions)) if m not in (k, k2)]
        free = base.difference(unary_union(others)) if others else base
        if self.safety > 0.0:
            free = free.buffer(-self.safety, join_style="mitre")
        seat1 = Point(*c1).buffer(R1 - r, quad_segs=DISK_QUAD_SEGS)
        seat2 = Point(*c2).buffer(R2 - r, quad_segs=DISK_QUAD_SEGS)
        return next((q for q in getattr(free, "geoms", [free])
                     if not q.is_empty and q.intersects(seat1) and q.intersects(seat2)), None)

    def _compute(self, r: float, k: int, k2: int) -> bool:
        return self._component(r, k, k2) is not None


#: Clearance (m) the planned legs keep from the grown disks (half of it is required of every leg).
PATH_CLEARANCE = 0.1
_NODES_PER_DISK = 16
#: Rounding allowance (m) of the clearance tests of :func:`local_path`: a chord between consecutive corners of a
#: ring is tangent to the ring's grown circle, at exactly ρ + need from the disk's centre.
_ROUND = 1e-9


def segment_distances(p: np.ndarray, q: np.ndarray, centers: np.ndarray) -> np.ndarray:
    """Distance from every centre (L, 2) to every segment p_k q_k (k, 2): shape (k, L)."""
    d = q - p
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    w = centers[None, :, :] - p[:, None, :]
    s = np.clip(np.einsum("kld,kd->kl", w, d) / dd[:, None], 0.0, 1.0)
    near = p[:, None, :] + s[..., None] * d[:, None, :]
    return np.linalg.norm(centers[None, :, :] - near, axis=-1)


def local_path(start, goal, centers, radii, rim_center, rim_radius, clearance: float = PATH_CLEARANCE,
               nodes_per_disk: int = _NODES_PER_DISK, narrow: int = 0) -> np.ndarray:
    """Shortest path of straight legs from ``start`` to ``goal`` inside the disk (rim_center, rim_radius)
    avoiding the disks (centers, radii): waypoints (k, 2), the last one the goal.

    A leg is admissible when it stays ``need`` = ``clearance``/2 from every disk (less next to the start or
    the goal if they are closer than that).  Candidate corners sit on two rings around each disk: n =
    ``nodes_per_disk`` corners at radius (ρ + clearance)/cos(π/n), and 2n at (ρ + need)/cos(π/2n) for gaps
    (between disks, or a disk and the rim) too narrow for the first; consecutive corners of a ring are joined by
    chords tangent to its grown circle (so those chords keep exactly ``need``: the tests allow rounding,
    :data:`_ROUND`).  Corners lie within ``need`` of the rim, and legs stay in the rim disk by convexity.  Without
    a path, ``need`` is halved up to ``narrow`` times (a gap exactly 2 ``need`` wide is missed by the corner rings
    by a few mm, and execution narrows planned gaps by its tolerances); raises ValueError if none is found then.
    """
    s = np.asarray(start, dtype=float).reshape(2)
    g = np.asarray(goal, dtype=float).reshape(2)
    c = np.asarray(centers, dtype=float).reshape(-1, 2)
    rho = np.asarray(radii, dtype=float).reshape(-1)
    rc = np.asarray(rim_center, dtype=float).reshape(2)
    for name, p in (("start", s), ("goal", g)):
        if len(c) and np.any(np.linalg.norm(c - p, axis=1) <= rho):
            raise ValueError(f"local path: the {name} ({p[0]:.3f}, {p[1]:.3f}) overlaps another entity")
    if np.linalg.norm(g - rc) > rim_radius:
        raise ValueError("local path: the goal is outside the region")
    if len(c) == 0:
        return g[None, :]

    def own_clear(p):
        return float(np.min(np.linalg.norm(c - p, axis=1) - rho))

    need = min(0.5 * clearance, 0.5 * own_clear(s), 0.5 * own_clear(g))
    for attempt in range(int(narrow) + 1):
        path = _visibility_path(s, g, c, rho, rc, rim_radius, clearance, need / 2.0 ** attempt, nodes_per_disk)
        if path is not None:
            return path
    raise ValueError("local path: no collision-free path inside the region between the start and the goal")


def _visibility_path(s, g, c, rho, rc, rim_radius, clearance, need, nodes_per_disk) -> np.ndarray | None:
    """:func:`local_path` for one ``need`` (None: no path)."""
    corners = []
    for n, offset in ((nodes_per_disk, clearance), (2 * nodes_per_disk, need)):
        ang = np.arange(n) * (2.0 * math.pi / n)
        ring = np.column_stack([np.cos(ang), np.sin(ang)]) / math.cos(math.pi / n)
        corners.append((c[:, None, :] + (rho + offset)[:, None, None] * ring[None, :, :]).reshape(-1, 2))
    corners = np.vstack(corners)
    ok = np.linalg.norm(corners - rc, axis=1) <= rim_radius - need + _ROUND
    ok &= np.all(np.linalg.norm(corners[:, None, :] - c[None, :, :], axis=-1) - rho[None, :] >= need - _ROUND,
                 axis=1)
    nodes = np.vstack([s, g, corners[ok]])
    n = len(nodes)
    i, j = np.triu_indices(n, 1)
    dist = segment_distances(nodes[i], nodes[j], c)
    free = np.all(dist - rho[None, :] >= need - _ROUND, axis=1)
    W = np.zeros((n, n))
    lengths = np.linalg.norm(nodes[j] - nodes[i], axis=1)
    W[i[free], j[free]] = np.maximum(lengths[free], 1e-12)
    W = W + W.T
    best, pred = dijkstra(W, directed=False, indices=0, return_predecessors=True)
    if not np.isfinite(best[1]):
        return None
    path, k = [], 1
    while k != 0:
        path.append(nodes[k])
        k = pred[k]
    return np.array(path[::-1])


def free_space_parts(boundary: Polygon, static: Sequence[Polygon], disks: Sequence[tuple[Sequence[float], float]],
                     radius: float, margin: float, safety: float) -> tuple[list[Polygon], list]:
    """The components of the free space of an entity of ``radius`` (paper Sec. III-A): the boundary shrunk and
    the ``static`` obstacles (walls, workspace obstacles, excluded regions) enlarged by radius + ``margin``, the
    ``disks`` (other entities: centre, radius) by the radius, all arcs on the outside of their chords, then
    eroded by ``safety`` (mitre joins).  Returns (components, enlarged obstacles: static first, then disks).

    An enlarged disk that lies inside an enlarged static obstacle (an entity parked in a region the entity
    avoids) adds nothing to their union and is left out of it: the polygon then does not depend on where
    in that region the entity stands."""
    grow, grow_static = radius * _CHORD, (radius + margin) * _CHORD
    shapes = list(static) + [disk(c, r) for c, r in disks]
    enlarged = [g.buffer(grow_static if i < len(static) else grow, quad_segs=DISK_QUAD_SEGS)
                for i, g in enumerate(shapes)]
    for g in enlarged[: len(static)]:
        shapely.prepare(g)
    union = enlarged[: len(static)] + [d for d in enlarged[len(static):]
                                       if not any(g.contains_properly(d) for g in enlarged[: len(static)])]
    inner = boundary.buffer(-grow_static, quad_segs=DISK_QUAD_SEGS)
    free = inner.difference(unary_union(union)) if union else inner
    if safety > 0.0:
        free = free.buffer(-float(safety), join_style="mitre")
    parts = list(free.geoms) if hasattr(free, "geoms") else ([free] if not free.is_empty else [])
    return parts, enlarged
