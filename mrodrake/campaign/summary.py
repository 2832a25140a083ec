"""summary.md: totals, success by family and size, failures by kind, distributions, primitives."""

from __future__ import annotations

import math


def _md_table(header: list[str], rows: list[list]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c).replace("|", "\\|") for c in r) + " |" for r in rows]
    return "\n".join(lines)


def _num(x, fmt: str = ".3g") -> str:
    """``x`` formatted, empty for None and non-finite values."""
    return "" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(float(x), fmt)


def _makespans(df) -> str:
    """Per family: missions both modes finished, and the median / min / max ratio of simulated mission time."""
    import pandas as pd

    seq = df[(df["execution"] == "sequential") & df["ok"].astype(bool)].set_index("mission_id")
    con = df[(df["execution"] == "concurrent") & df["ok"].astype(bool)].copy()
    con["base"] = con["mission_id"].str.removesuffix("-concurrent")
    con = con[con["base"].isin(seq.index)]
    rows = []
    for name, g in con.groupby("family", sort=False):
        r = pd.to_numeric(g["sim_seconds"]).to_numpy() / pd.to_numeric(seq.loc[g["base"], "sim_seconds"]).to_numpy()
        rows.append([name, len(g), _num(float(pd.Series(r).median()), ".3f"), _num(float(r.min()), ".3f"),
                     _num(float(r.max()), ".3f")])
    return _md_table(["family", "pairs", "median ratio", "min", "max"], rows)


def summarize(df, meta: dict, prims=None) -> str:
    """The campaign summary (Markdown): totals, success per family and size, failures by kind with one
    example each, clearance / gap / speed / wall-time distributions; with ``prims`` (primitives.csv) the
    per-primitive durations against their time bounds and the final estimates against the true values."""
    import pandas as pd

    n, total = len(df), meta["missions"]
    ok = int(df["ok"].sum()) if n else 0
    rate = f"{ok / n:.1%}" if n else "n/a"
    wall = meta["wall_seconds"]
    per_min = meta["ran"] / wall * 60.0 if wall > 0 and meta["ran"] else 0.0
    parts = [f"# Campaign {meta['name']}", "",
             f"spec `{meta['spec']}`, engine {meta['engine']}"
             + (f" ({meta['workers']} workers)" if meta.get("workers") else "")
             + (f", address {meta['address']}" if meta.get("address") else ""), "",
             f"- missions: {n}/{total} finished{' (interrupted)' if meta.get('interrupted') else ''}; "
             f"{meta['ran']} ran now, {meta['skipped']} resumed from the journal",
             f"- success: {ok}/{n} ({rate})",
             f"- wall time of this run: {wall:.1f} s ({per_min:.2f} missions/min)", ""]
    if not n:
        return "\n".join(parts) + "\n"
    parts += ["## Success by scenario family", ""]
    fam = []
    for name, g in df.groupby("family", sort=False):
        fam.append([name, len(g), int(g["ok"].sum()), f"{g['ok'].mean():.0%}",
                    _num(pd.to_numeric(g["wall_seconds"]).median(), ".1f")])
    parts += [_md_table(["family", "missions", "ok", "success", "median wall s"], fam), ""]
    size = []
    for (r, o, k), g in df.groupby(["robots", "objects", "regions"]):
        size.append([f"{r}/{o}/{k}", len(g), int(g["ok"].sum()), f"{g['ok'].mean():.0%}"])
    parts += ["## Success by size (robots/objects/regions)", "",
              _md_table(["size", "missions", "ok", "success"], size), ""]
    if "execution" in df.columns and df["execution"].nunique() > 1:
        parts += ["## Makespan, concurrent vs sequential (same plan and draw)", "",
                  _makespans(df), ""]
    failed = df[~df["ok"].astype(bool)]
    parts += ["## Failures by kind", ""]
    if len(failed):
        kinds = []
        for kind, g in failed.groupby("failure_kind"):
            ex = g.iloc[0]
            kinds.append([kind or "(none)", len(g), f"`{ex['mission_id']}`", ex["failure_message"]])
        kinds.sort(key=lambda r: -r[1])
        parts += [_md_table(["kind", "count", "example", "message"], kinds), ""]
    else:
        parts += ["none", ""]
    qs = [0.0, 0.05, 0.5, 0.95, 1.0]
    dist = []
    for col, label in (("min_clearance", "min clearance to walls/obstacles [m]"),
                       ("min_gap", "min gap between entity disks [m]"), ("max_speed", "max speed [m/s]"),
                       ("wall_seconds", "mission wall time [s]"), ("sim_seconds", "simulated time [s]"),
                       ("real_time_factor", "real-time factor")):
        v = pd.to_numeric(df[col], errors="coerce").dropna()
        if len(v):
            dist.append([label, len(v)] + [_num(v.quantile(q)) for q in qs])
    parts += ["## Distributions", "", _md_table(["quantity", "n", "min", "5%", "median", "95%", "max"], dist), ""]
    nan = int(df["nan_seen"].astype(bool).sum())
    neg = int((pd.to_numeric(df["min_clearance"], errors="coerce") < 0).sum())
    overlap = int((pd.to_numeric(df["min_gap"], errors="coerce") < 0).sum())
    parts += [f"- missions with NaN in the trajectory: {nan}; with a wall/obstacle contact (clearance < 0): {neg}; "
              f"with overlapping entity disks (gap < 0): {overlap}",
              "- figures: figures/success_by_size.png, figures/hist_wall.png, figures/hist_clearance.png", ""]
    if prims is not None and len(prims):
        parts += _primitive_sections(prims)
    return "\n".join(parts)


