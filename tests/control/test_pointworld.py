"""Tests of the harmonic point-world map H (mrodrake.control.pointworld)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from shapely.geometry import MultiPolygon, Point, Polygon, box
from shapely.ops import unary_union

from mrodrake.bench.control import office_like_free_space
from mrodrake.control import treecode
from mrodrake.control.pointworld import (
    PointWorldMap,
    _assemble,
    _ball_min,
    _chain,
    _cone_envelope,
    _hole_gaps,
    _kernel,
    _local_width,
    _prepare_ring,
    _residual,
    _separation,
    _vertex_logs_angles,
)
from mrodrake.errors import UserError

ROBOT_RADIUS = 0.4


def two_rooms_free_space():
    """40 m x 30 m, two rooms joined by a 4 m door, two boxes and two disks (4 holes)."""
    obstacles = [
        box(19.5, 0, 20.5, 13), box(19.5, 17, 20.5, 30), box(5, 5, 9, 7), box(28, 20, 31, 22),
        Point(10, 22).buffer(1.5), Point(32, 8).buffer(1.0),
    ]
    outer = box(0, 0, 40, 30).buffer(-ROBOT_RADIUS, join_style="mitre")
    return outer.difference(unary_union(obstacles).buffer(ROBOT_RADIUS))


@pytest.fixture(scope="module")
def rooms():
    free = two_rooms_free_space()
    return free, PointWorldMap.build(free)


@pytest.fixture(scope="module")
def office():
    free = office_like_free_space()
    return free, PointWorldMap.build(free)


def grid_away_from_margin(pw, free, spacing):
    """Grid points of the free space at least one local panel length from its boundary."""
    minx, miny, maxx, maxy = free.bounds
    gx, gy = np.meshgrid(np.arange(minx, maxx, spacing), np.arange(miny, maxy, spacing))
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    pts = pts[shapely.contains_xy(free, pts[:, 0], pts[:, 1])]
    dist = shapely.distance(free.boundary, shapely.points(pts))
    return pts[dist >= pw.local_margin(pts)]


def separation(b):
    """Per hole: half the distance to the nearest other b or to the unit circle (the r̄ of hole ℓ)."""
    r = 1.0 - np.linalg.norm(b, axis=1)
    if len(b) > 1:
        d = np.linalg.norm(b[:, None] - b[None], axis=-1) + np.diag(np.full(len(b), np.inf))
        r = np.minimum(r, d.min(axis=1))
    return 0.5 * r


# ---------------------------------------------------------------------- the panel kernel


def _one_panel(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = b - a
    L = np.hypot(*d)
    return np.array([a[0], b[0]]), np.array([a[1], b[1]]), np.array([d[0] / L]), np.array([d[1] / L]), np.array([L])


def _quad_kernel(x, a, b):
    """W and ∇W of one panel by adaptive quadrature."""
    a, b, x = (np.asarray(v, float) for v in (a, b, x))
    L = np.hypot(*(b - a))
    t = (b - a) / L
    proj = float(np.clip((x - a) @ t, 0.0, L))
    cuts = [0.0, proj, L] if 0.0 < proj < L else [0.0, L]  # split at the near-singular point

    def integrate(f):
        return sum(
            quad(lambda s: f(x - a - s * t), lo, hi, limit=400, epsabs=1e-13, epsrel=1e-12)[0]
            for lo, hi in zip(cuts[:-1], cuts[1:])
        )

    W = integrate(lambda r: math.log(r @ r))
    gx = integrate(lambda r: 2.0 * r[0] / (r @ r))
    gy = integrate(lambda r: 2.0 * r[1] / (r @ r))
    return W, np.array([gx, gy])


@pytest.mark.parametrize(
    "a, b",
    [((0.0, 0.0), (1.0, 0.0)), ((-1.0, -1.0), (-1.0, 1.0)), ((3.0, 2.0), (1.5, 4.0)), ((0.2, -0.7), (-2.0, -0.1))],
)
def test_kernel_matches_quadrature(a, b):
    """Closed-form W and ∇W agree with quadrature everywhere off the panel, across every atan branch."""
    geom = _one_panel(a, b)
    rng = np.random.default_rng(7)
    a_, b_ = np.asarray(a), np.asarray(b)
    mid, d = 0.5 * (a_ + b_), b_ - a_
    nrm = np.array([-d[1], d[0]]) / np.hypot(*d)
    pts = [mid + 0.3 * nrm, mid - 0.3 * nrm, mid + 1e-3 * nrm, mid - 1e-3 * nrm,  # just above / below
           a_ - 0.5 * d, b_ + 0.5 * d, a_ - 0.5 * d + 1e-4 * nrm, b_ + 0.5 * d - 1e-4 * nrm,  # on the line
           np.array([0.05, 0.3])]  # sees the panel (-1,-1)-(-1,1) across the atan2 cut
    pts += list(rng.uniform(-4, 4, size=(20, 2)))
    for x in pts:
        W, dl, th, _, _ = _kernel(np.array([x[0]]), np.array([x[1]]), *geom, derivs=True)
        t = d / np.hypot(*d)
        grad = dl[0, 0] * t + 2.0 * th[0, 0] * np.array([-t[1], t[0]])
        Wq, gq = _quad_kernel(x, a, b)
        assert W[0, 0] == pytest.approx(Wq, abs=1e-9)
        np.testing.assert_allclose(grad, gq, atol=1e-8 * max(1.0, np.abs(gq).max()))


def test_kernel_hessian_matches_finite_differences():
    geom = _one_panel((0.5, -0.3), (-1.0, 1.2))
    rng = np.random.default_rng(3)
    h = 1e-5
    for x in rng.uniform(-3, 3, size=(30, 2)):
        def grad(p):
            _, dl, th, _, _ = _kernel(np.array([p[0]]), np.array([p[1]]), *geom, derivs=True)
            tx, ty = geom[2][0], geom[3][0]
            return dl[0, 0] * np.array([tx, ty]) + 2.0 * th[0, 0] * np.array([-ty, tx])

        _, _, _, A, B = _kernel(np.array([x[0]]), np.array([x[1]]), *geom, derivs=True)
        tx, ty = geom[2][0], geom[3][0]
        c2, s2 = tx * tx - ty * ty, 2 * tx * ty
        hxx, hxy = A[0, 0] * c2 - B[0, 0] * s2, A[0, 0] * s2 + B[0, 0] * c2
        fd = np.column_stack([(grad(x + h * e) - grad(x - h * e)) / (2 * h) for e in np.eye(2)])
        np.testing.assert_allclose([[hxx, hxy], [hxy, -hxx]], fd, atol=1e-6 * max(1.0, np.abs(fd).max()))


def test_compiled_assembly_matches_the_closed_form(rooms):
    """The compiled matrix assembly writes the closed-form W of every panel at every collocation point (links
    between rings skipped), in float64 and float32; both evaluate the same formula in double precision, so
    they agree to rounding of terms of size |u_a ln r_a| (≤ ~10² here): within 1e-12 × max |W|; it returns
    max |W| of what it wrote (the scale of the solve's residual test)."""
    _, pw = rooms
    a, b, rid = pw.panel_start, pw.panel_end, pw.panel_ring
    v, L, tx, ty, real = _chain(a, b, rid)
    mid = 0.5 * (a + b)
    n = len(a)
    W = _kernel(mid[:, 0], mid[:, 1], v[:, 0], v[:, 1], tx, ty, L, derivs=False)[0][:, real]
    M, M32 = np.full((n, n), np.nan), np.full((n, n), np.nan, dtype=np.float32)
    col = np.where(real, np.cumsum(real) - 1, -1)
    big = _assemble(mid[:, 0].copy(), mid[:, 1].copy(), v[:, 0].copy(), v[:, 1].copy(), tx, ty, L, col, M, M32)
    assert big == np.abs(M).max()
    scale = np.abs(W).max()
    np.testing.assert_allclose(M, W, rtol=0.0, atol=1e-12 * scale)
    np.testing.assert_allclose(M32, W.astype(np.float32), rtol=2.0 ** -23, atol=2.0 ** -23 * scale)


@pytest.mark.parametrize("scale", [1e-6, 1e-2, 1.0, 1e2, 1e4])
def test_vectorised_logs_and_angles_match_the_c_library(scale):
    """The assembly's branch-free ln r² and atan2 stay within 4 units in the last place of numpy's (libm's),
    at every scale and in every octant, on the axes and at the vertex itself (r² floored at 1e-300)."""
    rng = np.random.default_rng(7)
    n = 2000
    vx, vy = rng.uniform(-scale, scale, n), rng.uniform(-scale, scale, n)
    pts = rng.uniform(-scale, scale, (40, 2))
    vx[:5] = pts[0, 0] + np.array([0.3, -0.3, 0.0, 0.0, 0.0]) * scale  # on both axes through the first point
    vy[:5] = pts[0, 1] + np.array([0.0, 0.0, 0.3, -0.3, 0.0]) * scale  # and at it
    lr, ang, r2 = np.empty(n), np.empty(n), np.empty(n)
    mant, expo = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    for x, y in pts:
        _vertex_logs_angles(x, y, vx, vy, lr, ang, r2, mant, expo)
        dx, dy = x - vx, y - vy
        lr0 = np.log(np.maximum(dx * dx + dy * dy, 1e-300))
        ang0 = np.arctan2(dy, dx)
        assert np.all(np.abs(lr - lr0) <= 4 * np.spacing(np.abs(lr0)))
        assert np.all(np.abs(ang - ang0) <= 4 * np.spacing(np.abs(ang0)))


def test_refinement_residual_matches_numpy_and_ignores_the_thread_count(monkeypatch):
    """The compiled residual of the refinement agrees with rhs − M x to rounding of the dot products
    (n ε |M| |x|) and gives the same bits on one thread as on several."""
    rng = np.random.default_rng(5)
    n = 2500
    M = rng.standard_normal((n, n))
    x = rng.standard_normal((n, 2))
    rhs = M @ x + 1e-9 * rng.standard_normal((n, 2))
    monkeypatch.setattr(treecode, "usable_cores", lambda: 2)
    split = _residual(M, x, rhs)
    np.testing.assert_allclose(split, rhs - M @ x, rtol=0.0, atol=n * 2.0**-52 * np.abs(M).max() * np.abs(x).max())
    monkeypatch.setattr(treecode, "usable_cores", lambda: 1)
    np.testing.assert_array_equal(_residual(M, x, rhs), split)


def _build_in_child(queue):
    queue.put(PointWorldMap.build(box(0, 0, 10, 10).difference(box(4, 4, 6, 6))).n_panels)


def test_maps_build_in_a_process_forked_after_a_build():
    """The assembly's threads live for one call, so a process forked after a build (a user's multiprocessing
    pool) builds maps too (a thread pool that outlived the call, e.g. GNU OpenMP's, aborts or hangs the child)."""
    import multiprocessing

    n = PointWorldMap.build(box(0, 0, 10, 10).difference(box(4, 4, 6, 6))).n_panels
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_build_in_child, args=(queue,))
    child.start()
    child.join(timeout=600)  # a hang guard only: the build itself takes well under a second
    hung = child.is_alive()
    if hung:
        child.kill()
    assert not hung and child.exitcode == 0
    assert queue.get(timeout=10) == n


