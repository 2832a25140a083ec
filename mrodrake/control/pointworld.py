"""Harmonic point-world map H: free space -> open unit disk (paper Sec. III-A, transformation χ = H(x)).

H = (u, v) with u, v harmonic in the free space F; on the outer boundary u + iv runs once
counter-clockwise around the unit circle (normalised arc length from a fixed vertex); on hole ℓ,
H equals an unknown constant b_ℓ fixed by zero flux (Vlantis et al., ICRA 2018).

Discretisation: single-layer potential u(x) = Σ_j σ_j W_j(x) + c with W_j(x) = ∫_panel_j ln|x − y|² ds_y
over straight panels, integrated in closed form; collocation at panel midpoints; one unknown b_ℓ and one
zero-charge row per hole (zero flux ⇔ zero charge when u is constant inside the hole), one constant c and
a zero-total-charge row (makes the representation complete at any length scale).  For a panel from a to
b (length L, unit tangent t, left normal n) and r_a = |x − a|², r_b = |x − b|², u_a = (x − a)·t,
u_b = u_a − L, η = (x − a)·n, θ = signed angle under which the panel is seen from x
(atan2 of cross and dot of x − a and x − b, continuous everywhere off the panel):

    W   = u_a ln r_a − u_b ln r_b − 2L + 2ηθ,
    ∇W  = (ln r_a − ln r_b) t + 2θ n,
    ∇²W = A (t tᵀ − n nᵀ) + B (t nᵀ + n tᵀ),  A = 2(u_a/r_a − u_b/r_b),  B = 2η(1/r_a − 1/r_b).

Solve: from :data:`HIERARCHICAL_PANELS` panels on, float64 iterative refinement preconditioned by the HODLR
inverse of :mod:`mrodrake.control.hodlr`; below (or if that does not converge), a float32 LU with refinement.
Both refine against the float64 system to the same residual bound (:func:`_solve_refined`).

Evaluation: H, J_H and the Hessians come from the compiled treecode of :mod:`mrodrake.control.treecode`
(multipole expansions of far clusters, these closed forms near the point), within :data:`TREE_TOLERANCES` of
the direct sum over all panels (kept as :meth:`PointWorldMap.evaluate_direct`).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from functools import cache, cached_property

import numpy as np
import scipy.linalg
import shapely
from scipy.linalg import get_lapack_funcs
from scipy.spatial import cKDTree
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.polygon import orient
from threadpoolctl import ThreadpoolController

from mrodrake.control.compiled import cached_njit
from mrodrake.control.hodlr import MAX_STEPS, MIN_GAIN, BorderedPreconditioner
from mrodrake.control.treecode import PanelTree, build_tree, in_row_blocks, tree_point_arrays
from mrodrake.errors import UserError

_SHARP_ANGLE = math.radians(30.0)  # vertices turning more than this are kept as panel ends
_GENTLE_ANGLE = math.radians(0.5)  # vertices turning less than this carry no curvature cap
_LOCAL_ARC_RATIO = 2.5  # boundary points closer along the boundary than this x straight are neighbours
_CHUNK = 1 << 15  # kernel entries per block in batch evaluation
_TWO_PI = 2.0 * math.pi
_TINY = 1e-300
_CORNER_FRACTION = 1.0 / 40.0  # panels at convex corners of the outer boundary: at most this x max_panel
#: A coarse hole is re-solved only if halving its panel caps adds at least this share of panels to its ring.
REFINE_GROWTH = 1.1
_RIDGE_FRACTIONS = (0.125, 0.875)  # circle-deficit samples along each outer panel (where its error peaks)
_RIDGE_OFFSETS = (0.0625, 0.125, 0.25, 0.5)  # inward steps (x panel length) searched for the ridge of |H|
#: Error bounds of the treecode on H, on every entry of J_H and on every second derivative
#: (:mod:`mrodrake.control.treecode`; the direct sum over all panels is the reference).
TREE_TOLERANCES = (5e-10, 5e-8, 5e-6)
#: Panels from which the system is solved with the hierarchical preconditioner of :mod:`mrodrake.control.hodlr`
#: (below, a dense float32 LU with refinement is as fast).
HIERARCHICAL_PANELS = 1024


@dataclass
class _Ring:
    """One boundary ring, oriented with the free side on the left, rotated to start at a panel end."""

    xy: np.ndarray  # (m+1, 2) closed vertex list
    cum: np.ndarray  # (m+1,) arc length at the vertices
    breaks: np.ndarray  # arc positions that must be panel ends (sorted, starts with 0)
    curv_s: np.ndarray  # (k,) arc positions of gently turning vertices
    curv_cap: np.ndarray  # (k,) panel-length cap there (fraction of the local radius of curvature)

    @property
    def perimeter(self) -> float:
        return float(self.cum[-1])

    def point(self, s: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(s, self.cum, self.xy[:, 0]), np.interp(s, self.cum, self.xy[:, 1])])

    @cached_property
    def tangents(self) -> np.ndarray:
        """Unit tangent of every edge."""
        edges = np.diff(self.xy, axis=0)
        return edges / np.linalg.norm(edges, axis=1)[:, None]

    def normal(self, s: np.ndarray) -> np.ndarray:
        """Unit normal pointing into the free space (left of travel); bisector at vertices."""
        return _ring_normals(np.asarray(s, dtype=float), self.cum, self.tangents, 1e-12 * max(self.perimeter, 1.0))


@cached_njit(nogil=True)
def _ring_normals(s, cum, tang, atol):
    """Normals of :meth:`_Ring.normal`: the left normal of the edge holding arc position s[i] (the last edge
    at or before it), of the bisector of the two edges at a vertex (within ``atol``) unless they turn back."""
    m = tang.shape[0]
    out = np.empty((s.shape[0], 2))
    for i in range(s.shape[0]):
        k = min(max(np.searchsorted(cum, s[i], side="right") - 1, 0), m - 1)
        tx, ty = tang[k, 0], tang[k, 1]
        if abs(s[i] - cum[k]) <= atol:
            bx = tang[k, 0] + tang[(k - 1) % m, 0]
            by = tang[k, 1] + tang[(k - 1) % m, 1]
            nb = math.sqrt(bx * bx + by * by)
            if nb > 1e-9:
                tx, ty = bx / nb, by / nb
        out[i, 0] = -ty
        out[i, 1] = tx
    return out


def _prepare_ring(coords: np.ndarray, *, is_exterior: bool, curvature_fraction: float,
                  corner_cap: float = math.inf, coarse_fraction: float = 0.0, coarse_cap: float = 0.0) -> _Ring:
    """Ring data; on the outer ring, panels at convex corners of the free space (sharp left turns) are capped
    at ``corner_cap`` (H degenerates there and its boundary error peaks on the panels next to them).  Curved
    parts take panels of ``curvature_fraction`` × their radius of curvature ρ, or of up to ``coarse_fraction`` × ρ
    where that is at most ``coarse_cap``."""
    pts = np.asarray(coords, dtype=float)[:-1]
    scale = float(np.max(np.ptp(pts, axis=0))) if len(pts) else 0.0
    keep = np.linalg.norm(pts - np.roll(pts, 1, axis=0), axis=1) > 1e-12 * max(scale, 1.0)
    pts = pts[keep]
    if len(pts) < 3:
        raise UserError("free_space: a boundary ring has fewer than 3 distinct vertices")
    e_in = pts - np.roll(pts, 1, axis=0)  # edge arriving at vertex i
    e_out = np.roll(pts, -1, axis=0) - pts  # edge leaving vertex i
    turn = np.arctan2(e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0], np.sum(e_in * e_out, axis=1))
    sharp = np.abs(turn) > _SHARP_ANGLE
    if is_exterior:
        start = int(np.lexsort((pts[:, 0], pts[:, 1]))[0])  # lowest, then leftmost vertex
    elif np.any(sharp):
        start = int(np.flatnonzero(sharp)[0])
    else:
        start = 0
    pts = np.roll(pts, -start, axis=0)
    turn = np.roll(turn, -start)
    sharp = np.roll(sharp, -start)
    sharp[0] = True
    closed = np.vstack([pts, pts[:1]])
    lengths = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(lengths)])
    breaks = cum[:-1][sharp]
    gentle = (~sharp) & (np.abs(turn) > _GENTLE_ANGLE)
    radius = 0.5 * (lengths + np.roll(lengths, 1)) / np.maximum(np.abs(turn), 1e-300)
    caps = np.maximum(curvature_fraction * radius, np.minimum(coarse_fraction * radius, coarse_cap))
    if is_exterior and math.isfinite(corner_cap):
        convex = sharp & (turn > 0.0)
        caps[convex] = corner_cap
        gentle |= convex
    return _Ring(
        xy=closed,
        cum=cum,
        breaks=breaks,
        curv_s=cum[:-1][gentle],
        curv_cap=caps[gentle],
    )


@cached_njit(nogil=True)
def _cone_envelope(s: np.ndarray, h: np.ndarray, perimeter: float, grading: float) -> np.ndarray:
    """min_j (h_j + grading · circular arc distance(s_i, s_j)) on a closed ring (exact, O(n)): running minima
    of h_j ∓ grading s_j over three copies of the ring, forwards and backwards."""
    n = s.shape[0]
    s3 = np.empty(3 * n)
    for c in range(3):
        for i in range(n):
            s3[c * n + i] = s[i] + (c - 1) * perimeter
    fwd = np.empty(3 * n)
    run = np.inf
    for i in range(3 * n):
        run = min(run, h[i % n] - grading * s3[i])
        fwd[i] = grading * s3[i] + run
    out = np.empty(n)
    run = np.inf
    for i in range(3 * n - 1, -1, -1):
        run = min(run, h[i % n] + grading * s3[i])
        if n <= i < 2 * n:
            out[i - n] = min(fwd[i], run - grading * s3[i])
    return out


def _ball_min(rows, width, cols, geom):
    """Per row i: min over the samples j of ``cols`` inside the ball of diameter width[i] tangent at sample i
    of the 2ρ = |q − p|² / ((q − p)·n_i) that j imposes on that ball (exactly the samples that give
    2ρ < width[i]), counting only samples in front of i whose free side faces it and that are not i's
    neighbours along the boundary (see :func:`_local_width`); inf where there are none.

    The samples ``cols`` are bucketed in a uniform grid (cells of about the median ball radius); every ball
    scans the cells its bounding box meets and keeps the samples with |q − centre|² ≤ radius²."""
    x, y, nx, ny, s, ring_id, perims = geom
    rows = np.asarray(rows, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    if len(rows) == 0 or len(cols) == 0:
        return np.full(len(rows), np.inf)
    half = 0.5 * width[rows]
    cx = x[rows] + half * nx[rows]
    cy = y[rows] + half * ny[rows]
    px, py = x[cols], y[cols]
    x0, y0 = px.min(), py.min()
    span = max(px.max() - x0, py.max() - y0, 1e-300)
    h = max(float(np.median(half)), span / 1024.0, 1e-300)
    gx = int((px.max() - x0) / h) + 1
    gy = int((py.max() - y0) / h) + 1
    cell = np.minimum(((px - x0) / h).astype(np.int64), gx - 1) * gy + np.minimum(((py - y0) / h).astype(np.int64),
                                                                                    gy - 1)
    order = np.argsort(cell, kind="stable")
    start = np.searchsorted(cell[order], np.arange(gx * gy + 1))
    out = np.empty(len(rows))
    in_row_blocks(_ball_min_grid, len(rows), 1024, out, cx, cy, half, rows, cols[order], x0, y0, h, gx, gy, start,
                  x, y, nx, ny, s, np.asarray(ring_id, dtype=np.int64), perims, _LOCAL_ARC_RATIO**2)
    return out


@cached_njit(nogil=True)
def _ball_min_grid(t0, t1, out, cx, cy, half, rows, cols, x0, y0, h, gx, gy, start, x, y, nx, ny, s, ring_id,
                   perims, arc_ratio2):
    """Rows t0 .. t1 − 1 of the scan of :func:`_ball_min` into ``out``: ``cols`` sorted by grid cell, cell c
    holding cols[start[c]:start[c + 1]] (every row on its own: the same on any number of threads)."""
    for t in range(t0, t1):
        i = rows[t]
        r = half[t]
        r2 = r * r
        ix0 = max(int(math.floor((cx[t] - r - x0) / h)), 0)
        ix1 = min(int(math.floor((cx[t] + r - x0) / h)), gx - 1)
        iy0 = max(int(math.floor((cy[t] - r - y0) / h)), 0)
        iy1 = min(int(math.floor((cy[t] + r - y0) / h)), gy - 1)
        best = np.inf
        ri = ring_id[i]
        for ix in range(ix0, ix1 + 1):
            for iy in range(iy0, iy1 + 1):
                c = ix * gy + iy
                for q in range(start[c], start[c + 1]):
                    j = cols[q]
                    ex = x[j] - cx[t]
                    ey = y[j] - cy[t]
                    if ex * ex + ey * ey > r2:
                        continue
                    dx = x[j] - x[i]
                    dy = y[j] - y[i]
                    dn = dx * nx[i] + dy * ny[i]
                    if not (dn > 0.0 and dx * nx[j] + dy * ny[j] < 0.0):  # j in front of i, facing it
                        continue
                    dd = dx * dx + dy * dy
                    ds = abs(s[j] - s[i])
                    ds = min(ds, perims[ri] - ds)
                    if ring_id[j] == ri and ds * ds <= arc_ratio2 * dd:  # a neighbour along the boundary
                        continue
                    best = min(best, dd / dn)
        out[t] = best


def _local_width(xy, nrm, ring_id, s, perims, radii, known=None):
    """Local width 2ρ of the free space at each boundary sample.

    ρ is the radius of the largest ball tangent at the sample (free side) that contains no other sample
    facing it, ignoring samples that are neighbours along the boundary (arc distance ≤ 2.5 × straight
    distance, so corners and the sample's own curve do not count); at most ``radii``.  A sample q gives
    2ρ = |q − p|² / ((q − p)·n) < w exactly when it lies inside the ball of diameter w tangent at p, so one
    ball query per sample (w = radii) finds every sample that constrains it, on its own ring or another.

    ``known`` = (index, width, radii) of samples whose widths were computed before, among all samples
    but the others (new ones): those are updated with the new samples only, which is exact unless a
    sample was unconstrained and its radius grew.
    """
    n = len(xy)
    geom = (xy[:, 0].copy(), xy[:, 1].copy(), nrm[:, 0].copy(), nrm[:, 1].copy(), s, ring_id, perims)
    width = np.array(radii, dtype=float, copy=True)
    full = np.arange(n)
    if known is not None:
        idx, w_old, r_old = known
        settled = (w_old < r_old) | (radii[idx] <= r_old)
        keep = idx[settled]
        width[keep] = np.minimum(w_old[settled], radii[keep])
        is_new = np.ones(n, dtype=bool)
        is_new[idx] = False
        new = np.flatnonzero(is_new)
        full = np.union1d(new, idx[~settled])
        if len(new) and len(keep):
            width[keep] = np.minimum(width[keep], _ball_min(keep, width, new, geom))
    if len(full):
        width[full] = np.minimum(width[full], _ball_min(full, width, np.arange(n), geom))
    return width


def _discretise(rings, *, max_panel, min_panel, fractions, grading, ring_caps):
    """Graded panels along every ring (see ``PointWorldMap.build``); returns ends, ring ids, arc params.

    Widths are computed at samples (refined until their spacing is at most half the target length);
    the target is the arc-length cone envelope of the raw sizes and of the curvature caps.  ``ring_caps``
    bounds every panel of a ring (the gap caps of the holes).
    """
    perims = np.array([ring.perimeter for ring in rings])
    breaks_all = [np.append(ring.breaks, ring.perimeter) for ring in rings]
    piece_caps = [
        np.maximum(np.minimum(fr * np.diff(br), cap), min_panel)
        for fr, br, cap in zip(fractions, breaks_all, ring_caps)
    ]
    samples = []  # initial samples: the breakpoints and a uniform spacing of max_panel / 2
    for ring in rings:
        count = int(math.ceil(ring.perimeter / (0.5 * max_panel)))
        samples.append(np.union1d(ring.breaks, np.linspace(0.0, ring.perimeter, count + 1)[:-1]))
    h_prev = prev_s = prev_width = prev_radii = None
    width_cap = max_panel / min(fractions)  # wider places get the maximal panel anyway
    for _ in range(12):
        ring_id = np.concatenate([np.full(len(sp), r) for r, sp in enumerate(samples)])
        s_all = np.concatenate(samples)
        xy = np.vstack([rings[r].point(sp) for r, sp in enumerate(samples)])
        nrm = np.vstack([rings[r].normal(sp) for r, sp in enumerate(samples)])
        if h_prev is None:
            radii = np.full(len(s_all), width_cap)
        else:
            frac_all = np.concatenate([np.full(len(sp), fractions[r]) for r, sp in enumerate(samples)])
            radii = np.minimum(width_cap, 1.5 * np.concatenate(h_prev) / frac_all)
        known = None
        if h_prev is not None:  # the previous samples are kept: update their widths with the new ones
            offsets = np.cumsum([0] + [len(sp) for sp in samples[:-1]])
            idx = np.concatenate([o + np.searchsorted(sp, old) for o, sp, old in zip(offsets, samples, prev_s)])
            known = (idx, prev_width, prev_radii)
        width = _local_width(xy, nrm, ring_id, s_all, perims, radii, known)
        prev_s, prev_width, prev_radii = samples, width, radii
        added = False
        new_samples, h_new, env = [], [], []
        off = 0
        for r, sp in enumerate(samples):
            ring = rings[r]
            w = width[off : off + len(sp)]
            off += len(sp)
            piece = np.searchsorted(breaks_all[r], sp, side="right") - 1
            raw = np.minimum(fractions[r] * w, piece_caps[r][piece])
            u_s = np.concatenate([sp, ring.curv_s])
            u_h = np.concatenate([raw, ring.curv_cap])
            order = np.argsort(u_s, kind="stable")
            u_s, u_h = u_s[order], u_h[order]
            u_hs = np.clip(_cone_envelope(u_s, u_h, perims[r], grading), min_panel, max_panel)
            s_ext = np.append(u_s, perims[r])
            h_ext = np.append(u_hs, u_hs[0])
            env.append((s_ext, h_ext))
            gap = np.diff(s_ext)
            need = np.ceil(gap / (0.5 * np.minimum(h_ext[:-1], h_ext[1:])) - 1e-9).astype(np.int64)
            # every interval with too few samples gets new ones (curvature points do not count)
            big = np.flatnonzero(need > 1)
            if len(big):
                per = need[big] - 1
                q = np.repeat(big, per)
                j = np.arange(len(q)) - np.repeat(np.cumsum(per) - per, per) + 1
                extra = s_ext[q] + gap[q] * j / need[q]
                cand = np.union1d(sp, extra)
                if len(cand) > len(sp):
                    added = True
                    sp = cand
            new_samples.append(sp)
            h_new.append(np.interp(sp, s_ext, h_ext))
        samples, h_prev = new_samples, h_new
        if not added:
            break
    # panel ends by equidistribution of ∫ ds / h on every piece between consecutive breakpoints
    ends_xy, ends_s, rid = [], [], []
    for r, ring in enumerate(rings):
        s_ext, h_ext = env[r]
        inv = 1.0 / h_ext
        cumn = np.concatenate([[0.0], np.cumsum(0.5 * (inv[1:] + inv[:-1]) * np.diff(s_ext))])
        br = breaks_all[r]
        nb = np.interp(br, s_ext, cumn)
        least = {1: 3, 2: 2}.get(len(br) - 1, 1)  # a ring needs at least three panels
        for a, b, na, nb_ in zip(br[:-1], br[1:], nb[:-1], nb[1:]):
            count = max(least, int(math.ceil(nb_ - na - 1e-6)))
            s_ends = np.interp(np.linspace(na, nb_, count + 1), cumn, s_ext)
            s_ends[0], s_ends[-1] = a, b
            ends_s.append(s_ends)
            ends_xy.append(ring.point(s_ends))
            rid.append(np.full(count, r))
    a_xy = np.vstack([e[:-1] for e in ends_xy])
    b_xy = np.vstack([e[1:] for e in ends_xy])
    s_a = np.concatenate([e[:-1] for e in ends_s])
    s_b = np.concatenate([e[1:] for e in ends_s])
    return a_xy, b_xy, np.concatenate(rid), s_a, s_b


def _kernel_values(x, y, vx, vy, tx, ty, L):
    """W of ``_kernel`` alone, with fewer temporaries (value-only evaluation; the reference of :func:`_assemble`)."""
    dx = x[:, None] - vx
    dy = y[:, None] - vy
    r = dx * dx
    r += dy * dy
    np.maximum(r, _TINY, out=r)  # at a panel end W is finite (0 · ln 0 = 0)
    lr = np.log(r, out=r)
    ang = np.arctan2(dy, dx)
    theta = ang[:, 1:] - ang[:, :-1]  # angle from x − a to x − b, up to a multiple of 2π
    wrap = np.rint(theta * (1.0 / _TWO_PI), out=ang[:, :-1])
    wrap *= _TWO_PI
    theta -= wrap
    dxa = dx[:, :-1]
    dya = dy[:, :-1]
    W = dya * tx  # η
    W -= dxa * ty
    W *= theta
    W *= 2.0
    ua = np.multiply(dxa, tx, out=theta)
    ua += dya * ty
    lb = lr[:, 1:]
    dl = lr[:, :-1] - lb
    dl *= ua
    W += dl
    lb = lb - 2.0
    lb *= L
    W += lb
    return W


def _assemble(mx, my, vx, vy, tx, ty, L, col, M, M32=None) -> float:
    """M[i, col[l]] = W of link l at point i (the closed form of ``_kernel_values``) for every real link
    (col[l] ≥ 0; consecutive within a ring), written to the float64 ``M`` and its float32 copy ``M32`` if given; returns
    the largest |W|.  Blocks of rows run on threads of their own (the compiled kernel releases the GIL; a pool
    per call, so a forked process can assemble too); every entry is computed on its own, so the result does not
    depend on the number of threads."""
    n = len(mx)
    real = np.concatenate([[False], col >= 0, [False]])
    starts = np.flatnonzero(real[1:] & ~real[:-1])
    ends = np.flatnonzero(real[:-1] & ~real[1:])
    runs = np.column_stack([starts, ends, col[starts]]).astype(np.int64)  # first link, end, first column
    copy32 = M32 is not None
    return max(in_row_blocks(_assemble_rows, n, 256, mx, my, vx, vy, tx, ty, L, runs, M,
                             M32 if copy32 else M[:1, :1].astype(np.float32), copy32))


@cached_njit(nogil=True, error_model="numpy")
def _assemble_rows(i0, i1, mx, my, vx, vy, tx, ty, L, runs, M, M32, copy32):
    """Rows i0 .. i1 − 1 of :func:`_assemble`, also written to ``M32`` if ``copy32`` (``runs``: first link,
    one-past-last link and first column of every run of real links); returns their largest |W|.  Per row,
    ln r² and the angle of x − v at every vertex v come from :func:`_vertex_logs_angles`, θ of a link from the
    angles at its ends, wrapped to (−π, π]."""
    nv = len(vx)
    lr = np.empty(nv)
    ang = np.empty(nv)
    r2 = np.empty(nv)
    mant = np.empty(nv, dtype=np.int64)
    expo = np.empty(nv, dtype=np.int64)
    wk = np.empty(nv - 1)
    big = 0.0
    for i in range(i0, i1):
        x, y = mx[i], my[i]
        _vertex_logs_angles(x, y, vx, vy, lr, ang, r2, mant, expo)
        for k in range(nv - 1):  # every link, the ones between rings too (not written)
            dxa = x - vx[k]
            dya = y - vy[k]
            theta = ang[k + 1] - ang[k]
            theta -= 2.0 * math.pi * np.rint(theta * (0.5 / math.pi))
            ua = dxa * tx[k] + dya * ty[k]
            eta = dya * tx[k] - dxa * ty[k]
            wk[k] = ua * (lr[k] - lr[k + 1]) + L[k] * (lr[k + 1] - 2.0) + 2.0 * eta * theta
        for q in range(runs.shape[0]):
            count = runs[q, 1] - runs[q, 0]
            src = wk[runs[q, 0] : runs[q, 1]]
            row = M[i, runs[q, 2] : runs[q, 2] + count]
            for t in range(count):
                row[t] = src[t]
            if copy32:
                row32 = M32[i, runs[q, 2] : runs[q, 2] + count]
                for t in range(count):
                    row32[t] = src[t]
            for t in range(count):
                big = max(big, abs(src[t]))
    return big


_LN2_HI = 0.6931471824645996  # ln 2 rounded to float32: e · _LN2_HI is exact for every binary exponent e
_LN2_LO = -1.904654299957768e-09  # ln 2 − _LN2_HI
_MANTISSA_BITS = 0x000FFFFFFFFFFFFF
_EXPONENT_ONE = 0x3FF0000000000000  # bits of 1.0: with a mantissa, a number in [1, 2)
_TWO52_BITS = 0x4330000000000000  # bits of 2^52: with a biased exponent b in the low bits, 2^52 + b
_TWO52_BIAS = 4503599627371519.0  # 2^52 + 1023
_TAN_PI_16 = 0.198912367379658
_TAN_3PI_16 = 0.6681786379192989
_TAN_PI_8 = 0.41421356237309503


@cached_njit(fastmath={"contract"})
def _odd_series_tail(w):
    """p(w) = Σ_{k=1}^{10} w^(k−1) / (2k + 1), so that atanh(s) = s + s · s² p(s²) and atan(u) = u − u · u²
    p(−u²); the first omitted term is below 1e-17 relative for |w| ≤ 0.04.  Horner steps may use fused
    multiply-adds (a correction term: its rounding stays far below the last place of the result)."""
    p = 1.0 / 21.0 + w / 23.0
    p = 1.0 / 19.0 + w * p
    p = 1.0 / 17.0 + w * p
    p = 1.0 / 15.0 + w * p
    p = 1.0 / 13.0 + w * p
    p = 1.0 / 11.0 + w * p
    p = 1.0 / 9.0 + w * p
    p = 1.0 / 7.0 + w * p
    p = 1.0 / 5.0 + w * p
    return 1.0 / 3.0 + w * p


@cached_njit(nogil=True, error_model="numpy")
def _vertex_logs_angles(x, y, vx, vy, lr, ang, r2, mant, expo):
    """lr[k] = ln max(|p − v_k|², 1e-300) and ang[k] = atan2 of p − v_k for p = (x, y), within a few units in
    the last place of the C library's functions (tested).  Written without calls or branches so that the
    loops run on vector registers: ln r² = e ln 2 + 2 atanh((m − 1)/(m + 1)) with r² = 2^e m, m in
    [√½, √2) (split off by the bits of r²); atan of t = min/max(|Δx|, |Δy|) ≤ 1 as atan(c) + atan((t − c) /
    (1 + t c)) with c in {0, tan π/8, 1} chosen so that the argument is at most tan π/16 in magnitude, then
    unfolded by octant.  ``r2``, ``mant`` and ``expo`` are work arrays of the length of ``vx``."""
    nv = vx.shape[0]
    bits = r2.view(np.int64)
    m_view = mant.view(np.float64)
    e_view = expo.view(np.float64)
    for k in range(nv):
        dx = x - vx[k]
        dy = y - vy[k]
        r2[k] = max(dx * dx + dy * dy, 1e-300)
    for k in range(nv):
        b = bits[k]
        mant[k] = (b & _MANTISSA_BITS) | _EXPONENT_ONE
        expo[k] = (b >> 52) | _TWO52_BITS
    for k in range(nv):
        m = m_view[k]
        e = e_view[k] - _TWO52_BIAS
        high = m > math.sqrt(2.0)
        m = 0.5 * m if high else m
        e = e + 1.0 if high else e
        f = m - 1.0
        s = f / (2.0 + f)
        t = 2.0 * s
        z = s * s
        lr[k] = e * _LN2_HI + (e * _LN2_LO + (t + t * (z * _odd_series_tail(z))))
    for k in range(nv):
        dx = x - vx[k]
        dy = y - vy[k]
        ax = abs(dx)
        ay = abs(dy)
        t = min(ax, ay) / max(max(ax, ay), 1e-300)
        c = (1.0 if t > _TAN_3PI_16 else _TAN_PI_8) if t > _TAN_PI_16 else 0.0
        base = (0.25 * math.pi if t > _TAN_3PI_16 else 0.125 * math.pi) if t > _TAN_PI_16 else 0.0
        u = (t - c) / (1.0 + t * c)
        z = u * u
        a = base + (u - u * (z * _odd_series_tail(-z)))
        a = 0.5 * math.pi - a if ay > ax else a
        a = math.pi - a if dx < 0.0 else a
        ang[k] = -a if dy < 0.0 else a


def _kernel(x, y, vx, vy, tx, ty, L, *, derivs: bool):
    """Closed forms for the panel chain at points (x, y) (shape (m,)).

    The chain is the vertex list (vx, vy); link j runs from vertex j to vertex j + 1 with unit tangent
    (tx, ty)_j and length L_j.  Returns arrays of shape (m, links): W, ln r_a − ln r_b, θ and the Hessian
    coefficients A, B (the last four only if ``derivs``).
    """
    if not derivs:
        return _kernel_values(x, y, vx, vy, tx, ty, L), None, None, None, None
    dx = x[:, None] - vx
    dy = y[:, None] - vy
    r = np.maximum(dx * dx + dy * dy, _TINY)  # at a panel end W is finite (0 · ln 0 = 0)
    lr = np.log(r)
    ang = np.arctan2(dy, dx)
    theta = ang[:, 1:] - ang[:, :-1]  # angle from x − a to x − b, up to a multiple of 2π
    theta -= _TWO_PI * np.rint(theta * (1.0 / _TWO_PI))
    dxa = dx[:, :-1]
    dya = dy[:, :-1]
    ua = dxa * tx + dya * ty
    eta = dya * tx - dxa * ty
    lb = lr[:, 1:]
    dl = lr[:, :-1] - lb
    W = ua * dl + L * (lb - 2.0) + 2.0 * eta * theta
    ir = 1.0 / r
    ib = ir[:, 1:]
    di = ir[:, :-1] - ib
    A = 2.0 * (ua * di + L * ib)
    B = 2.0 * eta * di
    return W, dl, theta, A, B


def _chain(a_xy, b_xy, ring_of_panel, with_rings=False):
    """Vertex chain of the panels (ring by ring, each ring closed); links between rings are dummies.

    Returns (vertices, link lengths, tangents x, y, real) and, ``with_rings``, the ring of every link (−1 on
    the dummies)."""
    vs, real, rings = [], [], []
    for r in np.unique(ring_of_panel):
        idx = np.flatnonzero(ring_of_panel == r)
        vs.append(np.vstack([a_xy[idx], b_xy[idx[-1:]]]))
        real.append(np.ones(len(idx), dtype=bool))
        real.append(np.zeros(1, dtype=bool))
        rings += [np.full(len(idx), r), [-1]]
    v = np.vstack(vs)
    real = np.concatenate(real)[:-1]
    d = np.diff(v, axis=0)
    L = np.hypot(d[:, 0], d[:, 1])
    out = (v, L, d[:, 0] / L, d[:, 1] / L, real)
    return (*out, np.concatenate(rings)[:-1]) if with_rings else out


_WORK = threading.local()


def _workspace(size: int) -> tuple[np.ndarray, np.ndarray]:
    """Uninitialised (size, size) float64 and float32 arrays, kept per thread from one solve to the next.

    A fresh array of this size comes from the operating system as untouched pages, and the first write to
    each page faults: about a tenth of a solve of 4,000 panels.  The buffers only grow (the largest solve of
    the thread so far); the arrays are views, valid until the thread's next call.
    """
    need = size * size
    buf = getattr(_WORK, "buffers", None)
    if buf is None or buf[0].size < need:
        buf = (np.empty(need), np.empty(need, dtype=np.float32))
        _WORK.buffers = buf
    return buf[0][:need].reshape(size, size), buf[1][:need].reshape(size, size)


def _solve_refined(M: np.ndarray, rhs: np.ndarray, m32: np.ndarray | None = None,
                   scale_m: float | None = None) -> np.ndarray:
    """Solve M X = rhs to float64 accuracy: float32 LU plus iterative refinement (float64 LU if that stalls).

    The float32 copy ``m32`` of the C-ordered M (overwritten) is factorised as Mᵀ (its Fortran-ordered
    view, no copy) and solved transposed; residuals are computed with the float64 M.  ``scale_m`` is the
    largest |entry| of M (found here if not given).
    """
    a32 = M.astype(np.float32) if m32 is None else m32
    getrf, getrs = get_lapack_funcs(("getrf", "getrs"), (a32,))
    lu, piv, info = getrf(a32.T, overwrite_a=True)
    if scale_m is None:
        scale_m = max(float(M.max()), -float(M.min()))
    if info == 0:
        def solve32(r):
            out, _ = getrs(lu, piv, r.astype(np.float32), trans=1)  # (Mᵀ)ᵀ out = r
            return out.astype(np.float64)

        x = solve32(rhs)
        scale = scale_m * np.abs(x).max() + np.abs(rhs).max()
        for _ in range(10):
            r = _residual(M, x, rhs)
            if math.isfinite(scale) and np.abs(r).max() <= 1e-13 * scale:
                return x
            x += solve32(r)
        if np.all(np.isfinite(x)) and np.abs(_residual(M, x, rhs)).max() <= 1e-11 * scale:
            return x
    return scipy.linalg.lu_solve(scipy.linalg.lu_factor(M, check_finite=False), rhs, check_finite=False)


def _system(panels, n_holes: int, M: np.ndarray, M32: np.ndarray | None) -> tuple[np.ndarray, float]:
    """Fill ``M`` (and the panel block of its float32 copy ``M32`` if given) with the system of one
    discretisation (``PointWorldMap._panels``): collocation rows u = Σ σ_j W_j + c with u = b_ℓ on hole ℓ,
    then one zero-charge row per hole and the zero-total-charge row; unknowns σ, b_ℓ, c.  Returns the two
    right-hand sides (the unit circle on the outer boundary) and the largest |entry| of M."""
    perimeter, a_xy, b_xy, rid, s_a, s_b = panels
    n = len(a_xy)
    v, L_link, tx, ty, real = _chain(a_xy, b_xy, rid)
    L = L_link[real]
    mid = 0.5 * (a_xy + b_xy)
    M[:, n:] = 0.0
    M[n:, :n] = 0.0
    col = np.where(real, np.cumsum(real) - 1, -1)  # the real links are the panels, in order
    big = _assemble(np.ascontiguousarray(mid[:, 0]), np.ascontiguousarray(mid[:, 1]),
                    np.ascontiguousarray(v[:, 0]), np.ascontiguousarray(v[:, 1]), tx, ty, L_link, col, M, M32)
    hole_of_panel = rid - 1
    on_hole = np.flatnonzero(hole_of_panel >= 0)
    M[on_hole, n + hole_of_panel[on_hole]] = -1.0  # u = b_ℓ on hole ℓ
    M[:n, n + n_holes] = 1.0  # the constant c
    M[n + hole_of_panel[on_hole], on_hole] = L[on_hole]  # zero charge per hole
    M[n + n_holes, :n] = L  # zero total charge
    ext = np.flatnonzero(rid == 0)
    theta = 2.0 * np.pi * (0.5 * (s_a + s_b)[ext]) / perimeter
    rhs = np.zeros((n + n_holes + 1, 2))
    rhs[ext, 0] = np.cos(theta)
    rhs[ext, 1] = np.sin(theta)
    return rhs, max(big, 1.0, float(L.max()))  # |W|, the ±1 of b_ℓ and c, the L_j


@cache
def _blas() -> ThreadpoolController:
    """The BLAS libraries loaded (found once: a fresh scan costs about 2 ms per map)."""
    return ThreadpoolController()


def _solve_hierarchical(M: np.ndarray, rhs: np.ndarray, n: int, points: np.ndarray,
                        scale_m: float) -> np.ndarray | None:
    """Solve M X = rhs (n panels at ``points``, then the border) to float64 accuracy by iterative refinement
    preconditioned with :class:`~mrodrake.control.hodlr.BorderedPreconditioner`; where a step gains less than
    :data:`~mrodrake.control.hodlr.MIN_GAIN` (a sibling block the cross approximation missed in part: long hole
    edges a centimetre or two apart), by preconditioned GMRES from there, which needs only a few more products
    for the few directions the preconditioner gets wrong.  None if the residual bound of
    :func:`_solve_refined` is not met within :data:`~mrodrake.control.hodlr.MAX_STEPS` products.  BLAS runs
    single-threaded (multithreaded LAPACK on these small blocks was over ten times slower on a busy machine)."""
    with _blas().limit(limits=1, user_api="blas"):
        try:
            pre = BorderedPreconditioner(M, n, points)
        except np.linalg.LinAlgError:
            return None
        x = pre(rhs)
        scale = scale_m * np.abs(x).max() + np.abs(rhs).max()
        if not math.isfinite(scale):
            return None
        bound = 1e-13 * scale
        last = math.inf
        for step in range(MAX_STEPS):
            r = _residual(M, x, rhs)
            err = float(np.abs(r).max())
            if err <= bound:
                return x
            if err > MIN_GAIN * last:
                return _gmres(M, rhs, x, pre, bound, MAX_STEPS - step)
            last = err
            x += pre(r)
    return None


def _gmres(M: np.ndarray, rhs: np.ndarray, x: np.ndarray, pre, bound: float, products: int) -> np.ndarray | None:
    """Right-preconditioned GMRES for each column of rhs from x, with at most ``products`` products with M
    each; x once every residual entry is at most ``bound`` (checked in float64), else None."""
    N = len(M)
    out = x.copy()
    for k in range(rhs.shape[1]):
        b = rhs[:, k]
        x0 = out[:, k]
        r0 = b - M @ x0
        beta = float(np.linalg.norm(r0))
        if np.abs(r0).max() <= bound:
            continue
        V = np.zeros((N, products + 1))
        Z = np.zeros((N, products))
        Hm = np.zeros((products + 1, products))
        V[:, 0] = r0 / beta
        done = False
        for j in range(products):
            Z[:, j] = pre(V[:, j : j + 1])[:, 0]
            w = M @ Z[:, j]
            for i in range(j + 1):  # modified Gram-Schmidt, twice for float64 orthogonality
                h = V[:, i] @ w
                Hm[i, j] += h
                w -= h * V[:, i]
            for i in range(j + 1):
                h = V[:, i] @ w
                Hm[i, j] += h
                w -= h * V[:, i]
            Hm[j + 1, j] = np.linalg.norm(w)
            e1 = np.zeros(j + 2)
            e1[0] = beta
            y, est = np.linalg.lstsq(Hm[: j + 2, : j + 1], e1, rcond=None)[:2]
            if math.sqrt(float(est[0])) <= bound if len(est) else True:  # ‖r‖₂ estimate ≥ max |r|: check it
                cand = x0 + Z[:, : j + 1] @ y
                if np.abs(b - M @ cand).max() <= bound:
                    out[:, k] = cand
                    done = True
                    break
            if Hm[j + 1, j] == 0.0:
                break
            V[:, j + 1] = w / Hm[j + 1, j]
        if not done:
            return None
    return out


def _residual(M: np.ndarray, x: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """rhs − M x in float64; for two right-hand sides by a compiled pass over the rows of M (one read of M for
    both, blocks of rows on threads of their own: every row is summed on its own, so the result does not depend
    on the number of threads)."""
    if rhs.ndim != 2 or rhs.shape[1] != 2 or not M.flags.c_contiguous:
        return rhs - M @ x
    n = M.shape[0]
    out = np.empty_like(rhs)
    x0, x1 = np.ascontiguousarray(x[:, 0]), np.ascontiguousarray(x[:, 1])
    in_row_blocks(_residual_rows, n, 1024, M, x0, x1, rhs, out)
    return out


@cached_njit(nogil=True, fastmath={"reassoc", "contract"})
def _residual_rows(i0, i1, M, x0, x1, rhs, out):
    """Rows i0 .. i1 − 1 of :func:`_residual` (each row's dot products summed in vector lanes; infinities and
    NaNs propagate as without reassociation)."""
    for i in range(i0, i1):
        row = M[i]
        a = 0.0
        b = 0.0
        for j in range(row.shape[0]):
            a += row[j] * x0[j]
            b += row[j] * x1[j]
        out[i, 0] = rhs[i, 0] - a
        out[i, 1] = rhs[i, 1] - b


def _as_points(x) -> tuple[np.ndarray, bool]:
    arr = np.asarray(x, dtype=float)
    if arr.shape == (2,):
        return arr[None, :], True
    if arr.ndim == 2 and arr.shape[1] == 2:
        return arr, False
    raise ValueError(f"points must have shape (2,) or (n, 2), got {arr.shape}")


class PointWorldMap:
    """The harmonic map H of one free space onto the unit disk, with J_H and the Hessians in closed form.

    ``hole_points[ℓ]`` is b_ℓ, the image of ``free_space.interiors[ℓ]``.
    """

    def __init__(self, a_xy, b_xy, ring_of_panel, sigma, hole_points, const, free_space, exterior_param,
                 build_seconds=0.0):
        """Use ``build``; ``exterior_param`` = (arc position of the outer panels' ends a and b, perimeter)."""
        self.panel_start = np.asarray(a_xy, dtype=float)
        self.panel_end = np.asarray(b_xy, dtype=float)
        self.panel_ring = np.asarray(ring_of_panel, dtype=int)
        self.sigma = np.asarray(sigma, dtype=float)  # (n, 2) panel charges for u and v
        self.hole_points = np.asarray(hole_points, dtype=float).reshape(-1, 2)
        self.free_space = free_space
        self.build_seconds = float(build_seconds)
        self.n_solves = 1
        self._ext_param = exterior_param
        d = self.panel_end - self.panel_start
        self.panel_length = np.hypot(d[:, 0], d[:, 1])
        v, L, tx, ty, real, link_ring = _chain(self.panel_start, self.panel_end, self.panel_ring, with_rings=True)
        self._geom = (v[:, 0].copy(), v[:, 1].copy(), tx, ty, L)
        self._link_ring = link_ring
        self._link_real = real
        self._tree_cache: PanelTree | None = None
        sig = np.zeros((len(L), 2))
        sig[real] = self.sigma
        self._sig_links = sig
        # J[k, i] = Σ_j σ_jk (dl_j t_ji + 2 θ_j n_ji),  n = (−t_y, t_x); columns (k, i) = (0,x),(1,x),(0,y),(1,y)
        self._S_dl = np.hstack([sig * tx[:, None], sig * ty[:, None]])
        self._S_th = np.hstack([-2.0 * sig * ty[:, None], 2.0 * sig * tx[:, None]])
        c2, s2 = tx * tx - ty * ty, 2.0 * tx * ty
        # Hxx = A c2 − B s2, Hxy = A s2 + B c2; columns (k, ·) = (0,xx),(1,xx),(0,xy),(1,xy)
        self._S_A = np.hstack([sig * c2[:, None], sig * s2[:, None]])
        self._S_B = np.hstack([-sig * s2[:, None], sig * c2[:, None]])
        self._const = np.asarray(const, dtype=float)
        self._mid_tree = cKDTree(0.5 * (self.panel_start + self.panel_end))
        self._seeds = None
        self.circle_deficit = 0.0  # δ_max of ``outer_ridge_deficit``; set by ``build``

    # ------------------------------------------------------------------ construction
    @classmethod
    def build(
        cls,
        free_space,
        *,
        max_panel: float | None = None,
        min_panel: float | None = None,
        clearance_fraction: float = 0.25,
        hole_refinement: float = 2.0,
        grading: float = 0.4,
        curvature_fraction: float = 0.5,
        hole_curvature_fraction: float | None = None,
        curved_gap_fraction: float = 0.1,
        gap_fraction: float = 0.25,
        blob_tolerance: float = 0.08,
        max_refinements: int = 3,
    ) -> PointWorldMap:
        """Discretise the boundary of ``free_space`` (a shapely Polygon with holes) and solve for H.

        Panel length ≈ ``clearance_fraction`` × local width of the free space (the diameter of the largest
        ball tangent there), at most ``curvature_fraction`` × the local radius of curvature and
        ``clearance_fraction`` × the length of a straight stretch between sharp corners, growing at most
        ``grading`` per unit distance, clipped to [min_panel, max_panel] (defaults: diameter/25 and
        diameter/2000); on the curved parts of a hole, up to ``hole_curvature_fraction`` × the radius of
        curvature (default: ``curvature_fraction``) where that is at most ``curved_gap_fraction`` × its gap g_ℓ
        (on a hole near another boundary long curved panels make a large image).  Holes are refined
        ``hole_refinement`` times more (their boundary error, relative to
        the separation of the points b_ℓ, scales with the product of the two fractions).  Every panel of hole ℓ
        is also at most ``gap_fraction`` × its gap g_ℓ (distance to the nearest other ring), on its whole
        boundary: the separation r̄_ℓ of b_ℓ scales with g_ℓ |J_H| near the gap, while the image of the hole
        grows with the square of its longest panels, wherever they are — long panels facing open space on the
        far side of a hole that sits in a corridor would otherwise dominate its image.  Panels at convex
        corners of the outer boundary are at most max_panel / 40 (H degenerates there; with max_panel / 2 its
        boundary image sank to |H| ≈ 0.97 at room corners of the case-study office, far inside the circle
        barrier's band 1 − |χ|² < τ₀ ~ 1e-3, so nothing kept entities out of those corners).  After each solve, a
        hole whose image (max |H − b_ℓ| on its boundary) exceeds ``blob_tolerance`` × its separation (half the
        distance from b_ℓ to the nearest other b or to the unit circle) gets twice finer panels (fraction and
        gap cap halved), at most ``max_refinements`` times, so that every hole really collapses to (nearly) a
        point — unless no coarse hole's ring gets :data:`REFINE_GROWTH` times the panels (the caps that bind
        there, min_panel or the corner and curvature caps, do not depend on the factor: on case study I's
        transport maps the image of one wall-side hole stayed at 0.21-0.26 of its separation over three
        re-solves of +3 panels each, which doubled the build time); ``n_solves`` records how many solves the
        build took.  ``circle_deficit`` is δ_max of :meth:`outer_ridge_deficit` (how far short of the unit
        circle |H| stays along the outer boundary).
        """
        t0 = time.perf_counter()
        poly = _validate(free_space)
        minx, miny, maxx, maxy = poly.bounds
        diam = math.hypot(maxx - minx, maxy - miny)
        if max_panel is None:
            max_panel = diam / 25.0
        if min_panel is None:
            min_panel = diam / 2000.0
        if not (0 < min_panel <= max_panel):
            raise ValueError("need 0 < min_panel <= max_panel")
        if not (0 < clearance_fraction <= 1 and grading > 0 and curvature_fraction > 0 and hole_refinement >= 1
                and gap_fraction > 0):
            raise ValueError("need clearance_fraction in (0, 1], grading, curvature_fraction, gap_fraction > 0, "
                             "hole_refinement >= 1")
        poly = orient(poly, sign=1.0)  # exterior counter-clockwise, holes clockwise: free side on the left
        outer = np.asarray(poly.exterior.coords)
        factors = [float(hole_refinement)] * len(poly.interiors)
        hole_curvature = curvature_fraction if hole_curvature_fraction is None else float(hole_curvature_fraction)
        if not (hole_curvature > 0 and curved_gap_fraction >= 0):
            raise ValueError("need hole_curvature_fraction > 0, curved_gap_fraction >= 0")
        gaps = _hole_gaps(poly)
        gap_caps = gap_fraction * gaps
        curved_caps = curved_gap_fraction * gaps
        opts = (max_panel, min_panel, clearance_fraction, grading, curvature_fraction, hole_curvature)

        def panels_for(fs):
            return cls._panels(poly, outer, fs, [c * hole_refinement / f for c, f in zip(gap_caps, fs)],
                               [c * hole_refinement / f for c, f in zip(curved_caps, fs)], *opts)

        panels = panels_for(factors)
        for attempt in range(max_refinements + 1):
            pw = cls._solve(poly, panels)
            if not factors:
                break
            coarse = pw._hole_blobs() > blob_tolerance * _separation(pw.hole_points)
            if attempt == max_refinements or not np.any(coarse):
                break
            refined = [f * 2.0 if c else f for f, c in zip(factors, coarse)]
            finer = panels_for(refined)
            old, new = (np.bincount(p[3], minlength=len(factors) + 1)[1:] for p in (panels, finer))
            if not np.any(new[coarse] >= REFINE_GROWTH * old[coarse]):
                break  # a re-solve would give (nearly) this map again
            factors, panels = refined, finer
        pw.n_solves = attempt + 1
        pw.circle_deficit = pw.outer_ridge_deficit()
        pw.tree  # noqa: B018 (built here: part of the map's construction)
        pw.build_seconds = time.perf_counter() - t0
        return pw

    @staticmethod
    def _panels(poly, outer, factors, caps, curved_caps, max_panel, min_panel, clearance_fraction, grading,
                curvature_fraction, hole_curvature_fraction):
        """One discretisation: hole ℓ refined ``factors[ℓ]`` times, its panels at most ``caps[ℓ]``, its coarser
        curved panels at most ``curved_caps[ℓ]``; returns
        (outer perimeter, panel starts, ends, ring ids, arc positions of starts and ends)."""
        rings = [_prepare_ring(outer, is_exterior=True, curvature_fraction=curvature_fraction,
                               corner_cap=_CORNER_FRACTION * max_panel)]
        rings += [
            _prepare_ring(np.asarray(h.coords), is_exterior=False, curvature_fraction=curvature_fraction / f,
                          coarse_fraction=hole_curvature_fraction / f, coarse_cap=cc)
            for h, f, cc in zip(poly.interiors, factors, curved_caps)
        ]
        fractions = [clearance_fraction] + [clearance_fraction / f for f in factors]
        a_xy, b_xy, rid, s_a, s_b = _discretise(
            rings,
            max_panel=max_panel,
            min_panel=min_panel,
            fractions=fractions,
            grading=grading,
            ring_caps=[math.inf, *caps],
        )
        return rings[0].perimeter, a_xy, b_xy, rid, s_a, s_b

    @classmethod
    def _solve(cls, poly, panels):
        """Solve for the panel charges of one discretisation (``_panels``): by iterative refinement with the
        hierarchical preconditioner from :data:`HIERARCHICAL_PANELS` panels on, else (or if that does not
        converge) by :func:`_solve_refined`."""
        t0 = time.perf_counter()
        perimeter, a_xy, b_xy, rid, s_a, s_b = panels
        n = len(a_xy)
        n_holes = len(poly.interiors)
        M, M32 = _workspace(n + n_holes + 1)  # M32: M's float32 copy for a dense LU, filled while cache-hot
        hierarchical = n >= HIERARCHICAL_PANELS
        rhs, scale_m = _system(panels, n_holes, M, None if hierarchical else M32)
        sol = _solve_hierarchical(M, rhs, n, 0.5 * (a_xy + b_xy), scale_m) if hierarchical else None
        if sol is None:
            if hierarchical:
                M32[:] = M
            else:
                M32[:, n:] = M[:, n:]
                M32[n:, :n] = M[n:, :n]
            sol = _solve_refined(M, rhs, M32, scale_m)
        ext = rid == 0
        exterior_param = (s_a[ext], s_b[ext], perimeter)
        return cls(a_xy, b_xy, rid, sol[:n], sol[n : n + n_holes], sol[n + n_holes], poly, exterior_param,
                   time.perf_counter() - t0)

    # ------------------------------------------------------------------ properties
    @property
    def n_panels(self) -> int:
        return len(self.panel_length)

    @property
    def margin(self) -> float:
        """A safety margin valid everywhere: the longest panel (see ``local_margin`` for a local one)."""
        return float(self.panel_length.max())

    def local_margin(self, x) -> np.ndarray | float:
        """Length of the panel nearest to x (midpoint distance): keep this far from the boundary."""
        pts, single = _as_points(x)
        _, k = self._mid_tree.query(pts)
        out = self.panel_length[k]
        return float(out[0]) if single else out

    # ------------------------------------------------------------------ evaluation
    @cached_property
    def extent(self) -> float:
        """Diagonal of the free space's bounding box (the diameter that scales a resolution)."""
        minx, miny, maxx, maxy = self.free_space.bounds
        return math.hypot(maxx - minx, maxy - miny)

    @property
    def tree(self) -> PanelTree:
        """The treecode of H (:mod:`mrodrake.control.treecode`), built on first use."""
        if self._tree_cache is None:
            vx, vy, tx, ty, L = self._geom
            self._tree_cache = build_tree(vx, vy, tx, ty, L, self._sig_links, self._link_ring, self._link_real,
                                          self._const, eps_value=TREE_TOLERANCES[0],
                                          eps_gradient=TREE_TOLERANCES[1], eps_hessian=TREE_TOLERANCES[2])
        return self._tree_cache

    def _eval(self, pts, want_derivs=True):
        """(H, J_H, Hessians) at the rows of ``pts`` by the treecode (Hessians only ``want_derivs``)."""
        out = self.tree.evaluate_many(pts, want_derivs)
        return self._unpack(out, want_derivs)

    @staticmethod
    def _unpack(out, want_derivs):
        Hv = out[..., 0:2]
        if not want_derivs:
            return Hv, None, None
        J = out[..., 2:6].reshape(out.shape[:-1] + (2, 2))
        hxx, hxy = out[..., 6:10:2], out[..., 7:10:2]
        Hs = np.stack([np.stack([hxx, hxy], axis=-1), np.stack([hxy, -hxx], axis=-1)], axis=-2)
        return Hv, J, Hs

    def evaluate_flat(self, x: float, y: float) -> list[float]:
        """[u, v, ∂x u, ∂y u, ∂x v, ∂y v, u_xx, u_xy, v_xx, v_xy] of H = (u, v) at (x, y) as Python floats
        (u_yy = −u_xx, v_yy = −v_xx): the control law's hot path."""
        return self.tree.evaluate(x, y, True).tolist()

    def evaluate_direct(self, x) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(H, J_H, Hessians) by the direct sum over all panels (the reference of the treecode)."""
        pts, single = _as_points(x)
        Hv, Jv, Hs = self._direct_eval(pts)
        return (Hv[0], Jv[0], Hs[0]) if single else (Hv, Jv, Hs)

    def _direct_eval(self, pts, want_derivs=True):
        m = len(pts)
        Hv = np.empty((m, 2))
        Jv = np.empty((m, 2, 2)) if want_derivs else None
        Hs = np.empty((m, 2, 2, 2)) if want_derivs else None
        rows = max(1, _CHUNK // self.n_panels)
        for i in range(0, m, rows):
            sl = slice(i, i + rows)
            W, dl, th, A, B = _kernel(pts[sl, 0], pts[sl, 1], *self._geom, derivs=want_derivs)
            Hv[sl] = W @ self._sig_links + self._const
            if want_derivs:
                g = (dl @ self._S_dl + th @ self._S_th).reshape(-1, 2, 2)  # [point, i, k]
                Jv[sl] = g.transpose(0, 2, 1)
                h = (A @ self._S_A + B @ self._S_B).reshape(-1, 2, 2)  # [point, (xx, xy), k]
                hxx = h[:, 0, :]
                hxy = h[:, 1, :]
                Hs[sl, :, 0, 0] = hxx
                Hs[sl, :, 0, 1] = hxy
                Hs[sl, :, 1, 0] = hxy
                Hs[sl, :, 1, 1] = -hxx
        return Hv, Jv, Hs

    def _eval_point(self, x: float, y: float, derivs: bool):
        t = self.tree
        buf = np.empty(14)
        tree_point_arrays(x, y, derivs, t.vert, t.links, t.nodef, t.nodei, t.coef, t.params, buf)
        if not derivs:
            return buf[0:2], None, None
        return buf[0:2], buf[2:6].reshape(2, 2), buf[6:14].reshape(2, 2, 2)

    def __call__(self, x) -> np.ndarray:
        """χ = H(x) for x of shape (2,) or (n, 2)."""
        pts, single = _as_points(x)
        if single:
            return self._eval_point(*pts[0].tolist(), False)[0]
        return self._eval(pts, want_derivs=False)[0]

    def jacobian(self, x) -> np.ndarray:
        """J_H(x)[k, i] = ∂H_k/∂x_i, shape (2, 2) or (n, 2, 2)."""
        pts, single = _as_points(x)
        if single:
            return self._eval_point(*pts[0].tolist(), True)[1]
        return self._eval(pts)[1]

    def hessians(self, x) -> np.ndarray:
        """Hess[k, i, j] = ∂²H_k/∂x_i∂x_j, shape (2, 2, 2) or (n, 2, 2, 2)."""
        pts, single = _as_points(x)
        if single:
            return self._eval_point(*pts[0].tolist(), True)[2]
        return self._eval(pts)[2]

    def evaluate(self, x) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(H, J_H, Hessians) at x, sharing the kernel work."""
        pts, single = _as_points(x)
        if single:
            return self._eval_point(*pts[0].tolist(), True)
        return self._eval(pts)

    # ------------------------------------------------------------------ diagnostics and inverse
    def _hole_blobs(self) -> np.ndarray:
        """Per hole ℓ: max |H − b_ℓ| on its panels (the size of the hole's image).

        Sampled at fractions 1/8 and 7/8 of every panel: the deviation vanishes at the collocation point
        (the midpoint) and grows towards the panel ends, so these two of the four samples of
        ``boundary_errors`` carry its maximum (on every panel of the case-study maps).
        """
        on = self.panel_ring > 0
        frac = np.array([0.125, 0.875])
        a, b = self.panel_start[on], self.panel_end[on]
        pts = a[:, None, :] + frac[None, :, None] * (b - a)[:, None, :]
        vals = self(pts.reshape(-1, 2)).reshape(len(a), len(frac), 2)
        ring = self.panel_ring[on] - 1
        err = np.max(np.linalg.norm(vals - self.hole_points[ring][:, None, :], axis=-1), axis=1)
        blobs = np.zeros(len(self.hole_points))
        np.maximum.at(blobs, ring, err)
        return blobs

    def boundary_errors(self, samples_per_panel: int = 4) -> tuple[float, np.ndarray]:
        """Deviation from the boundary data between collocation points.

        Returns (outer, holes): max |H − e^{2πi s/P}| over the outer boundary (s its arc position, P its
        perimeter) and, per hole ℓ, max |H − b_ℓ| over its boundary; sampled at fractions
        (k + 0.5)/samples_per_panel of every panel.
        """
        frac = (np.arange(samples_per_panel) + 0.5) / samples_per_panel
        d = self.panel_end - self.panel_start
        pts = self.panel_start[:, None, :] + frac[None, :, None] * d[:, None, :]
        vals = self(pts.reshape(-1, 2)).reshape(self.n_panels, samples_per_panel, 2)
        ext = self.panel_ring == 0
        s_a, s_b, perim = self._ext_param
        s = s_a[:, None] + frac[None, :] * (s_b - s_a)[:, None]
        target = np.stack([np.cos(2 * np.pi * s / perim), np.sin(2 * np.pi * s / perim)], axis=-1)
        outer = float(np.max(np.linalg.norm(vals[ext] - target, axis=-1)))
        holes = np.zeros(len(self.hole_points))
        if np.any(~ext):
            ring = self.panel_ring[~ext] - 1
            err = np.max(np.linalg.norm(vals[~ext] - self.hole_points[ring][:, None, :], axis=-1), axis=1)
            np.maximum.at(holes, ring, err)
        return outer, holes

    def outer_ridge_deficit(self) -> float:
        """δ_max = max over outer-boundary samples p of (1 − max_{0 ≤ t ≤ ℓ/2} |H(p + t n)|), n the inward normal.

        The discrete H only matches the unit circle at the collocation points: between them |H| < 1 on ∂F
        (≈1e-4 at door jambs, ≈1e-3 along long panels), and its maximum along the inward normal (the ridge
        of |H|) may lie a fraction of a panel inside.  Every sample p (fractions ``_RIDGE_FRACTIONS`` of each
        outer panel of length ℓ) has a ridge point with |H| ≥ 1 − δ_max on its normal within ℓ/2 (less than
        an eighth of the local clearance, so inside F), so the level set |H| = ρ₀ < 1 − δ_max separates
        every start with |H| < ρ₀ from the outer boundary (used by the circle barrier of
        :class:`mrodrake.control.adaptive.LocalBarrierNavigationFunction`).  Samples whose boundary deficit
        is already below the running δ_max cannot raise it (the ridge is at least the boundary value), so
        only the worst ones are stepped inward: a few thousand evaluations.  Evaluated by the treecode; δ_max
        includes twice its bound on H.
        """
        ext = self.panel_ring == 0
        a, d, ell = self.panel_start[ext], (self.panel_end - self.panel_start)[ext], self.panel_length[ext]
        frac = np.asarray(_RIDGE_FRACTIONS)
        pts = (a[:, None, :] + frac[None, :, None] * d[:, None, :]).reshape(-1, 2)
        nrm = np.repeat(np.column_stack([-d[:, 1], d[:, 0]]) / ell[:, None], len(frac), axis=0)
        step = np.repeat(ell, len(frac))
        deficit = 1.0 - np.linalg.norm(self(pts), axis=1)
        order = np.argsort(-deficit)
        offs = np.asarray(_RIDGE_OFFSETS)
        best = 0.0
        batch = 64
        for i in range(0, len(order), batch):
            k = order[i : i + batch]
            k = k[deficit[k] > best]
            if len(k) == 0:
                break
            q = pts[k, None, :] + (offs[None, :] * step[k, None])[..., None] * nrm[k, None, :]
            h = np.linalg.norm(self(q.reshape(-1, 2)), axis=1).reshape(len(k), len(offs))
            ridge = np.minimum(deficit[k], 1.0 - h.max(axis=1))
            best = max(best, float(ridge.max()))
        return best + 2.0 * TREE_TOLERANCES[0]

    def _inverse_seeds(self):
        if self._seeds is None:
            d = self.panel_end - self.panel_start
            nrm = np.column_stack([-d[:, 1], d[:, 0]]) / self.panel_length[:, None]
            mid = 0.5 * (self.panel_start + self.panel_end)
            cand = np.vstack([mid + f * self.panel_length[:, None] * nrm for f in (1.0, 3.0, 8.0)])
            minx, miny, maxx, maxy = self.free_space.bounds
            gx, gy = np.meshgrid(np.linspace(minx, maxx, 60), np.linspace(miny, maxy, 60))
            cand = np.vstack([cand, np.column_stack([gx.ravel(), gy.ravel()])])
            inside = shapely.contains_xy(self.free_space, cand[:, 0], cand[:, 1])
            cand = cand[inside]
            cand = cand[shapely.distance(self.free_space.boundary, shapely.points(cand)) >= self.local_margin(cand)]
            self._seeds = (cand, self(cand))
        return self._seeds

    def inverse(self, chi, guess=None, *, tol: float = 1e-12, max_iter: int = 100) -> np.ndarray:
        """x with H(x) = χ, by damped Newton from ``guess`` (default: the best of a set of interior seeds)."""
        chi = np.asarray(chi, dtype=float)
        if guess is None:
            cand, vals = self._inverse_seeds()
            guess = cand[np.argmin(np.linalg.norm(vals - chi, axis=1))]
        x = np.asarray(guess, dtype=float).copy()
        Hx, Jx, _ = self.evaluate(x)
        res = Hx - chi
        nres = float(np.linalg.norm(res))
        for _ in range(max_iter):
            if nres <= tol:
                return x
            step = np.linalg.solve(Jx, res)
            lam = 1.0
            while lam > 1e-6:
                x_new = x - lam * step
                H_new, J_new, _ = self.evaluate(x_new)
                n_new = float(np.linalg.norm(H_new - chi))
                if n_new < nres and shapely.contains_xy(self.free_space, x_new[0], x_new[1]):
                    break
                lam *= 0.5
            else:
                break
            x, Jx, res, nres = x_new, J_new, H_new - chi, n_new
        if nres > 1e3 * tol:
            raise RuntimeError(f"inverse did not converge: |H(x) - chi| = {nres:.3g}")
        return x


def _hole_gaps(poly: Polygon) -> np.ndarray:
    """Per hole: its distance to the nearest other boundary ring (the outer boundary or another hole).

    The distance to the outer boundary is that to its nearest edge (a search tree over the edges); only the
    holes within that distance are then measured, so each gap is the minimum of the same pairwise distances
    as over all rings."""
    holes = np.array(list(poly.interiors), dtype=object)
    if len(holes) == 0:
        return np.zeros(0)
    ext = np.asarray(poly.exterior.coords)
    edges = shapely.STRtree(shapely.linestrings(np.stack([ext[:-1], ext[1:]], axis=1)))
    (hole, _), dist = edges.query_nearest(holes, return_distance=True)
    gap = np.full(len(holes), np.inf)
    np.minimum.at(gap, hole, dist)
    i, j = shapely.STRtree(holes).query(holes, predicate="dwithin", distance=gap)
    other = i != j
    np.minimum.at(gap, i[other], shapely.distance(holes[i[other]], holes[j[other]]))
    return gap


def _separation(b: np.ndarray) -> np.ndarray:
    """Per point b_ℓ: half the distance to the nearest other b or to the unit circle."""
    r = 1.0 - np.linalg.norm(b, axis=1)
    if len(b) > 1:
        d = np.linalg.norm(b[:, None] - b[None], axis=-1) + np.diag(np.full(len(b), np.inf))
        r = np.minimum(r, d.min(axis=1))
    return 0.5 * r


def _validate(free_space) -> Polygon:
    if isinstance(free_space, MultiPolygon):
        parts = [g for g in free_space.geoms if not g.is_empty]
        if len(parts) != 1:
            raise UserError(f"free_space: not one connected polygon ({len(parts)} components)")
        free_space = parts[0]
    if not isinstance(free_space, Polygon):
        raise UserError(f"free_space: expected a shapely Polygon, got {type(free_space).__name__}")
    if free_space.is_empty:
        raise UserError("free_space: empty")
    if not free_space.is_valid:
        reason = shapely.is_valid_reason(free_space).splitlines()[0]
        raise UserError(f"free_space: invalid polygon ({reason})")
    if free_space.area <= 0.0:
        raise UserError("free_space: empty")
    return free_space
