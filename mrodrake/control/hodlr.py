"""Hierarchical (HODLR) preconditioner of the boundary-element system of :mod:`mrodrake.control.pointworld`.

The system is [[M, B], [C, 0]]: the panel block M (M_ij = W_j at the midpoint of panel i), the border B, C of
one unknown b_ℓ and one zero-charge row per hole, the constant c and the total-charge row Lᵀσ = 0.  After the
panels are ordered by recursive bisection of their midpoints, the block coupling two sibling clusters has low
numerical rank (the log kernel is smooth between them).  Each such block is compressed by adaptive cross
approximation (partial pivoting) to relative accuracy ``tol``, and the inverse of every cluster's block follows
from its children's by the Woodbury identity, leaves up: O(n k² log n) for ranks k (Ambikasaran and Darve,
J. Sci. Comput. 2013).  The border is eliminated by its Schur complement.

Shift: the kernel is approximated as ln(|x − y|² / s²) with s twice the panels' extent, i.e. M' = M − g 1 Lᵀ,
g = ln s².  It is negative on every pair of panels, so no cluster sees a log kernel on a curve of logarithmic
capacity 1 (where the single layer is singular).  The total-charge row makes the systems equivalent:
M σ + c 1 = M' σ + c' 1 with c' = c + g Lᵀσ.

The approximate inverse only preconditions iterative refinement (GMRES where that stalls) against the exact
float64 system (``pointworld._solve_hierarchical``), so the result meets the dense solve's residual bound.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from mrodrake.control.compiled import cached_njit
from mrodrake.control.treecode import usable_cores

#: Panels per leaf cluster at most.
LEAF = 128
#: Relative accuracy asked of the cross approximations (partial pivoting underestimates its error: the
#: preconditioned refinement gains about 1e-4 per step with 1e-7, two steps to the float64 bound on case study
#: I's maps).  On those maps 1e-6 needed four steps (two more passes over M) and 1e-8 one step but larger ranks,
#: each a few per cent slower in all.
TOL = 1e-7
#: Products with the system (refinement steps, then GMRES iterations) before the solve gives up (the caller
#: then solves densely).
MAX_STEPS = 12
#: Least factor by which a refinement step must shrink the largest residual entry (else GMRES takes over).
MIN_GAIN = 1e-2


@cached_njit(nogil=True, fastmath={"reassoc", "contract"})
def _aca(M, rows, cols, shift, tol):
    """Cross approximation U Vᵀ of the block (M[rows[i], cols[j]] − shift[cols[j]]) with partial pivoting:
    stops after two consecutive crosses |u| |v| ≤ tol ‖U Vᵀ‖_F (or at full rank).  Returns Uᵀ and Vᵀ."""
    m1, m2 = len(rows), len(cols)
    cap = min(m1, m2)
    room = min(cap, 32)
    Ut = np.empty((room, m1))
    Vt = np.empty((room, m2))
    used = np.zeros(m1, dtype=np.bool_)
    row = np.empty(m2)
    col = np.empty(m1)
    k = 0
    i = 0
    norm2 = 0.0
    small = 0
    while k < cap:
        used[i] = True
        ri = rows[i]
        for j in range(m2):
            row[j] = M[ri, cols[j]] - shift[cols[j]]
        for q in range(k):
            a = Ut[q, i]
            vq = Vt[q]
            for j in range(m2):
                row[j] -= a * vq[j]
        jb = 0
        best = 0.0
        for j in range(m2):
            if abs(row[j]) > best:
                best = abs(row[j])
                jb = j
        if best == 0.0:  # this row is reproduced exactly: try an unused one
            i = -1
            for r in range(m1):
                if not used[r]:
                    i = r
                    break
            if i < 0:
                break
            continue
        if k == room:
            room = min(cap, 2 * room)
            grown = np.empty((room, m1))
            grown[:k] = Ut[:k]
            Ut = grown
            grown = np.empty((room, m2))
            grown[:k] = Vt[:k]
            Vt = grown
        piv = row[jb]
        cj = cols[jb]
        vk = Vt[k]
        for j in range(m2):
            vk[j] = row[j] / piv
        for r in range(m1):
            col[r] = M[rows[r], cj] - shift[cj]
        for q in range(k):
            b = Vt[q, jb]
            uq = Ut[q]
            for r in range(m1):
                col[r] -= b * uq[r]
        uk = Ut[k]
        nu = 0.0
        nv = 0.0
        for r in range(m1):
            uk[r] = col[r]
            nu += col[r] * col[r]
        for j in range(m2):
            nv += vk[j] * vk[j]
        cross = 0.0
        for q in range(k):
            su = 0.0
            sv = 0.0
            uq = Ut[q]
            vq = Vt[q]
            for r in range(m1):
                su += uq[r] * col[r]
            for j in range(m2):
                sv += vq[j] * vk[j]
            cross += su * sv
        norm2 += nu * nv + 2.0 * cross
        k += 1
        if nu * nv <= tol * tol * norm2:
            small += 1
            if small >= 2:
                break
        else:
            small = 0
        i = -1
        best = -1.0
        for r in range(m1):
            if not used[r] and abs(col[r]) > best:
                best = abs(col[r])
                i = r
        if i < 0:
            break
    return Ut[:k].copy(), Vt[:k].copy()


@dataclass
class _Cluster:
    """Panels ``order[lo:hi]``; an inner cluster splits at ``mid`` into the clusters ``left`` and ``right``.
    ``inv``: the inverse of a leaf's block, or of an inner cluster's Woodbury capacitance matrix
    K = [[I, V1ᵀ Y2], [V2ᵀ Y1, I]], with the sibling blocks U1 V1ᵀ (rows lo:mid, columns mid:hi) and U2 V2ᵀ,
    Y1 = A_left⁻¹ U1 and Y2 = A_right⁻¹ U2."""

    lo: int
    hi: int
    mid: int = -1
    left: int = -1
    right: int = -1
    inv: np.ndarray | None = None
    U1: np.ndarray | None = None
    V1: np.ndarray | None = None
    U2: np.ndarray | None = None
    V2: np.ndarray | None = None
    Y1: np.ndarray | None = None
    Y2: np.ndarray | None = None


def _bisect(points: np.ndarray, idx: np.ndarray, lo: int, leaf: int, out: list, order: list) -> int:
    """Post-order clusters of ``idx`` (from position lo on), halved at the median along the longer side of
    their bounding box; returns the index of the cluster of ``idx``."""
    if len(idx) <= leaf:
        order.append(idx)
        out.append(_Cluster(lo, lo + len(idx)))
        return len(out) - 1
    pts = points[idx]
    axis = int(np.argmax(pts.max(axis=0) - pts.min(axis=0)))
    srt = idx[np.argsort(pts[:, axis], kind="stable")]
    half = len(srt) // 2
    left = _bisect(points, srt[:half], lo, leaf, out, order)
    right = _bisect(points, srt[half:], lo + half, leaf, out, order)
    out.append(_Cluster(lo, lo + len(srt), mid=lo + half, left=left, right=right))
    return len(out) - 1


class HodlrInverse:
    """Approximate inverse of the shifted panel block M' = M − g 1 Lᵀ (see the module docstring).

    The factorisation solves, leaves up, for every cluster at once the columns of all sibling blocks above it
    (each leaf's rows of them, stacked) and those of ``extra`` (n, m), whose solve M'⁻¹ extra is kept as
    ``solved_extra``: every cluster is visited once."""

    def __init__(self, M: np.ndarray, points: np.ndarray, lengths: np.ndarray, extra: np.ndarray | None = None,
                 *, leaf: int | None = None, tol: float | None = None, workers: int | None = None):
        leaf = LEAF if leaf is None else leaf
        tol = TOL if tol is None else tol
        self.tol = tol
        workers = usable_cores() if workers is None else workers
        if leaf < 2 or not tol > 0.0 or workers < 1:
            raise ValueError(f"need leaf >= 2, tol > 0 and workers >= 1, got {leaf}, {tol}, {workers}")
        n = len(points)
        ext = points.max(axis=0) - points.min(axis=0)
        self.g = 2.0 * math.log(2.0 * max(float(np.hypot(ext[0], ext[1])), 1e-300))
        self.shift = self.g * np.asarray(lengths, dtype=float)
        clusters: list[_Cluster] = []
        order: list[np.ndarray] = []
        _bisect(np.asarray(points, dtype=float), np.arange(n), 0, leaf, clusters, order)
        self.order = perm = np.concatenate(order)
        self.clusters = clusters
        self._parent = np.full(len(clusters), -1)
        inner = [k for k, cl in enumerate(clusters) if cl.mid >= 0]
        for k in inner:
            self._parent[clusters[k].left] = self._parent[clusters[k].right] = k
        self._extra = np.zeros((n, 0)) if extra is None else np.asarray(extra, dtype=float)[perm]
        self._M = M
        jobs = sorted(((k, side) for k in inner for side in (0, 1)),
                      key=lambda job: -(clusters[job[0]].hi - clusters[job[0]].lo))  # largest blocks first
        depth = max(0, math.ceil(math.log2(workers)))  # subtrees factorised on threads of their own
        with ThreadPoolExecutor(max(workers, 2**depth - 1)) as pool:  # the map runs on all, the recursion needs 2^d - 1
            for (k, side), (ut, vt) in zip(jobs, pool.map(self._cross, jobs)):
                if side == 0:
                    clusters[k].U1, clusters[k].V1 = ut.T, vt.T
                else:
                    clusters[k].U2, clusters[k].V2 = ut.T, vt.T
            top = self._factor(len(clusters) - 1, pool, depth)
        self.solved_extra = np.empty_like(self._extra)
        self.solved_extra[perm] = top
        del self._M, self._extra

    def _cross(self, job: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Cross approximation of one sibling block of inner cluster k: rows lo:mid × columns mid:hi (side 0)
        or the transposed pair (side 1)."""
        cl = self.clusters[job[0]]
        a, b = self.order[cl.lo : cl.mid], self.order[cl.mid : cl.hi]
        return _aca(self._M, a, b, self.shift, self.tol) if job[1] == 0 else _aca(self._M, b, a, self.shift, self.tol)

    def _factor(self, k: int, pool: ThreadPoolExecutor, depth: int) -> np.ndarray:
        """Factorise the cluster k's subtree; returns its block's inverse applied to its rows of the sibling
        blocks above it and of ``extra`` (stacked; those of the sibling blocks solved here are dropped).  The
        left subtree goes to ``pool`` while ``depth`` > 0: the same operations in the same order as in one
        thread, so the result does not depend on the number of threads."""
        cl = self.clusters[k]
        if cl.mid < 0:
            idx = self.order[cl.lo : cl.hi]
            cl.inv = self._inverse(self._M[np.ix_(idx, idx)] - self.shift[idx][None, :])
            cols = []
            child, up = k, self._parent[k]
            while up >= 0:  # this leaf's rows of the sibling blocks above it, nearest first
                p = self.clusters[up]
                U, lo = (p.U1, p.lo) if child == p.left else (p.U2, p.mid)
                cols.append(U[cl.lo - lo : cl.hi - lo])
                child, up = up, self._parent[up]
            cols.append(self._extra[cl.lo : cl.hi])
            return cl.inv @ np.hstack(cols)
        if depth > 0:
            left = pool.submit(self._factor, cl.left, pool, depth - 1)
            sb = self._factor(cl.right, pool, depth - 1)
            sa = left.result()
        else:
            sa = self._factor(cl.left, pool, 0)
            sb = self._factor(cl.right, pool, 0)
        k1, k2 = cl.U1.shape[1], cl.U2.shape[1]
        cl.Y1, cl.Y2 = sa[:, :k1].copy(), sb[:, :k2].copy()
        K = np.eye(k1 + k2)
        K[:k1, k1:] = cl.V1.T @ cl.Y2
        K[k1:, :k1] = cl.V2.T @ cl.Y1
        cl.inv = self._inverse(K)
        return self._correct(cl, np.vstack([sa[:, k1:], sb[:, k2:]]))

    @staticmethod
    def _inverse(A: np.ndarray) -> np.ndarray:
        """A⁻¹ (an explicit inverse: applying it is a matrix product, much faster than triangular solves at these
        sizes; numpy's LAPACK call releases the GIL, so subtrees factorise in parallel)."""
        return np.linalg.inv(A)

    def _correct(self, cl: _Cluster, X: np.ndarray) -> np.ndarray:
        """The Woodbury step of inner cluster ``cl`` on X = diag(A_left⁻¹, A_right⁻¹) R, in place."""
        x1 = X[: cl.mid - cl.lo]
        x2 = X[cl.mid - cl.lo :]
        k1 = cl.V1.shape[1]
        w = cl.inv @ np.vstack([cl.V1.T @ x2, cl.V2.T @ x1])
        x1 -= cl.Y1 @ w[:k1]
        x2 -= cl.Y2 @ w[k1:]
        return X

    def apply(self, R: np.ndarray) -> np.ndarray:
        """M'⁻¹ R (R: (n, m), panel order) approximately."""
        X = R[self.order]
        for cl in self.clusters:
            if cl.mid < 0:
                X[cl.lo : cl.hi] = cl.inv @ X[cl.lo : cl.hi]
            else:
                self._correct(cl, X[cl.lo : cl.hi])
        out = np.empty_like(X)
        out[self.order] = X
        return out


class BorderedPreconditioner:
    """Approximate inverse of the whole system [[M, B], [C, 0]] (n panels, then the border unknowns; the last
    border unknown is c and the last row Lᵀσ = 0): the HODLR inverse of M', the Schur complement of the
    border, and the change c = c' − g Lᵀσ."""

    def __init__(self, M: np.ndarray, n: int, points: np.ndarray, **options):
        lengths = M[-1, :n]
        self.inner = HodlrInverse(M, points, lengths, M[:n, n:], **options)
        self.n = n
        self.lengths = lengths
        self.C = M[n:, :n]
        self.Z = self.inner.solved_extra  # M'⁻¹ B
        self.S_inv = np.linalg.inv(-(self.C @ self.Z))

    def __call__(self, R: np.ndarray) -> np.ndarray:
        n = self.n
        y = self.inner.apply(R[:n])
        x2 = self.S_inv @ (R[n:] - self.C @ y)
        x = np.empty_like(R)
        x[:n] = y - self.Z @ x2
        x[n:] = x2
        x[-1] -= self.inner.g * (self.lengths @ x[:n])
        return x
