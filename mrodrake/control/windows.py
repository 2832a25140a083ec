"""Receding windows: the point-world law where the map of the whole free space does not resolve the motion.

The harmonic map H of a free space F is constant on each hole.  Along a channel of width w whose walls are
holes, H flattens like exp(−π s / w) with the distance s from the channel's mouth: in a dead end whose walls
are all one hole (warehouse aisle 3 closed by two robots parked in p6, merging both shelf rows into one hole:
w = 3.5 m) σ_max(J_H) fell from 3e-2 at the mouth to 2e-10 31 m in, below the panel solution's rounding
floor (σ_min ≈ 1e-12), and between two holes (a team in aisle 2, w = 1 m) the derivative along the channel
vanishes the same way.  There v_d = −J_H⁻¹∇φ is either a crawl (0.01 m/s for 1 000 s: χ hardly changes along
the channel) or, once ∇φ reaches the rounding floor too, a direction set by rounding: the entity chatters at
2 m/s on the spot, the integrator's steps shrink to 1e-4 s and the mission never ends.

Where H does not resolve the rest of the motion (:func:`resolution` below :data:`RESOLUTION` somewhere on a
shortest path to the goal, :func:`grid_path`), the same law runs on the map of a *window*: the component of
F ∩ B(x, :data:`WINDOW_RADIUS`) around the entity, whose holes cut by the window's rim become part of its
outer boundary (H runs along them with arc length instead of being constant), toward the farthest point of the
path inside the window (:func:`window_free_space`).  The same holds where the whole map puts the start or the
goal beyond its circle barrier ρ₀: a dead end of the outer boundary that is narrow for the entity gets a sliver
of the circle (arc length of a boundary hundreds of metres long), a window's boundary a larger share, a smaller
window a larger one still; a goal in such a pocket that no window around the entity resolves runs on a window
around the goal (:func:`goal_window_free_space`).
F ∩ B ⊂ F, so each window keeps the guarantees of the
law on its own map (no collision, φ bounded); the motion moves on to the next window near each waypoint.

A map can also resolve the entity's position and still hold it: H is constant on each hole, so a goal next
to a hole and the points along the rest of that hole all map near χ_d (warehouse, a goal beside a shelf row
that a parked robot joins to the next one: the law brought the entity to the row's far corner, 6.4 m from
its goal, with φ = 1e-8, and it stayed there), and two holes a few centimetres apart leave a channel in which
the entity chatters on the spot.  :func:`progress` detects such a stall from the motion alone; the motion then
moves to a window smaller than the map that held it, whose rim cuts the holes beyond it into its outer boundary.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from shapely.geometry import LineString, MultiPolygon, Point, Polygon

from mrodrake.control.freespace import EntityFreeSpace
from mrodrake.control.pointworld import PointWorldMap
from mrodrake.control.tasks import build_map, inside_circle
from mrodrake.geometry import DISK_QUAD_SEGS

#: Smallest σ_min(J_H) × diameter of F at which H resolves the start or the goal of a motion (module
#: docstring): 6e-10 at the start in aisle 3, 1e-6 at a goal 4.5 m inside aisle 2 for a team (crawl); at least
#: 1.9e-2 on every shortest path between the regions of the office, lab, corridor, narrow and tiny maps.
RESOLUTION = 1e-3
#: Speed (m/s) under which the law on the map of the whole motion counts as stalled where that map does not
#: resolve the entity's position (it then moves to a window): it crawled at 0.01-0.15 m/s for 300 s into aisle 2
#: and chattered on the spot at the rounding floor, but crosses the middle of an aisle open at both ends
#: (σ_min(J_H) × diameter down to 5e-7) at its 2 m/s bound.
STALL_SPEED = 0.25
#: σ_min(J_H) × diameter below which the law leaves the map of the whole motion for a window at any speed:
#: above the panel solution's rounding floor (~1e-12) and below the 5e-7 of an aisle crossed at full speed.
#: Warehouse mission n3 s3 (randomized), navigate r1 p2->p5: at every tick its point was resolved or it moved at
#: 0.25 m/s or more, until det J_H = 0 (2e-14 at the fault) ended the mission; with the floor it finishes.
RESOLUTION_FLOOR = 1e-8
#: Fraction of its distance to its goal below which an entity on the point-world law counts as stalled when that
#: is all it moved in one period 1/(2 k1) (:func:`progress`).  Away from barriers φ = k1‖χ − χ_d‖² and the law
#: drives χ̇ → −2 k1 (χ − χ_d) (its velocity loop settles in m/(k_v + 3/2 α̂) < 1 s), so in one period the
#: distance to χ_d falls by a factor e and, where J_H varies little, the entity covers e − 1 = 1.7 times the
#: distance it has left; where H squeezes a room, the entity runs at the speed bound.  In case study I no period
#: of a motion covered less than 10 % (5.5 m of 53 m at 0.1 m/s), a crawl to a goal beside a hole 13 %; the
#: corner stall above covered 0.8 %, then less, and a chatter on the spot nothing.
STALL_FRACTION = 0.02
#: Radius (m) of a window around the entity.
WINDOW_RADIUS = 12.0
#: Distance (m) a window's waypoint keeps inside the window's rim.
WINDOW_MARGIN = 1.5
#: Factor between the radii of successive windows tried by :func:`window_free_space` and
#: :func:`goal_window_free_space`.
WINDOW_GROWTH = 1.25
#: Distance (m) to its waypoint at which a windowed motion moves on to the next window.
WINDOW_SWITCH = 5.0
#: Grid step (m) and clearances to ∂F (m, tried in turn) of :func:`grid_path`; resampling step (m).
GRID_STEP = 0.25
GRID_CLEARANCES = (1.0, 0.5, 0.2, 0.0)
SAMPLE_STEP = 0.5


def resolution(pw_map, points) -> np.ndarray:
    """σ_min(J_H(p)) × the diameter of the map's free space at each of ``points`` (n, 2).

    For a 2 × 2 J, σ_max² + σ_min² = ‖J‖_F² and σ_max σ_min = |det J|, so σ_min = |det J| / σ_max with
    σ_max² = (‖J‖_F² + √(‖J‖_F⁴ − 4 det² J)) / 2 (no cancellation in either step)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    minx, miny, maxx, maxy = pw_map.free_space.bounds
    J = np.asarray(pw_map.jacobian(pts[0] if len(pts) == 1 else pts), dtype=float).reshape(-1, 2, 2)
    fro = np.einsum("nij,nij->n", J, J)
    det = np.abs(J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0])
    s_max = np.sqrt(0.5 * (fro + np.sqrt(np.maximum(fro * fro - 4.0 * det * det, 0.0))))
    with np.errstate(divide="ignore", invalid="ignore"):
        s_min = np.where(s_max > 0.0, det / s_max, 0.0)
    return s_min * math.hypot(maxx - minx, maxy - miny)