# ---------------------------------------------------------------------- the map


def test_boundary_conditions(rooms):
    """Outer boundary on the unit circle, every hole collapsed to its b_ℓ (between collocation points too)."""
    free, pw = rooms
    outer, holes = pw.boundary_errors(samples_per_panel=8)
    assert len(pw.hole_points) == len(free.interiors) == 4
    assert outer < 0.08  # largest at the convex corners, where the map is degenerate; see refinement test
    assert holes.max() < 1e-3
    assert np.all(holes < 0.05 * separation(pw.hole_points))
    assert np.all(np.linalg.norm(pw.hole_points, axis=1) < 0.99)
    # hole_points[ℓ] belongs to free_space.interiors[ℓ] of the caller's polygon
    for k, ring in enumerate(free.interiors):
        vals = pw(np.asarray(ring.coords))
        assert np.abs(vals - pw.hole_points[k]).max() < 2e-3
    # the outer boundary is traversed counter-clockwise: the argument of H increases along the ring
    mids = 0.5 * (pw.panel_start + pw.panel_end)[pw.panel_ring == 0]
    ang = np.unwrap(np.arctan2(*pw(mids)[:, ::-1].T))
    assert ang[-1] - ang[0] == pytest.approx(2 * np.pi, abs=0.1)
    assert np.all(np.diff(ang) > 0)


