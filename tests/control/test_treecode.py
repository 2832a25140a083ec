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
from mrodrake.control import treecode
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


def test_batches_split_over_threads_agree_exactly(office, monkeypatch):
    """Every point is evaluated on its own, so a batch gives the same bits on one thread as on several."""
    free, pw = office
    pts = sample_points(pw, free, np.random.default_rng(4), 600, 600)
    assert len(pts) >= 2 * treecode.BATCH_PER_THREAD
    monkeypatch.setattr(treecode, "usable_cores", lambda: 2)
    split = pw.tree.evaluate_many(pts)
    monkeypatch.setattr(treecode, "usable_cores", lambda: 1)
    assert np.array_equal(split, pw.tree.evaluate_many(pts))


def test_tree_clusters_split_the_leaves_in_pre_order(office):
    """Node k's children are k + 1 and k + 2h (h: leaves of the first child), the leaves are runs of one ring's
    real links that cover every real link once, and every node's disk holds the vertices of its links."""
    _, pw = office
    tree = pw.tree
    nodei, nodef = tree.nodei, tree.nodef

    def leaves_under(k):
        if nodei[k, 0] < 0:
            return [k]
        left, right = nodei[k, :2]
        h = len(leaves_under(left))
        assert left == k + 1 and right == k + 2 * h
        return leaves_under(left) + leaves_under(right)

    leaves = leaves_under(0)
    assert len(nodei) == 2 * len(leaves) - 1
    runs = sorted((int(nodei[k, 2]), int(nodei[k, 3])) for k in leaves)
    covered = np.concatenate([np.arange(a, b) for a, b in runs])
    assert np.array_equal(covered, np.flatnonzero(pw._link_real))
    assert all(len(set(pw._link_ring[a:b])) == 1 for a, b in runs)
    for k in range(len(nodei)):
        links = np.concatenate([np.arange(nodei[q, 2], nodei[q, 3]) for q in leaves_under(k)])
        verts = tree.vert[np.union1d(links, links + 1)]
        assert np.hypot(*(verts - nodef[k, :2]).T).max() <= nodef[k, 2] * (1 + 1e-12)


def test_tree_moments_do_not_depend_on_the_thread_count(office, monkeypatch):
    _, pw = office
    v, L, tx, ty, real, rings = _chain(pw.panel_start, pw.panel_end, pw.panel_ring, with_rings=True)
    trees = []
    for cores in (1, 2):
        monkeypatch.setattr(treecode, "usable_cores", lambda c=cores: c)
        trees.append(build_tree(v[:, 0], v[:, 1], tx, ty, L, pw._sig_links, rings, real, pw._const))
    for field in ("nodef", "nodei", "coef", "params"):
        assert np.array_equal(getattr(trees[0], field), getattr(trees[1], field))
