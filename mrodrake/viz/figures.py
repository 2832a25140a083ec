"""The paper's Figs. 2-5 for any simulated transition (matplotlib, Agg; no pyplot state).

* Fig. 2 / Fig. 4 — :func:`figure_trajectory`: the trajectory in the workspace, where the obstacles, the other
  entities and the other regions are drawn enlarged by the entity radius (the complement of the free space
  F, so the entity is a point), and in the point world (unit disk, points b_ℓ, χ(t) = H(x(t))).
* Fig. 3 / Fig. 5 — :func:`figure_signals`: the control input u(t) (of one team member for a transport) and
  the adaptation signals m̂(t), α̂(t).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle, PathPatch
from matplotlib.patches import Polygon as MplPolygon
from matplotlib.path import Path as MplPath
from shapely.geometry import Polygon

_FREE = "#ffffff"
_BLOCKED = "#c8c8c8"
_TRAJ = "#1f5fbf"


def _polygon_path(poly: Polygon) -> MplPath:
    """A matplotlib path of a shapely polygon with holes (even-odd filling)."""
    verts, codes = [], []
    for ring in [poly.exterior, *poly.interiors]:
        xy = np.asarray(ring.coords)
        verts.append(xy)
        codes.append(np.r_[MplPath.MOVETO, np.full(len(xy) - 2, MplPath.LINETO), MplPath.CLOSEPOLY])
    return MplPath(np.vstack(verts), np.concatenate(codes))


def _title(result) -> str:
    src, dst = result.scenario.regions[result.src].name, result.scenario.regions[result.dst].name
    if result.kind == "transport":
        return f"transport of {result.entity} by {', '.join(result.team)}: {src} → {dst}"
    return f"navigation of {result.entity}: {src} → {dst}"


def plot_workspace(result, ax) -> None:
    """Trajectory x(t) in the workspace; blocked area = complement of F (obstacles enlarged by r)."""
    free = result.free
    minx, miny, maxx, maxy = free.boundary.bounds
    pad = 0.02 * max(maxx - minx, maxy - miny)
    ax.add_patch(PathPatch(MplPath([(minx - pad, miny - pad), (maxx + pad, miny - pad), (maxx + pad, maxy + pad),
                                    (minx - pad, maxy + pad), (minx - pad, miny - pad)], closed=True),
                           facecolor=_BLOCKED, edgecolor="none"))
    ax.add_patch(PathPatch(_polygon_path(free.polygon), facecolor=_FREE, edgecolor="#808080", linewidth=0.4))
    ax.plot(*np.asarray(free.boundary.exterior.coords).T, color="k", linewidth=0.8)
    for _, geom in free.obstacles:
        ax.plot(*np.asarray(geom.exterior.coords).T, color="#404040", linewidth=0.5)
    for k, reg in enumerate(result.scenario.regions):
        colour = "#2a9d3a" if k in (result.src, result.dst) else "#b04040"
        ax.add_patch(Circle(reg.center, reg.radius, fill=False, edgecolor=colour, linewidth=0.8, linestyle="--"))
        ax.annotate(reg.name, reg.center, ha="center", va="center", fontsize=7, color=colour)
    pos = result.positions
    ax.plot(pos[:, 0], pos[:, 1], color=_TRAJ, linewidth=1.2, label="x(t)")
    ax.plot(*result.start, "o", color="#2a9d3a", markersize=4, label="start")
    ax.plot(*result.goal, "*", color="#d62728", markersize=8, label="goal $x_d$")
    ax.add_patch(Circle(pos[-1], result.radius, fill=False, edgecolor=_TRAJ, linewidth=0.8))
    if result.kind == "transport":  # the team at the end: robots at their grasp offsets
        radii = {r.name: r.radius for r in result.scenario.robots}
        for name in result.team:
            ax.add_patch(Circle(result.member_positions(name)[-1], radii[name], fill=False, edgecolor="#555555",
                                linewidth=0.6))
    ax.set_xlim(minx - pad, maxx + pad)
    ax.set_ylim(miny - pad, maxy + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper right", fontsize=7)


def plot_point_world(result, ax) -> None:
    """Trajectory χ(t) = H(x(t)) in the point world: unit circle, obstacle points b_ℓ, χ_d."""
    chi = result.point_world()
    ax.add_patch(Circle((0.0, 0.0), 1.0, fill=False, edgecolor="k", linewidth=0.8))
    b = result.task.pw_map.hole_points
    if len(b):
        ax.plot(b[:, 0], b[:, 1], "x", color="#b04040", markersize=4, label="$b_\\ell$")
    ax.plot(chi[:, 0], chi[:, 1], color=_TRAJ, linewidth=1.2, label="χ(t)")
    ax.plot(*chi[0], "o", color="#2a9d3a", markersize=4)
    ax.plot(*result.task.nf.goal, "*", color="#d62728", markersize=8, label="$χ_d$")
    ax.set_xlim(-1.05, 1.05)
    ax.set_ylim(-1.05, 1.05)
    ax.set_aspect("equal")
    ax.set_xlabel("$χ_1$")
    ax.set_ylabel("$χ_2$")
    ax.legend(loc="upper right", fontsize=7)


def plot_inputs(result, ax, member: str | None = None) -> None:
    """u(t) components (of ``member`` = u_ℓ = cf_ℓ u for a transport; default: the first member)."""
    t = result.log["t"].to_numpy()
    if result.kind == "transport":
        member = member or result.team[0]
        u, name = result.member_input(member), f"u_{{{member}}}"
    else:
        u, name = result.inputs, f"u_{{{result.entity}}}"
    ax.plot(t, u[:, 0], label=f"${name},1$")
    ax.plot(t, u[:, 1], label=f"${name},2$")
    grid = np.linspace(t[0], t[-1], 2000) if len(t) > 1 else t
    uniform = np.abs(np.c_[np.interp(grid, t, u[:, 0]), np.interp(grid, t, u[:, 1])])  # time-, not step-weighted
    typical = float(np.percentile(uniform, 99)) if len(t) else 0.0
    if typical > 0.0 and float(np.abs(u).max()) > 100.0 * typical:  # brief barrier spikes: keep the rest visible
        ax.set_yscale("symlog", linthresh=typical)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("u [N]")
    ax.grid(True, linewidth=0.3)
    ax.legend(fontsize=7)


def plot_estimates(result, ax) -> None:
    """m̂(t) and α̂(t)."""
    t = result.log["t"].to_numpy()
    ax.plot(t, result.log["m_hat"], label="$\\hat m$")
    ax.plot(t, result.log["alpha_hat"], label="$\\hat\\alpha$")
    ax.set_xlabel("t [s]")
    ax.grid(True, linewidth=0.3)
    ax.legend(fontsize=7)


def _save(fig: Figure, path) -> None:
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=150, bbox_inches="tight")


def figure_trajectory(result, path: str | Path | None = None) -> Figure:
    """Paper Fig. 2 (navigation) / Fig. 4 (transport): workspace (left) and point world (right)."""
    fig = Figure(figsize=(11, 5.2))
    ax1, ax2 = fig.subplots(1, 2)
    plot_workspace(result, ax1)
    plot_point_world(result, ax2)
    fig.suptitle(_title(result), fontsize=10)
    _save(fig, path)
    return fig


def figure_signals(result, path: str | Path | None = None, member: str | None = None) -> Figure:
    """Paper Fig. 3 (navigation) / Fig. 5 (transport): u(t) (left) and m̂(t), α̂(t) (right)."""
    fig = Figure(figsize=(10, 3.6))
    ax1, ax2 = fig.subplots(1, 2)
    plot_inputs(result, ax1, member)
    plot_estimates(result, ax2)
    fig.suptitle(_title(result), fontsize=10)
    _save(fig, path)
    return fig


def figure_initial(scenario, trajectory, path=None) -> Figure:
    """Paper Fig. 1 analogue: the workspace, regions (labelled) and every entity at the first sample of
    ``trajectory`` (t, entity, x, y)."""
    s = scenario
    fig = Figure(figsize=(8, 7.5))
    ax = fig.subplots()
    ax.add_patch(MplPolygon(s.workspace.boundary, closed=True, fill=False, edgecolor="k", linewidth=0.8))
    for o in s.workspace.obstacles:
        ax.add_patch(MplPolygon(o.polygon, closed=True, facecolor="#808080", edgecolor="#404040"))
    for g in s.regions:
        ax.add_patch(Circle(g.center, g.radius, fill=True, facecolor="#cfe8cf", edgecolor="#2a9d3a"))
        ax.annotate(g.name, (g.center[0], g.center[1] + g.radius + 1.0), ha="center", fontsize=8)
    t0 = trajectory[trajectory["t"] == trajectory["t"].min()]
    rad = {r.name: r.radius for r in s.robots} | {o.name: o.radius for o in s.objects}
    for _, row in t0.iterrows():
        robot = row["entity"] in s.robot_names
        ax.add_patch(Circle((row["x"], row["y"]), rad[row["entity"]],
                            facecolor="#1f5fbf" if robot else "#d62728", edgecolor="k", linewidth=0.3))
    bx = np.asarray(s.workspace.boundary)
    ax.set_xlim(bx[:, 0].min() - 2, bx[:, 0].max() + 2)
    ax.set_ylim(bx[:, 1].min() - 2, bx[:, 1].max() + 2)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{s.name}: initial configuration (robots blue, objects red)", fontsize=10)
    if path is not None:
        fig.savefig(path, dpi=150, bbox_inches="tight")
    return fig
