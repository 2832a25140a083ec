"""Adaptive navigation / transport laws (paper Sec. III-A), pure numpy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from shapely.geometry import Point, box

from mrodrake.control.adaptive import (
    CIRCLE_DEFICIT_FACTOR,
    FAULT_DAMPING,
    AdaptiveGains,
    LocalBarrierNavigationFunction,
    NavigationTask,
    adaptation_rates,
    load_sharing,
    local_barriers,
    navigation_input,
    saturate_velocity,
    transport_inputs,
)
from mrodrake.control.local import DiskWorldNavigationFunction, local_task
from mrodrake.control.navfunc import NavigationFunction
from mrodrake.control.pointworld import PointWorldMap
from mrodrake.systems.plants import friction

finite = st.floats(-50, 50, allow_nan=False)
vec = st.tuples(finite, finite).map(np.array)

# A 20 m x 12 m room with a round pillar and a square cabinet: small enough to build in ~50 ms.
ROOM = box(0, 0, 20, 12).difference(Point(6, 6).buffer(1.5)).difference(box(12, 4, 14, 8))
START, GOAL = np.array([2.0, 2.0]), np.array([18.0, 10.0])


@pytest.fixture(scope="module")
def room_map():
    return PointWorldMap.build(ROOM)


DEFAULT_GAINS = AdaptiveGains()


def make_task(pw, start=START, goal=GOAL, v_max=2.0, gains=DEFAULT_GAINS, cf=1):
    return NavigationTask.build(pw, goal, gains, k1=1.0, k2=1.0, r_bar_cap=0.1, tau_cap=0.01, cf=cf,
                                start=start, v_max=v_max)


def test_navigation_input_cancels_the_lyapunov_cross_term():
    """e_vᵀ(u − m̂ v̇_d + (k_v + 3/2 α̂) e_v) = −k_φ e_vᵀ J_Hᵀ ∇φ: the term that cancels k_φ ∇φᵀ J_H e_v."""
    rng = np.random.default_rng(3)
    for _ in range(50):
        J, g, vd, ev = rng.normal(size=(2, 2)), rng.normal(size=2), rng.normal(size=2), rng.normal(size=2)
        m, a, kp, kv = rng.uniform(0.1, 3, size=4)
        u = navigation_input(J, g, vd, ev, m, a, kp, kv)
        assert ev @ (u - m * vd + (kv + 1.5 * a) * ev) == pytest.approx(-kp * ev @ J.T @ g, abs=1e-12)
        np.testing.assert_allclose(u, -kp * J.T @ g + m * vd - (kv + 1.5 * a) * ev, atol=1e-12)


@given(vec, vec)
def test_adaptation_rates(ev, vd):
    dm, da = adaptation_rates(ev, vd, 0.3, 0.7)
    assert dm == pytest.approx(-0.3 * float(ev @ vd))
    assert da == pytest.approx(0.7 * float(ev @ ev)) and da >= 0.0


@given(vec, vec, st.floats(0.1, 10))
def test_saturation_is_a_positive_rescaling_below_v_max(v, vdot, v_max):
    s, _ = saturate_velocity(v, vdot, v_max)
    assert np.linalg.norm(s) < v_max
    c = 1.0 / math.sqrt(1.0 + (v @ v) / v_max**2)
    np.testing.assert_allclose(s, c * v, rtol=1e-12, atol=1e-300)


@given(vec, vec, st.floats(0.1, 10))
def test_saturation_derivative_is_exact(v, vdot, v_max):
    """Dσ(v) v̇ equals the central difference of σ along v + h v̇ (error O(h²))."""
    _, ds = saturate_velocity(v, vdot, v_max)
    h = 1e-5 * max(1.0, float(np.linalg.norm(v))) / max(1.0, float(np.linalg.norm(vdot)))
    fd = (saturate_velocity(v + h * vdot, vdot, v_max)[0] - saturate_velocity(v - h * vdot, vdot, v_max)[0]) / (2 * h)
    np.testing.assert_allclose(ds, fd, atol=1e-6 * (1.0 + np.linalg.norm(vdot)))


def test_no_saturation_for_infinite_v_max():
    v, vdot = np.array([300.0, -4.0]), np.array([1.0, 2.0])
    s, ds = saturate_velocity(v, vdot, math.inf)
    assert s is v and ds is vdot


@given(st.lists(st.floats(0, 10), min_size=1, max_size=6).filter(lambda w: sum(w) > 1e-3), vec)
def test_transport_split_sums_to_the_entity_law(w, u):
    cf = load_sharing(np.array(w) / sum(w))
    parts = transport_inputs(u, cf)
    assert parts.shape == (len(w), 2)
    np.testing.assert_allclose(parts.sum(axis=0), u, atol=1e-9 * (1 + np.abs(u).max()))
    for k in range(len(w)):
        assert parts[k] @ u >= -1e-12  # each robot pushes along the entity law (cf_ℓ ≥ 0)


def test_load_sharing_validation():
    np.testing.assert_allclose(load_sharing(4), [0.25] * 4)
    for bad in ([0.5, 0.6], [1.2, -0.2], [], [math.nan, 1.0]):
        with pytest.raises(ValueError):
            load_sharing(bad)
    with pytest.raises(ValueError):
        load_sharing(0)


def test_start_and_goal_are_outside_every_barrier(room_map):
    """τ_ℓ keep χ_s and χ_d out of every region of influence: β' = 0 there, ∇φ is pure attraction."""
    start = np.array([4.45, 6.0])  # 0.05 m from the pillar
    task = make_task(room_map, start=start)
    for x in (start, GOAL):
        chi = room_map(x)
        _, grad, _ = task.nf.evaluate(chi)
        np.testing.assert_allclose(grad, 2 * task.nf.k1 * (chi - task.nf.goal), atol=1e-15)


