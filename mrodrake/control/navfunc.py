"""2nd-order navigation function in the point world (paper Sec. III-A: Def. 3, eq. (8),
Proposition 1, eq. (9)).

φ(χ) = k1‖χ − χ_d‖² + k2 Σ_{ℓ∈J̄0} (β(d_ℓ(χ)) − β(τ)),  d_ℓ = ‖χ − b_ℓ‖² (ℓ ≥ 1), d_0 = 1 − ‖χ‖².

β is the polynomial barrier of eq. (8) with its region of influence scaled to τ:
β(x) = 1 / P(x/τ), P(s) = 6s⁵ − 15s⁴ + 10s³, for x < τ and β(x) = 1 for x ≥ τ.  The constant β(τ) = 1 is
subtracted in φ so that φ(χ_d) = 0 (property 2 of the definition); this shifts φ only, ∇φ is unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mrodrake.control.compiled import cached_njit

R_BAR_CAP = 0.1  # scenario default for r̄ (an upper bound; the map's b_ℓ may force a smaller one)
TAU_FRACTION = 0.9  # τ = TAU_FRACTION × min(r̄², r̄_d): strictly inside the interval of Prop. 1
_ORIGIN = np.zeros(2)


def beta(x, tau: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """β(x), β'(x), β''(x) of eq. (8) with region of influence τ (x > 0; vectorised over x and τ).

    C² at x = τ: P(1) = 1, P'(1) = P''(1) = 0.
    """
    x, t = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(tau, dtype=float))
    b, db, ddb = _beta_array(np.ascontiguousarray(x).ravel(), np.ascontiguousarray(t).ravel())
    return b.reshape(x.shape), db.reshape(x.shape), ddb.reshape(x.shape)


@cached_njit(nogil=True, error_model="numpy")
def _beta_point(x, tau):
    """β(x), β'(x), β''(x) of :func:`beta` at one x (the only implementation of eq. (8))."""
    if not x < tau:
        return 1.0, 0.0, 0.0
    s = x / tau
    P = min(s * s * s * (10.0 + s * (-15.0 + 6.0 * s)), 1.0)  # P ≤ 1 on [0, 1]; guard rounding
    dP = 30.0 * s * s * (s - 1.0) ** 2
    ddP = 60.0 * s * (2.0 * s - 1.0) * (s - 1.0)
    return 1.0 / P, -dP / (P * P) / tau, (2.0 * dP * dP / P - ddP) / (P * P) / (tau * tau)


@cached_njit(nogil=True)
def _beta_array(x, tau):
    b, db, ddb = np.empty(len(x)), np.empty(len(x)), np.empty(len(x))
    for i in range(len(x)):
        b[i], db[i], ddb[i] = _beta_point(x[i], tau[i])
    return b, db, ddb


def r_bar_max(obstacles: np.ndarray) -> float:
    """Supremum of the r̄ of Sec. III-A: min(½ min_{i≠j} ‖b_i − b_j‖, ½ min_i (1 − ‖b_i‖)); ∞ without b."""
    b = np.asarray(obstacles, dtype=float).reshape(-1, 2)
    if len(b) == 0:
        return np.inf
    r = 0.5 * float(np.min(1.0 - np.linalg.norm(b, axis=1)))
    if len(b) > 1:
        d = np.linalg.norm(b[:, None, :] - b[None, :, :], axis=-1)
        d[np.diag_indices(len(b))] = np.inf
        r = min(r, 0.5 * float(d.min()))
    return r


def r_bar_d(goal: np.ndarray, obstacles: np.ndarray) -> float:
    """r̄_d of eq. (7): min(1 − ‖χ_d‖², min_ℓ d_ℓ(χ_d))."""
    g = np.asarray(goal, dtype=float)
    b = np.asarray(obstacles, dtype=float).reshape(-1, 2)
    r = 1.0 - float(g @ g)
    if len(b):
        r = min(r, float(np.min(np.sum((b - g) ** 2, axis=1))))
    return r