def point_resolution(pw_map, x) -> float:
    """:func:`resolution` at the one point ``x`` (2,), on Python floats (the sequencer's check on every tick)."""
    x0, x1 = np.asarray(x, dtype=float).reshape(2).tolist()
    tree = getattr(pw_map, "tree", None)
    if tree is not None:
        a, b, c, d = tree.evaluate(x0, x1, True)[2:6].tolist()
    else:
        (a, b), (c, d) = np.asarray(pw_map.jacobian(np.array([x0, x1])), dtype=float).tolist()
    fro = a * a + b * b + c * c + d * d
    det = abs(a * d - b * c)
    s_max = math.sqrt(0.5 * (fro + math.sqrt(max(fro * fro - 4.0 * det * det, 0.0))))
    extent = getattr(pw_map, "extent", None)
    if extent is None:
        minx, miny, maxx, maxy = pw_map.free_space.bounds
        extent = math.hypot(maxx - minx, maxy - miny)
    return (det / s_max if s_max > 0.0 else 0.0) * extent


def progress(anchor: tuple[float, float, float], t: float, x, goal, period: float, tol: float
             ) -> tuple[tuple[float, float, float], bool]:
    """Stall detection on the point-world law: ``anchor`` (t₀, x₀, y₀) is where the entity was when the current
    period started.  Once ``period`` has passed, the entity has stalled if it is more than ``tol`` from
    ``goal`` and moved less than :data:`STALL_FRACTION` of its distance to it since t₀; otherwise a new period
    starts at (t, x).  Returns the anchor to keep and whether the entity has stalled."""
    x0, x1 = np.asarray(x, dtype=float).reshape(2).tolist()
    t0, a0, a1 = anchor
    if t - t0 < period:
        return anchor, False
    g0, g1 = np.asarray(goal, dtype=float).reshape(2).tolist()
    left = math.hypot(g0 - x0, g1 - x1)
    if left > tol and math.hypot(x0 - a0, x1 - a1) < STALL_FRACTION * left:
        return anchor, True
    return (float(t), x0, x1), False


