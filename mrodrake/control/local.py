"""Local motions inside one region: docking at a grasp point, backing off after a release, and settling at
the P_s goal once a navigating or transported entity has entered its target region.

Grasping is abstract in the paper (Table I: the robot and the object share a region).  Executing it, the
robot must reach its grasp point, ``layout.grasp_gap`` (0.1 m) from the object's rim.  In the office-wide
point world that goal lies a few millimetres from the object's hole image b_ℓ; Proposition 1 then forces
τ ~ 1e-8 and the law crawls for hundreds of seconds.  Inside a region the free space is a disk (the region)
minus disks (the other entities), so no map is needed: we use the identity map H(x) = x and the same
adaptive law (paper Sec. III-A: eqs. (9)–(11)) on a disk-world navigation function

    φ(x) = k1‖x − x_d‖² + k2 Σ_ℓ (β_ℓ(d_ℓ(x)) − 1),   d_ℓ = ‖x − c_ℓ‖² − ρ_ℓ²,   d_0 = R² − ‖x − c‖²,

with β_ℓ the barrier of eq. (8) with its own region of influence τ_ℓ (ρ_ℓ = r_ℓ + r: the other
entity grown by the robot radius; d_0: the region's disk shrunk by r, so the robot never leaves the region).
With J_H = I the paper's Lyapunov argument holds unchanged, so φ stays bounded: no collision and no exit
from the region, whatever the masses and frictions.

Settling: inside a region the paper's k1 = 0.01 makes the point-world law move at about 0.02 (x − x_d) per
second, and entering behind another entity it crawls around the saddle of that entity's hole for hundreds of
seconds; the region is reached at that point (the TS transition is complete), the local law only places the
entity at its goal.

Other entities packed by P_s can touch the rim of the shrunk region disk and each other, so the disk world
may have crevices where φ has local minima.  The motion therefore follows a shortest path of straight legs
(:func:`local_path`, a visibility graph around the grown disks) and each leg is one task whose barrier
regions exclude the whole leg: the ideal flow ẋ = v_d runs straight along the leg, barriers act only on
deviations.  On a leg whose barrier annuli are disjoint (the usual case), the goal is the only minimum:
a critical point x ≠ x_d of φ needs x − x_d ∥ x − c_ℓ in an annulus, and if x_d is outside the annulus the
tangential curvature there is 2k1(1 − ‖x − x_d‖/‖x − c_ℓ‖) < 0 (a saddle).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mrodrake.control.adaptive import V_MAX, AdaptiveGains, NavigationTask, load_sharing
from mrodrake.control.navfunc import TAU_FRACTION, Barriers, phi_terms
from mrodrake.geometry import PATH_CLEARANCE, local_path, segment_distances

#: Largest barrier annulus width (m).
WIDTH_CAP = 0.5


class IdentityMap:
    """H(x) = x: the local motions need no point-world transformation (same interface as PointWorldMap)."""

    hole_points = np.zeros((0, 2))
    _HS = np.zeros((2, 2, 2))
    _I = np.eye(2)

    def __call__(self, x) -> np.ndarray:
        return np.asarray(x, dtype=float)

    def jacobian(self, x) -> np.ndarray:
        return self._I.copy()

    def evaluate(self, x) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return np.asarray(x, dtype=float), self._I, self._HS


@dataclass(frozen=True)
class DiskWorldNavigationFunction:
    """φ of the module docstring: goal x_d, disks (c_ℓ, ρ_ℓ) with regions of influence τ_ℓ, and the rim
    disk (c, R) with τ_0 (τ_0 = 0: no rim barrier).  Same interface as the point-world φ (``evaluate``)."""

    goal: np.ndarray
    centers: np.ndarray
    radii: np.ndarray
    taus: np.ndarray
    rim_center: np.ndarray
    rim_radius: float
    tau0: float
    k1: float = 1.0
    k2: float = 1.0

    def distances(self, x) -> np.ndarray:
        """(d_0, d_1..d_L) at x."""
        x = np.asarray(x, dtype=float)
        diff = x - self.centers
        r = x - self.rim_center
        return np.concatenate([[self.rim_radius**2 - r @ r], np.einsum("ij,ij->i", diff, diff) - self.radii**2])

    def __post_init__(self):
        object.__setattr__(self, "_bar", Barriers.make(self.rim_center, self.rim_radius, self.centers, self.radii,
                                                       np.concatenate([[self.tau0], self.taus])))

    def evaluate(self, x) -> tuple[float, np.ndarray, np.ndarray]:
        """(φ, ∇φ, ∇²φ) at x (φ = +∞ past a barrier's pole: inside a grown disk or outside the rim)."""
        return phi_terms(np.asarray(x, dtype=float), self.goal, self._bar, self.k1, self.k2)


def exit_path(start, centers, radii, rim_center, rim_radius: float, clearance: float, toward=None,
              step: float = 0.1, angles: int = 36, tries: int = 24) -> np.ndarray:
    """Straight legs (:func:`local_path`) from ``start`` to the nearest point (by path length; ties: nearer to
    ``toward``) that keeps ``clearance`` from every disk (centers, radii) and lies in the rim disk: the exit leg of
    a motion that starts closer than that to other entities.  Candidates lie on rings around the start every
    ``step``; the ``tries`` nearest clear ones are routed.  Raises ValueError without one."""
    s = np.asarray(start, dtype=float).reshape(2)
    c = np.asarray(centers, dtype=float).reshape(-1, 2)
    rho = np.asarray(radii, dtype=float).reshape(-1)
    rc = np.asarray(rim_center, dtype=float).reshape(2)
    ang = np.arange(angles) * (2.0 * math.pi / angles)
    dirs = np.column_stack([np.cos(ang), np.sin(ang)])
    rings = np.arange(1, int(math.ceil(2.0 * rim_radius / step)) + 1) * step
    pts = (s + rings[:, None, None] * dirs[None, :, :]).reshape(-1, 2)
    ok = np.linalg.norm(pts - rc, axis=1) <= rim_radius - 0.5 * PATH_CLEARANCE
    if len(c):
        ok &= np.all(np.linalg.norm(pts[:, None, :] - c[None, :, :], axis=-1) - rho[None, :] >= clearance, axis=1)
    pts = pts[ok]
    if not len(pts):
        raise ValueError(f"exit path: no point in the region keeps {clearance:g} m from the other entities")
    hint = np.asarray(toward, dtype=float).reshape(2) if toward is not None else s
    order = np.lexsort((np.linalg.norm(pts - hint, axis=1), np.round(np.linalg.norm(pts - s, axis=1), 9)))
    best, best_len = None, math.inf
    for p in pts[order[:tries]]:
        try:
            legs = local_path(s, p, c, rho, rc, rim_radius)
        except ValueError:
            continue
        length = float(np.sum(np.linalg.norm(np.diff(np.vstack([s, legs]), axis=0), axis=1)))
        if length < best_len - 1e-9:
            best, best_len = legs, length
    if best is None:
        raise ValueError(f"exit path: no straight-leg path to a point {clearance:g} m clear of the other entities")
    return best


def clear_goal(goal, centers, radii, rim_center, rim_radius: float, max_shift: float,
               margin: float = 0.25 * PATH_CLEARANCE) -> np.ndarray:
    """``goal``, or the point it is pushed to (radially out of every disk (centers, radii) it comes within
    ``margin`` of, repeatedly) when that moves it at most ``max_shift`` and keeps it within ``rim_radius`` of
    ``rim_center``: a planned goal that an entity ended a few centimetres away from its own planned point has
    come to overlap.  Raises ValueError otherwise."""
    g0 = np.asarray(goal, dtype=float).reshape(2)
    c = np.asarray(centers, dtype=float).reshape(-1, 2)
    rho = np.asarray(radii, dtype=float).reshape(-1)
    g = g0.copy()
    for _ in range(20):
        d = np.linalg.norm(c - g, axis=1) if len(c) else np.zeros(0)
        near = np.flatnonzero(d < rho + margin - 1e-9)
        if not len(near):
            break
        n = near[np.argmin(d[near] - rho[near])]
        u = (g - c[n]) / d[n] if d[n] > 1e-12 else (g - np.asarray(rim_center, dtype=float))
        u = u / max(float(np.linalg.norm(u)), 1e-12)
        g = c[n] + (rho[n] + margin) * u
    else:
        raise ValueError("local path: no clear goal near the planned one")
    if np.linalg.norm(g - g0) > max_shift or np.linalg.norm(g - np.asarray(rim_center, dtype=float)) > rim_radius:
        raise ValueError(f"local path: the goal ({g0[0]:.3f}, {g0[1]:.3f}) overlaps another entity")
    return g


def leg_barriers(leg_start, leg_end, centers, radii, rim_center, rim_radius, *, width_cap: float = WIDTH_CAP,
                 fraction: float = TAU_FRACTION) -> tuple[np.ndarray, float]:
    """Regions of influence (τ_1..τ_L, τ_0) for one leg (Prop. 1 per barrier, module docstring).

    Disk ℓ gets an annulus of width w_ℓ = min(f·(leg clearance to it), f·½ gap to every disk and to the rim
    where that gap is positive, width_cap), τ_ℓ = (ρ_ℓ + w_ℓ)² − ρ_ℓ²; the rim band τ_0 =
    f·min over the leg of d_0 (a chord's d_0 is smallest at an end point), capped likewise.  The whole leg,
    its goal included, lies outside every barrier region.
    """
    p = np.asarray(leg_start, dtype=float).reshape(1, 2)
    q = np.asarray(leg_end, dtype=float).reshape(1, 2)
    c = np.asarray(centers, dtype=float).reshape(-1, 2)
    rho = np.asarray(radii, dtype=float).reshape(-1)
    rc = np.asarray(rim_center, dtype=float).reshape(2)
    w = np.full(len(c), float(width_cap))
    if len(c):
        w = np.minimum(w, fraction * (segment_distances(p, q, c)[0] - rho))
        rim_gap = rim_radius - np.linalg.norm(c - rc, axis=1) - rho
        w = np.where(rim_gap > 0.0, np.minimum(w, fraction * 0.5 * rim_gap), w)
        if len(c) > 1:
            gap = np.linalg.norm(c[:, None, :] - c[None, :, :], axis=-1) - rho[:, None] - rho[None, :]
            np.fill_diagonal(gap, np.inf)
            gap = np.where(gap > 0.0, gap, np.inf)
            w = np.minimum(w, fraction * 0.5 * gap.min(axis=1))
    if np.any(w <= 0.0):
        raise ValueError("leg_barriers: the leg touches another entity")
    taus = (rho + w) ** 2 - rho**2
    d0 = min(rim_radius**2 - float((p[0] - rc) @ (p[0] - rc)), rim_radius**2 - float((q[0] - rc) @ (q[0] - rc)))
    cap0 = (rim_radius**2 - (rim_radius - width_cap) ** 2)
    tau0 = max(0.0, min(fraction * d0, cap0))
    return taus, tau0


def local_task(goal, centers, radii, rim_center, rim_radius, gains: AdaptiveGains, *, k1: float, k2: float,
               start, cf: Sequence[float] | int = 1, v_max: float = V_MAX, label: str = "") -> NavigationTask:
    """The adaptive law of paper Sec. III-A on the identity map for the leg start → goal (module docstring);
    ``cf``: load sharing of a transporting team (u_ℓ = cf_ℓ u)."""
    g = np.asarray(goal, dtype=float).reshape(2)
    c = np.asarray(centers, dtype=float).reshape(-1, 2)
    rho = np.asarray(radii, dtype=float).reshape(-1)
    taus, tau0 = leg_barriers(start, g, c, rho, rim_center, rim_radius)
    nf = DiskWorldNavigationFunction(g, c, rho, taus, np.asarray(rim_center, dtype=float).reshape(2),
                                     float(rim_radius), tau0, float(k1), float(k2))
    return NavigationTask(IdentityMap(), nf, g, gains, load_sharing(cf), float(v_max), label)


def disk_obstacles(positions: np.ndarray, radii: Sequence[float], robot_radius: float, exclude: Sequence[int],
                   rim_center, rim_radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Centres and grown radii r_e + r of the entities (rows of ``positions``) that can reach the disk of
    radius ``rim_radius`` (robot centres) around ``rim_center``, except ``exclude``."""
    X = np.asarray(positions, dtype=float)[:, :2]
    r = np.asarray(radii, dtype=float) + float(robot_radius)
    near = np.linalg.norm(X - np.asarray(rim_center, dtype=float), axis=1) < rim_radius + r
    keep = [e for e in range(len(X)) if near[e] and e not in set(exclude)]
    return X[keep].reshape(-1, 2), r[keep]