def select_tau(goal, obstacles, *, r_bar_cap: float = R_BAR_CAP, tau_cap: float | None = None,
               fraction: float = TAU_FRACTION) -> tuple[float, float, float]:
    """(τ, r̄, r̄_d) per Proposition 1: r̄ = min(r̄_cap, r̄_max(b)), τ = min(τ_cap, fraction·min(r̄², r̄_d)).

    ``tau_cap`` defaults to r̄_cap².  Raises ValueError if the goal is not strictly inside the point world.
    """
    if not 0.0 < fraction < 1.0:
        raise ValueError("fraction must be in (0, 1)")
    rd = r_bar_d(goal, obstacles)
    if not rd > 0.0:
        raise ValueError(f"goal {np.asarray(goal).tolist()} is not inside the point world (r̄_d = {rd:.3g})")
    rb = min(r_bar_cap, r_bar_max(obstacles))
    if tau_cap is None:
        tau_cap = r_bar_cap**2
    tau = min(tau_cap, fraction * min(rb * rb, rd))
    return tau, rb, rd


#: Relative rounding bound of a barrier distance d = ‖χ − c‖² − ρ² (d_0 = ρ² − ‖χ − c‖²): with every term of
#: magnitude at most s = (‖χ‖ + ‖c‖)² + ρ², the computed d is within POLE_ULPS · ε · s of the exact one.
POLE_ULPS = 8.0
_EPS = float(np.finfo(float).eps)


@dataclass(frozen=True)
class Barriers:
    """The barriers of a navigation function, precomputed once: centres c_0..c_L (c_0: the rim's), signed
    squared radii (d_ℓ = s_ℓ(‖χ − c_ℓ‖² − ρ_ℓ²) with s_0 = −1 for the rim, +1 for disks), regions of
    influence τ_ℓ (−∞ switches a barrier off) and the rounding scales of :data:`POLE_ULPS`."""

    centers: np.ndarray
    rho2: np.ndarray
    sign: np.ndarray
    taus: np.ndarray
    cnorm: np.ndarray

    @classmethod
    def make(cls, rim_center, rim_radius: float, centers, radii, taus) -> Barriers:
        c = np.vstack([np.reshape(np.asarray(rim_center, dtype=float), (1, 2)),
                       np.asarray(centers, dtype=float).reshape(-1, 2)])
        rho = np.concatenate([[float(rim_radius)], np.asarray(radii, dtype=float).reshape(-1)])
        t = np.asarray(taus, dtype=float).reshape(-1)
        sign = np.ones(len(c))
        sign[0] = -1.0
        return cls(c, rho * rho, sign, np.where(t > 0.0, t, -np.inf), np.hypot(c[:, 0], c[:, 1]))


def phi_terms(chi: np.ndarray, goal: np.ndarray, bar: Barriers, k1: float,
              k2: float) -> tuple[float, np.ndarray, np.ndarray]:
    """(φ, ∇φ, ∇²φ) at χ of φ = k1‖χ − χ_d‖² + k2 Σ_ℓ (β_ℓ(d_ℓ) − 1) with the rim barrier
    d_0 = R² − ‖χ − c_0‖² and disk barriers d_ℓ = ‖χ − c_ℓ‖² − ρ_ℓ² (ρ_ℓ = 0: the point obstacles b_ℓ of the
    point world), :class:`Barriers` ``bar``.

    Only barriers with d_ℓ < τ_ℓ contribute (β' = β'' = 0 beyond).  Past a pole, i.e. where some active
    d_ℓ is not positive beyond its rounding bound (:data:`POLE_ULPS`), χ is outside the free set and φ = +∞
    with NaN derivatives (never a finite, negative φ that would push the entity further out).  Computed by
    the compiled :func:`_phi_point` (the control law's hot path: one point, tens of barriers)."""
    c0, c1 = np.asarray(chi, dtype=float).reshape(2).tolist()
    g0, g1 = np.asarray(goal, dtype=float).reshape(2).tolist()
    value, gx, gy, hxx, hxy, hyy = _phi_point(c0, c1, g0, g1, bar.centers, bar.rho2, bar.sign, bar.taus,
                                               bar.cnorm, float(k1), float(k2))
    return value, np.array([gx, gy]), np.array([[hxx, hxy], [hxy, hyy]])