def _primitive_sections(prims) -> list[str]:
    """Summary sections of primitives.csv: durations by kind; final m̂/m and α̂/α by kind."""
    import pandas as pd

    rows = []
    for kind, g in prims.groupby("kind", sort=True):
        sec = pd.to_numeric(g["seconds"], errors="coerce")
        lim = pd.to_numeric(g["time_limit"], errors="coerce")
        frac = (sec / lim).dropna()
        rows.append([kind, len(g), int(g["ok"].astype(bool).sum()), _num(sec.median(), ".1f"),
                     _num(sec.quantile(0.95), ".1f"), _num(sec.max(), ".1f"),
                     _num(frac.max(), ".3f") if len(frac) else "", int((frac > 1).sum())])
    parts = ["## Primitives", "",
             _md_table(["kind", "n", "ok", "median s", "95% s", "max s", "max s / bound", "over bound"], rows), ""]
    est = prims.dropna(subset=["m_hat", "m_true", "alpha_hat", "alpha_true"])
    if not len(est):
        return parts
    rows = []
    for kind, g in est.groupby("kind", sort=True):
        m = pd.to_numeric(g["m_hat"]) / pd.to_numeric(g["m_true"])
        at = pd.to_numeric(g["alpha_true"])
        a = (pd.to_numeric(g["alpha_hat"]) / at.where(at > 0)).dropna()
        cover = int((pd.to_numeric(g["alpha_hat"]) >= at).sum())
        rows.append([kind, len(g)] + [_num(m.quantile(q)) for q in (0.05, 0.5, 0.95)]
                    + [_num(a.quantile(q)) if len(a) else "" for q in (0.05, 0.5, 0.95)] + [f"{cover}/{len(g)}"])
    parts += ["## Final estimates against the true values (navigations and transports)", "",
              _md_table(["kind", "n", "m̂/m 5%", "m̂/m median", "m̂/m 95%", "α̂/α 5%", "α̂/α median", "α̂/α 95%",
                         "α̂ ≥ α"], rows), "",
              "- m: true mass of the moving entity (a transport: object + members); α: its friction bound of "
              "Assumption 1 (summed over the bodies); m̂, α̂: the controller's estimates at the primitive's end", ""]
    return parts
