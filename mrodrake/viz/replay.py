"""Meshcat replay of a mission: a top-down HTML page that plays offline, built from the logs.

The replay uses only the scenario, the logged trajectory (columns ``t, entity, x, y, vx, vy``) and
optional grasp intervals (``t_start, t_end, robot, object``), so it works however the logs were
produced.  The page shows the office from above (walls, obstacles, regions with their names), robots and
objects as coloured disks at their true size (with a translucent halo of a minimum display size so that
sub-metre entities stay visible in a 200 m office), a dark bar from each grasping robot's centre to its
object's centre drawn over both disks, the trails, a legend and a timeline whose marker shows the simulated time.

Drake's Meshcat API has no text primitive.  Names are drawn as filled glyph outlines: matplotlib's
``TextPath`` with its bundled DejaVu Sans font, triangulated with shapely's constrained Delaunay
triangulation and sent with ``SetTriangleMesh``.  The HTML therefore needs no font or image file.

Long missions play faster.  The default speed-up is the smallest of 1, 2, 3, 5, 10, 20, 30, 50, ... that
keeps the replay at most 120 s long, so a mission longer than 120 s replays in 60-120 s.  The trajectory
is resampled at the replay's frame rate.  Keyframes that linear interpolation reproduces within a small
tolerance are dropped (an entity standing still, a straight run at constant speed), which keeps the file
small: Meshcat's 2.2 MB viewer plus a few hundred kB of scene and animation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd
import shapely
from shapely.geometry import MultiPolygon, Polygon, box

from mrodrake.errors import UserError
from mrodrake.scenario import initial_layout

__all__ = [
    "ROOT", "write_replay", "scene_only", "choose_speedup", "view_bounds", "entity_colors",
    "synthetic_mission",
]

#: Root of everything this module draws in a Meshcat scene tree; entity ``e`` is ``ROOT/entities/e``.
ROOT = "/mrodrake"

# Heights (z) of the layers in drawing coordinates: the view looks down -z (see _set_view), so higher
# layers cover lower ones.
_Z_FLOOR, _Z_REGION, _Z_WALL, _Z_TRAIL = 0.0, 0.02, 0.05, 0.08
_Z_HALO, _Z_DISK, _Z_LINK, _Z_TEXT = 0.12, 0.14, 0.17, 0.2
_THIN = 0.005  # thickness of the flat cylinders and boxes (m)
_CAMERA_DISTANCE = 10.0
_TRAIL_TOL = 5e-4  # trail keyframe tolerance relative to the workspace extent (about 0.5 px at full view)
_MAX_TRAIL_PIECES = 150  # per entity; each piece is a Meshcat object of about 0.7 kB

# Colour-blind-friendly palette (Okabe-Ito, then Tol's bright), RGB in [0, 1].
_PALETTE = [
    (0.0, 0.447, 0.698), (0.835, 0.369, 0.0), (0.0, 0.620, 0.451), (0.800, 0.475, 0.655),
    (0.902, 0.624, 0.0), (0.337, 0.706, 0.914), (0.941, 0.894, 0.259), (0.4, 0.8, 0.933),
    (0.933, 0.4, 0.467), (0.133, 0.533, 0.2), (0.667, 0.2, 0.467), (0.267, 0.467, 0.667),
]
_FLOOR = (0.99, 0.98, 0.95)
_WALL = (0.35, 0.35, 0.38)
_OBSTACLE = (0.62, 0.60, 0.57)
_REGION = (0.30, 0.65, 0.30)
_REGION_TEXT = (0.1, 0.4, 0.1)
_TEXT = (0.10, 0.10, 0.12)
_MARKER = (0.8, 0.1, 0.1)
_NICE = (1.0, 2.0, 3.0, 5.0)


def _rgba(rgb, a=1.0):
    from pydrake.geometry import Rgba

    return Rgba(float(rgb[0]), float(rgb[1]), float(rgb[2]), float(a))


def entity_colors(scenario) -> dict[str, tuple[float, float, float]]:
    """Colour (RGB in [0, 1]) of every robot and object: robots first, then objects, in palette order."""
    names = scenario.robot_names + scenario.object_names
    return {n: _PALETTE[i % len(_PALETTE)] for i, n in enumerate(names)}


def choose_speedup(duration: float, max_replay: float = 120.0) -> float:
    """Smallest speed-up in {1, 2, 3, 5} x 10^k (k >= 0) with ``duration / speedup <= max_replay``.

    Consecutive candidates differ by at most a factor 2, so a mission longer than ``max_replay`` replays
    in ``(max_replay / 2, max_replay]`` seconds (60-120 s by default).
    """
    if not math.isfinite(duration) or duration <= max_replay:
        return 1.0
    decade = 1.0
    while True:
        for n in _NICE:
            if duration / (n * decade) <= max_replay:
                return n * decade
        decade *= 10.0


# --------------------------------------------------------------------------------------------------
# Layout of the page (drawing coordinates = workspace coordinates, metres)
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Layout:
    """Where the map, legend and timeline go, and the text sizes, for one scenario."""

    extent: float  # largest side of the workspace's bounding box
    wall: float  # thickness drawn for the outer wall
    map_box: tuple[float, float, float, float]  # workspace bounding box xmin, ymin, xmax, ymax
    title_y: float
    legend_y: float
    timeline_y: float
    view: tuple[float, float, float, float]  # camera bounds xmin, xmax, ymin, ymax
    label_h: float
    legend_h: float
    tick_h: float
    halo_r: float  # minimum display radius of an entity
    trail_piece: float  # path length of one trail piece


def _layout(scenario) -> _Layout:
    bx0, by0, bx1, by1 = Polygon(scenario.workspace.boundary).bounds
    extent = max(bx1 - bx0, by1 - by0)
    wall = 0.005 * extent
    title_y = by1 + wall + 0.02 * extent
    legend_y = by0 - wall - 0.045 * extent
    timeline_y = legend_y - 0.05 * extent
    margin = 0.02 * extent
    view = (bx0 - wall - margin, bx1 + wall + margin, timeline_y - 0.06 * extent, title_y + 0.045 * extent)
    return _Layout(
        extent=extent, wall=wall, map_box=(bx0, by0, bx1, by1), title_y=title_y, legend_y=legend_y,
        timeline_y=timeline_y, view=view, label_h=0.025 * extent, legend_h=0.022 * extent,
        tick_h=0.017 * extent, halo_r=0.008 * extent, trail_piece=0.025 * extent,
    )


def view_bounds(scenario) -> tuple[float, float, float, float]:
    """Workspace rectangle ``(xmin, xmax, ymin, ymax)`` shown by the replay's camera.

    The viewer keeps ``xmin``, ``ymin`` and ``ymax`` and moves ``xmax`` to match the window's aspect
    ratio: a window at least as wide (relative to its height) as this rectangle shows all of it, at
    ``height_px / (ymax - ymin)`` pixels per metre with ``(xmin, ymax)`` in the top-left corner.
    """
    return _layout(scenario).view


# --------------------------------------------------------------------------------------------------
# Geometry: triangulation, text, circles
# --------------------------------------------------------------------------------------------------


def _triangles(geom) -> np.ndarray:
    """Triangles (m, 3, 2) of a constrained Delaunay triangulation of a (multi)polygon with holes."""
    if geom.is_empty:
        return np.zeros((0, 3, 2))
    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(geom))
    if len(tris) == 0:
        return np.zeros((0, 3, 2))
    coords = shapely.get_coordinates(shapely.get_exterior_ring(tris))
    return coords.reshape(len(tris), 4, 2)[:, :3, :]


def _indexed(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shared vertices (n, 2) and faces (m, 3) from triangles (m, 3, 2)."""
    if len(tris) == 0:
        return np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int32)
    verts, inverse = np.unique(tris.reshape(-1, 2), axis=0, return_inverse=True)
    return verts, inverse.reshape(-1, 3).astype(np.int32)


