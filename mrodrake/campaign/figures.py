"""The campaign's figures: success by size, wall-time and clearance histograms."""

from __future__ import annotations

from pathlib import Path


def write_figures(df, folder: Path) -> list[Path]:
    """success_by_size.png, hist_wall.png, hist_clearance.png (matplotlib, no display)."""
    import pandas as pd
    from matplotlib.figure import Figure

    folder.mkdir(parents=True, exist_ok=True)
    written = []
    if not len(df):
        return written
    fig = Figure(figsize=(7, 3.5))
    ax = fig.subplots()
    groups = list(df.groupby(["robots", "objects", "regions"]))
    labels = [f"{r}/{o}/{k}" for (r, o, k), _ in groups]
    rates = [g["ok"].astype(bool).mean() * 100 for _, g in groups]
    bars = ax.bar(labels, rates, color="#2a9d3a")
    for b, (_, g) in zip(bars, groups):
        ax.annotate(f"{int(g['ok'].sum())}/{len(g)}", (b.get_x() + b.get_width() / 2, b.get_height()),
                    ha="center", va="bottom", fontsize=8)
    ax.set_ylim(0, 110)
    ax.set_xlabel("robots/objects/regions")
    ax.set_ylabel("success [%]")
    ax.set_title("success by scenario size", fontsize=10)
    fig.savefig(folder / "success_by_size.png", dpi=120, bbox_inches="tight")
    written.append(folder / "success_by_size.png")

    ok = df["ok"].astype(bool)
    fig = Figure(figsize=(6, 3.5))
    ax = fig.subplots()
    wall = pd.to_numeric(df["wall_seconds"], errors="coerce")
    ax.hist([wall[ok].dropna(), wall[~ok].dropna()], bins=20, stacked=True, label=["ok", "failed"],
            color=["#2a9d3a", "#d62728"])
    ax.set_xlabel("mission wall time [s]")
    ax.set_ylabel("missions")
    ax.legend()
    fig.savefig(folder / "hist_wall.png", dpi=120, bbox_inches="tight")
    written.append(folder / "hist_wall.png")

    fig = Figure(figsize=(9, 3.5))
    axes = fig.subplots(1, 2)
    for ax, col, label in zip(axes, ("min_clearance", "min_gap"),
                              ("min clearance to walls/obstacles [m]", "min gap between entity disks [m]")):
        v = pd.to_numeric(df[col], errors="coerce")
        ax.hist([v[ok].dropna(), v[~ok].dropna()], bins=20, stacked=True, label=["ok", "failed"],
                color=["#2a9d3a", "#d62728"])
        ax.set_xlabel(label)
        ax.set_ylabel("missions")
        ax.legend()
    fig.savefig(folder / "hist_clearance.png", dpi=120, bbox_inches="tight")
    written.append(folder / "hist_clearance.png")
    return written
