"""A scenario's map for authors: ``mrodrake draw FILE -o map.png|map.html``.

One panel shows the workspace, the obstacles, the regions (names and radii) and the initial layout (P_s).
One more panel per traveller (the robots of one radius, and each object carried by its smallest team
strong enough, :meth:`~mrodrake.ts.TransitionSystem.smallest_team`) shades where its centre cannot go (walls
and obstacles grown by its radius plus the control margin, :class:`~mrodrake.geometry.RegionGraph`) and draws
the region pairs it travels between (green) and the passages it cannot use (red, dashed: open to an entity
of radius 0, while at its radius the two regions are cut off from each other), so a door that is too narrow
is seen.
"""

from __future__ import annotations

import html
import io
import math
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, PathPatch
from matplotlib.patches import Polygon as MplPolygon

from mrodrake.errors import UserError
from mrodrake.scenario import Scenario, initial_layout
from mrodrake.ts import TransitionSystem
from mrodrake.viz.figures import _polygon_path

__all__ = ["Traveller", "travellers", "figure_map", "write_map"]

_ROBOT, _OBJECT = "#1f5fbf", "#d62728"
_OPEN, _CLOSED, _SHADE = "#2a9d3a", "#d62728", "#d0d0d0"


@dataclass(frozen=True)
class Traveller:
    """Entities that travel with one radius: robots (``team`` empty) or one object with its team."""

    label: str
    radius: float
    starts: dict[str, int]
    team: tuple[str, ...] = ()
    open: tuple[tuple[int, int], ...] = ()
    closed: tuple[tuple[int, int], ...] = ()
    unreachable: dict[str, tuple[int, ...]] | None = None


def _pairs(ts: TransitionSystem, radius: float) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """Region pairs connected at ``radius``, and those connected at radius 0 whose regions ``radius`` cannot
    travel between at all (not through other regions either)."""
    C, C0 = ts.connections(radius), ts.connections(0.0)
    pairs = [(a, b) for a in range(ts.K) for b in range(a + 1, ts.K)]
    reach = [ts.reach(radius, k) for k in range(ts.K)]
    return [p for p in pairs if C[p]], [(a, b) for a, b in pairs if C0[a, b] and b not in reach[a]]


def travellers(ts: TransitionSystem) -> list[Traveller]:
    """The robots grouped by radius, then every object that some team is strong enough to carry."""
    groups: dict[float, list[int]] = {}
    for i, r in enumerate(ts.robot_radius):
        groups.setdefault(round(r, 2), []).append(i)
    out = []
    for _, members in sorted(groups.items()):
        r = max(ts.robot_radius[i] for i in members)
        names = [ts.robot_names[i] for i in members]
        label = f"robot{'s' if len(names) > 1 else ''} {', '.join(names)} (radius {r:.2f} m)"
        out.append(_traveller(ts, label, r, {ts.robot_names[i]: ts.initial[i] for i in members}))
    for j in range(ts.M):
        best = ts.smallest_team(j)
        if best is None:
            continue
        team, r = best
        names = tuple(ts.robot_names[i] for i in team)
        label = (f"object {ts.object_names[j]} with {'+'.join(names)} (covering radius {r:.2f} m, "
                 f"travels as r = {ts.travel_radius(j, team):.2f} m)")
        out.append(_traveller(ts, label, ts.travel_radius(j, team), {ts.object_names[j]: ts.initial[ts.N + j]}, names))
    return out


def _traveller(ts, label, radius, starts, team=()) -> Traveller:
    open_, closed = _pairs(ts, radius)
    miss = {n: tuple(k for k in range(ts.K) if k not in ts.reach(radius, k0)) for n, k0 in starts.items()}
    return Traveller(label, float(radius), starts, tuple(team), tuple(open_), tuple(closed),
                     {n: m for n, m in miss.items() if m})