def _set_mesh(meshcat, path: str, mesh: tuple[np.ndarray, np.ndarray], z: float, rgb, alpha=1.0) -> None:
    verts, faces = mesh
    v = np.vstack([verts[:, 0], verts[:, 1], np.full(len(verts), z)])
    meshcat.SetTriangleMesh(path, np.asfortranarray(v), np.asfortranarray(faces.T), _rgba(rgb, alpha))


def _merge(meshes) -> tuple[np.ndarray, np.ndarray]:
    verts, faces, n = [], [], 0
    for v, f in meshes:
        verts.append(v)
        faces.append(f + n)
        n += len(v)
    return np.concatenate(verts), np.concatenate(faces)


@lru_cache(maxsize=512)
def _glyphs(text: str) -> tuple[np.ndarray, np.ndarray, tuple[float, float, float, float]]:
    """Triangulated outline of ``text`` at font size 1 (DejaVu Sans bold): vertices, faces, bounds."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    path = TextPath((0.0, 0.0), text, size=1.0, prop=FontProperties(family="DejaVu Sans", weight="bold"))
    shape = Polygon()
    for ring in path.to_polygons(closed_only=True):
        if len(ring) >= 3:
            # Glyph outlines follow the even-odd rule: a ring inside another ring is a hole.
            shape = shape.symmetric_difference(shapely.make_valid(Polygon(ring)))
    shape = shapely.make_valid(shapely.simplify(shape, 0.004, preserve_topology=True))
    polys = [g for g in shapely.get_parts(shape) if isinstance(g, Polygon) and not g.is_empty]
    shape = MultiPolygon(polys) if polys else Polygon()
    verts, faces = _indexed(_triangles(shape))
    bounds = shape.bounds if not shape.is_empty else (0.0, 0.0, 0.0, 0.0)
    return verts, faces, bounds


def _text(text: str, height: float, x: float, y: float, align: str = "center",
          valign: str = "baseline") -> tuple[np.ndarray, np.ndarray]:
    """Mesh of ``text`` at font size ``height`` anchored at (x, y); ``valign`` 'baseline' ignores the
    string's own ascenders and descenders, so labels on one line share a baseline."""
    verts, faces, (x0, y0, x1, y1) = _glyphs(text)
    dx = {"left": -x0, "center": -(x0 + x1) / 2.0, "right": -x1}[align]
    dy = {"baseline": 0.0, "bottom": -y0, "top": -y1}[valign]
    out = verts * height
    out[:, 0] += x + dx * height
    out[:, 1] += y + dy * height
    return out, faces


