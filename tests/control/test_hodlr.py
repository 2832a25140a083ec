"""Tests of the hierarchical preconditioner of the point-world map's system (mrodrake.control.hodlr)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Polygon, box

from mrodrake.bench.control import office_like_free_space
from mrodrake.control import hodlr, pointworld
from mrodrake.control.hodlr import BorderedPreconditioner, _aca, _bisect
from mrodrake.control.pointworld import HIERARCHICAL_PANELS, PointWorldMap, _residual, _system
from mrodrake.control.tasks import MAP_OPTIONS


@pytest.fixture(scope="module")
def office_system():
    """The system of the office map's final discretisation: (M, rhs, n panels, midpoints, max |M|)."""
    free = office_like_free_space()
    pw = PointWorldMap.build(free, **MAP_OPTIONS)
    s_a, s_b, perimeter = pw._ext_param
    ext = pw.panel_ring == 0
    sa, sb = np.zeros(pw.n_panels), np.zeros(pw.n_panels)
    sa[ext], sb[ext] = s_a, s_b
    panels = (perimeter, pw.panel_start, pw.panel_end, pw.panel_ring, sa, sb)
    n, n_holes = pw.n_panels, len(pw.hole_points)
    M = np.empty((n + n_holes + 1, n + n_holes + 1))
    rhs, scale_m = _system(panels, n_holes, M, None)
    return M, rhs, n, 0.5 * (pw.panel_start + pw.panel_end), scale_m, pw


def test_cross_approximation_reproduces_a_low_rank_block():
    """A block of exact rank 7 (less a column shift, which the approximation subtracts) is reproduced to
    rounding by 7 crosses plus the two that confirm convergence at most."""
    rng = np.random.default_rng(3)
    M = rng.standard_normal((90, 7)) @ rng.standard_normal((7, 90))
    shift = rng.standard_normal(90)
    rows, cols = np.arange(0, 40), np.arange(40, 90)
    Ut, Vt = _aca(M + shift[None, :], rows, cols, shift, 1e-12)
    assert Ut.shape[0] <= 9
    block = M[np.ix_(rows, cols)]
    np.testing.assert_allclose(Ut.T @ Vt, block, rtol=0.0, atol=1e-10 * np.abs(block).max())


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 400), st.integers(2, 70), st.integers(0, 2**31 - 1))
def test_bisection_partitions_the_points_into_nested_clusters(n, leaf, seed):
    """The clusters are listed children first; each is a contiguous range of the ordering, which is a
    permutation; leaves hold at most ``leaf`` points and an inner cluster is its two children side by side."""
    pts = np.random.default_rng(seed).uniform(-5, 5, (n, 2))
    clusters, order = [], []
    root = _bisect(pts, np.arange(n), 0, leaf, clusters, order)
    assert root == len(clusters) - 1
    assert sorted(np.concatenate(order)) == list(range(n))
    assert (clusters[root].lo, clusters[root].hi) == (0, n)
    for k, cl in enumerate(clusters):
        if cl.mid < 0:
            assert 0 < cl.hi - cl.lo <= leaf
            continue
        left, right = clusters[cl.left], clusters[cl.right]
        assert cl.left < cl.right < k
        assert (left.lo, left.hi, right.lo, right.hi) == (cl.lo, cl.mid, cl.mid, cl.hi)


def test_one_leaf_is_an_exact_inverse_of_the_bordered_system(office_system):
    """With a single leaf the panel block is factorised exactly, so the preconditioner solves the whole
    system (border by its Schur complement, c by c = c' − g Lᵀσ) for any right-hand side, also one with
    nonzero charges, up to the rounding of a dense LU of a first-kind system: residual within 1e-9 of
    max |M| max |x|."""
    M, _, n, mid, scale_m, _ = office_system
    pre = BorderedPreconditioner(M, n, mid, leaf=n)
    rhs = np.random.default_rng(1).standard_normal((len(M), 2))
    x = pre(rhs)
    assert np.abs(_residual(M, x, rhs)).max() <= 1e-9 * scale_m * np.abs(x).max()


@pytest.mark.parametrize("workers", [2, 3, 4])
def test_factorisation_on_threads_is_bitwise_that_of_one_thread(office_system, workers):
    """Subtrees factorised and blocks approximated on several threads: every block sees the same operations in
    the same order, so the preconditioner (and the map) does not depend on the number of threads."""
    M, _, n, mid, _, _ = office_system
    rhs = np.random.default_rng(2).standard_normal((len(M), 2))
    one = BorderedPreconditioner(M, n, mid, leaf=64, workers=1)(rhs)
    many = BorderedPreconditioner(M, n, mid, leaf=64, workers=workers)(rhs)
    assert np.array_equal(one, many)