def test_boundary_error_shrinks_and_b_converges_under_refinement():
    free = two_rooms_free_space()
    maps = [
        PointWorldMap.build(free, clearance_fraction=0.5 / k, curvature_fraction=1.0 / k, max_panel=4.0 / k)
        for k in (1, 2, 4, 8)
    ]
    counts = [m.n_panels for m in maps]
    assert counts == sorted(counts) and counts[-1] > 3 * counts[0]
    outer = [m.boundary_errors()[0] for m in maps]
    holes = [m.boundary_errors()[1].max() for m in maps]
    assert all(o2 < o1 for o1, o2 in zip(outer, outer[1:]))
    assert all(h2 < h1 for h1, h2 in zip(holes, holes[1:]))
    ref = maps[-1]
    b_err = [np.abs(m.hole_points - ref.hole_points).max() for m in maps[:-1]]
    x = np.array([[15.0, 15.0], [30.0, 25.0], [25.0, 5.0]])
    h_err = [np.abs(m(x) - ref(x)).max() for m in maps[:-1]]
    # second order in the panel length: each halving divides the error by about 4 (at least 2.5 asserted)
    assert all(e2 < e1 / 2.5 for e1, e2 in zip(b_err, b_err[1:]))
    assert all(e2 < e1 / 2.5 for e1, e2 in zip(h_err, h_err[1:]))
    assert b_err[-1] < 1e-4


