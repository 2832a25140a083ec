"""Safety metrics of a logged trajectory and per-primitive records of a mission log."""

from __future__ import annotations

import math

import numpy as np

from mrodrake.scenario import Scenario


def trajectory_metrics(scenario: Scenario, trajectory) -> dict:
    """Safety metrics recomputed from a logged trajectory (t, entity, x, y, vx, vy).

    ``min_clearance``: smallest signed distance from any entity disk to the walls and obstacles (shapely
    distance of the centre to the free-space boundary, negative outside it, minus the radius);
    ``min_gap``: smallest distance between two entity disks (centre distance minus both radii) at a common
    sample time; ``max_speed``; ``nan_seen``: a non-finite value anywhere.
    """
    import shapely

    from mrodrake import geometry as geo

    out = {"min_clearance": None, "min_clearance_entity": "", "min_gap": None, "min_gap_pair": "",
           "max_speed": None, "max_speed_entity": "", "nan_seen": False}
    if trajectory is None or len(trajectory) == 0:
        return out
    radius = {b.name: float(b.radius) for b in list(scenario.robots) + list(scenario.objects)}
    names = [n for n in radius if n in set(trajectory["entity"].unique())]
    wide = trajectory.pivot_table(index="t", columns="entity", values=["x", "y", "vx", "vy"], aggfunc="first",
                                  dropna=False)
    X = wide["x"][names].to_numpy(float)
    Y = wide["y"][names].to_numpy(float)
    VX = wide["vx"][names].to_numpy(float)
    VY = wide["vy"][names].to_numpy(float)
    out["nan_seen"] = bool(not (np.isfinite(X).all() and np.isfinite(Y).all() and np.isfinite(VX).all()
                                and np.isfinite(VY).all()))
    R = np.array([radius[n] for n in names])
    with np.errstate(invalid="ignore"):
        speed = np.hypot(VX, VY)
    if np.isfinite(speed).any():
        k = int(np.nanargmax(speed))
        out["max_speed"], out["max_speed_entity"] = float(speed.flat[k]), names[k % len(names)]
    free = geo.workspace_free_space(geo.polygon(scenario.workspace.boundary),
                                    [geo.polygon(o.polygon) for o in scenario.workspace.obstacles])
    walls = free.boundary
    shapely.prepare(free)
    shapely.prepare(walls)
    best = (math.inf, "")
    for e, name in enumerate(names):
        xy = np.column_stack([X[:, e], Y[:, e]])
        xy = xy[np.isfinite(xy).all(axis=1)]
        if not len(xy):
            continue
        xy = np.unique(xy, axis=0)
        pts = shapely.points(xy)
        d = shapely.distance(walls, pts)
        signed = np.where(shapely.covers(free, pts), d, -d) - R[e]
        if signed.min() < best[0]:
            best = (float(signed.min()), name)
    if best[1]:
        out["min_clearance"], out["min_clearance_entity"] = best
    if len(names) > 1:
        i, j = np.triu_indices(len(names), k=1)
        with np.errstate(invalid="ignore"):
            gap = np.hypot(X[:, i] - X[:, j], Y[:, i] - Y[:, j]) - (R[i] + R[j])
        if np.isfinite(gap).any():
            k = int(np.nanargmin(gap))
            p = k % len(i)
            out["min_gap"], out["min_gap_pair"] = float(gap.flat[k]), f"{names[i[p]]}-{names[j[p]]}"
    return out


def primitive_records(scenario: Scenario, log) -> list[dict]:
    """One record per executed primitive of a mission log: step, kind, entities, duration against the motion's
    time bound, and for navigations and transports the final estimates m̂, α̂ of its controller against the
    true mass and friction bound of the moving entity (a transport: object plus members, the bounds of
    Assumption 1 adding up)."""
    bodies = {b.name: b for b in list(scenario.robots) + list(scenario.objects)}
    ev = log.events
    if ev is None or not len(ev):
        return []
    sig = log.signals
    out = []
    for _, e in ev[ev["kind"].isin(["primitive", "room"])].iterrows():
        names = str(e["entities"]).split()
        kind = "room" if e["kind"] == "room" else str(e["action"]).split()[0]
        t0, t1 = float(e["t_start"]), float(e["t_end"])
        limit = _finite(e.get("time_limit"))
        rec = {"step": int(e["step"]), "kind": kind, "action": str(e["action"]), "entities": " ".join(names),
               "ok": bool(e["ok"]), "seconds": t1 - t0, "time_limit": limit,
               "m_true": None, "m_hat": None, "alpha_true": None, "alpha_hat": None}
        if kind in ("navigate", "transport") and names:
            s = sig[(sig["entity"] == names[0]) & (sig["t"] >= t0) & (sig["t"] <= t1)]
            if len(s):
                last = s.iloc[-1]
                rec.update(m_true=float(sum(bodies[n].mass for n in names)),
                           alpha_true=float(sum(bodies[n].friction.alpha_bound for n in names)),
                           m_hat=float(last["m_hat"]), alpha_hat=float(last["alpha_hat"]))
        out.append(rec)
    return out


def _finite(value) -> float | None:
    """A finite float, or None for empty / NaN cells."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None