points_in_disk = st.tuples(st.floats(0, 0.999), st.floats(0, 2 * math.pi)).map(
    lambda p: np.array([p[0] * math.cos(p[1]), p[0] * math.sin(p[1])]))


@settings(max_examples=200)
@given(st.lists(points_in_disk, min_size=1, max_size=8), points_in_disk, points_in_disk, st.floats(1e-4, 0.2),
       st.sampled_from([1.0, 0.999, 0.95]))
def test_local_barriers_satisfy_proposition_1_per_barrier(holes, goal, start, cap, rho0):
    """Barrier disks pairwise disjoint and off the band of the circle of radius ρ₀ (inside it, or wholly outside
    it for b_ℓ beyond ρ₀); χ_d, χ_s outside all; caps respected."""
    b = np.array(holes)
    dist = np.linalg.norm(b[:, None] - b[None], axis=-1)
    assume(np.all(dist[np.triu_indices(len(b), 1)] > 1e-9))
    assume(np.min(np.linalg.norm(b - goal, axis=1)) > 1e-9 and np.min(np.linalg.norm(b - start, axis=1)) > 1e-9)
    assume(goal @ goal < rho0**2 and start @ start < rho0**2)
    nb = np.linalg.norm(b, axis=1)
    assume(np.all(np.abs(nb - rho0) > 1e-9))
    taus = local_barriers(goal, b, [start], rho_cap=cap, tau_cap=cap**2, rho0=rho0)
    assert np.all(taus > 0) and np.all(taus <= cap**2 * (1 + 1e-12))
    rho = np.sqrt(taus[1:])
    for i, j in zip(*np.triu_indices(len(b), 1)):
        assert rho[i] + rho[j] < dist[i, j]
    inner = nb < rho0
    assert np.all(nb[inner] + rho[inner] < math.sqrt(rho0**2 - taus[0]))
    assert np.all(nb[~inner] - rho[~inner] > rho0)
    for p in (goal, start):
        assert rho0**2 - p @ p > taus[0] and np.all(np.sum((b - p) ** 2, axis=1) > taus[1:])


def test_goal_or_start_beyond_the_circle_barrier_is_rejected():
    b = np.array([[0.2, 0.0]])
    with pytest.raises(ValueError, match="circle barrier"):
        local_barriers(np.array([0.0, 0.985]), b, rho_cap=0.1, tau_cap=0.01, rho0=0.98)
    with pytest.raises(ValueError, match="circle barrier"):
        local_barriers(np.array([0.0, 0.5]), b, [np.array([0.99, 0.0])], rho_cap=0.1, tau_cap=0.01, rho0=0.98)