def grid_path(poly: Polygon, start, goal, step: float = GRID_STEP,
              clearances: tuple[float, ...] = GRID_CLEARANCES, halvings: int = 0) -> np.ndarray:
    """A shortest 8-connected grid path (spacing ``step``) from ``start`` to ``goal`` through the points of
    ``poly`` at least the first of ``clearances`` from its boundary that connects them, start and goal
    included: waypoints (k, 2).  The start and the goal join the grid at the nearest node that a straight
    segment inside ``poly`` reaches (within ``clearance`` + 2 steps; else the next clearance is tried), so that
    every leg of the path lies in ``poly``.  Where no clearance connects them, the grid of half the step is
    tried, up to ``halvings`` times (a channel of ``poly`` narrower than the step, such as a door a team just
    fits through, may fall between two grid rows).  Raises ValueError if no grid connects them."""
    s = np.asarray(start, dtype=float).reshape(2)
    g = np.asarray(goal, dtype=float).reshape(2)
    shapely.prepare(poly)
    for h in range(halvings + 1):
        size = step / 2 ** h
        for clear in clearances:
            inner = poly.buffer(-clear) if clear > 0.0 else poly
            if inner.is_empty:
                continue
            path = _grid_path(poly, inner, s, g, size, clear + 2.0 * size)
            if path is not None:
                return path
    raise ValueError("grid path: the grid does not connect the start and the goal")


def _entry(poly, nodes: np.ndarray, p: np.ndarray, reach: float) -> int | None:
    """The nearest of ``nodes`` within ``reach`` of p that a straight segment inside ``poly`` joins to p."""
    d = np.linalg.norm(nodes - p, axis=1)
    for k in np.argsort(d, kind="stable"):
        if d[k] > reach:
            return None
        if poly.covers(LineString([p, nodes[k]])):
            return int(k)
    return None


def _grid_path(poly, inner, s: np.ndarray, g: np.ndarray, step: float, reach: float) -> np.ndarray | None:
    minx, miny, maxx, maxy = inner.bounds
    xs = np.arange(minx, maxx + step, step)
    ys = np.arange(miny, maxy + step, step)
    X, Y = np.meshgrid(xs, ys)
    shapely.prepare(inner)
    ok = shapely.contains_xy(inner, X, Y)
    idx = -np.ones(ok.shape, dtype=int)
    idx[ok] = np.arange(int(ok.sum()))
    nodes = np.column_stack([X[ok], Y[ok]])
    if len(nodes) < 2:
        return None
    rows, cols, w = [], [], []
    ny, nx = ok.shape
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = idx[max(0, -di):ny - max(0, di), max(0, -dj):nx - max(0, dj)]
        b = idx[max(0, di):ny - max(0, -di) or None, max(0, dj):nx - max(0, -dj) or None]
        both = (a >= 0) & (b >= 0)
        a, b = a[both], b[both]
        mid = 0.5 * (nodes[a] + nodes[b])
        keep = shapely.contains_xy(inner, mid[:, 0], mid[:, 1])
        rows.append(a[keep])
        cols.append(b[keep])
        w.append(np.full(int(keep.sum()), step * math.hypot(di, dj)))
    rows, cols, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
    graph = coo_matrix((w, (rows, cols)), shape=(len(nodes), len(nodes))).tocsr()
    i_s, i_g = _entry(poly, nodes, s, reach), _entry(poly, nodes, g, reach)
    if i_s is None or i_g is None:
        return None
    dist, pred = dijkstra(graph, directed=False, indices=i_g, return_predecessors=True)
    if not np.isfinite(dist[i_s]):
        return None
    out, k = [s], i_s
    while k != i_g:
        k = int(pred[k])
        out.append(nodes[k])
    out.append(g)
    return np.array(out)


def resample(path, step: float = SAMPLE_STEP) -> np.ndarray:
    """Points every ``step`` along the polyline ``path`` (its end points included)."""
    p = np.asarray(path, dtype=float).reshape(-1, 2)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    if cum[-1] <= 0.0:
        return p[:1]
    s = np.append(np.arange(0.0, cum[-1], step), cum[-1])
    return np.column_stack([np.interp(s, cum, p[:, 0]), np.interp(s, cum, p[:, 1])])