def _circle(center, radius, z, n=48) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * np.pi, n + 1)
    return np.asfortranarray(np.vstack([center[0] + radius * np.cos(a), center[1] + radius * np.sin(a),
                                        np.full(n + 1, z)]))


def _ring_line(coords, z) -> np.ndarray:
    c = np.asarray(coords, dtype=float)
    c = np.vstack([c, c[:1]])
    return np.asfortranarray(np.vstack([c[:, 0], c[:, 1], np.full(len(c), z)]))


def _points3(xy: np.ndarray, z: float) -> np.ndarray:
    return np.asfortranarray(np.vstack([xy[:, 0], xy[:, 1], np.full(len(xy), z)]))


# --------------------------------------------------------------------------------------------------
# Static scene
# --------------------------------------------------------------------------------------------------


def _set_flat_disk(meshcat, path, center, radius, z, rgb, alpha=1.0):
    from pydrake.geometry import Cylinder
    from pydrake.math import RigidTransform

    meshcat.SetObject(path, Cylinder(radius, _THIN), _rgba(rgb, alpha))
    meshcat.SetTransform(path, RigidTransform([center[0], center[1], z]))


def _draw_static(scenario, meshcat, lay: _Layout, *, title: str, t_range: tuple[float, float] | None) -> None:
    """Office (floor, walls, obstacles), regions with labels, legend, title, timeline axis, camera."""
    boundary = Polygon(scenario.workspace.boundary)
    scene = f"{ROOT}/scene"
    _set_mesh(meshcat, f"{scene}/floor", _indexed(_triangles(boundary)), _Z_FLOOR, _FLOOR)
    # Walls: a band around the bounding box plus everything between the box and the boundary (the
    # interior walls are notches of the boundary polygon).
    frame = box(*lay.map_box).buffer(lay.wall, join_style="mitre")
    _set_mesh(meshcat, f"{scene}/walls", _indexed(_triangles(frame.difference(boundary))), _Z_WALL, _WALL)
    meshcat.SetLine(f"{scene}/outline", _ring_line(boundary.exterior.coords[:-1], _Z_WALL + 0.01), 1.0,
                    _rgba(_WALL))
    fills, outlines = [], []
    for ob in scenario.workspace.obstacles:
        fills.append(_indexed(_triangles(shapely.make_valid(Polygon(ob.polygon)))))
        ring = np.asarray(ob.polygon, dtype=float)
        outlines.append((ring, np.roll(ring, -1, axis=0)))
    if fills:
        _set_mesh(meshcat, f"{scene}/obstacles/fill", _merge(fills), _Z_WALL, _OBSTACLE)
        starts = np.concatenate([a for a, _ in outlines])
        ends = np.concatenate([b for _, b in outlines])
        meshcat.SetLineSegments(f"{scene}/obstacles/outline", _points3(starts, _Z_WALL + 0.01),
                                _points3(ends, _Z_WALL + 0.01), 1.0, _rgba(_WALL))
    labels = []
    for reg in scenario.regions:
        base = f"{scene}/regions/{reg.name}"
        _set_flat_disk(meshcat, f"{base}/disk", reg.center, reg.radius, _Z_REGION, _REGION, 0.3)
        meshcat.SetLine(f"{base}/rim", _circle(reg.center, reg.radius, _Z_REGION + 0.01), 1.0, _rgba(_REGION))
        labels.append(_text(reg.name, lay.label_h, reg.center[0], reg.center[1] + reg.radius + 0.3 * lay.label_h,
                            valign="bottom"))
    if labels:
        _set_mesh(meshcat, f"{scene}/regions/labels", _merge(labels), _Z_TEXT, _REGION_TEXT)
    _draw_legend(scenario, meshcat, lay)
    _set_mesh(meshcat, f"{ROOT}/title", _text(title, lay.legend_h, lay.map_box[0], lay.title_y, align="left"),
              _Z_TEXT, _TEXT)
    if t_range is not None:
        _draw_timeline_axis(meshcat, lay, t_range)
    _set_view(meshcat, lay)