def test_circle_barrier_blows_up_at_rho0():
    """d_0 = ρ₀² − ‖χ‖² → 0 as ‖χ‖ → ρ₀, so φ → ∞ (property 1 of Def. 3 on the circle of radius ρ₀).

    Near the pole β_0 ≈ τ_0³ / (10 d_0³) with d_0 ≈ 2ρ₀ε at ‖χ‖ = ρ₀ − ε: ε = 1e-6 gives k2 β_0 ≈ 1.6e10 for
    τ_0 = 0.05; φ grows monotonically along the ray (χ·∇φ > 0) and is infinite at ‖χ‖ = ρ₀."""
    rho0 = 0.97
    nf = LocalBarrierNavigationFunction(np.array([0.0, 0.1]), np.array([[0.3, 0.1]]), np.array([0.05, 0.01]),
                                        0.5, 1.0, rho0)
    u = np.array([0.6, -0.8])
    eps = np.array([1e-2, 1e-3, 1e-4, 1e-5, 1e-6])
    vals = []
    for e in eps:
        v, g, _ = nf.evaluate((rho0 - e) * u)
        vals.append(v)
        assert g @ u > 0.0
    assert np.all(np.diff(vals) > 0.0) and vals[-1] > 1e9
    with np.errstate(divide="ignore", invalid="ignore"):
        assert nf.evaluate(rho0 * u)[0] == math.inf  # the pole: d_0 = 0


@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 2.0 * math.pi), st.integers(-8, 8), st.floats(0.5, 0.999))
def test_phi_is_infinite_at_and_past_the_circle_pole_for_every_rounding(angle, ulps, rho0):
    """Near ‖χ‖ = ρ₀ the computed d_0 = ρ₀² − χ·χ may round to either sign: within 2 ulps of the circle
    (d_0 below its rounding bound 16 ε ρ₀²) and beyond it φ = +∞, never the huge negative value a rounded
    d_0 < 0 used to give; a few ulps inside, φ is finite and huge (> 1e30)."""
    nf = LocalBarrierNavigationFunction(np.array([0.0, 0.1]), np.zeros((0, 2)), np.array([0.05]), 0.5, 1.0, rho0)
    u = np.array([math.cos(angle), math.sin(angle)])
    r = rho0 * (1.0 + ulps * np.finfo(float).eps)
    phi = nf.evaluate(r * u)[0]
    assert phi == math.inf if ulps >= -2 else phi > 1e30
    assert nf.evaluate((rho0 + 0.01) * u)[0] == math.inf


@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 2.0 * math.pi), st.floats(0.0, 1.0))
def test_phi_is_never_finite_and_negative_inside_an_obstacle(angle, depth):
    """Inside a grown disk of the disk-world φ (d_ℓ ≤ 0) φ is +∞, as it is at a point obstacle b_ℓ itself."""
    c = np.array([103.0, -240.0])  # office coordinates: rounding of x − c_ℓ matters there
    nf = DiskWorldNavigationFunction(c + [5.0, 0.0], c[None, :], np.array([1.2]), np.array([0.5]), c, 10.0, 0.5)
    x = c + depth * 1.2 * np.array([math.cos(angle), math.sin(angle)])
    assert nf.evaluate(x)[0] == math.inf
    pw = LocalBarrierNavigationFunction(np.array([0.0, 0.1]), np.array([[0.3, 0.1]]), np.array([0.05, 0.01]))
    assert pw.evaluate(np.array([0.3, 0.1]))[0] == math.inf


def test_task_reports_a_fault_past_a_pole_and_drives_nothing():
    """Past a barrier's pole (here: inside another entity's grown disk) the law is undefined: the evaluation
    carries a fault naming the state, zero rates and a stiff finite brake instead of −∇φ, so the integrator
    rejects a trial step that gets there rather than following the law out of the free set."""
    task = local_task([5.0, 0.0], [[2.5, 1.5]], [1.0], [0.0, 0.0], 8.0, AdaptiveGains(), k1=0.25, k2=5.0,
                      start=[0.0, 0.0])
    ok = task.evaluate(np.zeros(2), np.zeros(2), 0.5, 0.0)
    assert ok.fault == "" and np.linalg.norm(ok.u) > 0.0
    ev = task.evaluate(np.array([2.5, 1.0]), np.array([0.3, 0.0]), 0.5, 0.0)
    assert "outside the free set" in ev.fault and "x = (2.5000, 1.0000)" in ev.fault
    np.testing.assert_allclose(ev.u, [-FAULT_DAMPING * 0.3, 0.0])
    assert ev.m_hat_dot == 0.0 and ev.alpha_hat_dot == 0.0
    assert task.evaluate(np.array([9.0, 0.0]), np.zeros(2), 0.5, 0.0).fault  # outside the rim