@cached_njit(nogil=True)
def _phi_point(c0, c1, g0, g1, centers, rho2, sign, taus, cnorm, k1, k2):
    """(φ, ∂φ/∂χ_0, ∂φ/∂χ_1, ∂²φ/∂χ_0², ∂²φ/∂χ_0∂χ_1, ∂²φ/∂χ_1²) of :func:`phi_terms` at χ = (c0, c1), with
    β of :func:`_beta_point` per active barrier (grad d_ℓ = 2 s_ℓ (χ − c_ℓ), ∇²d_ℓ = 2 s_ℓ I)."""
    e0, e1 = c0 - g0, c1 - g1
    value = k1 * (e0 * e0 + e1 * e1)
    gx, gy = 2.0 * k1 * e0, 2.0 * k1 * e1
    hxx, hxy, hyy = 2.0 * k1, 0.0, 2.0 * k1
    norm = math.sqrt(c0 * c0 + c1 * c1)
    for k in range(len(taus)):
        dx, dy = c0 - centers[k, 0], c1 - centers[k, 1]
        d = sign[k] * (dx * dx + dy * dy - rho2[k])
        tau = taus[k]
        if not d < tau:
            continue
        scale = (norm + cnorm[k]) ** 2 + rho2[k]
        if d <= POLE_ULPS * _EPS * scale:
            return math.inf, math.nan, math.nan, math.nan, math.nan, math.nan
        b, db, ddb = _beta_point(d, tau)
        ax, ay = 2.0 * sign[k] * dx, 2.0 * sign[k] * dy
        value += k2 * (b - 1.0)
        gx += k2 * db * ax
        gy += k2 * db * ay
        hxx += k2 * (2.0 * sign[k] * db + ddb * ax * ax)
        hxy += k2 * ddb * ax * ay
        hyy += k2 * (2.0 * sign[k] * db + ddb * ay * ay)
    return value, gx, gy, hxx, hxy, hyy


@dataclass(frozen=True)
class NavigationFunction:
    """φ of Def. 3 for goal χ_d, point obstacles b_ℓ and the unit-circle boundary."""

    goal: np.ndarray
    obstacles: np.ndarray
    tau: float
    k1: float = 1.0
    k2: float = 1.0
    r_bar: float = float("nan")
    r_bar_d: float = float("nan")

    @classmethod
    def for_goal(cls, goal, obstacles, *, k1: float = 1.0, k2: float = 1.0, r_bar_cap: float = R_BAR_CAP,
                 tau_cap: float | None = None, fraction: float = TAU_FRACTION) -> NavigationFunction:
        """φ with τ chosen by ``select_tau`` from the actual b_ℓ."""
        if not (k1 > 0 and k2 > 0):
            raise ValueError("k1 and k2 must be positive")
        goal = np.asarray(goal, dtype=float).reshape(2)
        obstacles = np.asarray(obstacles, dtype=float).reshape(-1, 2)
        tau, rb, rd = select_tau(goal, obstacles, r_bar_cap=r_bar_cap, tau_cap=tau_cap, fraction=fraction)
        return cls(goal, obstacles, tau, k1, k2, rb, rd)

    @classmethod
    def for_map(cls, pw_map, x_goal, **kwargs) -> NavigationFunction:
        """φ for a workspace goal x_d: χ_d = H(x_d), b_ℓ = the map's hole points."""
        return cls.for_goal(pw_map(np.asarray(x_goal, dtype=float)), pw_map.hole_points, **kwargs)

    def __post_init__(self):
        b = self.obstacles
        object.__setattr__(self, "_bar",
                           Barriers.make(_ORIGIN, 1.0, b, np.zeros(len(b)), np.full(len(b) + 1, self.tau)))

    def evaluate(self, chi) -> tuple[float, np.ndarray, np.ndarray]:
        """(φ, ∇φ, ∇²φ) at χ (shape (2,)); only barriers with d_ℓ(χ) < τ contribute (β' = β'' = 0 beyond)."""
        return phi_terms(np.asarray(chi, dtype=float), self.goal, self._bar, self.k1, self.k2)

    def value(self, chi) -> float:
        return self.evaluate(chi)[0]

    def gradient(self, chi) -> np.ndarray:
        return self.evaluate(chi)[1]

    def hessian(self, chi) -> np.ndarray:
        return self.evaluate(chi)[2]