def test_hierarchical_solve_matches_the_dense_map(office_system):
    """The office map (above :data:`HIERARCHICAL_PANELS`) is solved by the preconditioned refinement, to
    the dense solve's residual bound 1e-13 (max |M| max |x| + max |rhs|); both maps then agree on H, J_H at
    interior points within 1e-9 and 1e-7: the difference of two solutions is harmonic with boundary values
    at most the sum of the residuals (~1e-11 here), and the direct sums add rounding of 3 000 terms."""
    M, rhs, n, mid, scale_m, pw = office_system
    assert n >= HIERARCHICAL_PANELS
    x = pointworld._solve_hierarchical(M.copy(), rhs, n, mid, scale_m)
    assert x is not None
    scale = scale_m * np.abs(x).max() + np.abs(rhs).max()
    assert np.abs(_residual(M, x, rhs)).max() <= 1e-13 * scale
    dense = pointworld._solve_refined(M.copy(), rhs)
    other = PointWorldMap(pw.panel_start, pw.panel_end, pw.panel_ring, dense[:n], dense[n:-1], dense[-1],
                          pw.free_space, pw._ext_param)
    mine = PointWorldMap(pw.panel_start, pw.panel_end, pw.panel_ring, x[:n], x[n:-1], x[-1], pw.free_space,
                         pw._ext_param)
    rng = np.random.default_rng(0)
    minx, miny, maxx, maxy = pw.free_space.bounds
    pts = rng.uniform([minx, miny], [maxx, maxy], (4000, 2))
    pts = pts[shapely.contains_xy(pw.free_space, pts[:, 0], pts[:, 1])][:300]
    h1, j1, _ = mine.evaluate_direct(pts)
    h2, j2, _ = other.evaluate_direct(pts)
    assert np.abs(h1 - h2).max() <= 1e-9
    assert np.abs(j1 - j2).max() <= 1e-7


def test_a_useless_preconditioner_falls_back_to_the_dense_solve(monkeypatch):
    """With sibling blocks compressed to 90 % only, the refinement does not reach the bound within
    MAX_STEPS and the map comes from the dense solve: the same boundary data as the default build."""
    free = office_like_free_space()
    ref = PointWorldMap.build(free, **MAP_OPTIONS)
    calls = []
    solve = pointworld._solve_refined
    monkeypatch.setattr(pointworld, "_solve_refined", lambda *a, **k: calls.append(1) or solve(*a, **k))
    monkeypatch.setattr(hodlr, "TOL", 0.9)
    monkeypatch.setattr(hodlr, "MAX_STEPS", 1)
    monkeypatch.setattr(pointworld, "MAX_STEPS", 1)
    pw = PointWorldMap.build(free, **MAP_OPTIONS)
    assert calls
    np.testing.assert_allclose(pw.hole_points, ref.hole_points, rtol=0.0, atol=1e-9)


def test_long_hole_edges_two_centimetres_apart_are_solved_without_the_dense_fallback(monkeypatch):
    """Two 3 m slabs 2 cm apart: the cross approximation misses part of the block across the gap, so the
    refinement stalls (a gain of ~0.5 per step); GMRES on the same preconditioner then reaches the bound, and
    the map agrees with the dense solve (hole points within 1e-9, the harmonic difference bounded by the two
    residuals)."""
    holes = [box(0.5, 1.39, 3.5, 1.49), box(0.5, 1.51, 3.5, 1.61)]
    free = Polygon(box(0, 0, 4, 3).exterior.coords, [h.exterior.coords for h in holes])
    gmres, dense = [], []
    solve_gmres, solve_dense = pointworld._gmres, pointworld._solve_refined
    monkeypatch.setattr(pointworld, "_gmres", lambda *a: gmres.append(1) or solve_gmres(*a))
    monkeypatch.setattr(pointworld, "_solve_refined", lambda *a, **k: dense.append(1) or solve_dense(*a, **k))
    pw = PointWorldMap.build(free, **MAP_OPTIONS)
    assert pw.n_panels >= HIERARCHICAL_PANELS and gmres and not dense
    monkeypatch.setattr(pointworld, "HIERARCHICAL_PANELS", 10**9)
    ref = PointWorldMap.build(free, **MAP_OPTIONS)
    assert ref.n_panels == pw.n_panels
    np.testing.assert_allclose(pw.hole_points, ref.hole_points, rtol=0.0, atol=1e-9)
