"""Guarantee checks of simulated transitions (tests/systems/test_transitions.py, test_regressions.py).

Time bound.  With perfect velocity tracking and no saturation, χ̇ = −∇φ = −2k1(χ − χ_d) away from the
barriers, so ‖χ − χ_d‖ shrinks like e^{−2 k1 t}; the ball is inside the region once ‖χ − χ_d‖ ≤ ρ, the
distance from χ_d to the image of the circle of centres whose ball touches the region's rim.  The speed
bound v_max costs at most the time to drive a path twice as long as the straight line at v_max (office
paths via doors).  Friction slows tracking: in steady state (k_v + 3/2 α̂) e_v = −f with ‖f‖ ≤ α‖ẋ‖, α̂ ≥ 0,
gives ‖ẋ‖ ≥ η‖v_d‖ with η = k_v / (k_v + α) (α the sum over the bodies of the entity).  Hence

    T = [ln(‖χ_0 − χ_d‖ / ρ) / (2 k1) + 2 ‖x_0 − x_d‖ / v_max] / η.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import LineString, Point

from mrodrake.control.freespace import clearances, inside_region
from mrodrake.control.tasks import entity_layout
from mrodrake.errors import UserError
from mrodrake.geometry import polygon
from mrodrake.scenario import load_scenario
from mrodrake.systems.transition import IMPLICIT_ACCURACY, simulate_transition

SCEN = Path(__file__).resolve().parents[2] / "scenarios"
CASE1 = load_scenario(SCEN / "case_study_1.yaml")
#: Drake's Newton stopping factor κ of its implicit integrators (update norm < κ × accuracy).
NEWTON_KAPPA = 0.05
M_HAT_BOUND = 50.0  # |m̂| and α̂ stay far below this (true masses <= 10 kg per entity, α̂(0) <= 4 x 5 = 20)


def time_bound(r) -> float:
    """The bound T of the module docstring for a simulated transition ``r``."""
    s, task = r.scenario, r.task
    reg = s.regions[r.dst]
    th = np.linspace(0.0, 2.0 * math.pi, 720, endpoint=False)
    circle = np.asarray(reg.center) + (reg.radius - r.radius) * np.c_[np.cos(th), np.sin(th)]
    circle = circle[shapely.contains_xy(r.free.polygon, circle[:, 0], circle[:, 1])]
    rho = float(np.min(np.linalg.norm(task.pw_map(circle) - task.nf.goal, axis=1)))
    chi0 = task.pw_map(r.start)
    bodies = [r.entity] + list(r.team)
    frictions = {b.name: b.friction for b in [*s.robots, *s.objects]}
    alpha = sum((2.0 if frictions[b].model == "paper" else 1.0) * r.true_params[b]["scale"] for b in bodies)
    eta = s.control.k_v / (s.control.k_v + alpha)
    k1 = task.nf.k1
    return (math.log(np.linalg.norm(chi0 - task.nf.goal) / rho) / (2 * k1)
            + 2 * np.linalg.norm(r.start - r.goal) / task.v_max) / eta


def min_clearance(r) -> tuple[float, str]:
    """Smallest clearance of the entity ball over the logged states and the polyline between them."""
    s = r.scenario
    avoid = [k for k in range(len(s.regions)) if k not in (r.src, r.dst)]
    pts = r.positions
    cl = clearances(s, pts, r.radius, r.others, avoid)
    worst = min((float(v.min()), k) for k, v in cl.items())
    path = LineString(pts) if len(pts) > 1 else Point(pts[0])
    boundary = polygon(s.workspace.boundary)
    assert boundary.contains(path)
    seg = [(boundary.exterior.distance(path) - r.radius, "wall (polyline)")]
    seg += [(polygon(o.polygon).distance(path) - r.radius, o.name + " (polyline)") for o in s.workspace.obstacles]
    seg += [(Point(d.center).distance(path) - d.radius - r.radius, d.name + " (polyline)") for d in r.others]
    seg += [(Point(s.regions[k].center).distance(path) - s.regions[k].radius - r.radius,
             s.regions[k].name + " (polyline)") for k in avoid]
    return min([worst, *seg])


def check_guarantees(r) -> None:
    """Assert the guarantees of a simulated transition ``r`` (arrival in time, clearance, bounded estimates)."""
    log = r.log
    assert np.all(np.isfinite(log.to_numpy())), "NaN or inf in the log"
    assert r.reached, f"{r.task.label}: not reached ({r.status}) at t = {r.t_final:.1f} s"
    bound = time_bound(r)
    assert r.t_final <= bound, f"{r.task.label}: arrival at {r.t_final:.1f} s > bound {bound:.1f} s"
    assert inside_region(r.scenario, r.dst, r.positions[-1], r.radius)
    assert np.hypot(*r.velocities[-1]) <= 0.05 + 1e-12
    clear, what = min_clearance(r)
    assert clear > 0.0, f"{r.task.label}: clearance {clear:.4f} m to {what}"
    assert np.all(np.abs(log["m_hat"]) < M_HAT_BOUND)
    assert np.all((log["alpha_hat"] >= 0.0) & (log["alpha_hat"] < M_HAT_BOUND))
    # dα̂/dt = k_α‖e_v‖² ≥ 0: α̂ never falls, up to the implicit-Euler spans (stiff stretches): their Newton
    # iteration stops once its update is below κ × accuracy in the weighted state norm (Drake's implicit
    # integrators, κ = 0.05 after Hairer & Wanner IV.8; accuracy 1e-3 there), so one step may lose up to that,
    # relative to max(1, |α̂|).  A reset to α̂(0) (a drop of the ~1e-2 gained over a transition) exceeds it;
    # a sign error of the law shows as a net loss over the transition.
    a = log["alpha_hat"].to_numpy()
    newton = NEWTON_KAPPA * IMPLICIT_ACCURACY
    assert np.all(np.diff(a) >= -newton * np.maximum(1.0, np.abs(a[1:])))
    assert a[-1] >= a[0]


def random_spot(region, radius, others, rng):
    """A start centre drawn uniformly among those whose ball is in the region and clear of the others."""
    c, room = np.asarray(region.center), region.radius - radius - 0.05
    for _ in range(2000):
        p = c + rng.uniform(-room, room, size=2)
        if np.hypot(*(p - c)) <= room and all(np.hypot(*(p - d.center)) > d.radius + radius + 0.05 for d in others):
            return p
    return None


def random_transition(case, masses, scales, frequencies, seed, pair_index):
    """Simulate ``case`` = (kind, entity, team) of case study I between the ``pair_index``-th ordered region pair
    with the given true parameters and a random start spot (None when no spot is free)."""
    kind, entity, team = case
    pairs = list(itertools.permutations(range(4), 2))
    src, dst = pairs[pair_index % len(pairs)]
    bodies = [entity, *team]
    over = {b: {"mass": m, "scale": sc, "frequency": fq} for b, m, sc, fq in zip(bodies, masses, scales, frequencies)}
    teams = {entity: list(team)} if team else {}
    spot = f"{entity}@goal"
    radius = 0.75 if kind == "navigate" else 1.8
    placed = entity_layout(CASE1, {entity: src}, teams, seed=seed, reserve={dst: [(spot, radius)]})
    others = [d for n, d in placed.items() if n not in (entity, spot)]
    start = random_spot(CASE1.regions[src], radius, others, np.random.default_rng(seed))
    if start is None:
        return None
    return simulate_transition(CASE1, kind, entity, team=list(team), src_region=src, dst_region=dst, others=others,
                               start=start, goal=placed[spot].center, true_params_override=over, t_max=20000.0,
                               seed=seed)


def transition_property(case, masses, scales, frequencies, seed, pair_index):
    """:func:`random_transition` then :func:`check_guarantees` (nothing to check when P_s finds no room)."""
    try:
        r = random_transition(case, masses, scales, frequencies, seed, pair_index)
    except UserError as e:  # P_s found no room for this combination: nothing to simulate
        assert "do not fit" in str(e) or "no room" in str(e)
        return
    if r is not None:
        check_guarantees(r)