def test_office_map_converges_under_refinement(office):
    """b_ℓ of the office map move less as panels refine; at the defaults they are within 5 % of their
    separation r̄_ℓ of the refined values (the barrier radius of the navigation function scales with r̄)."""
    free, pw = office
    diam = math.hypot(200.0, 200.0)
    coarse, fine = (
        PointWorldMap.build(free, clearance_fraction=0.25 * k, curvature_fraction=0.5 * k, max_panel=diam / 25 * k)
        for k in (2.0, 0.5)
    )
    assert coarse.n_panels < pw.n_panels < fine.n_panels
    sep = separation(fine.hole_points)
    err_coarse = np.linalg.norm(coarse.hole_points - fine.hole_points, axis=1)
    err_default = np.linalg.norm(pw.hole_points - fine.hole_points, axis=1)
    assert err_default.max() < 0.6 * err_coarse.max()
    assert np.all(err_default < 0.05 * sep)


@pytest.mark.parametrize("which", ["rooms", "office"])
def test_inside_disk_and_orientation_preserving_away_from_margin(which, request):
    free, pw = request.getfixturevalue(which)
    spacing = 0.25 if which == "rooms" else 1.5
    pts = grid_away_from_margin(pw, free, spacing)
    assert len(pts) > 3000
    H, J, _ = pw.evaluate(pts)
    assert np.linalg.norm(H, axis=1).max() < 1.0
    assert np.linalg.det(J).min() > 0.0


def test_derivatives_match_finite_differences(office):
    free, pw = office
    rng = np.random.default_rng(11)
    pts = rng.uniform(0, 200, size=(400, 2))
    pts = pts[shapely.contains_xy(free, pts[:, 0], pts[:, 1])][:60]
    h = 1e-4  # metres; central differences are accurate to O(h²) ≈ 1e-8 relative here
    H, J, Hs = pw.evaluate(pts)
    for p, Jp, Hp in zip(pts, J, Hs):
        Jfd = np.column_stack([(pw(p + h * e) - pw(p - h * e)) / (2 * h) for e in np.eye(2)])
        Hfd = np.stack([(pw.jacobian(p + h * e) - pw.jacobian(p - h * e)) / (2 * h) for e in np.eye(2)], axis=2)
        np.testing.assert_allclose(Jp, Jfd, rtol=0, atol=1e-6 * np.abs(Jp).max())
        np.testing.assert_allclose(Hp, Hfd, rtol=0, atol=1e-5 * np.abs(Hp).max())
    # Hessians are symmetric in (i, j) and each component is harmonic (trace zero)
    np.testing.assert_allclose(Hs, np.swapaxes(Hs, 2, 3), atol=0)
    np.testing.assert_allclose(np.trace(Hs, axis1=2, axis2=3), 0.0, atol=1e-12 * np.abs(Hs).max())


