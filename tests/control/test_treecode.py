"""The treecode of the point-world map (mrodrake.control.treecode) against the direct sum over all panels.

The treecode's error is bounded by its tolerances (ε_H, ε_J, ε_Hess) = ``TREE_TOLERANCES`` (module docstring of
the treecode: truncation tails of the multipole series, summed over disjoint clusters); the direct sum itself
rounds by ~n ε_mach times the largest panel term (n ~ 1e3-1e4 panels, terms ≤ ~10): ≤ ~1e-11 on H and its
derivatives away from the boundary.  The tests allow twice the bound.
"""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from mrodrake.bench.control import office_like_free_space
from mrodrake.control.pointworld import TREE_TOLERANCES, PointWorldMap, _chain
from mrodrake.control.treecode import build_tree


@pytest.fixture(scope="module")
def office():
    free = office_like_free_space()
    return free, PointWorldMap.build(free, curvature_fraction=0.1, hole_refinement=1.0)


def sample_points(pw, free, rng, n_inside=400, n_near=400):
    """Random points of the free space and points a 1e-5 .. 1 panel length inside the boundary."""
    minx, miny, maxx, maxy = free.bounds
    pts = rng.uniform((minx, miny), (maxx, maxy), size=(20 * n_inside, 2))
    pts = pts[shapely.contains_xy(free, pts[:, 0], pts[:, 1])][:n_inside]
    a, d, ell = pw.panel_start, pw.panel_end - pw.panel_start, pw.panel_length
    nrm = np.column_stack([-d[:, 1], d[:, 0]]) / ell[:, None]
    k = rng.integers(0, pw.n_panels, n_near)
    frac = rng.uniform(0.0, 1.0, n_near)
    off = ell[k] * 10.0 ** rng.uniform(-5.0, 0.0, n_near)
    near = a[k] + frac[:, None] * d[k] + off[:, None] * nrm[k]
    near = near[shapely.contains_xy(free, near[:, 0], near[:, 1])]
    return np.vstack([pts, near])


def test_treecode_matches_direct_sum(office):
    free, pw = office
    pts = sample_points(pw, free, np.random.default_rng(1))
    H, J, Hs = pw.evaluate(pts)
    H0, J0, Hs0 = pw.evaluate_direct(pts)
    eps_h, eps_j, eps_hess = TREE_TOLERANCES
    assert np.abs(H - H0).max() <= 2 * eps_h
    assert np.abs(J - J0).max() <= 2 * eps_j
    assert np.abs(Hs - Hs0).max() <= 2 * eps_hess
    assert eps_h <= 5e-10 and eps_j <= 5e-8  # the targets |ΔH| <= 1e-9, |ΔJ| <= 1e-7 with the factor 2


@pytest.mark.parametrize("eps", [1e-3, 1e-6])
def test_error_stays_within_the_stated_bound(office, eps):
    """Loose tolerances (expansions used much closer to the point and with fewer terms): the error still stays
    below the bound (which is conservative: it bounds every moment by the cluster's total |charge|)."""
    free, pw = office
    v, L, tx, ty, real, rings = _chain(pw.panel_start, pw.panel_end, pw.panel_ring, with_rings=True)
    tree = build_tree(v[:, 0], v[:, 1], tx, ty, L, pw._sig_links, rings, real, pw._const, eps_value=eps,
                      eps_gradient=eps, eps_hessian=eps, max_ratio=0.9)
    pts = sample_points(pw, free, np.random.default_rng(2), 300, 300)
    out = tree.evaluate_many(pts)
    H0, J0, Hs0 = pw.evaluate_direct(pts)
    rounding = 1e-11
    assert np.abs(out[:, :2] - H0).max() <= eps + rounding
    assert np.abs(out[:, 2:6] - J0.reshape(-1, 4)).max() <= eps + rounding
    assert np.abs(out[:, 6:10] - Hs0[:, :, 0, :].reshape(-1, 4)).max() <= eps + rounding


def test_single_point_batch_and_flat_agree_exactly(office):
    free, pw = office
    pts = sample_points(pw, free, np.random.default_rng(3), 20, 20)
    H, J, Hs = pw.evaluate(pts)
    for k, p in enumerate(pts):
        h1, j1, hs1 = pw.evaluate(p)
        assert np.array_equal(h1, H[k]) and np.array_equal(j1, J[k]) and np.array_equal(hs1, Hs[k])
        assert np.array_equal(pw(p), H[k])
        flat = pw.evaluate_flat(float(p[0]), float(p[1]))
        assert flat[:2] == H[k].tolist() and flat[2:6] == J[k].ravel().tolist()
        assert flat[6:8] == Hs[k, 0, 0].tolist() and flat[8:10] == Hs[k, 1, 0].tolist()
