"""Tests of the 2nd-order navigation function (mrodrake.control.navfunc)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from mrodrake.bench.control import office_like_free_space
from mrodrake.control.navfunc import (
    NavigationFunction,
    beta,
    desired_velocity,
    r_bar_d,
    r_bar_max,
    select_tau,
)
from mrodrake.control.pointworld import PointWorldMap

TAU = 0.01


# ---------------------------------------------------------------------- β


def test_beta_values_and_barrier():
    x = np.linspace(1e-4, 2 * TAU, 2001)
    b, db, ddb = beta(x, TAU)
    inside = x < TAU
    assert np.all(np.diff(b[inside]) < 0)  # property 1: strictly decreasing on (0, τ]
    assert np.all(b[~inside] == 1.0) and np.all(db[~inside] == 0.0) and np.all(ddb[~inside] == 0.0)
    assert np.all(b >= 1.0)
    assert beta(np.array([1e-9 * TAU]), TAU)[0][0] > 1e25  # → ∞ at 0 like (τ/x)³/10


def test_beta_is_twice_continuously_differentiable_at_tau():
    """β, β', β'' → (1, 0, 0) as x ↑ τ, at the rates of a C² join (β''' jumps by 60/τ³)."""
    for eps in (1e-2, 1e-3, 1e-4):
        b, db, ddb = beta(np.array([TAU * (1 - eps)]), TAU)
        assert 0.0 < b[0] - 1.0 < 11 * eps**3  # 1/P(1 − ε) − 1 ≈ 10 ε³
        assert abs(db[0]) < 31 * eps**2 / TAU  # β' ≈ −30 ε² / τ
        assert abs(ddb[0]) < 61 * eps / TAU**2  # β'' ≈ 60 ε / τ²


def test_beta_derivatives_match_finite_differences():
    x = np.linspace(0.05 * TAU, 0.999 * TAU, 300)
    h = 1e-7 * TAU
    b, db, ddb = beta(x, TAU)
    bp, dbp, _ = beta(x + h, TAU)
    bm, dbm, _ = beta(x - h, TAU)
    np.testing.assert_allclose(db, (bp - bm) / (2 * h), rtol=1e-6, atol=1e-6 * np.abs(db).max())
    np.testing.assert_allclose(ddb, (dbp - dbm) / (2 * h), rtol=1e-6, atol=1e-6 * np.abs(ddb).max())


def test_beta_property_4_tilde_beta_strictly_decreasing():
    """β''(x)·x·√x strictly decreasing on (0, τ) (Def. 3, property 4), on a dense grid."""
    for tau in (1e-5, 1e-2, 1.0):
        x = np.geomspace(1e-6 * tau, tau, 200000, endpoint=False)
        _, _, ddb = beta(x, tau)
        tilde = ddb * x * np.sqrt(x)
        assert np.all(tilde > 0)
        assert np.all(np.diff(tilde) < 0)


# ---------------------------------------------------------------------- constants of Prop. 1


def test_r_bar_and_tau_from_the_actual_points():
    b = np.array([[0.5, 0.0], [0.56, 0.0], [-0.2, 0.7]])
    assert r_bar_max(b) == pytest.approx(0.03)  # the close pair, not the scenario's 0.1
    goal = np.array([0.0, -0.3])
    assert r_bar_d(goal, b) == pytest.approx(min(1 - 0.09, 0.25 + 0.09))
    tau, rb, rd = select_tau(goal, b)
    assert rb == pytest.approx(0.03) and tau == pytest.approx(0.9 * 0.03**2)
    # caps: r̄ never exceeds r̄_cap, τ never exceeds τ_cap
    far = np.array([[0.0, 0.5]])
    tau, rb, _ = select_tau(np.zeros(2), far, r_bar_cap=0.1)
    assert rb == pytest.approx(0.1) and tau == pytest.approx(0.9 * 0.01)
    tau, _, _ = select_tau(np.zeros(2), far, r_bar_cap=0.1, tau_cap=1e-3)
    assert tau == pytest.approx(1e-3)
    # the goal close to an obstacle limits τ through r̄_d
    tau, _, rd = select_tau(np.array([0.0, 0.45]), far)
    assert rd == pytest.approx(0.0025) and tau == pytest.approx(0.9 * 0.0025)
    with pytest.raises(ValueError):
        select_tau(np.array([0.0, 0.5]), far)  # goal on an obstacle point


@st.composite
def point_worlds(draw):
    n = draw(st.integers(0, 6))
    pts = []
    for _ in range(n):
        rad = draw(st.floats(0.0, 0.95))
        ang = draw(st.floats(0.0, 2 * np.pi))
        pts.append([rad * np.cos(ang), rad * np.sin(ang)])
    b = np.array(pts).reshape(-1, 2)
    if len(b) > 1 and np.min(np.linalg.norm(b[:, None] - b[None], axis=-1) + 9 * np.eye(len(b))) < 1e-3:
        b = b[:1]
    gr = draw(st.floats(0.0, 0.9))
    ga = draw(st.floats(0.0, 2 * np.pi))
    goal = np.array([gr * np.cos(ga), gr * np.sin(ga)])
    if len(b) and np.min(np.linalg.norm(b - goal, axis=1)) < 1e-3:
        goal = goal * 0.5 + 0.01
    seed = draw(st.integers(0, 2**31 - 1))
    return b, goal, seed


@settings(max_examples=60, deadline=None)
@given(point_worlds())
def test_proposition_1_at_most_one_barrier_active(world):
    """With τ from select_tau, no point of the disk has two d_ℓ ≤ τ, and none is active at the goal."""
    b, goal, seed = world
    nf = NavigationFunction.for_goal(goal, b)
    assert 0 < nf.tau < min(nf.r_bar**2, nf.r_bar_d)
    rng = np.random.default_rng(seed)
    # sample where two barriers could meet: near every b, near the circle and between pairs
    cand = [rng.uniform(-1, 1, size=(2000, 2))]
    for p in b:
        cand.append(p + rng.normal(scale=2 * np.sqrt(nf.tau), size=(500, 2)))
    ang = rng.uniform(0, 2 * np.pi, 2000)
    cand.append(np.column_stack([np.cos(ang), np.sin(ang)]) * (1 - rng.uniform(0, 2 * nf.tau, 2000))[:, None])
    for i in range(len(b)):
        for j in range(i + 1, len(b)):
            cand.append(0.5 * (b[i] + b[j]) + rng.normal(scale=np.sqrt(nf.tau), size=(200, 2)))
    chi = np.vstack(cand)
    chi = chi[np.linalg.norm(chi, axis=1) < 1]
    d = np.column_stack([1 - np.sum(chi**2, axis=1)] + [np.sum((chi - p) ** 2, axis=1) for p in b])
    assert np.all(np.sum(d <= nf.tau, axis=1) <= 1)
    d_goal = np.concatenate([[1 - goal @ goal], np.sum((b - goal) ** 2, axis=1)])
    assert np.all(d_goal > nf.tau)


# ---------------------------------------------------------------------- φ


@pytest.fixture(scope="module")
def nf():
    b = np.array([[0.4, 0.1], [-0.3, 0.5], [0.0, -0.6]])
    return NavigationFunction.for_goal(np.array([-0.5, -0.2]), b, k1=1.5, k2=0.7)


def test_phi_minimum_at_goal(nf):
    value, grad, hess = nf.evaluate(nf.goal)
    assert value == 0.0
    np.testing.assert_array_equal(grad, 0.0)
    np.testing.assert_allclose(hess, 2 * nf.k1 * np.eye(2))
    rng = np.random.default_rng(5)
    chi = rng.uniform(-1, 1, size=(3000, 2))
    chi = chi[np.linalg.norm(chi, axis=1) < 1]
    assert min(nf.value(c) for c in chi) > 0.0


def test_phi_derivatives_match_finite_differences(nf):
    rng = np.random.default_rng(9)
    s = np.sqrt(nf.tau)
    pts = list(rng.uniform(-0.7, 0.7, size=(20, 2)))
    pts += [p + 0.6 * s * np.array([np.cos(a), np.sin(a)]) for p, a in zip(nf.obstacles, (0.3, 2.0, 4.0))]
    pts += [np.array([0.0, 1.0 - 0.3 * nf.tau]), np.array([-(1.0 - 0.2 * nf.tau), 0.0])]  # d_0 < τ
    for chi in pts:
        d = np.concatenate([[1 - chi @ chi], np.sum((nf.obstacles - chi) ** 2, axis=1)])
        h = 5e-4 * min(d.min(), 0.1)  # |∇d_ℓ| ≤ 2, so each d_ℓ changes by at most 0.1 % over the stencil
        v, g, G = nf.evaluate(chi)
        gfd = np.array([(nf.value(chi + h * e) - nf.value(chi - h * e)) / (2 * h) for e in np.eye(2)])
        Gfd = np.column_stack([(nf.gradient(chi + h * e) - nf.gradient(chi - h * e)) / (2 * h) for e in np.eye(2)])
        # central differences: relative truncation error ~ C (2h/d)² ≈ 1e-6 C
        np.testing.assert_allclose(g, gfd, rtol=1e-5, atol=1e-7 * max(1, np.abs(g).max()))
        np.testing.assert_allclose(G, Gfd, rtol=1e-5, atol=1e-6 * max(1, np.abs(G).max()))
        np.testing.assert_allclose(G, G.T)


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 2 * np.pi), st.floats(0.02, 1.5), st.integers(0, 3))
def test_phi_equals_the_sum_of_its_beta_terms(nf, angle, depth, which):
    """φ, ∇φ, ∇²φ at points inside a barrier's region of influence (depth < 1 of τ) or outside (> 1) equal
    the vectorised closed form k1‖χ − χ_d‖² + k2 Σ (β(d_ℓ) − 1) with ∇d_ℓ = ±2(χ − c_ℓ), to rounding
    (a few ulps of the largest term)."""
    if which == 0:  # the rim barrier: d_0 = 1 − ‖χ‖² = depth · τ
        chi = np.sqrt(1.0 - depth * nf.tau) * np.array([np.cos(angle), np.sin(angle)])
    else:
        chi = nf.obstacles[which - 1] + np.sqrt(depth * nf.tau) * np.array([np.cos(angle), np.sin(angle)])
    centers = np.vstack([np.zeros((1, 2)), nf.obstacles])
    sign = np.array([-1.0] + [1.0] * len(nf.obstacles))
    rho2 = np.array([1.0] + [0.0] * len(nf.obstacles))
    d = sign * (np.sum((chi - centers) ** 2, axis=1) - rho2)
    b, db, ddb = beta(np.maximum(d, 1e-300), nf.tau)
    grad_d = 2.0 * sign[:, None] * (chi - centers)
    value = nf.k1 * np.sum((chi - nf.goal) ** 2) + nf.k2 * np.sum(b - 1.0)
    grad = 2 * nf.k1 * (chi - nf.goal) + nf.k2 * db @ grad_d
    hess = 2 * nf.k1 * np.eye(2) + nf.k2 * (np.sum(db * 2 * sign) * np.eye(2) + (grad_d.T * ddb) @ grad_d)
    v, g, G = nf.evaluate(chi)
    scale = max(1.0, abs(value))
    assert abs(v - value) <= 1e-12 * scale
    np.testing.assert_allclose(g, grad, rtol=1e-11, atol=1e-12 * max(1.0, np.abs(grad).max()))
    np.testing.assert_allclose(G, hess, rtol=1e-11, atol=1e-12 * max(1.0, np.abs(hess).max()))


def test_phi_past_a_pole_is_infinite_with_nan_derivatives(nf):
    for chi in (nf.obstacles[0], np.array([0.0, 1.0]), np.array([1.2, 0.0])):  # on a b_ℓ, on and past the rim
        v, g, G = nf.evaluate(chi)
        assert v == np.inf and np.all(np.isnan(g)) and np.all(np.isnan(G))


def test_phi_without_obstacles():
    nf0 = NavigationFunction.for_goal(np.array([0.2, 0.1]), np.zeros((0, 2)))
    assert nf0.r_bar == pytest.approx(0.1) and nf0.tau == pytest.approx(0.009)
    chi = np.array([0.0, 1.0 - 0.2 * nf0.tau])  # inside the boundary barrier
    v, g, G = nf0.evaluate(chi)
    assert v > nf0.k1 * np.sum((chi - nf0.goal) ** 2)
    assert g[1] > 2 * nf0.k1 * (chi - nf0.goal)[1]  # pushed back towards the centre


def test_phi_barrier_grows_towards_obstacles_and_circle(nf):
    for p in nf.obstacles:
        d = np.array([0.5, 0.1, 0.01, 1e-4]) * np.sqrt(nf.tau)
        vals = [nf.value(p + r * np.array([1.0, 0.0])) for r in d]
        assert np.all(np.diff(vals) > 0)
    vals = [nf.value(np.array([0.0, np.sqrt(1 - f * nf.tau)])) for f in (0.5, 0.1, 1e-3)]
    assert np.all(np.diff(vals) > 0)


# ---------------------------------------------------------------------- v_d on the office map


@pytest.fixture(scope="module")
def office_nav():
    free = office_like_free_space()
    pw = PointWorldMap.build(free)
    goal = np.array([175.0, 150.0])
    return free, pw, NavigationFunction.for_map(pw, goal), goal


def test_desired_velocity_and_its_time_derivative(office_nav):
    free, pw, nf, _ = office_nav
    rng = np.random.default_rng(2)
    pts = rng.uniform(0, 200, size=(300, 2))
    pts = pts[shapely.contains_xy(free, pts[:, 0], pts[:, 1])][:25]
    for x in pts:
        xdot = rng.normal(size=2)
        v_d, vdot_d, J, g, _ = desired_velocity(pw, nf, x, xdot)
        np.testing.assert_allclose(J @ v_d, -g, atol=1e-12 * np.abs(g).max())
        h = 1e-4 / np.linalg.norm(xdot)
        vp = desired_velocity(pw, nf, x + h * xdot, xdot)[0]
        vm = desired_velocity(pw, nf, x - h * xdot, xdot)[0]
        fd = (vp - vm) / (2 * h)
        np.testing.assert_allclose(vdot_d, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_kinematic_navigation_reaches_goal_safely(office_nav):
    """ẋ = v_d (speed saturated at 2 m/s; direction kept, so φ∘H still decreases), RK4: reaches the goal,
    φ(H(x)) decreases monotonically, and every state stays inside the free space (shapely)."""
    free, pw, nf, goal = office_nav
    vmax, dt = 2.0, 0.25

    def f(x):
        v = desired_velocity(pw, nf, x, np.zeros(2))[0]
        return v * min(1.0, vmax / np.linalg.norm(v))

    x = np.array([25.0, 20.0])
    traj, phis = [x], [nf.value(pw(x))]
    for _ in range(1500):
        k1 = f(x)
        k2 = f(x + 0.5 * dt * k1)
        k3 = f(x + 0.5 * dt * k2)
        k4 = f(x + dt * k3)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        traj.append(x)
        phis.append(nf.value(pw(x)))
        if np.linalg.norm(x - goal) < 0.05:
            break
    traj = np.array(traj)
    assert np.linalg.norm(traj[-1] - goal) < 0.05
    assert np.all(shapely.contains_xy(free, traj[:, 0], traj[:, 1]))
    assert shapely.distance(free.boundary, shapely.points(traj)).min() > 0.1
    assert np.all(np.diff(phis) < 1e-12)
    # the route leaves the start room, crosses the corridor and enters the goal room: > 250 m of path
    assert np.sum(np.linalg.norm(np.diff(traj, axis=0), axis=1)) > 250.0