def test_batch_matches_single_point(rooms):
    _, pw = rooms
    pts = np.array([[3.0, 3.0], [15.0, 15.0], [25.0, 28.0], [37.0, 10.0]])
    H, J, Hs = pw.evaluate(pts)
    # the two paths sum the same n panel terms (each |term| <= ~1) in different orders (BLAS or not, threads):
    # rounding differs by up to ~n eps ~ 1e-13 absolute, whatever the size of the component itself
    for k, p in enumerate(pts):
        h1, j1, hs1 = pw.evaluate(p)
        np.testing.assert_allclose(h1, H[k], rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(j1, J[k], rtol=1e-12, atol=1e-16)
        np.testing.assert_allclose(hs1, Hs[k], rtol=1e-11, atol=1e-16)
        np.testing.assert_allclose(pw(p), H[k], rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(pw.jacobian(p), J[k], rtol=1e-12, atol=1e-16)
        np.testing.assert_allclose(pw.hessians(p), Hs[k], rtol=1e-11, atol=1e-16)


def test_inverse_round_trip(rooms):
    free, pw = rooms
    pts = grid_away_from_margin(pw, free, 3.0)
    for x in pts[::7]:
        chi = pw(x)
        x_back = pw.inverse(chi)
        np.testing.assert_allclose(pw(x_back), chi, atol=1e-10)
        np.testing.assert_allclose(x_back, x, atol=1e-6)


def test_ring_orientation_and_start_do_not_matter(rooms):
    free, pw = rooms
    ext = list(free.exterior.coords)[:-1]
    rotated = Polygon(ext[3:] + ext[:3], [list(h.coords)[::-1] for h in free.interiors])
    reversed_ = Polygon(ext[::-1], [list(h.coords) for h in free.interiors])
    x = np.array([[12.0, 14.0], [33.0, 16.0]])
    for other in (rotated, reversed_):
        pw2 = PointWorldMap.build(other)
        np.testing.assert_allclose(pw2(x), pw(x), atol=1e-9)
        np.testing.assert_allclose(pw2.hole_points, pw.hole_points, atol=1e-9)


def test_office_panel_budget(office):
    free, pw = office
    # ~2375 panels at the defaults: the gap cap (panels of a hole <= gap_fraction x its gap) adds ~230 on the
    # two long corridor walls whose door gaps are 4-5 m, the convex-corner cap (test_circle_barrier_band_...)
    # ~345 at the room corners; uniform panels at the smallest needed length would be an order of magnitude more
    assert 300 <= pw.n_panels <= 2450
    assert len(pw.hole_points) == len(free.interiors) == 20
    # panels graded: long in open space, short near doors and small obstacles
    assert pw.panel_length.max() > 20 * pw.panel_length.min()
    assert pw.margin == pytest.approx(pw.panel_length.max())


def test_user_errors():
    with pytest.raises(UserError, match="empty"):
        PointWorldMap.build(Polygon())
    two = MultiPolygon([box(0, 0, 1, 1), box(2, 0, 3, 1)])
    with pytest.raises(UserError, match="not one connected polygon"):
        PointWorldMap.build(two)
    with pytest.raises(UserError, match="invalid"):
        PointWorldMap.build(Polygon([(0, 0), (2, 2), (2, 0), (0, 2)]))
    with pytest.raises(UserError, match="Polygon"):
        PointWorldMap.build(Point(0, 0))
    for msg in ("empty", "not one connected polygon"):
        try:
            PointWorldMap.build(Polygon() if msg == "empty" else two)
        except UserError as err:
            assert "\n" not in str(err)
    # a single-part MultiPolygon is accepted
    assert PointWorldMap.build(MultiPolygon([box(0, 0, 4, 3)])).n_panels > 0


def test_tiny_hole_gets_a_proper_polygon():
    """A hole shorter than min_panel still becomes (at least) a triangle of panels and collapses to b."""
    free = box(0, 0, 10, 10).difference(Point(5, 5).buffer(0.001))
    pw = PointWorldMap.build(free)
    assert np.sum(pw.panel_ring == 1) >= 3
    assert np.all(np.isfinite(pw.sigma))
    assert pw.boundary_errors()[1][0] < 1e-3
    assert np.linalg.norm(pw(np.array([5.0, 5.2])) - pw.hole_points[0]) < 0.1


@st.composite
def random_layouts(draw):
    """A rectangular room with up to four disjoint boxes and disks well inside."""
    w = draw(st.floats(8.0, 40.0))
    h = draw(st.floats(8.0, 40.0))
    n = draw(st.integers(0, 4))
    shapes = []
    for _ in range(n):
        cx = draw(st.floats(0.2 * w, 0.8 * w))
        cy = draw(st.floats(0.2 * h, 0.8 * h))
        r = draw(st.floats(0.3, 0.08 * min(w, h)))
        g = Point(cx, cy).buffer(r) if draw(st.booleans()) else box(cx - r, cy - 0.5 * r, cx + r, cy + 0.5 * r)
        if all(g.distance(o) > 0.5 for o in shapes):
            shapes.append(g)
    free = box(0, 0, w, h)
    for g in shapes:
        free = free.difference(g)
    return free


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(random_layouts())
def test_random_layouts_are_valid_maps(free):
    pw = PointWorldMap.build(free)
    assert len(pw.hole_points) == len(free.interiors)
    outer, holes = pw.boundary_errors()
    assert outer < 0.1
    # each hole's image is a blob much smaller than its separation from the other b's and the circle
    assert np.all(holes < 0.1 * separation(pw.hole_points))
    pts = grid_away_from_margin(pw, free, min(free.bounds[2], free.bounds[3]) / 40)
    H, J, _ = pw.evaluate(pts)
    assert np.linalg.norm(H, axis=1).max() < 1.0
    assert np.linalg.det(J).min() > 0.0
    if len(pw.hole_points):
        assert np.linalg.norm(pw.hole_points, axis=1).max() < 1.0


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 1.0), st.floats(0.01, 5.0)), min_size=1, max_size=40),
       st.floats(1.0, 100.0), st.floats(0.05, 2.0))