def _draw_legend(scenario, meshcat, lay: _Layout) -> None:
    """One swatch and name per robot, then per object, on one line under the map."""
    colors = entity_colors(scenario)
    h = lay.legend_h
    y = lay.legend_y - 0.35 * h  # baseline, so that the swatches sit at mid-height of the letters
    x = lay.map_box[0]
    texts = []
    for group, names in (("robots:", scenario.robot_names), ("objects:", scenario.object_names)):
        if not names:
            continue
        texts.append(_text(group, h, x, y, align="left"))
        x = float(texts[-1][0][:, 0].max()) + 0.6 * h
        for name in names:
            _set_flat_disk(meshcat, f"{ROOT}/legend/swatch_{name}", (x + 0.4 * h, lay.legend_y), 0.4 * h,
                           _Z_DISK, colors[name])
            texts.append(_text(name, h, x + 1.0 * h, y, align="left"))
            x = float(texts[-1][0][:, 0].max()) + 0.8 * h
        x += 0.8 * h
    if texts:
        _set_mesh(meshcat, f"{ROOT}/legend/names", _merge(texts), _Z_TEXT, _TEXT)


def _nice_step(span: float, max_ticks: int = 8) -> float:
    raw = span / max_ticks
    decade = 10.0 ** math.floor(math.log10(raw))
    for n in (1.0, 2.0, 5.0):
        if n * decade >= raw:
            return n * decade
    return 10.0 * decade


def _draw_timeline_axis(meshcat, lay: _Layout, t_range) -> None:
    """Timeline under the map from the first to the last logged time, with ticks in seconds."""
    from pydrake.geometry import Box
    from pydrake.math import RigidTransform

    t0, t1 = t_range
    x0, x1 = lay.map_box[0], lay.map_box[2]
    y, h = lay.timeline_y, lay.tick_h
    base = f"{ROOT}/timeline"
    meshcat.SetObject(f"{base}/axis", Box(x1 - x0, 0.15 * h, _THIN), _rgba(_WALL))
    meshcat.SetTransform(f"{base}/axis", RigidTransform([0.5 * (x0 + x1), y, _Z_WALL]))
    span = max(t1 - t0, 1e-9)
    step = _nice_step(span)
    ticks = np.arange(math.ceil(t0 / step), math.floor(t1 / step + 1e-9) + 1) * step
    if len(ticks) == 0:
        return
    xt = x0 + (ticks - t0) / span * (x1 - x0)
    starts = np.column_stack([xt, np.full(len(xt), y)])
    ends = np.column_stack([xt, np.full(len(xt), y - 0.5 * h)])
    meshcat.SetLineSegments(f"{base}/ticks", _points3(starts, _Z_WALL), _points3(ends, _Z_WALL), 1.0, _rgba(_WALL))
    texts = [_text(f"{tk:g}", h, xk, y - 1.6 * h) for tk, xk in zip(ticks, xt)]
    texts.append(_text("s", h, float(texts[-1][0][:, 0].max()) + 0.3 * h, y - 1.6 * h, align="left"))
    _set_mesh(meshcat, f"{base}/labels", _merge(texts), _Z_TEXT, _TEXT)


def _set_view(meshcat, lay: _Layout) -> None:
    """Top-down orthographic view with flat (ambient-only) lighting.

    Meshcat's orbit controls keep the camera looking at the world origin, so a camera pose above an x-y
    workspace ends up oblique.  The drawing is turned into Meshcat's default 2-D plane instead: ``ROOT``
    maps drawing coordinates (x, y, z) to world (x - cx, -z, y - cy) (90 degrees about x), and the
    default camera of ``Set2dRenderMode`` looks along +y at it.  Drawing x is then screen right, drawing
    y screen up, and higher layers are nearer to the camera.  Only the ambient light is kept, at
    intensity pi (three.js divides the Lambert term by pi), so colours render flat as given.
    """
    from pydrake.math import RigidTransform, RollPitchYaw

    xmin, xmax, ymin, ymax = lay.view
    cx, cy = 0.5 * (xmin + xmax), 0.5 * (ymin + ymax)
    meshcat.SetTransform(ROOT, RigidTransform(RollPitchYaw(np.pi / 2.0, 0.0, 0.0), [-cx, 0.0, -cy]))
    meshcat.Set2dRenderMode(RigidTransform([0.0, -_CAMERA_DISTANCE, 0.0]), xmin - cx, xmax - cx, ymin - cy,
                            ymax - cy)
    for light in ("SpotLight", "PointLightNegativeX", "PointLightPositiveX", "FillLight"):
        meshcat.SetProperty(f"/Lights/{light}/<object>", "intensity", 0.0)
    meshcat.SetProperty("/Lights/AmbientLight/<object>", "intensity", np.pi)