def test_task_uses_the_maps_circle_deficit(room_map):
    """NavigationTask.build sets ρ₀ = 1 − κ δ_max from the map; objects without circle_deficit give ρ₀ = 1."""
    assert room_map.circle_deficit > 0.0
    task = make_task(room_map)
    assert task.nf.rho0 == pytest.approx(1.0 - CIRCLE_DEFICIT_FACTOR * room_map.circle_deficit, abs=1e-15)
    assert task.nf.rho0 < 1.0


def test_local_barrier_phi_reduces_to_the_papers_phi_for_equal_taus():
    """With all τ_ℓ = τ, φ, ∇φ, ∇²φ equal navfunc's single-τ φ (Def. 3)."""
    rng = np.random.default_rng(1)
    b, goal, tau = rng.uniform(-0.5, 0.5, size=(4, 2)), np.array([0.1, 0.2]), 0.01
    ours = LocalBarrierNavigationFunction(goal, b, np.full(5, tau), 0.3, 2.0)
    paper = NavigationFunction(goal, b, tau, 0.3, 2.0)
    for chi in rng.uniform(-0.7, 0.7, size=(50, 2)):
        for a, c in zip(ours.evaluate(chi), paper.evaluate(chi)):
            np.testing.assert_allclose(a, c, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("rho0", [1.0, 0.97])
def test_local_barrier_phi_derivatives_match_finite_differences(rho0):
    b, goal = np.array([[0.3, 0.1], [-0.4, 0.2]]), np.array([0.0, -0.5])
    nf = LocalBarrierNavigationFunction(goal, b, np.array([0.05, 0.02, 0.03]), 0.5, 1.0, rho0)
    h = 1e-6
    for chi in (np.array([0.35, 0.15]), np.array([-0.3, 0.25]), np.array([0.0, 0.95]), np.array([0.1, 0.1])):
        v, g, H = nf.evaluate(chi)
        for k in range(2):
            e = np.zeros(2)
            e[k] = h
            vp, gp, _ = nf.evaluate(chi + e)
            vm, gm, _ = nf.evaluate(chi - e)
            assert g[k] == pytest.approx((vp - vm) / (2 * h), rel=1e-5, abs=1e-7)
            np.testing.assert_allclose(H[:, k], (gp - gm) / (2 * h), rtol=1e-5, atol=1e-5 * (1 + np.abs(H).max()))


@pytest.mark.parametrize("v_max", [math.inf, 0.5])
def test_vdot_d_is_the_time_derivative_along_the_motion(room_map, v_max):
    """v̇_d from the law equals d/dt v_d(x(t)) along x(t) = x + t ẋ (central difference, O(h²))."""
    task = make_task(room_map, v_max=v_max)
    rng = np.random.default_rng(0)
    pts = rng.uniform((0.5, 0.5), (19.5, 11.5), size=(200, 2))
    pts = [p for p in pts if ROOM.buffer(-0.5).contains(Point(p))][:30]
    for x in pts:
        xdot = rng.normal(size=2)
        ev = task.evaluate(x, xdot, 1.0, 0.0)
        h = 1e-5
        vp = task.evaluate(x + h * xdot, xdot, 1.0, 0.0).v_d
        vm = task.evaluate(x - h * xdot, xdot, 1.0, 0.0).v_d
        fd = (vp - vm) / (2 * h)
        np.testing.assert_allclose(ev.vdot_d, fd, rtol=1e-4, atol=1e-7 * (1 + np.abs(fd).max()))
        assert np.linalg.norm(ev.v_d) < v_max


@pytest.mark.parametrize("v_max", [math.inf, 0.5])
def test_task_evaluate_is_eqs_9_to_11_composed(room_map, v_max):
    """The law's hot path (2 x 2 algebra on floats) equals eq. (9) (``desired_velocity``), σ
    (``saturate_velocity``), eq. (10) (``navigation_input``) and eq. (11) (``adaptation_rates``) composed, up to
    rounding: 1e-12 relative to the terms' magnitudes (a few operations of relative error ε each)."""
    from mrodrake.control.navfunc import desired_velocity

    gains = AdaptiveGains(k_phi=1.3, k_v=0.7, k_m=0.02, k_alpha=0.05)
    task = make_task(room_map, v_max=v_max, gains=gains)
    rng = np.random.default_rng(1)
    pts = rng.uniform((0.5, 0.5), (19.5, 11.5), size=(200, 2))
    pts = [p for p in pts if ROOM.buffer(-0.5).contains(Point(p))][:30]
    for x in pts:
        xdot, m_hat, alpha_hat = rng.normal(size=2), rng.uniform(0.1, 3.0), rng.uniform(0.0, 5.0)
        ev = task.evaluate(x, xdot, m_hat, alpha_hat)
        v_raw, vdot_raw, J, grad, _ = desired_velocity(task.pw_map, task.nf, x, xdot)
        v_d, vdot_d = saturate_velocity(v_raw, vdot_raw, v_max)
        e_v = xdot - v_d
        u = navigation_input(J, grad, vdot_d, e_v, m_hat, alpha_hat, gains.k_phi, gains.k_v)
        dm, da = adaptation_rates(e_v, vdot_d, gains.k_m, gains.k_alpha)
        scale = 1.0 + np.abs(J.T @ grad).max() + m_hat * np.abs(vdot_d).max() + (1 + alpha_hat) * np.abs(e_v).max()
        np.testing.assert_allclose(ev.v_d, v_d, rtol=0, atol=1e-12 * (1 + np.abs(v_d).max()))
        np.testing.assert_allclose(ev.vdot_d, vdot_d, rtol=0, atol=1e-12 * (1 + np.abs(vdot_d).max()))
        np.testing.assert_allclose(ev.u, u, rtol=0, atol=1e-12 * scale)
        assert abs(ev.m_hat_dot - dm) <= 1e-12 * (1 + abs(dm))
        assert abs(ev.alpha_hat_dot - da) <= 1e-12 * (1 + abs(da))


def test_task_is_shared_not_copied_by_deepcopy(room_map):
    import copy

    task = make_task(room_map)
    assert copy.deepcopy(task) is task


def _closed_loop(task, mass, fr_scale, t_end):
    """Numpy simulation of m ẍ + f = u (paper friction), law + adaptation (eq. (11))."""

    def rhs(_, y):
        x, v, m_hat, a_hat = y[:2], y[2:4], y[4], y[5]
        ev = task.evaluate(x, v, m_hat, a_hat)
        acc = (ev.u - friction("paper", fr_scale, 0.5, x, v)) / mass
        return np.concatenate([v, acc, [ev.m_hat_dot, ev.alpha_hat_dot]])

    y0 = np.concatenate([START, [0, 0], [task.gains.m_hat0, task.gains.alpha_hat0]])
    return solve_ivp(rhs, (0, t_end), y0, method="LSODA", rtol=1e-8, atol=1e-9, max_step=0.5)


@pytest.mark.parametrize("mass,fr_scale", [(1.0, 1.25), (3.0, 0.3), (0.5, 2.0)])
def test_closed_loop_converges_safely_in_a_room(room_map, mass, fr_scale):
    """The law drives the true plant (unknown m, f) to x_d without leaving the free space; estimates bounded.

    With k1 = 1, χ converges like exp(−2 k1 η t) with tracking ratio η ≥ k_v/(k_v + α) = 1/(1 + 2 scale);
    180 s leaves ample margin over ln(‖χ0 − χd‖ / 1e-3) / (2 η) ≈ 15-20 s.
    """
    task = make_task(room_map, gains=AdaptiveGains(k_phi=1.0, k_v=1.0, k_m=0.01, k_alpha=0.01))
    sol = _closed_loop(task, mass, fr_scale, 180.0)
    assert sol.success and np.all(np.isfinite(sol.y))
    xy = sol.y[:2].T
    assert np.linalg.norm(xy[-1] - GOAL) < 0.05
    clear = np.array([ROOM.boundary.distance(Point(p)) for p in xy])
    inside = np.array([ROOM.contains(Point(p)) for p in xy])
    assert inside.all() and clear.min() > 0.0
    assert np.all(np.abs(sol.y[4]) < 10) and np.all((sol.y[5] >= 0) & (sol.y[5] < 10))