def test_cone_envelope_is_the_least_graded_size_on_the_closed_ring(samples, perimeter, grading):
    """The envelope at s_i is min_j h_j + grading × (arc distance from s_i to s_j the shorter way round):
    the brute-force minimum, up to the rounding of a few sums of numbers below 3 × perimeter."""
    s = np.sort(np.array([f for f, _ in samples])) * perimeter * (1.0 - 1e-9)
    h = np.array([v for _, v in samples])
    d = np.abs(s[:, None] - s[None, :])
    brute = np.min(h[None, :] + grading * np.minimum(d, perimeter - d), axis=1)
    env = _cone_envelope(s, h, perimeter, grading)
    np.testing.assert_allclose(env, brute, rtol=0.0, atol=1e-12 * (1.0 + grading) * perimeter)


def test_ring_normals_point_into_the_free_side_and_bisect_at_vertices():
    """On the outer ring of a 4 × 2 room (counter-clockwise) the normal on an edge is the inward unit normal
    of that edge; at a corner it is the unit bisector of the two edges' normals."""
    ring = _prepare_ring(np.array([[0, 0], [4, 0], [4, 2], [0, 2], [0, 0]], dtype=float), is_exterior=True,
                         curvature_fraction=0.5)
    s = np.array([1.0, 4.0, 5.0, 6.0, 9.0, 11.0, 0.0])
    expected = np.array([[0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, 0], [1, 1]], dtype=float)
    expected /= np.linalg.norm(expected, axis=1)[:, None]
    np.testing.assert_allclose(ring.normal(s), expected, rtol=0.0, atol=1e-15)


def test_local_width_sees_a_wall_behind_many_own_samples():
    """The width at a densely sampled wall is the distance to the facing wall, however many samples of the
    wall itself lie closer (they are neighbours along the boundary and never constrain the tangent ball)."""
    own = np.column_stack([np.linspace(0.0, 20.0, 2001), np.zeros(2001)])  # 1 cm spacing, free side up
    facing = np.column_stack([np.linspace(0.0, 20.0, 41), np.full(41, 5.0)])  # free side down
    xy = np.vstack([own, facing])
    nrm = np.vstack([np.tile([0.0, 1.0], (len(own), 1)), np.tile([0.0, -1.0], (len(facing), 1))])
    ring_id = np.concatenate([np.zeros(len(own), dtype=int), np.ones(len(facing), dtype=int)])
    s = np.concatenate([own[:, 0], facing[:, 0]])
    perims = np.array([40.0, 40.0])
    radii = np.full(len(xy), 50.0)
    width = _local_width(xy, nrm, ring_id, s, perims, radii)
    # between the samples of the facing wall (0.5 m apart) the tangent ball touches two of them:
    # 2ρ = 5 + (0.25)² / 5 at most
    mid = (own[:, 0] > 1.0) & (own[:, 0] < 19.0)
    assert np.all(width[: len(own)][mid] >= 5.0 - 1e-12)
    assert np.all(width[: len(own)][mid] <= 5.0 + 0.25**2 / 5.0 + 1e-12)
    # incremental update with new samples on the facing wall gives the same widths as from scratch
    extra = np.column_stack([np.linspace(0.25, 19.75, 40), np.full(40, 5.0)])
    xy2 = np.vstack([xy, extra])
    nrm2 = np.vstack([nrm, np.tile([0.0, -1.0], (40, 1))])
    rid2 = np.concatenate([ring_id, np.ones(40, dtype=int)])
    s2 = np.concatenate([s, extra[:, 0]])
    radii2 = np.full(len(xy2), 50.0)
    fresh = _local_width(xy2, nrm2, rid2, s2, perims, radii2)
    update = _local_width(xy2, nrm2, rid2, s2, perims, radii2, (np.arange(len(xy)), width, radii))
    np.testing.assert_array_equal(update, fresh)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ball_query_on_a_grid_matches_all_pairs(seed):
    """The compiled ball query finds exactly what testing every pair finds: per sample i, the least
    2ρ = |q − p|² / ((q − p)·n_i) over the samples q in front of i, facing it, not its neighbours along the
    boundary and inside its tangent ball of diameter width[i] (balls from 1e-3 to 50 x the sample spacing)."""
    rng = np.random.default_rng(seed)
    n = 600
    xy = rng.uniform(0.0, 10.0, (n, 2))
    ang = rng.uniform(0.0, 2.0 * np.pi, n)
    nrm = np.column_stack([np.cos(ang), np.sin(ang)])
    ring_id = rng.integers(0, 3, n)
    s = rng.uniform(0.0, 30.0, n)
    perims = np.array([30.0, 31.0, 32.0])
    width = 10.0 ** rng.uniform(-3.0, 1.0, n)
    geom = (xy[:, 0].copy(), xy[:, 1].copy(), nrm[:, 0].copy(), nrm[:, 1].copy(), s, ring_id, perims)
    rows, cols = np.arange(0, n, 2), np.arange(n)
    half = 0.5 * width[rows]
    centre = xy[rows] + half[:, None] * nrm[rows]
    inside = np.sum((xy[None, :, :] - centre[:, None, :]) ** 2, axis=-1) <= half[:, None] ** 2
    d = xy[None, :, :] - xy[rows, None, :]
    dn = np.einsum("ijk,ik->ij", d, nrm[rows])
    facing = np.einsum("ijk,jk->ij", d, nrm) < 0.0
    dd = np.sum(d * d, axis=-1)
    ds = np.abs(s[None, :] - s[rows, None])
    ds = np.minimum(ds, perims[ring_id[rows]][:, None] - ds)
    apart = (ring_id[None, :] != ring_id[rows, None]) | (ds * ds > 2.5**2 * dd)
    ok = inside & (dn > 0.0) & facing & apart
    expected = np.where(ok, dd / np.where(ok, dn, 1.0), np.inf).min(axis=1)
    assert np.isfinite(expected).sum() > len(rows) // 4
    np.testing.assert_array_equal(_ball_min(rows, width, cols, geom), expected)
    part = cols[::3]
    expected_part = np.where(ok[:, part], (dd / np.where(ok, dn, 1.0))[:, part], np.inf).min(axis=1)
    np.testing.assert_array_equal(_ball_min(rows, width, part, geom), expected_part)


