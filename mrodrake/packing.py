"""Circle packing procedure P_s = [P_{s,0}, P_{s,1}] (paper Sec. II-B, the paragraph after
the grasping and releasing definitions): do non-overlapping disks with given radii fit in a region disk, and where.

P_s is **sound but incomplete**.  Deciding whether disks fit in a disk is NP-hard in general, so a "no"
means "no packing found" (or a proven necessary condition fails), while every "yes" carries centres
that were verified before being returned: all pairwise gaps ``|c_i - c_j| - r_i - r_j`` and boundary
gaps ``R - |c_i| - r_i`` are at least ``margin + SLACK * R`` in floating point.  The strictly positive
slack makes round-off irrelevant (computed gaps have relative error ~1e-16), so the real-number disks
are disjoint and inside.  Consequently P_s answers "no" for instances that are feasible only with a
gap smaller than ``SLACK * R`` (e.g. two disks of radius R/2 exactly).

The search runs in three stages, all on the problem scaled to R = 1:

1. fast rejection by necessary conditions (:func:`_necessary`): the largest disk, the two largest
   along a diameter (r_1 + r_2 <= R), the area bound, the proven optimal container ratios for k <= 13
   equal circles and the Folkman-Graham inequality applied to the k largest disks;
2. greedy constructive placement, largest first, on candidate positions tangent to two of
   {container, placed disks}, chosen by hole degree or by closeness to the rim;
3. penalty-energy minimisation (overlap + protrusion, L-BFGS) from seeded random starts.

Every random choice uses ``numpy.random.default_rng(seed)``; results are deterministic.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache

import numpy as np
from scipy.optimize import minimize

SLACK = 1e-9
"""Relative guaranteed slack: every returned gap is at least ``margin + SLACK * R``."""

_BUILD = 2.0 * SLACK
_OPT_EXTRA = 1e-6
_TOL = 1e-12
_RESTARTS = 8
_LBFGS_ITERS = 400
_LBFGS_MEMORY = 10
_SPREAD_ITERS = 40
_SPREAD_STARTS = 4
_RIM_ANGLES = 12

# Proven optimal container ratios R/r for k equal circles, k <= 13 (closed forms where known, other
# values rounded down so they stay valid lower bounds).  Sources: Graham (1968), Pirl (1969),
# Melissen (1994), Fodor (2000, 2003); see also the survey by Hifi & M'Hallah (2009).
_EQUAL_OPT = np.array([
    1.0,
    2.0,
    1.0 + 2.0 / math.sqrt(3.0),
    1.0 + math.sqrt(2.0),
    1.0 + math.sqrt(2.0 + 2.0 / math.sqrt(5.0)),
    3.0,
    3.0,
    1.0 + 1.0 / math.sin(math.pi / 7.0),
    1.0 + math.sqrt(2.0 * (2.0 + math.sqrt(2.0))),
    3.81302,
    1.0 + 1.0 / math.sin(math.pi / 9.0),
    4.02960,
    2.0 + math.sqrt(5.0),
])


def _check_radius(value: float, what: str) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise ValueError(f"{what} must be a finite positive number, got {value!r}")
    return v


def _check_radii(radii: Sequence[float], what: str) -> np.ndarray:
    arr = np.asarray([float(r) for r in radii], dtype=float).reshape(-1)
    bad = ~np.isfinite(arr) | (arr <= 0.0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{what}[{i}] must be a finite positive number, got {radii[i]!r}")
    return arr


def _gaps_ok(R, c: np.ndarray, r: np.ndarray, fc: np.ndarray, fr: np.ndarray, g: float) -> bool:
    """All gaps involving the disks (c, r) are >= g: pairwise, to the fixed disks (fc, fr), to the rim (R: one
    radius, or one per disk: the rim that disk must keep inside)."""
    if not np.all(np.isfinite(c)):
        return False
    if np.any(R - np.hypot(c[:, 0], c[:, 1]) - r < g):
        return False
    n = len(r)
    if n > 1:
        i, j = np.triu_indices(n, 1)
        d = np.hypot(c[i, 0] - c[j, 0], c[i, 1] - c[j, 1])
        if np.any(d - r[i] - r[j] < g):
            return False
    if len(fr):
        d = np.hypot(c[:, None, 0] - fc[None, :, 0], c[:, None, 1] - fc[None, :, 1])
        if np.any(d - r[:, None] - fr[None, :] < g):
            return False
    return True


def _min_gap(c: np.ndarray, r: np.ndarray, fc: np.ndarray, fr: np.ndarray) -> float:
    """Smallest gap (pairwise, to fixed disks, to the unit rim) in the normalised problem."""
    g = float(np.min(1.0 - np.hypot(c[:, 0], c[:, 1]) - r))
    n = len(r)
    if n > 1:
        i, j = np.triu_indices(n, 1)
        g = min(g, float(np.min(np.hypot(c[i, 0] - c[j, 0], c[i, 1] - c[j, 1]) - r[i] - r[j])))
    if len(fr):
        d = np.hypot(c[:, None, 0] - fc[None, :, 0], c[:, None, 1] - fc[None, :, 1])
        g = min(g, float(np.min(d - r[:, None] - fr[None, :])))
    return g


def verify_packing(region_radius: float, centres: np.ndarray, radii: Sequence[float], margin: float = 0.0) -> bool:
    """True iff the disks (centres relative to the region centre, radii) are inside the region disk and
    pairwise apart with every gap (pairwise and to the rim) at least ``margin``, in floating point."""
    R = _check_radius(region_radius, "region_radius")
    r = _check_radii(radii, "radii")
    c = np.asarray(centres, dtype=float)
    if len(r) == 0:
        return c.size == 0
    if c.shape != (len(r), 2):
        raise ValueError(f"centres must have shape ({len(r)}, 2), got {c.shape}")
    return _gaps_ok(R, c, r, np.empty((0, 2)), np.empty(0), float(margin))


def _necessary(rs: np.ndarray) -> bool:
    """Necessary conditions for radii ``rs`` (sorted descending, container radius 1) to pack.

    Shrinking each of the k largest disks to radius r_k about its own centre keeps a packing, so k
    equal circles of radius r_k must fit: R/r_k >= the proven optimal ratio (k <= 13), and the k
    centres lie in the disk of radius R - r_k at mutual distances >= 2 r_k, so the Folkman-Graham
    inequality n <= 2A/sqrt(3) + P/2 + 1 (points at mutual distance >= 1 in a compact convex set of
    area A and perimeter P) bounds k.  Plus r_1 <= R, r_1 + r_2 <= R (both centres on a diameter)
    and sum r_i^2 <= R^2 (area).
    """
    n = len(rs)
    if n == 0:
        return True
    if rs[0] > 1.0:
        return False
    if n >= 2 and rs[0] + rs[1] > 1.0:
        return False
    if float(np.sum(rs * rs)) > 1.0:
        return False
    k = np.arange(1, n + 1)
    ratio = 1.0 / rs
    m = min(n, len(_EQUAL_OPT))
    if np.any(ratio[:m] < _EQUAL_OPT[:m]):
        return False
    rho = (ratio - 1.0) / 2.0
    bound = 2.0 / math.sqrt(3.0) * math.pi * rho * rho + math.pi * rho + 1.0
    return not np.any(k > bound)


def _candidates(C: np.ndarray, Rr: np.ndarray, r: float, rho) -> np.ndarray:
    """Positions for a disk of radius r tangent to two of {container of radius rho, placed disks},
    plus rim points and the origin (used when nothing is nearby)."""
    ang = 2.0 * math.pi * np.arange(_RIM_ANGLES) / _RIM_ANGLES
    extra = np.vstack([np.c_[np.cos(ang), np.sin(ang)] * (rho - r), np.zeros((1, 2))])
    m = len(Rr)
    if m == 0:
        return extra
    A = np.vstack([C, np.zeros((1, 2))])
    rad = np.concatenate([Rr + r, [rho - r]])
    i, j = np.triu_indices(m + 1, 1)
    D = A[j] - A[i]
    d = np.hypot(D[:, 0], D[:, 1])
    ra, rb = rad[i], rad[j]
    ok = (d > 1e-15) & (d <= ra + rb) & (d >= np.abs(ra - rb))
    if not ok.any():
        return extra
    D, d, ra, rb, Ai = D[ok], d[ok], ra[ok], rb[ok], A[i[ok]]
    a = (ra * ra - rb * rb + d * d) / (2.0 * d)
    h = np.sqrt(np.maximum(ra * ra - a * a, 0.0))
    u = D / d[:, None]
    base = Ai + a[:, None] * u
    perp = np.c_[-u[:, 1], u[:, 0]] * h[:, None]
    return np.vstack([base + perp, base - perp, extra])


def _greedy(rads: np.ndarray, fc: np.ndarray, fr: np.ndarray, rhos: np.ndarray, rule: str) -> tuple[np.ndarray, int]:
    """Place disks of radii ``rads`` one by one (in the given order) next to fixed disks (fc, fr), disk i in
    the container of radius ``rhos[i]`` (one container; smaller for a disk whose centre is bound closer to the
    centre).  The first disk of an empty container touches the rim at angle 0; each
    later one goes to the valid tangency candidate with the smallest third-smallest gap ("hole": snug
    in a hole, ties to the rim) or with the largest |c| ("rim"), ties broken by polar angle.
    Returns (centres, number placed); rows after that count are undefined."""
    n, m0 = len(rads), len(fr)
    C = np.zeros((m0 + n, 2))
    Rr = np.zeros(m0 + n)
    C[:m0], Rr[:m0] = fc, fr
    for k, (r, rho) in enumerate(zip(rads, rhos)):
        m = m0 + k
        if r > rho:
            return C[m0:], k
        if m == 0:
            C[0] = rho - r, 0.0
            Rr[0] = r
            continue
        P = _candidates(C[:m], Rr[:m], r, rho)
        norm = np.hypot(P[:, 0], P[:, 1])
        gaps = np.hypot(P[:, None, 0] - C[None, :m, 0], P[:, None, 1] - C[None, :m, 1]) - Rr[:m] - r
        valid = (norm <= rho - r + _TOL) & np.all(gaps >= -_TOL, axis=1)
        if not valid.any():
            return C[m0:], k
        P, norm, gaps = P[valid], norm[valid], gaps[valid]
        ang = np.mod(np.arctan2(P[:, 1], P[:, 0]), 2.0 * math.pi)
        if rule == "hole":
            allg = np.sort(np.c_[gaps, rho - r - norm], axis=1)
            third = allg[:, min(2, allg.shape[1] - 1)]
            best = np.lexsort((ang, -np.round(norm, 9), np.round(third, 9)))[0]
        else:
            best = np.lexsort((ang, -np.round(norm, 9)))[0]
        C[m], Rr[m] = P[best], r
    return C[m0:], n


def _energy(x: np.ndarray, r: np.ndarray, rho, fc: np.ndarray, fr: np.ndarray) -> tuple[float, np.ndarray]:
    """Penalty energy sum(overlap^2) + sum(protrusion^2) and its gradient (fixed disks are constants; rho:
    the container's radius, or one per disk)."""
    c = x.reshape(-1, 2)
    D = c[:, None, :] - c[None, :, :]
    d = np.sqrt(np.einsum("ijk,ijk->ij", D, D))
    np.fill_diagonal(d, np.inf)
    O = np.maximum(r[:, None] + r[None, :] - d, 0.0)
    E = 0.5 * float(np.einsum("ij,ij->", O, O))
    W = O / np.maximum(d, 1e-12)
    grad = -2.0 * np.einsum("ij,ijk->ik", W, D)
    if len(fr):
        Df = c[:, None, :] - fc[None, :, :]
        df = np.sqrt(np.einsum("ijk,ijk->ij", Df, Df))
        Of = np.maximum(r[:, None] + fr[None, :] - df, 0.0)
        E += float(np.einsum("ij,ij->", Of, Of))
        grad -= 2.0 * np.einsum("ij,ijk->ik", Of / np.maximum(df, 1e-12), Df)
    nc = np.hypot(c[:, 0], c[:, 1])
    Ob = np.maximum(nc + r - rho, 0.0)
    E += float(Ob @ Ob)
    grad += (2.0 * Ob / np.maximum(nc, 1e-12))[:, None] * c
    return E, grad.reshape(-1)


def _relax(start: np.ndarray, r: np.ndarray, rho, fc: np.ndarray, fr: np.ndarray) -> np.ndarray:
    """Minimise the penalty energy from ``start`` with a small L-BFGS (two-loop recursion, Armijo
    backtracking).  Own implementation: scipy's L-BFGS-B calls multithreaded BLAS on these tiny
    problems and was measured 60-100x slower on a loaded 2-core machine."""
    x = start.reshape(-1).copy()
    f, g = _energy(x, r, rho, fc, fr)
    S: list[np.ndarray] = []
    Y: list[np.ndarray] = []
    for _ in range(_LBFGS_ITERS):
        if f == 0.0 or float(np.max(np.abs(g))) <= 1e-13:
            break
        q = g.copy()
        alphas = []
        for s, y in zip(reversed(S), reversed(Y)):
            a = float(s @ q) / float(y @ s)
            alphas.append(a)
            q -= a * y
        if S:
            q *= float(S[-1] @ Y[-1]) / float(Y[-1] @ Y[-1])
        for (s, y), a in zip(zip(S, Y), reversed(alphas)):
            q += s * (a - float(y @ q) / float(y @ s))
        d = -q
        slope = float(g @ d)
        if slope >= 0.0:
            d, slope = -g, -float(g @ g)
            S.clear()
            Y.clear()
        t = 1.0
        while True:
            xn = x + t * d
            fn, gn = _energy(xn, r, rho, fc, fr)
            if fn <= f + 1e-4 * t * slope:
                break
            t *= 0.5
            if t < 1e-10:
                return x.reshape(-1, 2)
        s, y = xn - x, gn - g
        if float(s @ y) > 1e-18:
            S.append(s)
            Y.append(y)
            if len(S) > _LBFGS_MEMORY:
                S.pop(0)
                Y.pop(0)
        stalled = f - fn <= 1e-9 * f
        x, f, g = xn, fn, gn
        if stalled:
            break
    return x.reshape(-1, 2)


def _random_start(rng: np.random.Generator, r: np.ndarray, rho) -> np.ndarray:
    rad = np.maximum(rho - r, 0.0) * np.sqrt(rng.random(len(r)))
    th = 2.0 * math.pi * rng.random(len(r))
    return np.c_[rad * np.cos(th), rad * np.sin(th)]


def _solutions(r: np.ndarray, fc: np.ndarray, fr: np.ndarray, gap: float, seed: int, restarts: int = _RESTARTS,
               rims: np.ndarray | None = None):
    """Yield verified centres for radii ``r`` (descending, unit container) next to the fixed disks
    (fc, fr) with every gap involving a new disk >= gap + 1.5 SLACK (to the rim ``rims[i]`` for disk i, a
    smaller container for a disk whose centre is bound closer to the centre; default 1): first the greedy
    placements, then penalty-energy minima from seeded random starts (at most ``restarts`` of them)."""
    infl = (gap + _BUILD) / 2.0
    rads, frads = r + infl, fr + infl
    rho = 1.0 - infl if rims is None else rims - infl
    rhos = np.broadcast_to(rho, r.shape)
    rim = 1.0 if rims is None else rims
    check = gap + (SLACK + _BUILD) / 2.0
    partial = None
    for rule in ("hole", "rim"):
        c, k = _greedy(rads, fc, frads, rhos, rule)
        if k == len(r) and _gaps_ok(rim, c, r, fc, fr, check):
            yield c
        elif partial is None or k > partial[1]:
            partial = (c, k)
    rng = np.random.default_rng(seed)
    ro, fro, rhoo = rads + _OPT_EXTRA, frads + _OPT_EXTRA, rho - _OPT_EXTRA
    for attempt in range(restarts):
        start = _random_start(rng, ro, rhoo)
        if attempt == 0 and partial is not None:
            start[: partial[1]] = partial[0][: partial[1]]
        c = _relax(start, ro, rhoo, fc, fro)
        if _gaps_ok(rim, c, r, fc, fr, check):
            yield c


@lru_cache(maxsize=1 << 16)
def _pack_sorted(R: float, radii: tuple[float, ...], seed: int, rims: tuple[float, ...] | None = None
                 ) -> np.ndarray | None:
    """Cached P_s on radii sorted in descending order (``rims``: the rim each disk keeps inside, at most R;
    default R); returns read-only centres in that order."""
    if not radii:
        out = np.zeros((0, 2))
        out.flags.writeable = False
        return out
    r = np.asarray(radii) / R
    if not _necessary(r):
        return None
    rim = R if rims is None else np.asarray(rims)
    if rims is not None:
        reach = rim - np.asarray(radii)  # |c_i| <= reach_i, so |c_i - c_j| <= reach_i + reach_j
        i, j = np.triu_indices(len(r), 1)
        if np.any(reach < 0.0) or np.any(reach[i] + reach[j] < r[i] * R + r[j] * R):
            return None
    none = np.empty((0, 2)), np.empty(0)
    if len(r) == 1:
        c = np.zeros((1, 2))
    else:
        c = next(_solutions(r, *none, 0.0, seed, rims=None if rims is None else rim / R), None)
        if c is None:
            return None
    out = c * R
    if not _gaps_ok(rim, out, np.asarray(radii), *none, SLACK * R):
        return None
    out.flags.writeable = False
    return out


def pack(region_radius: float, radii: Sequence[float], seed: int = 0) -> np.ndarray | None:
    """P_{s,1}: centres (n, 2) relative to the region centre, in the order of ``radii``, of a verified
    packing with every gap >= SLACK * region_radius; None if no packing was found (cached)."""
    R = _check_radius(region_radius, "region_radius")
    r = _check_radii(radii, "radii")
    order = np.argsort(-r, kind="stable")
    sol = _pack_sorted(R, tuple(r[order].tolist()), int(seed))
    if sol is None:
        return None
    out = np.empty((len(r), 2))
    out[order] = sol
    return out


def fits(region_radius: float, radii: Sequence[float], rims: Sequence[float] | None = None) -> bool:
    """P_{s,0}: True iff P_s finds a verified packing of ``radii`` in the region disk (sound, cached on
    the region radius and the sorted radii; ``fits.cache_info()`` / ``fits.cache_clear()``).  ``rims``: per
    disk, the radius of the concentric disk it must keep inside (at most the region's; a disk whose centre
    is bound to |c| <= rim - r)."""
    R = _check_radius(region_radius, "region_radius")
    r = _check_radii(radii, "radii")
    if rims is None:
        return _pack_sorted(R, tuple(sorted(r.tolist(), reverse=True)), 0) is not None
    rim = np.minimum(np.asarray([float(x) for x in rims], dtype=float).reshape(-1), R)
    if len(rim) != len(r) or not np.all(np.isfinite(rim)):
        raise ValueError(f"rims must be {len(r)} finite numbers")
    pairs = sorted(zip(r.tolist(), rim.tolist()), key=lambda p: (-p[0], p[1]))
    return _pack_sorted(R, tuple(p[0] for p in pairs), 0, tuple(p[1] for p in pairs)) is not None


fits.cache_info = _pack_sorted.cache_info  # type: ignore[attr-defined]
fits.cache_clear = _pack_sorted.cache_clear  # type: ignore[attr-defined]


def entities_fit(region_radius: float, radii, spacing: float, bounds: Sequence[float | None] | None = None) -> bool:
    """P_{s,0} with the layout spacing: disks of ``radii`` fit in the region keeping ``spacing`` between
    any two of them and between each and the region's rim (radii inflated by spacing/2, container
    shrunk by spacing/2).  ``bounds[i]`` (None: none): disk i's centre is at most region_radius − bounds[i]
    − spacing/2 from the region's centre, where a disk of radius bounds[i] around it keeps spacing/2 to the
    rim (an object put down by a team of that covering radius)."""
    half = 0.5 * spacing
    if bounds is None or all(b is None for b in bounds):
        return fits(region_radius - half, sorted((float(r) + half for r in radii), reverse=True))
    R = region_radius - half
    rims = [R if b is None else min(R, region_radius - float(b) + float(r)) for r, b in zip(radii, bounds)]
    return fits(R, [float(r) + half for r in radii], rims)


def _spread(c: np.ndarray, r: np.ndarray, fc: np.ndarray, fr: np.ndarray) -> np.ndarray:
    """Increase the minimum gap t of the new disks (pairwise, to fixed disks, to the unit rim) with a
    few SLSQP steps on max t s.t. every gap >= t (rim gaps in the smooth form
    (1 - r_i - t)^2 >= |c_i|^2, 1 - r_i - t >= 0); returns the improved centres (unverified)."""
    n, m = len(r), len(fr)
    ii, jj = np.triu_indices(n, 1)
    fi, fj = np.repeat(np.arange(n), m), np.tile(np.arange(m), n)
    npair, nfix = len(ii), len(fi)

    def cons(z: np.ndarray) -> np.ndarray:
        c, t = z[:-1].reshape(-1, 2), z[-1]
        dp = np.hypot(*(c[ii] - c[jj]).T) - r[ii] - r[jj] - t
        df = np.hypot(*(c[fi] - fc[fj]).T) - r[fi] - fr[fj] - t
        room = 1.0 - r - t
        return np.concatenate([dp, df, room * room - np.einsum("ij,ij->i", c, c), room])

    def jac(z: np.ndarray) -> np.ndarray:
        c, t = z[:-1].reshape(-1, 2), z[-1]
        J = np.zeros((npair + nfix + 2 * n, 2 * n + 1))
        J[:, -1] = -1.0
        U = c[ii] - c[jj]
        U /= np.maximum(np.hypot(*U.T), 1e-15)[:, None]
        rows = np.arange(npair)
        for k in range(2):
            J[rows, 2 * ii + k] = U[:, k]
            J[rows, 2 * jj + k] = -U[:, k]
        V = c[fi] - fc[fj]
        V /= np.maximum(np.hypot(*V.T), 1e-15)[:, None]
        rows = npair + np.arange(nfix)
        for k in range(2):
            J[rows, 2 * fi + k] = V[:, k]
        rows = npair + nfix + np.arange(n)
        for k in range(2):
            J[rows, 2 * np.arange(n) + k] = -2.0 * c[:, k]
        J[rows, -1] = -2.0 * (1.0 - r - t)
        return J

    z0 = np.concatenate([c.reshape(-1), [_min_gap(c, r, fc, fr)]])
    obj = np.zeros_like(z0)
    obj[-1] = -1.0
    res = minimize(lambda z: -z[-1], z0, jac=lambda z: obj, method="SLSQP",
                   constraints=[{"type": "ineq", "fun": cons, "jac": jac}],
                   options={"maxiter": _SPREAD_ITERS, "ftol": 1e-12})
    return res.x[:-1].reshape(-1, 2)


def _place_inputs(region_radius, fixed_centres, fixed_radii, new_radii, margin):
    """Checked (R, new radii, fixed centres, fixed radii, margin) of :func:`place` / :func:`can_place`."""
    R = _check_radius(region_radius, "region_radius")
    fr = _check_radii(fixed_radii, "fixed_radii")
    r = _check_radii(new_radii, "new_radii")
    fc = np.asarray(fixed_centres, dtype=float)
    if fc.size == 0:
        fc = fc.reshape(0, 2)
    if fc.shape != (len(fr), 2) or not np.all(np.isfinite(fc)):
        raise ValueError(f"fixed_centres must be a finite array of shape ({len(fr)}, 2)")
    g = float(margin)
    if not math.isfinite(g) or g < 0.0:
        raise ValueError(f"margin must be a finite non-negative number, got {margin!r}")
    return R, r, fc, fr, g


def can_place(region_radius: float, fixed_centres: np.ndarray, fixed_radii: Sequence[float],
              new_radii: Sequence[float], seed: int = 0, margin: float = 0.0, restarts: int = _RESTARTS) -> bool:
    """True iff the search of :func:`place` finds a verified placement of ``new_radii`` next to the fixed
    disks (the same gaps), trying the greedy placements and then at most ``restarts`` seeded relaxations;
    the first verified placement answers (no spreading, so much cheaper than ``place`` when only existence
    matters)."""
    R, r, fc, fr, g = _place_inputs(region_radius, fixed_centres, fixed_radii, new_radii, margin)
    if len(r) == 0:
        return True
    order = np.argsort(-r, kind="stable")
    rs, fcs, frs, gs = r[order] / R, fc / R, fr / R, g / R
    if gs / 2.0 >= 1.0 or not _necessary((rs + gs / 2.0) / (1.0 - gs / 2.0)):
        return False
    for c in _solutions(rs, fcs, frs, gs, int(seed), int(restarts)):
        if _gaps_ok(R, c * R, r[order], fc, fr, g + SLACK * R):
            return True
    return False


def place(region_radius: float, fixed_centres: np.ndarray, fixed_radii: Sequence[float],
          new_radii: Sequence[float], seed: int = 0, margin: float = 0.0) -> np.ndarray | None:
    """Centres (relative to the region centre, in the order of ``new_radii``) for new disks in a region
    that already holds the fixed disks, which are not moved ("goal points given the entities already
    there").  Every gap involving a new disk (to other new disks, to fixed disks, to the rim) is at
    least ``margin + SLACK * region_radius``; the minimum gap is then enlarged by a few optimisation
    steps (spread-out goals) when the result stays verified.  Gaps among fixed disks are not checked.
    None if no placement was found.  Not cached."""
    R, r, fc, fr, g = _place_inputs(region_radius, fixed_centres, fixed_radii, new_radii, margin)
    if len(r) == 0:
        return np.zeros((0, 2))
    order = np.argsort(-r, kind="stable")
    rs, fcs, frs, gs = r[order] / R, fc / R, fr / R, g / R
    if gs / 2.0 >= 1.0 or not _necessary((rs + gs / 2.0) / (1.0 - gs / 2.0)):
        return None
    first = next(_solutions(rs, fcs, frs, gs, int(seed)), None)
    if first is None:
        return None
    rng = np.random.default_rng(int(seed))
    starts = [first] + [_random_start(rng, rs, 1.0) for _ in range(_SPREAD_STARTS)]
    best, best_gap = first, _min_gap(first, rs, fcs, frs)
    for start in starts:
        cand = _spread(start, rs, fcs, frs)
        gap = _min_gap(cand, rs, fcs, frs)
        if gap > best_gap and _gaps_ok(1.0, cand, rs, fcs, frs, gs + SLACK):
            best, best_gap = cand, gap
    c = best
    sol = c * R
    if not _gaps_ok(R, sol, r[order], fc, fr, g + SLACK * R):
        return None
    out = np.empty((len(r), 2))
    out[order] = sol
    return out