def desired_velocity(pw_map, nf: NavigationFunction, x, xdot):
    """v_d = −J_H(x)⁻¹ ∇φ(H(x)) (eq. (9)) and its exact time derivative along ẋ.

    With χ̇ = J ẋ, J̇ = Σ_i ∂J/∂x_i ẋ_i (the Hessians of H) and J v_d = −∇φ:
    v̇_d = −J⁻¹ (∇²φ χ̇ + J̇ v_d).  Returns (v_d, v̇_d, J_H, ∇φ, φ); φ = +∞ (NaN v_d) past a barrier's pole,
    NaN v_d and v̇_d where det J_H = 0.  The algebra is :func:`velocity_point`'s.
    """
    flat = getattr(pw_map, "evaluate_flat", None)
    if flat is not None:
        x0, x1 = np.asarray(x, dtype=float).tolist()
        h = flat(x0, x1)
    else:
        chi, J, Hs = pw_map.evaluate(np.asarray(x, dtype=float))
        (a, b), (c, d) = J.tolist()
        ((h000, h001), _), ((h100, h101), _) = Hs.tolist()
        h = [float(chi[0]), float(chi[1]), a, b, c, d, h000, h001, h100, h101]
    w0, w1 = np.asarray(xdot, dtype=float).tolist()
    bar = nf._bar
    g0, g1 = np.asarray(nf.goal, dtype=float).reshape(2).tolist()
    out = np.empty(8)
    velocity_point(*h, w0, w1, g0, g1, bar.centers, bar.rho2, bar.sign, bar.taus, bar.cnorm, float(nf.k1),
                   float(nf.k2), out)
    J = np.array([[h[2], h[3]], [h[4], h[5]]])
    return out[3:5].copy(), out[5:7].copy(), J, out[1:3].copy(), float(out[0])


@cached_njit(nogil=True, error_model="numpy")
def velocity_point(u, v, a, b, c, d, h000, h001, h100, h101, w0, w1, g0, g1, centers, rho2, sign, taus, cnorm,
                   k1, k2, out):
    """eq. (9) and its time derivative at one point, from H = (u, v), J_H = [[a, b], [c, d]] and the Hessian
    entries u_xx = h000, u_xy = h001, v_xx = h100, v_xy = h101 (u_yy = −u_xx, v_yy = −v_xx), ẋ = (w0, w1) and
    the barriers of φ (:func:`_phi_point`, goal (g0, g1)): out = φ, ∇φ (2), v_d (2), v̇_d (2), det J_H."""
    phi, p0, p1, G00, G01, G11 = _phi_point(u, v, g0, g1, centers, rho2, sign, taus, cnorm, k1, k2)
    h010, h011, h110, h111 = h001, -h000, h101, -h100
    det = a * d - b * c
    out[0], out[1], out[2], out[7] = phi, p0, p1, det
    if det == 0.0:  # degenerate map: NaN velocities (the law reports a fault)
        out[3] = out[4] = out[5] = out[6] = math.nan
        return
    v0 = -(d * p0 - b * p1) / det
    v1 = -(a * p1 - c * p0) / det
    c0 = a * w0 + b * w1  # χ̇ = J ẋ
    c1 = c * w0 + d * w1
    r0 = G00 * c0 + G01 * c1 + (h000 * w0 + h001 * w1) * v0 + (h010 * w0 + h011 * w1) * v1  # ∇²φ χ̇ + J̇ v_d
    r1 = G01 * c0 + G11 * c1 + (h100 * w0 + h101 * w1) * v0 + (h110 * w0 + h111 * w1) * v1
    out[3], out[4] = v0, v1
    out[5] = -(d * r0 - b * r1) / det
    out[6] = -(a * r1 - c * r0) / det