def _draw_entity(meshcat, lay: _Layout, name: str, radius: float, rgb) -> None:
    base = f"{ROOT}/entities/{name}"
    _set_flat_disk(meshcat, f"{base}/disk", (0.0, 0.0), radius, _Z_DISK, rgb)
    meshcat.SetLine(f"{base}/rim", _circle((0.0, 0.0), radius, _Z_DISK + 0.01, n=32), 1.0,
                    _rgba(tuple(0.5 * c for c in rgb)))
    if lay.halo_r > 1.2 * radius:
        _set_flat_disk(meshcat, f"{base}/halo", (0.0, 0.0), lay.halo_r, _Z_HALO, rgb, 0.35)




def scene_only(scenario, meshcat) -> None:
    """Draw the static scene (office, obstacles, labelled regions, legend) top-down in a live Meshcat,
    with every robot and object at a P_s position inside its initial region.

    Replaces what was drawn under ``/mrodrake`` and sets the camera.  Entity ``e`` is the frame
    ``/mrodrake/entities/e`` in workspace coordinates: move it with ``meshcat.SetTransform``.
    """
    from pydrake.math import RigidTransform

    meshcat.Delete(ROOT)
    lay = _layout(scenario)
    _draw_static(scenario, meshcat, lay, title=scenario.name, t_range=None)
    colors = entity_colors(scenario)
    radii = {e.name: e.radius for e in list(scenario.robots) + list(scenario.objects)}
    for name, p in initial_layout(scenario).items():
        _draw_entity(meshcat, lay, name, radii[name], colors[name])
        meshcat.SetTransform(f"{ROOT}/entities/{name}", RigidTransform([p[0], p[1], 0.0]))


# --------------------------------------------------------------------------------------------------
# Animation
# --------------------------------------------------------------------------------------------------