def _frame(ax, scenario: Scenario) -> None:
    ws = scenario.workspace
    bx = np.asarray(ws.boundary, dtype=float)
    pad = 0.03 * float(np.ptp(bx, axis=0).max())
    ax.add_patch(MplPolygon(bx, closed=True, fill=False, edgecolor="k", linewidth=1.0))
    for o in ws.obstacles:
        ax.add_patch(MplPolygon(o.polygon, closed=True, facecolor="#808080", edgecolor="#404040", linewidth=0.5))
    ax.set_xlim(bx[:, 0].min() - pad, bx[:, 0].max() + pad)
    ax.set_ylim(bx[:, 1].min() - pad, bx[:, 1].max() + pad)
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)


def _regions(ax, scenario: Scenario, radii: bool, fill: bool = True, fontsize: float = 7) -> None:
    for g in scenario.regions:
        ax.add_patch(Circle(g.center, g.radius, fill=fill, facecolor="#e3f2e3", edgecolor="#2a9d3a", linewidth=0.8))
        text = f"{g.name}\nR = {g.radius:g} m" if radii else g.name
        ax.annotate(text, (g.center[0], g.center[1] + g.radius), xytext=(0, 2), textcoords="offset points",
                    ha="center", va="bottom", fontsize=fontsize)


def _overview(ax, scenario: Scenario, layout: dict[str, np.ndarray]) -> None:
    _frame(ax, scenario)
    _regions(ax, scenario, radii=True)
    robots = set(scenario.robot_names)
    for e in list(scenario.robots) + list(scenario.objects):
        p = layout[e.name]
        colour = _ROBOT if e.name in robots else _OBJECT
        ax.add_patch(Circle(p, e.radius, facecolor=colour, edgecolor="k", linewidth=0.3))
        ax.annotate(e.name, p, xytext=(0, -3), textcoords="offset points", ha="center", va="top", fontsize=6,
                    color=colour)
    ax.set_title(f"{scenario.name}: regions and initial layout (P_s)\nrobots blue, objects red", fontsize=9)


def _panel(ax, ts: TransitionSystem, t: Traveller) -> None:
    sc = ts.scenario
    graph = ts.region_graph
    ws = graph.boundary
    minx, miny, maxx, maxy = ws.bounds
    shade = ws.difference(graph.clearance_space(t.radius))
    for part in getattr(shade, "geoms", [shade]):
        if not part.is_empty and part.geom_type == "Polygon":
            ax.add_patch(PathPatch(_polygon_path(part), facecolor=_SHADE, edgecolor="none"))
    _frame(ax, sc)
    _regions(ax, sc, radii=False, fill=False)
    c = ts.centers
    for a, b in t.open:
        ax.plot(*c[[a, b]].T, color=_OPEN, linewidth=1.0, alpha=0.7)
    for a, b in t.closed:
        ax.plot(*c[[a, b]].T, color=_CLOSED, linewidth=1.6, linestyle="--")
    for k in t.starts.values():
        ax.add_patch(Circle(c[k], t.radius, fill=False, edgecolor=_ROBOT if not t.team else _OBJECT, linewidth=1.2))
    lines = [t.label, f"shaded: walls and obstacles grown by r + {graph.margin:g} m"]
    for name, miss in (t.unreachable or {}).items():
        lines.append(f"{name} can never reach {', '.join(ts.region_names[k] for k in miss)}")
    ax.set_title("\n".join(lines), fontsize=8)