def test_hole_gaps_are_the_least_distance_to_every_other_ring(office):
    """The tree-pruned gaps equal the minimum over all pairwise ring distances, for holes far from the walls,
    near each other and in a corridor."""
    free, _ = office
    extra = [Point(30.0, 30.0).buffer(2.0), Point(35.0, 30.0).buffer(2.0), box(60.0, 2.0, 62.0, 4.0)]
    for poly in (free, free.difference(unary_union(extra))):
        rings = np.array([poly.exterior, *poly.interiors], dtype=object)
        d = shapely.distance(rings[1:, None], rings[None, :])
        d[np.arange(len(rings) - 1), np.arange(1, len(rings))] = np.inf
        np.testing.assert_array_equal(_hole_gaps(poly), d.min(axis=1))


def test_case_study_map_collapses_holes_in_one_solve():
    """Case study I, longest navigation (holes in corridors along the outer wall, open space behind them):
    the first discretisation already makes every hole's image smaller than 0.08 x its separation."""
    from mrodrake.bench.control import longest_navigation
    from mrodrake.control.tasks import MAP_OPTIONS

    free = longest_navigation()[-1].polygon
    pw = PointWorldMap.build(free, **{**MAP_OPTIONS, "max_refinements": 0})
    assert pw.n_solves == 1
    _, holes = pw.boundary_errors()
    assert np.all(holes < 0.08 * _separation(pw.hole_points))


def test_circle_barrier_band_reaches_convex_outer_corners():
    """The outer boundary's image must lie in the unit-circle barrier band 1 − ‖χ‖² < τ₀ of φ, also at the
    convex corners of F, where H degenerates and the panel solution sinks furthest into the disk.  With
    corner panels of max_panel / 2 the rooms' corners of case study I mapped to ‖H‖ ≈ 0.97 (1 − ‖H‖² ≈ 0.06,
    while τ₀ ≤ the scenario cap 0.01): nothing kept an entity out of them.  Here: a 200 m x 100 m room with a
    pillar, φ with the scenario defaults (r̄ ≤ 0.1, τ ≤ 0.01); before the fix 1 − ‖H‖² reached 0.033 there."""
    from mrodrake.control.adaptive import AdaptiveGains, NavigationTask

    pw = PointWorldMap.build(box(0.0, 0.0, 200.0, 100.0).difference(box(90.0, 40.0, 110.0, 60.0)))
    task = NavigationTask.build(pw, np.array([30.0, 50.0]), AdaptiveGains(), k1=0.01, k2=5.0, r_bar_cap=0.1,
                                tau_cap=0.01, start=np.array([170.0, 50.0]))
    ext = pw.panel_ring == 0
    a, b = pw.panel_start[ext], pw.panel_end[ext]
    frac = (np.arange(8) + 0.5) / 8
    pts = (a[:, None, :] + frac[None, :, None] * (b - a)[:, None, :]).reshape(-1, 2)
    depth = task.nf.rho0**2 - np.sum(pw(pts) ** 2, axis=1)  # d_0 = ρ₀² − ‖H‖² of the circle barrier
    assert depth.max() < task.nf.taus[0]


