"""Whole-mission tests on case studies I and II (prefix + one suffix cycle), recomputed from the written CSV
files.  Case II (4 robots, 3 objects in 4 m regions) also exercises deferred grasps and make-room moves."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import shapely

from mrodrake.execution.monitor import WordMonitor, entity_regions
from mrodrake.geometry import polygon
from mrodrake.planning.plan import task_words
from mrodrake.planning.steps import expand_steps

ROOT = Path(__file__).resolve().parents[2]


# case II (about twice case I's simulation) is in the slow set, to keep the default suite within its budget
@pytest.fixture(scope="module", params=["case_study_1", pytest.param("case_study_2", marks=pytest.mark.slow)])
def mission(request, tmp_path_factory):
    from mrodrake.run import run_mission
    from mrodrake.scenario import load_scenario

    scn = load_scenario(ROOT / "scenarios" / f"{request.param}.yaml")
    out = tmp_path_factory.mktemp(request.param)
    log = run_mission(scn, suffix_cycles=1, seed=0, out_dir=out)  # plans (STyLuS*, seed 0), as `mrodrake run`
    return scn, log.plan, log, out


def _positions(out: Path, scn):
    tr = pd.read_csv(out / "trajectory.csv")
    names = scn.robot_names + scn.object_names
    T = np.sort(tr["t"].unique())
    piv = {c: tr.pivot(index="t", columns="entity", values=c)[names].to_numpy() for c in ("x", "y", "vx", "vy")}
    P = np.stack([piv["x"], piv["y"]], axis=-1)
    V = np.stack([piv["vx"], piv["vy"]], axis=-1)
    radii = np.array([r.radius for r in scn.robots] + [o.radius for o in scn.objects])
    return T, P, V, radii, names


def test_every_primitive_ok(mission):
    scn, plan, log, out = mission
    ev = pd.read_csv(out / "events.csv")
    prim = ev[ev["kind"] == "primitive"]
    assert log.ok, log.message
    assert len(prim) > 0 and prim["ok"].all()
    assert log.steps_done == log.steps_total == len(plan.prefix) + len(plan.suffix)
    for name in ("plan.json", "plan.csv", "signals.csv", "replay.html", "figures/fig1_initial.png"):
        assert (out / name).is_file()
    assert len(list((out / "figures").glob("fig[2-5]_*.png"))) == 4


def test_clearance_positive(mission):
    """Every entity's disk stays clear of walls, obstacles and every other entity at every sample."""
    scn, plan, log, out = mission
    T, P, V, radii, names = _positions(out, scn)
    pts = P.reshape(-1, 2)
    r = np.tile(radii, len(T))
    boundary = polygon(scn.workspace.boundary)
    assert shapely.contains_xy(boundary, pts[:, 0], pts[:, 1]).all()
    geo = shapely.points(pts)
    assert (shapely.distance(boundary.exterior, geo) - r).min() > 0.0
    for o in scn.workspace.obstacles:
        assert (shapely.distance(polygon(o.polygon), geo) - r).min() > 0.0, o.name
    E = len(names)
    for a in range(E):
        for b in range(a + 1, E):
            gap = np.hypot(*(P[:, a] - P[:, b]).T) - radii[a] - radii[b]
            assert gap.min() > 0.0, (names[a], names[b], gap.min())


def test_no_jumps(mission):
    """|Δx| ≤ Δt (V + A Δt) per entity: V the largest logged speed, A the largest logged |Δv|/Δt; between
    samples |v(t)| ≤ |v(t_k)| + A (t − t_k), so the displacement over one sample period is at most
    Δt V + A Δt²/2 ≤ Δt (V + A Δt).  A teleport (sync to a wrong state) would exceed it by metres."""
    scn, plan, log, out = mission
    T, P, V, radii, names = _positions(out, scn)
    dt = np.diff(T)
    assert np.allclose(dt, dt[0], rtol=1e-6)  # uniform sampling
    for e, name in enumerate(names):
        speed = np.hypot(*V[:, e].T)
        Vmax = speed.max()
        Amax = (np.hypot(*np.diff(V[:, e], axis=0).T) / dt).max()
        step = np.hypot(*np.diff(P[:, e], axis=0).T)
        bound = dt * (Vmax + Amax * dt) + 1e-9
        assert (step <= bound).all(), (name, step.max(), bound.max())


def test_monitored_run_consistent(mission):
    """Re-run the executed-word monitor on the logged trajectory: it never dies and, at the end of every
    executed plan step, contains the plan's NBA state."""
    scn, plan, log, out = mission
    ts = plan.ts
    _, nba, words = task_words(scn, ts)
    T, P, V, radii, names = _positions(out, scn)
    centers = np.array([g.center for g in scn.regions], dtype=float)
    rr = np.array([g.radius for g in scn.regions], dtype=float)
    ev = pd.read_csv(out / "events.csv")
    prim = ev[ev["kind"] == "primitive"]
    steps = expand_steps(plan, 1)
    ends, t_last = [], 0.0
    for spec in steps:
        rows = prim[prim["step"] == spec.index]
        t_last = max(t_last, rows["t_end"].max()) if len(rows) else t_last
        ends.append(t_last)
    monitor = WordMonitor(words, entity_regions(centers, radii, P[0], rr, tol=1e-6))
    k = 0
    for i, t in enumerate(T):
        monitor.observe(entity_regions(centers, radii, P[i], rr, tol=1e-6))
        assert monitor.run, f"NBA run died at t={t}"
        while k < len(steps) and ends[k] <= t + 1e-9:
            monitor.end_step()
            assert monitor.contains(steps[k].dst_q), (steps[k].index, monitor.states, steps[k].dst_q)
            k += 1
            monitor.begin_step()
    assert k == len(steps)


def test_final_state_equals_plan(mission):
    scn, plan, log, out = mission
    T, P, V, radii, names = _positions(out, scn)
    ts = plan.ts
    centers = np.array([g.center for g in scn.regions], dtype=float)
    rr = np.array([g.radius for g in scn.regions], dtype=float)
    regions = entity_regions(centers, radii, P[-1], rr, tol=1e-6)
    expected = plan.suffix[0][0]  # the last suffix step closes the cycle
    assert tuple(int(k) for k in regions) == tuple(expected[: ts.N + ts.M])
    assert log.final_state == ts.state_dict(expected) == log.expected_final_state