def figure_map(scenario: Scenario, ts: TransitionSystem | None = None,
               group: list[Traveller] | None = None) -> Figure:
    """The map's figure: the overview panel, then one panel per :func:`travellers` entry."""
    ts = ts or TransitionSystem(scenario)
    layout = initial_layout(scenario)
    group = travellers(ts) if group is None else group
    n = 1 + len(group)
    cols = min(n, 3)
    rows = math.ceil(n / cols)
    bx = np.asarray(scenario.workspace.boundary, dtype=float)
    w, h = np.ptp(bx, axis=0)
    cell = 5.0
    aspect = float(h / w) if w > 0 else 1.0
    fig = Figure(figsize=(cell * cols, (cell * min(max(aspect, 0.35), 1.6) + 1.1) * rows))
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    _overview(axes[0], scenario, layout)
    for ax, t in zip(axes[1:], group):
        _panel(ax, ts, t)
    for ax in axes[n:]:
        ax.set_axis_off()
    handles = [Line2D([], [], color=_OPEN, label="regions it travels between"),
               Line2D([], [], color=_CLOSED, linestyle="--", label="passage it cannot use (too narrow at its radius)")]
    fig.legend(handles=handles, loc="lower center", ncol=2, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    return fig


def _report(scenario: Scenario, ts: TransitionSystem, group: list[Traveller]) -> str:
    """The HTML tables of the page: regions, entities and every traveller's closed passages."""
    esc = html.escape
    names = ts.region_names
    rows = "".join(f"<tr><td>{esc(g.name)}</td><td>({g.center[0]:g}, {g.center[1]:g})</td><td>{g.radius:g}</td></tr>"
                   for g in scenario.regions)
    out = [f"<h2>Regions</h2><table><tr><th>name</th><th>centre</th><th>radius (m)</th></tr>{rows}</table>"]
    ents = [("robot", e) for e in scenario.robots] + [("object", e) for e in scenario.objects]
    rows = "".join(f"<tr><td>{kind}</td><td>{esc(e.name)}</td><td>{e.radius:g}</td>"
                   f"<td>{esc(e.initial_region)}</td></tr>" for kind, e in ents)
    out.append("<h2>Entities</h2><table><tr><th>kind</th><th>name</th><th>radius (m)</th><th>starts in</th></tr>"
               f"{rows}</table>")
    items = []
    for t in group:
        closed = ", ".join(f"{names[a]}–{names[b]}" for a, b in t.closed) or "none"
        miss = "; ".join(f"{n} can never reach {', '.join(names[k] for k in m)}"
                         for n, m in (t.unreachable or {}).items())
        items.append(f"<li><b>{esc(t.label)}</b>: passages it cannot use: {esc(closed)}"
                     + (f"; {esc(miss)}" if miss else "") + "</li>")
    out.append(f"<h2>Passages</h2><ul>{''.join(items)}</ul>")
    return "\n".join(out)


def _html(scenario: Scenario, fig: Figure, ts: TransitionSystem, group: list[Traveller]) -> str:
    buf = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        fig.savefig(buf, format="svg", bbox_inches="tight")
    svg = buf.getvalue()
    svg = svg[svg.index("<svg"):]
    title = html.escape(f"{scenario.name}: map")
    style = ("body{font-family:sans-serif;margin:1em;} svg{max-width:100%;height:auto;} "
             "table{border-collapse:collapse;} td,th{border:1px solid #bbb;padding:2px 6px;font-size:90%;}")
    return (f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{title}</title><style>{style}</style>"
            f"</head><body><h1>{title}</h1>\n<div id=\"map\">{svg}</div>\n{_report(scenario, ts, group)}"
            "\n</body></html>\n")


def write_map(scenario: Scenario, path: str | Path) -> Path:
    """Draw the map to ``path``: a PNG, or a self-contained HTML page (inline SVG and tables)."""
    path = Path(path)
    kind = path.suffix.lower()
    if kind not in (".png", ".html"):
        raise UserError(f"-o: expected a .png or .html file name, got '{path}'")
    ts = TransitionSystem(scenario)
    group = travellers(ts)
    fig = figure_map(scenario, ts, group)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if kind == ".png":
            fig.savefig(path, dpi=120, bbox_inches="tight")
        else:
            path.write_text(_html(scenario, fig, ts, group), encoding="utf-8")
    except OSError as e:
        raise UserError(f"-o: cannot write '{path}': {e.strerror or e}") from None
    return path