@pytest.mark.parametrize("which", [
    pytest.param("rooms", marks=pytest.mark.xfail(strict=True, reason=(
        "open defect: on the rounded wall ends, outer panels are chords across several polygon vertices and lie "
        "outside F; the true boundary arc sits up to ~0.075 panel inside, where ‖H‖ ≈ 0.985 < ρ₀ ≈ 0.990, "
        "and circle_deficit (sampled on the chords) misses it"))),
    "room_with_pillar",
])
def test_outer_ridge_lies_beyond_the_circle_barrier(which, request):
    """Every point of ∂F has, on its inward normal within half a panel, a point with ‖H‖ ≥ ρ₀ = 1 − κ δ_max
    (δ_max = ``circle_deficit``, κ = CIRCLE_DEFICIT_FACTOR): checked on 16 samples per outer panel and 41
    steps per normal (those in F), 8x and 10x denser than the build's own search, so the ridge curve between the build's
    samples also clears ρ₀ and every path from ‖H‖ < ρ₀ to ∂F meets the barrier's pole ‖H‖ = ρ₀."""
    from mrodrake.control.adaptive import circle_radius

    if which == "rooms":
        pw = request.getfixturevalue("rooms")[1]
    else:
        pw = PointWorldMap.build(box(0.0, 0.0, 200.0, 100.0).difference(box(90.0, 40.0, 110.0, 60.0)))
    assert 0.0 < pw.circle_deficit < 0.01
    rho0 = circle_radius(pw)
    ext = pw.panel_ring == 0
    a, d, ell = pw.panel_start[ext], (pw.panel_end - pw.panel_start)[ext], pw.panel_length[ext]
    nrm = np.column_stack([-d[:, 1], d[:, 0]]) / ell[:, None]
    frac = (np.arange(16) + 0.5) / 16
    steps = np.linspace(0.0, 0.5, 41)
    pts = (a[:, None, None, :] + frac[None, :, None, None] * d[:, None, None, :]
           + (steps[None, None, :, None] * ell[:, None, None, None]) * nrm[:, None, None, :])
    # only points of F count (panel chords of arcs cut slightly outside F, by < 1e-3 m here)
    inside = shapely.intersects_xy(pw.free_space, pts[..., 0], pts[..., 1])  # F with its boundary
    assert np.all(inside.sum(axis=2) >= 30)
    norm_h = np.linalg.norm(pw(pts.reshape(-1, 2)), axis=1).reshape(pts.shape[:3])
    ridge = np.where(inside, norm_h, 0.0).max(axis=2)
    assert ridge.min() > rho0


def test_refinement_stops_when_halving_the_caps_adds_no_panels():
    """A hole stays coarse (blob tolerance 0) in both builds; with every panel at min_panel = max_panel halving
    its caps cannot change the discretisation, so the build does not re-solve, while with free panel sizes
    it refines (and re-solves) up to max_refinements."""
    free = box(0.0, 0.0, 20.0, 10.0).difference(Point(10.0, 5.0).buffer(1.0))
    fixed = PointWorldMap.build(free, max_panel=0.2, min_panel=0.2, blob_tolerance=0.0, max_refinements=2)
    assert fixed.n_solves == 1
    free_sizes = PointWorldMap.build(free, blob_tolerance=0.0, max_refinements=2)
    assert free_sizes.n_solves == 3


def test_holes_take_coarser_curved_panels_only_where_their_gap_allows():
    """Curved hole panels of up to hole_curvature_fraction × ρ where that is ≤ curved_gap_fraction × the gap:
    a disk far from every other boundary gets fewer panels, one near a wall keeps the fine ones, and both
    still collapse to points (image ≤ blob_tolerance × separation, as every map build checks)."""
    outer = box(0, 0, 60, 40)
    far, near = Point(20, 20).buffer(3.0), Point(50, 3.6).buffer(3.0)  # gaps 17 m and 0.6 m
    free = outer.difference(far).difference(near)
    fine = PointWorldMap.build(free, curvature_fraction=0.1)
    coarse = PointWorldMap.build(free, curvature_fraction=0.1, hole_curvature_fraction=0.2)
    count = {name: np.bincount(pw.panel_ring, minlength=3) for name, pw in (("fine", fine), ("coarse", coarse))}
    k_far = 1 + min(range(2), key=lambda k: abs(list(free.interiors)[k].centroid.x - 20.0))
    k_near = 3 - k_far
    assert count["coarse"][k_far] < 0.75 * count["fine"][k_far]
    assert count["coarse"][k_near] == count["fine"][k_near]
    assert count["coarse"][0] == count["fine"][0]  # the outer boundary is not a hole
    for pw in (fine, coarse):
        assert np.all(pw._hole_blobs() <= 0.08 * separation(pw.hole_points))
