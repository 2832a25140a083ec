"""Fast evaluation of a panel single-layer potential and its first two derivatives: a compiled treecode.

The potential of panel charges σ_j on straight panels is u(z) = Σ_j σ_j ∫_panel ln|z − w|² ds_w + c =
2 Re F(z) + c with F(z) = Σ_j σ_j ∫ log(z − w) ds_w (z = x + iy).  For a cluster of panels inside the disk
|w − c| ≤ R and a point with |z − c| = ρ > R, ζ = R / (z − c), r = R / ρ < 1,

    F   = Q log(z − c) − Σ_{p≥1} (m_p / p) ζ^p,
    F'  = (z − c)⁻¹  Σ_{p≥0} m_p ζ^p,
    F'' = −(z − c)⁻² Σ_{p≥0} (p + 1) m_p ζ^p,

with the scaled moments m_p = R^{−p} Σ_j σ_j ∫ (w − c)^p ds (m_0 = Q, |m_p| ≤ S = Σ_j |σ_j| L_j), exact for a
straight panel from a to b with unit direction τ: ∫ (w − c)^p ds = ((b − c)^{p+1} − (a − c)^{p+1}) / (τ (p + 1)).
Then ∂_x u = 2 Re F', ∂_y u = −2 Im F', ∂_xx u = −∂_yy u = 2 Re F'', ∂_xy u = −2 Im F''.

Truncation after p = P (tails of geometric series, |ζ| ≤ r):

    |Δu|         ≤ 2 S r^{P+1} / ((P + 1)(1 − r)),
    |Δ∂_i u|     ≤ 2 S r^{P+1} / (ρ (1 − r)),
    |Δ∂_i∂_j u|  ≤ 2 S r^{P+1} ((P + 2) − (P + 1) r) / (ρ² (1 − r)²).

A cluster is summed by its expansion when the P these bounds need for tolerances ε · S / S_tot (S_tot: the
total Σ |σ_j| L_j of the component) is at most ``order``; otherwise its two halves are tried, and a leaf (a run
of consecutive panels of one ring) is summed directly with the closed forms of
:mod:`mrodrake.control.pointworld`.  The clusters summed by expansion are disjoint, so the total error of u,
of every first and of every second derivative is at most ε_H, ε_J and ε_Hess (plus rounding).
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from mrodrake.control.compiled import cached_njit

#: Panels per leaf (a run of consecutive panels on one ring).
LEAF_PANELS = 16
#: Highest term of the stored expansions.
ORDER = 50
#: Largest R / ρ at which a cluster's expansion is used.
MAX_RATIO = 0.6
#: Points per thread at least before a batch evaluation is split over threads.
BATCH_PER_THREAD = 512
_TWO_PI = 2.0 * math.pi
_TINY = 1e-300
_STACK = 256


def usable_cores() -> int:
    """Cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def in_row_blocks(kernel, n: int, rows_per_thread: int, *args) -> list:
    """``kernel(i0, i1, *args)`` on contiguous blocks [i0, i1) of the rows 0 .. n − 1, a thread each (at most
    one per core and at least ``rows_per_thread`` rows per block; in this thread when that leaves one block);
    the kernels' results in block order.  For compiled kernels that release the GIL and compute every row on
    its own, so the result does not depend on the number of threads."""
    workers = max(1, min(usable_cores(), n // rows_per_thread))
    if workers == 1:
        return [kernel(0, n, *args)]
    bounds = np.linspace(0, n, workers + 1).astype(np.int64)
    with ThreadPoolExecutor(workers) as pool:
        jobs = [pool.submit(kernel, int(i0), int(i1), *args) for i0, i1 in zip(bounds[:-1], bounds[1:])]
        return [job.result() for job in jobs]


class PanelTree:
    """Clusters of the panels of a chain (see :func:`build_tree`) with the expansions of two potentials."""

    def __init__(self, vert, links, nodef, nodei, coef, params):
        self.vert = vert  # (nv, 2) chain vertices
        self.links = links  # (nl, 5): tx, ty, L, σ_u, σ_v per link (σ = 0 on the links between rings)
        self.nodef = nodef  # (nn, 4): centre x, y, radius R and ln R
        self.nodei = nodei  # (nn, 4): children (−1 at a leaf), first and one-past-last link of a leaf
        self.coef = coef  # (nn, 2, 3, ORDER + 1) complex: m_p / p, m_p, (p + 1) m_p per component
        # ln ε_H/(2 S_tot), ln ε_J/(2 S_tot), ln ε_Hess/(2 S_tot (ORDER + 2)), const_u, const_v, ratio²
        self.params = params

    def evaluate(self, x: float, y: float, derivs: bool = True) -> np.ndarray:
        """[u, v, ∂x u, ∂y u, ∂x v, ∂y v, u_xx, u_xy, v_xx, v_xy] at one point (see ``tree_point``)."""
        out = np.empty(10)
        tree_point(x, y, derivs, self.vert, self.links, self.nodef, self.nodei, self.coef, self.params, out)
        return out

    def evaluate_many(self, pts: np.ndarray, derivs: bool = True) -> np.ndarray:
        """``evaluate`` at every row of ``pts`` (n, 2); shape (n, 10).  Large batches are split over threads
        (the compiled loop releases the GIL); every point is evaluated on its own, so the result does not
        depend on the number of threads."""
        pts = np.ascontiguousarray(pts, dtype=float)
        out = np.empty((len(pts), 10))
        args = (derivs, self.vert, self.links, self.nodef, self.nodei, self.coef, self.params)
        in_row_blocks(lambda i0, i1: tree_points(pts[i0:i1], *args, out[i0:i1]), len(pts), BATCH_PER_THREAD)
        return out


@cached_njit(nogil=True)
def _leaves(ring_of_link, real, lengths, max_panels, max_length):
    """(first, end) link ranges, shape (k, 2): runs of consecutive real links of one ring, at most
    ``max_panels`` links and (beyond their first link) at most ``max_length`` long each."""
    n = real.shape[0]
    out = np.empty((n, 2), dtype=np.int64)
    count = 0
    j = 0
    while j < n:
        if not real[j]:
            j += 1
            continue
        k = j + 1
        total = lengths[j]
        while (k < n and real[k] and ring_of_link[k] == ring_of_link[j] and k - j < max_panels
               and total + lengths[k] <= max_length):
            total += lengths[k]
            k += 1
        out[count, 0] = j
        out[count, 1] = k
        count += 1
        j = k
    return out[:count]


@cached_njit(nogil=True)
def _leaf_boxes(vert, leaves):
    """Bounding boxes (lower, upper corners) of the vertices of every leaf."""
    m = leaves.shape[0]
    lo = np.empty((m, 2))
    hi = np.empty((m, 2))
    for q in range(m):
        for c in range(2):
            a = vert[leaves[q, 0], c]
            b = a
            for i in range(leaves[q, 0] + 1, leaves[q, 1] + 1):
                a = min(a, vert[i, c])
                b = max(b, vert[i, c])
            lo[q, c] = a
            hi[q, c] = b
    return lo, hi


@cached_njit(nogil=True)
def _stable_sort_by(order, lo, hi, key, axis, work):
    """Sort order[lo:hi] by key[order, axis] keeping the order of equal keys (bottom-up merge sort; ``work``
    is scratch of the length of ``order``)."""
    width = 1
    in_work = False
    while width < hi - lo:
        src, dst = (work, order) if in_work else (order, work)
        for a in range(lo, hi, 2 * width):
            b = min(a + width, hi)
            c = min(a + 2 * width, hi)
            i, j = a, b
            for t in range(a, c):
                if i < b and (j >= c or key[src[i], axis] <= key[src[j], axis]):
                    dst[t] = src[i]
                    i += 1
                else:
                    dst[t] = src[j]
                    j += 1
        in_work = not in_work
        width *= 2
    if in_work:
        for t in range(lo, hi):
            order[t] = work[t]


@cached_njit(nogil=True)
def _split_nodes(box_lo, box_hi, mid):
    """The binary tree over the leaves in pre-order: a node's leaves are split into two halves (the first
    ⌊m/2⌋ and the rest) of their order by the centre coordinate along the longer side of their bounding box
    (stable).  Returns (children (−1 at a leaf), centres of the bounding boxes, first and one-past-last
    position of every node's leaves in the returned leaf order, leaf order)."""
    m = box_lo.shape[0]
    nn = 2 * m - 1
    children = np.empty((nn, 2), dtype=np.int64)
    centre = np.empty((nn, 2))
    first = np.empty(nn, dtype=np.int64)
    last = np.empty(nn, dtype=np.int64)
    order = np.arange(m)
    work = np.empty(m, dtype=np.int64)
    stack = np.empty((nn, 3), dtype=np.int64)  # node, first, one-past-last
    stack[0, 0], stack[0, 1], stack[0, 2] = 0, 0, m
    top = 1
    while top > 0:
        top -= 1
        k, lo, hi = stack[top, 0], stack[top, 1], stack[top, 2]
        first[k] = lo
        last[k] = hi
        q = order[lo]
        lx, ly = box_lo[q, 0], box_lo[q, 1]
        ux, uy = box_hi[q, 0], box_hi[q, 1]
        for t in range(lo + 1, hi):
            q = order[t]
            lx = min(lx, box_lo[q, 0])
            ly = min(ly, box_lo[q, 1])
            ux = max(ux, box_hi[q, 0])
            uy = max(uy, box_hi[q, 1])
        centre[k, 0] = 0.5 * (lx + ux)
        centre[k, 1] = 0.5 * (ly + uy)
        children[k, 0] = -1
        children[k, 1] = -1
        if hi - lo == 1:
            continue
        axis = 1 if uy - ly > ux - lx else 0
        _stable_sort_by(order, lo, hi, mid, axis, work)
        half = (hi - lo) // 2
        left, right = k + 1, k + 2 * half  # a subtree of h leaves has 2h − 1 nodes
        children[k, 0], children[k, 1] = left, right
        stack[top, 0], stack[top, 1], stack[top, 2] = right, lo + half, hi
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = left, lo, lo + half
        top += 2
    return children, centre, first, last, order


@cached_njit(nogil=True)
def _node_moments(nodes, vert, links, leaf_lo, leaf_hi, first, last, centre, coef, radius):
    """Radius R and coefficients (m_p / p, m_p, (p + 1) m_p) of the ``nodes``: the links of leaves
    first..last − 1 (in tree order) about the node's centre."""
    order = coef.shape[3] - 1
    for k in nodes:
        cx = centre[k, 0]
        cy = centre[k, 1]
        R2 = 0.0
        for q in range(first[k], last[k]):
            for i in range(leaf_lo[q], leaf_hi[q] + 1):
                ex = vert[i, 0] - cx
                ey = vert[i, 1] - cy
                R2 = max(R2, ex * ex + ey * ey)
        R = max(math.sqrt(R2), 1e-300)
        radius[k] = R
        for q in range(first[k], last[k]):
            for j in range(leaf_lo[q], leaf_hi[q]):
                alpha = complex(vert[j, 0] - cx, vert[j, 1] - cy) / R
                beta = complex(vert[j + 1, 0] - cx, vert[j + 1, 1] - cy) / R
                scale = R / complex(links[j, 0], links[j, 1])
                su = links[j, 3]
                sv = links[j, 4]
                pa = alpha
                pb = beta
                for p in range(order + 1):
                    term = scale * (pb - pa) / (p + 1)
                    coef[k, 0, 1, p] += su * term
                    coef[k, 1, 1, p] += sv * term
                    pa *= alpha
                    pb *= beta
        for c in range(2):
            for p in range(order + 1):
                m = coef[k, c, 1, p]
                coef[k, c, 0, p] = m / p if p > 0 else 0j
                coef[k, c, 2, p] = m * (p + 1)


def build_tree(vx, vy, tx, ty, L, sigma_links, ring_of_link, real, const, *, eps_value: float = 5e-10,
               eps_gradient: float = 5e-8, eps_hessian: float = 5e-6, leaf_panels: int = LEAF_PANELS,
               order: int = ORDER, max_ratio: float = MAX_RATIO) -> PanelTree:
    """The tree of a panel chain (vertices (vx, vy); link j from vertex j to j + 1 with unit tangent (tx, ty)_j,
    length L_j, charges ``sigma_links`` (nl, 2), ring ``ring_of_link``; ``real`` false on the links between
    rings) and tolerances on u, on each first and on each second derivative (module docstring).

    Leaves are split in two halves of their centres along the longer side of their bounding box."""
    vert = np.ascontiguousarray(np.column_stack([vx, vy]), dtype=float)
    links = np.ascontiguousarray(np.column_stack([tx, ty, L, sigma_links[:, 0], sigma_links[:, 1]]), dtype=float)
    span = float(np.hypot(*(vert.max(axis=0) - vert.min(axis=0))))
    leaves = _leaves(np.ascontiguousarray(ring_of_link, dtype=np.int64), np.ascontiguousarray(real, dtype=np.bool_),
                     np.ascontiguousarray(L, dtype=float), leaf_panels, span / 32.0)
    box_lo, box_hi = _leaf_boxes(vert, leaves)
    children, centre, first_a, last_a, tree_order = _split_nodes(box_lo, box_hi, 0.5 * (box_lo + box_hi))
    nn = len(children)
    coef = np.zeros((nn, 2, 3, order + 1), dtype=complex)
    radius = np.empty(nn)
    args = (vert, links, leaves[tree_order, 0], leaves[tree_order, 1], first_a, last_a, centre, coef, radius)
    nodes = np.arange(nn)
    workers = min(usable_cores(), max(1, nn // 64))
    if workers == 1:
        _node_moments(nodes, *args)
    else:  # every node on its own (the same bits on any number of threads); every other node balances the work
        with ThreadPoolExecutor(workers) as pool:
            for job in [pool.submit(_node_moments, nodes[w::workers], *args) for w in range(workers)]:
                job.result()
    nodei = np.full((nn, 4), -1, dtype=np.int64)
    nodei[:, :2] = children
    leaf = nodei[:, 0] < 0
    nodei[leaf, 2:] = leaves[tree_order[first_a[leaf]]]
    nodef = np.column_stack([centre, radius, np.log(radius)])
    s_tot = max(float(np.max(np.abs(sigma_links).T @ np.asarray(L, dtype=float))), 1e-300)
    params = np.array([math.log(eps_value / (2.0 * s_tot)), math.log(eps_gradient / (2.0 * s_tot)),
                       math.log(eps_hessian / (2.0 * s_tot * (order + 2))), float(const[0]), float(const[1]),
                       max_ratio * max_ratio])
    return PanelTree(vert, links, nodef, nodei, coef, params)


@cached_njit(nogil=True)
def _direct(x, y, derivs, vert, links, lo, hi, out):
    """Closed-form sums of the links [lo, hi) added to ``out``."""
    dxp = x - vert[lo, 0]
    dyp = y - vert[lo, 1]
    rp = max(dxp * dxp + dyp * dyp, _TINY)
    lrp = math.log(rp)
    angp = math.atan2(dyp, dxp)
    irp = 1.0 / rp
    for j in range(lo, hi):
        dx = x - vert[j + 1, 0]
        dy = y - vert[j + 1, 1]
        r = max(dx * dx + dy * dy, _TINY)
        lr = math.log(r)
        ang = math.atan2(dy, dx)
        tx = links[j, 0]
        ty = links[j, 1]
        L = links[j, 2]
        su = links[j, 3]
        sv = links[j, 4]
        dl = lrp - lr
        th = ang - angp
        th -= _TWO_PI * np.rint(th * (1.0 / _TWO_PI))
        ua = dxp * tx + dyp * ty
        eta = dyp * tx - dxp * ty
        W = ua * dl + L * (lr - 2.0) + 2.0 * eta * th
        out[0] += su * W
        out[1] += sv * W
        if derivs:
            gx = dl * tx - 2.0 * th * ty
            gy = dl * ty + 2.0 * th * tx
            out[2] += su * gx
            out[3] += su * gy
            out[4] += sv * gx
            out[5] += sv * gy
            ir = 1.0 / r
            di = irp - ir
            A = 2.0 * (ua * di + L * ir)
            B = 2.0 * eta * di
            c2 = tx * tx - ty * ty
            s2 = 2.0 * tx * ty
            hxx = A * c2 - B * s2
            hxy = A * s2 + B * c2
            out[6] += su * hxx
            out[7] += su * hxy
            out[8] += sv * hxx
            out[9] += sv * hxy
            irp = ir
        dxp = dx
        dyp = dy
        lrp = lr
        angp = ang


@cached_njit(nogil=True)
def _expansion(dx, dy, ln_rho, R, P, derivs, coef, node, out):
    """The expansion of ``node`` (radius R) with terms p = 0..P at z − c = dx + i dy (ln_rho = ln |z − c|)
    added to ``out``."""
    d = complex(dx, dy)
    zeta = R / d
    f0u = 0j
    f0v = 0j
    f1u = 0j
    f1v = 0j
    f2u = 0j
    f2v = 0j
    for p in range(P, -1, -1):
        f0u = f0u * zeta + coef[node, 0, 0, p]
        f0v = f0v * zeta + coef[node, 1, 0, p]
        if derivs:
            f1u = f1u * zeta + coef[node, 0, 1, p]
            f1v = f1v * zeta + coef[node, 1, 1, p]
            f2u = f2u * zeta + coef[node, 0, 2, p]
            f2v = f2v * zeta + coef[node, 1, 2, p]
    qu = coef[node, 0, 1, 0].real
    qv = coef[node, 1, 1, 0].real
    out[0] += 2.0 * (qu * ln_rho - f0u.real)
    out[1] += 2.0 * (qv * ln_rho - f0v.real)
    if not derivs:
        return
    inv = 1.0 / d
    g_u = f1u * inv
    g_v = f1v * inv
    out[2] += 2.0 * g_u.real
    out[3] -= 2.0 * g_u.imag
    out[4] += 2.0 * g_v.real
    out[5] -= 2.0 * g_v.imag
    inv2 = inv * inv
    h_u = -f2u * inv2
    h_v = -f2v * inv2
    out[6] += 2.0 * h_u.real
    out[7] -= 2.0 * h_u.imag
    out[8] += 2.0 * h_v.real
    out[9] -= 2.0 * h_v.imag


@cached_njit(nogil=True)
def _terms(log_k, log_r, order):
    """Least P ≥ 0 with r^{P+1} ≤ k (log_r < 0), or order + 1 if that is above ``order``."""
    need = math.ceil(log_k / log_r) - 1
    if need < 0:
        return 0
    return min(need, order + 1)


@cached_njit(nogil=True)
def tree_point(x, y, derivs, vert, links, nodef, nodei, coef, params, out):
    """out = u, v, ∂x u, ∂y u, ∂x v, ∂y v, u_xx, u_xy, v_xx, v_xy at (x, y) (the second derivatives only
    with ``derivs``; u_yy = −u_xx).  A cluster is expanded where R / ρ is below the largest ratio and the
    tolerances need at most ``order`` terms (module docstring); all three series are truncated at the largest P
    of the three bounds, so the derivatives are as smooth along a path as the value."""
    order = coef.shape[3] - 1
    for i in range(10):
        out[i] = 0.0
    stack = np.empty(_STACK, dtype=np.int64)
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        dx = x - nodef[node, 0]
        dy = y - nodef[node, 1]
        rho2 = dx * dx + dy * dy
        R = nodef[node, 2]
        if R * R < params[5] * rho2:
            rho = math.sqrt(rho2)
            ln_rho = math.log(rho)
            log_r = nodef[node, 3] - ln_rho
            log_q = math.log1p(-R / rho)
            log_k = params[0] + log_q
            if derivs:
                log_k = min(log_k, params[1] + ln_rho + log_q, params[2] + 2.0 * (ln_rho + log_q))
            P = _terms(log_k, log_r, order)
            if P <= order:
                _expansion(dx, dy, ln_rho, R, P, derivs, coef, node, out)
                continue
        if nodei[node, 0] < 0:
            _direct(x, y, derivs, vert, links, nodei[node, 2], nodei[node, 3], out)
        else:
            stack[top] = nodei[node, 1]
            stack[top + 1] = nodei[node, 0]
            top += 2
    out[0] += params[3]
    out[1] += params[4]


@cached_njit(nogil=True)
def tree_point_arrays(x, y, derivs, vert, links, nodef, nodei, coef, params, out):
    """``tree_point`` into out (14) = H (2), J_H (2 × 2) and the Hessians (2 × 2 × 2) in row-major order."""
    tree_point(x, y, derivs, vert, links, nodef, nodei, coef, params, out)
    if derivs:
        uxx, uxy, vxx, vxy = out[6], out[7], out[8], out[9]
        out[8], out[9] = uxy, -uxx
        out[10], out[11], out[12], out[13] = vxx, vxy, vxy, -vxx


@cached_njit(nogil=True)
def tree_points(pts, derivs, vert, links, nodef, nodei, coef, params, out):
    """``tree_point`` at every row of ``pts``."""
    for i in range(pts.shape[0]):
        tree_point(pts[i, 0], pts[i, 1], derivs, vert, links, nodef, nodei, coef, params, out[i])