def goal_window_free_space(free: EntityFreeSpace, x, goal, growth: float = WINDOW_GROWTH,
                           radius: float = WINDOW_RADIUS) -> tuple[EntityFreeSpace, PointWorldMap]:
    """A window around the goal (its map puts the goal and ``x`` inside its circle barrier ρ₀, when neither the
    map of the whole free space nor the window around ``x`` does): the component of ``free.polygon`` ∩ B(goal, ρ)
    containing x and the goal, for ρ = |x − goal| + :data:`GRID_STEP` times 1, ``growth``, growth², ... up
    to ``radius``, the first whose map puts both inside ρ₀; the smaller the window, the larger the share of
    its outer boundary, and of the unit circle, that a pocket around the goal gets.  Raises ValueError without
    one."""
    x = np.asarray(x, dtype=float).reshape(2)
    goal = np.asarray(goal, dtype=float).reshape(2)
    rho = float(np.hypot(*(goal - x))) + GRID_STEP
    pts = [Point(x), Point(goal)]
    while rho <= radius:
        part = free.polygon.intersection(Point(goal).buffer(rho, quad_segs=DISK_QUAD_SEGS))
        parts = list(part.geoms) if isinstance(part, MultiPolygon) else [part]
        comp = next((p for p in parts if isinstance(p, Polygon) and all(p.contains(q) for q in pts)), None)
        if comp is not None:
            comp = shapely.geometry.polygon.orient(comp, 1.0)
            window = dataclasses.replace(free, polygon=comp, start=x, goal=goal,
                                         hole_names=[[] for _ in comp.interiors])
            pw = build_map(window)
            if np.all(inside_circle(pw, [x, goal])):
                return window, pw
        rho *= growth
    raise ValueError("goal window: no window around the goal maps the entity and the goal inside its circle barrier")


def window_free_space(free: EntityFreeSpace, x, path, radius: float = WINDOW_RADIUS,
                      margin: float = WINDOW_MARGIN, growth: float = WINDOW_GROWTH
                      ) -> tuple[EntityFreeSpace, PointWorldMap]:
    """The window around ``x`` (module docstring) and its map: the component of ``free.polygon`` ∩ B(x, ρ)
    containing x, with x as start and, as goal, the farthest point of ``path`` (from x to the goal) before it
    first leaves B(x, ρ − margin) (the goal itself if it does not) that maps inside the map's circle
    barrier (a point near a convex corner of the window can map outside it).  ρ = ``radius``, else radius /
    growth, radius / growth², ... down to 2 margin, the first whose map puts x and a waypoint inside its
    circle barrier: the smaller the window, the larger the share of its outer boundary, and of the unit circle,
    that a pocket around x gets (lab, a team leaving its goal between two parked robots and a wall:
    ‖χ(x)‖ = 0.998 on the map of radius 12 m, 0.994 < ρ₀ = 0.995 on the map of radius 7 m).  Of those, the first
    whose map also resolves x (:func:`resolution` at least :data:`RESOLUTION`): a pocket around x walled by one
    hole that lies wholly inside the window flattens H there as on the whole map (warehouse, a robot parked
    against a shelf closed an aisle whose other side was another shelf row: resolution 6e-4 at the start on the
    map of radius 12 m, and the law ran into the shelf at 2 m/s), a smaller window cuts that hole into its outer
    boundary; the first at all when none does.  Raises ValueError without one."""
    rho, first, error = float(radius), None, None
    while True:
        try:
            found = _window(free, x, path, rho, margin)
        except ValueError as exc:
            error = error or exc
        else:
            if resolution(found[1], [x])[0] >= RESOLUTION:
                return found
            first = first or found
        rho /= growth
        if rho < 2.0 * margin:
            break
    if first is None:
        raise error
    return first


def _window(free: EntityFreeSpace, x, path, radius: float, margin: float) -> tuple[EntityFreeSpace, PointWorldMap]:
    x = np.asarray(x, dtype=float).reshape(2)
    pts = resample(path, 0.5 * GRID_STEP)
    out = np.flatnonzero(np.linalg.norm(pts - x, axis=1) > radius - margin)
    cands = pts[1:] if not len(out) else pts[1:max(1, int(out[0]))]
    part = free.polygon.intersection(Point(x).buffer(radius, quad_segs=DISK_QUAD_SEGS))
    parts = list(part.geoms) if isinstance(part, MultiPolygon) else [part]
    comp = next((p for p in parts if isinstance(p, Polygon) and p.contains(Point(x))), None)
    if comp is None or not len(cands):
        raise ValueError("window: no waypoint in the window's component around the entity")
    comp = shapely.geometry.polygon.orient(comp, 1.0)
    window = dataclasses.replace(free, polygon=comp, start=x, goal=cands[-1], hole_names=[[] for _ in comp.interiors])
    pw = build_map(window)
    ok = shapely.contains_xy(comp, cands[:, 0], cands[:, 1]) & inside_circle(pw, cands)
    if not ok.any() or not inside_circle(pw, x)[0]:
        raise ValueError("window: the entity or every waypoint maps outside the window map's circle barrier")
    return dataclasses.replace(window, goal=cands[np.flatnonzero(ok)[-1]].copy()), pw