def _keyframes(samples: np.ndarray, tol: float) -> np.ndarray:
    """Indices of the uniformly timed samples (n, d) to keep so that linear interpolation between kept
    samples is within ``tol`` (Euclidean) of every dropped sample (Ramer-Douglas-Peucker in time)."""
    n = len(samples)
    if n <= 2:
        return np.arange(n)
    keep = np.zeros(n, dtype=bool)
    keep[0] = keep[-1] = True
    stack = [(0, n - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        s = (np.arange(a + 1, b) - a) / (b - a)
        interp = samples[a] + s[:, None] * (samples[b] - samples[a])
        err = np.linalg.norm(samples[a + 1:b] - interp, axis=1)
        i = int(np.argmax(err))
        if err[i] > tol:
            k = a + 1 + i
            keep[k] = True
            stack.append((a, k))
            stack.append((k, b))
    return np.flatnonzero(keep)


def _check_logs(scenario, trajectory, grasps) -> None:
    if not isinstance(trajectory, pd.DataFrame):
        raise UserError("trajectory: expected a pandas DataFrame with columns t, entity, x, y, vx, vy")
    missing = [c for c in ("t", "entity", "x", "y", "vx", "vy") if c not in trajectory.columns]
    if missing:
        raise UserError(f"trajectory: missing column(s) {', '.join(missing)}")
    if len(trajectory) == 0:
        raise UserError("trajectory: no rows")
    names = set(trajectory["entity"].astype(str))
    unknown = sorted(names - set(scenario.robot_names) - set(scenario.object_names))
    if unknown:
        raise UserError(f"trajectory.entity: unknown entity '{unknown[0]}' (not a robot or object of the scenario)")
    absent = [n for n in scenario.robot_names + scenario.object_names if n not in names]
    if absent:
        raise UserError(f"trajectory.entity: no rows for entity '{absent[0]}'")
    try:
        values = trajectory[["t", "x", "y"]].to_numpy(dtype=float)
    except (TypeError, ValueError) as exc:
        raise UserError(f"trajectory: columns t, x, y must be numeric ({exc})") from None
    bad = ~np.all(np.isfinite(values), axis=1)
    if bad.any():
        raise UserError(f"trajectory: non-finite t, x or y in row {int(np.flatnonzero(bad)[0])}")
    if grasps is None:
        return
    if not isinstance(grasps, pd.DataFrame):
        raise UserError("grasps: expected a pandas DataFrame with columns t_start, t_end, robot, object")
    if len(grasps) == 0:
        return
    missing = [c for c in ("t_start", "t_end", "robot", "object") if c not in grasps.columns]
    if missing:
        raise UserError(f"grasps: missing column(s) {', '.join(missing)}")
    for i, row in enumerate(grasps.itertuples(index=False)):
        if str(row.robot) not in scenario.robot_names:
            raise UserError(f"grasps[{i}].robot: unknown robot '{row.robot}'")
        if str(row.object) not in scenario.object_names:
            raise UserError(f"grasps[{i}].object: unknown object '{row.object}'")
        t_start, t_end = float(row.t_start), float(row.t_end)
        if not (math.isfinite(t_start) and math.isfinite(t_end)) or t_end < t_start:
            raise UserError(f"grasps[{i}]: need finite t_start <= t_end, got {t_start} and {t_end}")


def _resample(trajectory: pd.DataFrame, names: list[str], times: np.ndarray) -> np.ndarray:
    """Positions (n_entities, n_frames, 2) of the entities at ``times`` (linear interpolation)."""
    out = np.empty((len(names), len(times), 2))
    groups = dict(tuple(trajectory.groupby(trajectory["entity"].astype(str), sort=False)))
    for i, name in enumerate(names):
        g = groups[name].sort_values("t", kind="stable")
        t = g["t"].to_numpy(dtype=float)
        out[i, :, 0] = np.interp(times, t, g["x"].to_numpy(dtype=float))
        out[i, :, 1] = np.interp(times, t, g["y"].to_numpy(dtype=float))
    return out


def _animate_segment(anim, path: str, a: np.ndarray, b: np.ndarray, first: int, tol: float, z: float) -> str:
    """Keyframes (from frame ``first``) that make a unit segment along +x run from a[k] to b[k] (a, b:
    (n, 2) per frame).  ``path`` carries the position of a; its child ``path/dir``, returned, carries
    the turn and the stretch (``scale``) along b - a, so a rigidly carried segment needs two keyframes
    for its direction.  Put the unit-segment geometry under the returned path."""
    from pydrake.math import RigidTransform, RotationMatrix

    for k in _keyframes(a, tol):
        anim.SetProperty(first + int(k), path, "position", [a[k, 0], a[k, 1], z])
    inner = f"{path}/dir"
    d = b - a
    angle = 0.0
    for k in _keyframes(d, tol):
        length = float(np.hypot(d[k, 0], d[k, 1]))
        if length > 1e-9:
            angle = math.atan2(d[k, 1], d[k, 0])
        anim.SetTransform(first + int(k), inner, RigidTransform(RotationMatrix.MakeZRotation(angle), [0.0, 0.0, 0.0]))
        anim.SetProperty(first + int(k), inner, "scale", [max(length, 1e-6), 1.0, 1.0])
    return inner


def _record_trail(meshcat, anim, base: str, pos: np.ndarray, tol: float, piece_len: float, rgb) -> int:
    """Trail of one entity: polyline pieces of about ``piece_len`` of path (longer if the path would need
    more than ``_MAX_TRAIL_PIECES``), each shown from the frame the entity reaches its end, plus a chord
    from the end of the last shown piece to the entity.  Returns the number of pieces."""
    n = len(pos)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pos, axis=0), axis=1))])
    if arc[-1] <= tol:
        return 0
    piece_len = max(piece_len, arc[-1] / _MAX_TRAIL_PIECES)
    # Piece ends: first frame of each new multiple of piece_len along the path, and the last frame.
    level = np.floor(arc / piece_len)
    ends = np.flatnonzero(np.diff(level) > 0) + 1
    if len(ends) == 0 or (ends[-1] != n - 1 and arc[-1] - arc[ends[-1]] > tol):
        ends = np.append(ends, n - 1)
    keep = np.zeros(n, dtype=bool)
    keep[_keyframes(pos, tol)] = True
    color = _rgba(rgb, 0.9)
    start = 0
    for j, end in enumerate(ends):
        idx = np.flatnonzero(keep[start:end + 1]) + start
        idx = np.unique(np.concatenate([[start], idx, [end]]))
        piece = f"{base}/piece{j}"
        meshcat.SetLine(piece, _points3(pos[idx], _Z_TRAIL), 1.0, color)
        # Hidden at frame 0 by the animation, which plays on load (no live 'visible' call: 0.1 kB each).
        anim.SetProperty(0, piece, "visible", False)
        anim.SetProperty(int(end), piece, "visible", True)
        start = int(end)
    anchor_frame = np.concatenate([[0], ends])[np.searchsorted(ends, np.arange(n), side="right")]
    inner = _animate_segment(anim, f"{base}/chord", pos[anchor_frame], pos, 0, tol, _Z_TRAIL)
    meshcat.SetLine(f"{inner}/line", np.asfortranarray([[0.0, 1.0], [0.0, 0.0], [0.0, 0.0]]), 1.0, color)
    return len(ends)


def write_replay(scenario, trajectory: pd.DataFrame, path, *, grasps: pd.DataFrame | None = None, fps: float = 30,
                 speedup: float | None = None, trail: bool = True, meshcat=None) -> Path:
    """Write a self-contained HTML replay of a mission: a Meshcat recording exported with ``StaticHtml``.

    ``trajectory``: columns ``t, entity, x, y, vx, vy`` for every robot and object (any sampling; resampled
    at the replay's frame rate).  ``grasps``: rows ``t_start, t_end, robot, object``; a link is drawn from
    the robot to the object while engaged.  ``speedup``: simulated seconds per replay second (default:
    :func:`choose_speedup`, a 60-120 s replay).  ``meshcat``: a ``Meshcat`` to draw into (its
    ``/mrodrake`` subtree, camera, lights and recording are replaced); by default a private one.
    Returns the path written.
    """
    from pydrake.geometry import Box, Meshcat
    from pydrake.math import RigidTransform

    _check_logs(scenario, trajectory, grasps)
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not (math.isfinite(fps) and fps > 0):
        raise UserError(f"fps: must be a positive number, got {fps!r}")
    t_all = trajectory["t"].to_numpy(dtype=float)
    t0, t1 = float(t_all.min()), float(t_all.max())
    if speedup is None:
        speedup = choose_speedup(t1 - t0)
    if isinstance(speedup, bool) or not isinstance(speedup, (int, float)) or not (
            math.isfinite(speedup) and speedup > 0):
        raise UserError(f"speedup: must be a positive number, got {speedup!r}")
    fps, speedup = float(fps), float(speedup)
    path = Path(path)
    if meshcat is None:
        meshcat = Meshcat()
    meshcat.Delete(ROOT)
    meshcat.DeleteRecording()
    lay = _layout(scenario)
    title = f"{scenario.name}: {t1 - t0:.6g} s simulated, replayed \u00d7{speedup:g}"
    _draw_static(scenario, meshcat, lay, title=title, t_range=(t0, t1))

    n_frames = int(math.ceil((t1 - t0) / speedup * fps - 1e-9)) + 1
    times = np.minimum(t0 + np.arange(n_frames) * (speedup / fps), t1)
    names = scenario.robot_names + scenario.object_names
    radii = {e.name: e.radius for e in list(scenario.robots) + list(scenario.objects)}
    colors = entity_colors(scenario)
    pos = _resample(trajectory, names, times)
    tol = 0.05 * min(radii.values())  # keyframe tolerance: invisible next to the smallest disk

    meshcat.StartRecording(frames_per_second=fps, set_visualizations_while_recording=False)
    # Keyframes are addressed by frame index on the recording itself: Meshcat's time -> frame conversion
    # floors t * fps, which sends some times k / fps to frame k - 1 in floating point.
    anim = meshcat.get_mutable_recording()
    for i, name in enumerate(names):
        _draw_entity(meshcat, lay, name, radii[name], colors[name])
        ent = f"{ROOT}/entities/{name}"
        meshcat.SetTransform(ent, RigidTransform([pos[i, 0, 0], pos[i, 0, 1], 0.0]))
        for k in _keyframes(pos[i], tol):  # entities never turn: a position track is enough
            anim.SetProperty(int(k), ent, "position", [pos[i, k, 0], pos[i, k, 1], 0.0])
        if trail:
            _record_trail(meshcat, anim, f"{ROOT}/trails/{name}", pos[i], max(tol, _TRAIL_TOL * lay.extent),
                          lay.trail_piece, colors[name])
    for g_i, row in enumerate(grasps.itertuples(index=False) if grasps is not None else ()):
        k0 = int(np.searchsorted(times, float(row.t_start) - 1e-9))
        k1 = int(np.searchsorted(times, float(row.t_end) + 1e-9, side="right")) - 1
        if k1 < k0:
            continue
        r, o = names.index(str(row.robot)), names.index(str(row.object))
        link = f"{ROOT}/grasps/{g_i}_{row.robot}_{row.object}"
        width = 0.6 * min(radii[names[r]], radii[names[o]])
        inner = _animate_segment(anim, link, pos[r, k0:k1 + 1], pos[o, k0:k1 + 1], k0, tol, _Z_LINK)
        meshcat.SetObject(f"{inner}/bar", Box(1.0, width, _THIN), _rgba(tuple(0.4 * c for c in colors[names[r]])))
        meshcat.SetTransform(f"{inner}/bar", RigidTransform([0.5, 0.0, 0.0]))
        if k0 > 0:
            anim.SetProperty(0, link, "visible", False)
        anim.SetProperty(k0, link, "visible", True)
        if k1 + 1 < n_frames:
            anim.SetProperty(k1 + 1, link, "visible", False)
        meshcat.SetProperty(link, "visible", k0 == 0)
    # The timeline's marker moves at constant speed: two keyframes.
    x0, x1 = lay.map_box[0], lay.map_box[2]
    marker = f"{ROOT}/timeline/marker"
    meshcat.SetObject(f"{marker}/shape", Box(0.3 * lay.tick_h, 1.2 * lay.tick_h, _THIN), _rgba(_MARKER))
    span = max(t1 - t0, 1e-9)
    for k in (0, n_frames - 1):
        xk = x0 + (times[k] - t0) / span * (x1 - x0)
        anim.SetTransform(k, marker, RigidTransform([xk, lay.timeline_y, _Z_DISK]))
    meshcat.SetTransform(marker, RigidTransform([x0, lay.timeline_y, _Z_DISK]))
    meshcat.StopRecording()
    meshcat.PublishRecording()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(meshcat.StaticHtml(), encoding="utf-8")
    except OSError as exc:
        raise UserError(f"{path}: cannot write the replay ({exc.strerror or exc})") from None
    return path


# --------------------------------------------------------------------------------------------------
# Synthetic missions (tests, previews, benchmark)
# --------------------------------------------------------------------------------------------------


def synthetic_mission(scenario, duration: float = 200.0, *, dt: float = 0.1, speed: float = 2.0,
                      dwell: float = 5.0, bend: float = 0.2, seed: int = 0) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Logs of a made-up sequential mission, for tests, previews and the replay benchmark.

    Moves go between regions at about ``speed`` along quadratic Bezier arcs whose control point is off
    the straight line by up to ``bend`` times its length (0: straight lines); walls and obstacles are
    ignored.  Transports (a robot drives next to an object, grasps it, carries it to another region,
    releases it and backs off) alternate with navigations, one at a time.  Returns
    ``(trajectory, grasps)`` in the format of :func:`write_replay`, sampled every ``dt`` over [0, duration].
    """
    rng = np.random.default_rng(seed)
    pos = initial_layout(scenario)
    radii = {e.name: e.radius for e in list(scenario.robots) + list(scenario.objects)}
    centres = {g.name: np.asarray(g.center, dtype=float) for g in scenario.regions}
    region_radius = {g.name: g.radius for g in scenario.regions}
    where = {e.name: e.initial_region for e in list(scenario.robots) + list(scenario.objects)}
    keys = {n: [np.array([[0.0, p[0], p[1]]])] for n, p in pos.items()}
    grasp_rows = []
    t = 0.0

    def move(names, delta, curved=True):
        nonlocal t
        length = float(np.hypot(*delta))
        normal = np.array([-delta[1], delta[0]])
        control = 0.5 * delta + (rng.uniform(-bend, bend) * normal if curved else 0.0)
        n = max(2, int(math.ceil(length / speed / dt)) + 1)
        s = np.linspace(0.0, 1.0, n)[:, None]
        offsets = 2.0 * s * (1.0 - s) * control + s * s * delta
        times = t + s[:, 0] * length / speed
        for name in names:
            keys[name].append(np.column_stack([times, pos[name] + offsets]))
            pos[name] = pos[name] + delta
        t = float(times[-1])

    def goal(region, r):
        ang, rad = rng.uniform(0.0, 2.0 * np.pi), rng.uniform(0.0, 0.5) * max(region_radius[region] - r, 0.0)
        return centres[region] + rad * np.array([np.cos(ang), np.sin(ang)])

    step = 0
    while t < duration:
        robot = scenario.robot_names[rng.integers(len(scenario.robot_names))]
        if step % 2 == 0 and scenario.objects:
            obj = scenario.object_names[rng.integers(len(scenario.object_names))]
            away = pos[robot] - pos[obj]
            u = away / np.hypot(*away) if np.hypot(*away) > 1e-9 else np.array([1.0, 0.0])
            offset = u * (radii[robot] + scenario.layout.grasp_gap + radii[obj])
            move([robot], pos[obj] + offset - pos[robot])
            t += dwell
            t_grasp = t
            dest = str(rng.choice([g for g in centres if g != where[obj]] or list(centres)))
            move([robot, obj], goal(dest, radii[obj]) - pos[obj])
            grasp_rows.append((t_grasp, t + 0.5 * dwell, robot, obj))
            t += dwell
            where[obj] = where[robot] = dest
            move([robot], u * 2.0 * radii[robot], curved=False)
        else:
            dest = str(rng.choice([g for g in centres if g != where[robot]] or list(centres)))
            move([robot], goal(dest, radii[robot]) - pos[robot])
            where[robot] = dest
        t += dwell
        step += 1

    ts = np.arange(0.0, duration + 0.5 * dt, dt)
    frames = []
    for name in scenario.robot_names + scenario.object_names:
        k = np.concatenate(keys[name] + [np.array([[t + 1.0, pos[name][0], pos[name][1]]])])
        x, y = np.interp(ts, k[:, 0], k[:, 1]), np.interp(ts, k[:, 0], k[:, 2])
        frames.append(pd.DataFrame({"t": ts, "entity": name, "x": x, "y": y,
                                    "vx": np.gradient(x, ts), "vy": np.gradient(y, ts)}))
    grasps = pd.DataFrame(grasp_rows, columns=["t_start", "t_end", "robot", "object"])
    grasps = grasps[grasps["t_start"] <= duration].assign(t_end=lambda g: g["t_end"].clip(upper=duration))
    return pd.concat(frames, ignore_index=True), grasps.reset_index(drop=True)
