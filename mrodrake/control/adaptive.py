"""Adaptive navigation and cooperative-transport control laws (paper Sec. III-A); the hot path is one compiled kernel.

Navigation of one entity with unknown mass m and friction bound α (Assumption 1):

    v_d = −J_H(x)⁻¹ ∇φ(H(x))                                              (eq. (9))
    e_v = ẋ − v_d
    u   = −k_φ J_H(x)ᵀ ∇φ(H(x)) + m̂ v̇_d − (k_v + 3/2 α̂) e_v                  (eq. (10))
    dm̂/dt = −k_m e_vᵀ v̇_d,   dα̂/dt = k_α ‖e_v‖²                            (eq. (11))

Cooperative transport: the same law for the coupled robots-object entity (eq. (5), estimates
m̂_A,j, α̂_A,j), split to the team by load-sharing coefficients: u_ℓ = cf_ℓ u, cf_ℓ ≥ 0, Σ cf_ℓ = 1, so
that Σ_ℓ u_ℓ = u.  The paper prints the transport law as u_ℓ = −cf_ℓ{k_φ Jᵀ∇φ + m̂ v̇_d − (k_v + 3/2 α̂) e_v};
taken literally that flips the sign of the m̂ v̇_d and damping terms (a destabilising positive velocity
feedback), which contradicts the paper's own argument ("by invoking Σ cf_ℓ = 1 ... similar to the robot
navigation case"); we implement u_ℓ = cf_ℓ × (navigation law), the reading that argument needs.

Velocity saturation (our addition, documented deviation).  H squeezes whole rooms of an office into thin
slivers near the unit circle, where J_H⁻¹ is large: the raw v_d reaches ~100 m/s in the case-study rooms,
and at such speeds the entity enters the (tiny, τ ~ 1e-7) barrier regions so fast that u reaches 1e9 and
the integrator stalls.  We therefore use

    v_d = σ(ṽ_d),  ṽ_d = −J_H⁻¹ ∇φ,  σ(v) = v / sqrt(1 + ‖v‖²/v_max²)

(smooth, σ(v) ≈ v for ‖v‖ ≪ v_max, ‖σ(v)‖ < v_max) with its exact derivative v̇_d = Dσ(ṽ_d) dṽ_d/dt,
Dσ(v) = q^{-1/2} (I − v vᵀ / (v_max² q)), q = 1 + ‖v‖²/v_max².  σ rescales ṽ_d by the positive scalar
c(x) = q^{-1/2} ∈ (0, 1], so χ̇ = J_H v_d = −c ∇φ still descends φ, and in the paper's Lyapunov argument
the term k_φ ∇φᵀ J_H v_d becomes −k_φ c ‖∇φ‖² ≤ 0 while the cross terms are cancelled by −k_φ J_Hᵀ∇φ as
before.  ``v_max = inf`` recovers the paper's law exactly.

Initial friction estimate at the design bound (our choice; README deviations).  Assumption 1 leaves α
unknown; the controllers are designed for a known bound ᾱ per body (``alpha_max``, scenario
``control.alpha_max``), so an entity of n bodies (a robot: n = 1; an object and its team A: n = 1 + |A|) has
α ≤ n ᾱ (α_A,j = Σ of the bodies' α).  The estimate starts there, α̂(0) = max(α̂_0, n ᾱ)
(:meth:`AdaptiveGains.initial_estimates`); the law and the adaptation are the paper's, only their free initial
condition is fixed.  With W = k_φ φ + m/2 ‖e_v‖² + m̃²/(2 k_m) (the paper's V without its α̃ term), the
paper's steps (‖f‖ ≤ α‖ẋ‖, ẋ = e_v + v_d, α‖e_v‖‖v_d‖ ≤ α/2 (‖e_v‖² + ‖v_d‖²)) give

    Ẇ = −k_φ c ‖∇φ‖² − (k_v + 3/2 α̂) ‖e_v‖² − e_vᵀ f  ≤  −k_φ c ‖∇φ‖² − (k_v + 3/2 (α̂ − α)) ‖e_v‖² + α/2 ‖v_d‖²,

and α̂ is non-decreasing, so α̂(t) ≥ α̂(0) ≥ n ᾱ ≥ α gives, for all t ≥ 0 and every true (m, α) with α ≤ n ᾱ,

    Ẇ ≤ −k_v ‖e_v‖² − k_φ c ‖∇φ‖² + α/2 ‖v_d‖²                                 (gain condition α̂(0) ≥ α)

— the paper's final inequality, now without drawing on the α̃ term.  In V = W + 3/(4 k_α) α̃² that term is an
energy reserve 3 α̃(0)²/(4 k_α) = 75 α² for α̂(0) = 0, k_α = 0.01 (12 500 for a team with α = 12.9: ‖e_v‖ up
to 100 m/s allowed) which the friction moves into e_v while α̂ < α: wherever the anti-damping part of the
paper's f (up to α‖ẋ‖ at low speed) exceeds k_v + 3/2 α̂, e_v grows like exp((anti-damping − k_v − 3/2 α̂) t/m).
With randomized true parameters that made whole missions diverge (speeds 10-17 m/s, the entity crossed a barrier
band within one step and left the region the map resolves).  Also, with K = k_v + 3/2 α̂ ≥ k_v + 3/2 α the
velocity-error loop m ė_v = −K e_v − f + (m̂ − m) v̇_d − k_φ J_Hᵀ∇φ is contracting and, up to its last two terms,
‖e_v‖ ≤ max(‖e_v(0)‖, α v_max / (K − α)) < max(‖e_v(0)‖, 2 v_max): speeds stay below 3 v_max.
The residual α/2 ‖v_d‖² is the paper's (dominated by k_φ c ‖∇φ‖² when k_φ ≥ α/2 · c ‖J_H⁻¹‖², the paper's
k_φ > α/2 for ‖J_H⁻¹‖ ≤ 1); with v_d saturated it is at most α v_max²/2.  ``alpha_max = 0`` (the
:class:`AdaptiveGains` default) is the paper's law with α̂(0) = α̂_0.

Barrier regions (our generalisation, :class:`LocalBarrierNavigationFunction`): one region of influence τ_ℓ
per point obstacle and τ_0 for the unit circle, each chosen by Proposition 1's rule from that barrier's own
neighbourhood, instead of one τ for the whole map.  The start is kept outside every region as well.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from mrodrake.control.compiled import cached_njit
from mrodrake.control.navfunc import TAU_FRACTION, Barriers, phi_terms, velocity_point
from mrodrake.control.treecode import tree_point

_ORIGIN = np.zeros(2)

#: Default speed bound v_max (m/s) of the desired velocity (module docstring).
V_MAX = 2.0

#: κ in ρ₀ = 1 − κ δ_max, the radius of the circle barrier (:class:`LocalBarrierNavigationFunction`).  δ_max
#: (``PointWorldMap.circle_deficit``) is measured on a finite sample of the outer boundary; κ = 2 leaves as much
#: again for the ridge of |H| between samples, so that |H| > ρ₀ holds on a whole curve around ∂F.
CIRCLE_DEFICIT_FACTOR = 2.0


def circle_radius(pw_map) -> float:
    """ρ₀ = 1 − κ δ_max for a point-world map (δ_max = ``circle_deficit``, 0 for maps without it)."""
    delta = float(getattr(pw_map, "circle_deficit", 0.0))
    if not 0.0 <= CIRCLE_DEFICIT_FACTOR * delta < 1.0:
        raise ValueError(f"point-world map misses the unit circle by δ_max = {delta:.3g} on its outer boundary")
    return 1.0 - CIRCLE_DEFICIT_FACTOR * delta


@dataclass(frozen=True)
class AdaptiveGains:
    """k_φ, k_v, k_m, k_α of the control and adaptation laws, the initial estimates m̂_0, α̂_0 and the design
    friction bound ᾱ per body (``alpha_max``; 0: none, the paper's law with α̂(0) = α̂_0)."""

    k_phi: float = 1.0
    k_v: float = 1.0
    k_m: float = 0.01
    k_alpha: float = 0.01
    m_hat0: float = 0.5
    alpha_hat0: float = 0.0
    alpha_max: float = 0.0

    @classmethod
    def from_scenario(cls, control) -> AdaptiveGains:
        """From the scenario's ``control`` section (:class:`mrodrake.scenario.ControlGains`)."""
        return cls(control.k_phi, control.k_v, control.k_m, control.k_alpha, control.m_hat0, control.alpha_hat0,
                   control.alpha_max)

    def initial_estimates(self, bodies: int = 1) -> tuple[float, float]:
        """(m̂(0), α̂(0)) of an entity of ``bodies`` bodies: (m̂_0, max(α̂_0, bodies · ᾱ)) (module docstring:
        α̂(0) ≥ α for every true friction of the design range makes the velocity-error loop contracting)."""
        if bodies < 1:
            raise ValueError(f"an entity has at least one body, got {bodies}")
        return float(self.m_hat0), max(float(self.alpha_hat0), int(bodies) * float(self.alpha_max))


def navigation_input(J: np.ndarray, grad_phi: np.ndarray, vdot_d: np.ndarray, e_v: np.ndarray,
                     m_hat: float, alpha_hat: float, k_phi: float, k_v: float) -> np.ndarray:
    """u = −k_φ J_Hᵀ ∇φ + m̂ v̇_d − (k_v + 3/2 α̂) e_v (paper Sec. III-A, eq. (10))."""
    return -k_phi * (J.T @ grad_phi) + m_hat * vdot_d - (k_v + 1.5 * alpha_hat) * e_v


def adaptation_rates(e_v: np.ndarray, vdot_d: np.ndarray, k_m: float, k_alpha: float) -> tuple[float, float]:
    """(dm̂/dt, dα̂/dt) = (−k_m e_vᵀ v̇_d, k_α ‖e_v‖²) (eq. (11))."""
    return -k_m * float(e_v @ vdot_d), k_alpha * float(e_v @ e_v)


def saturate_velocity(v: np.ndarray, vdot: np.ndarray, v_max: float) -> tuple[np.ndarray, np.ndarray]:
    """(σ(v), Dσ(v) v̇) with σ(v) = v / sqrt(1 + ‖v‖²/v_max²) (module docstring); identity for v_max = inf."""
    if not math.isfinite(v_max):
        return v, vdot
    v0, v1, a0, a1 = _saturate(*np.asarray(v, dtype=float).tolist(), *np.asarray(vdot, dtype=float).tolist(), v_max)
    return np.array([v0, v1]), np.array([a0, a1])


@cached_njit(nogil=True)
def _saturate(v0: float, v1: float, a0: float, a1: float, v_max: float) -> tuple[float, float, float, float]:
    """:func:`saturate_velocity` on the components (σ(v), Dσ(v) v̇) of v = (v0, v1), v̇ = (a0, a1)."""
    if not math.isfinite(v_max):
        return v0, v1, a0, a1
    w = 1.0 / (v_max * v_max)
    q = 1.0 + w * (v0 * v0 + v1 * v1)
    c = 1.0 / math.sqrt(q)
    dot = w * (v0 * a0 + v1 * a1) / q
    return c * v0, c * v1, c * (a0 - v0 * dot), c * (a1 - v1 * dot)


_OUTSIDE, _DEGENERATE = 1, 2  # statuses of _law_values and _law_point besides 0 (the law is defined)


@cached_njit(nogil=True, error_model="numpy")
def _law_values(u, v, a, b, c, d, h000, h001, h100, h101, w0, w1, m_hat, alpha_hat, gd0, gd1, centers, rho2,
                sign, taus, cnorm, k1, k2, k_phi, k_v, k_m, k_alpha, v_max, out):
    """The law at one state from the map's values there (H = (u, v), J_H = [[a, b], [c, d]], Hessian entries as
    in :func:`~mrodrake.control.navfunc.velocity_point`), ẋ = (w0, w1) and the estimates: eq. (9) with σ, eq. (10)
    and eq. (11) on floats (the control law's hot path).  out = u (2), dm̂/dt, dα̂/dt, v_d (2), v̇_d (2), e_v (2),
    det J_H; returns 0, or _OUTSIDE past a barrier's pole, or _DEGENERATE where v_d or v̇_d is not finite."""
    vel = np.empty(8)
    velocity_point(u, v, a, b, c, d, h000, h001, h100, h101, w0, w1, gd0, gd1, centers, rho2, sign, taus, cnorm,
                   k1, k2, vel)
    out[10] = vel[7]
    if not math.isfinite(vel[0]):
        return _OUTSIDE
    g0, g1, v0, v1, a0, a1 = vel[1], vel[2], vel[3], vel[4], vel[5], vel[6]
    if not (math.isfinite(v0) and math.isfinite(v1) and math.isfinite(a0) and math.isfinite(a1)):
        return _DEGENERATE
    v0, v1, a0, a1 = _saturate(v0, v1, a0, a1, v_max)
    e0, e1 = w0 - v0, w1 - v1
    damp = k_v + 1.5 * alpha_hat
    out[0] = -k_phi * (a * g0 + c * g1) + m_hat * a0 - damp * e0
    out[1] = -k_phi * (b * g0 + d * g1) + m_hat * a1 - damp * e1
    out[2] = -k_m * (e0 * a0 + e1 * a1)
    out[3] = k_alpha * (e0 * e0 + e1 * e1)
    out[4], out[5], out[6], out[7], out[8], out[9] = v0, v1, a0, a1, e0, e1
    return 0


@cached_njit(nogil=True, error_model="numpy")
def _law_point(x0, x1, w0, w1, m_hat, alpha_hat, vert, links, nodef, nodei, coef, params, gd0, gd1, centers, rho2,
               sign, taus, cnorm, k1, k2, k_phi, k_v, k_m, k_alpha, v_max, out):
    """:func:`_law_values` at x = (x0, x1) with the map's values from its treecode (:func:`tree_point`)."""
    h = np.empty(10)
    tree_point(x0, x1, True, vert, links, nodef, nodei, coef, params, h)
    return _law_values(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8], h[9], w0, w1, m_hat, alpha_hat, gd0,
                       gd1, centers, rho2, sign, taus, cnorm, k1, k2, k_phi, k_v, k_m, k_alpha, v_max, out)


def load_sharing(cf: Sequence[float] | int) -> np.ndarray:
    """Validated load-sharing coefficients cf_ℓ ≥ 0 with Σ cf_ℓ = 1 (an int n gives equal shares 1/n)."""
    if isinstance(cf, (int, np.integer)):
        if cf < 1:
            raise ValueError("a team needs at least one member")
        return np.full(int(cf), 1.0 / int(cf))
    arr = np.asarray(cf, dtype=float).reshape(-1)
    if len(arr) == 0 or not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
        raise ValueError(f"load-sharing coefficients must be finite and >= 0, got {arr.tolist()}")
    if not math.isclose(float(arr.sum()), 1.0, rel_tol=0.0, abs_tol=1e-9):
        raise ValueError(f"load-sharing coefficients must sum to 1, got sum {arr.sum():.12g}")
    return arr


def transport_inputs(u: np.ndarray, cf: np.ndarray) -> np.ndarray:
    """u_ℓ = cf_ℓ u for every team member ℓ (rows), paper Sec. III-A, 2) Cooperative Object Transportation;
    Σ_ℓ u_ℓ = u."""
    return np.outer(cf, u)


@dataclass(frozen=True)
class LocalBarrierNavigationFunction:
    """φ(χ) = k1‖χ − χ_d‖² + k2 Σ_{ℓ∈J̄0} (β_ℓ(d_ℓ(χ)) − 1) with one region of influence τ_ℓ per barrier
    (β_ℓ(x) = β(x/τ_ℓ), β of eq. (8)); ℓ = 0 is the circle of radius ρ₀ ≤ 1 (d_0 = ρ₀² − ‖χ‖²).

    Circle radius ρ₀ = 1 − κ δ_max (our correction, :data:`CIRCLE_DEFICIT_FACTOR`): the discrete map H falls
    short of the unit circle on the outer boundary ∂F by up to δ_max (``PointWorldMap.circle_deficit``), so
    with d_0 = 1 − ‖χ‖² the barrier β_0 stays finite (or even 1) on ∂F and nothing stops an entity at the
    wall.  With ρ₀ below the ridge of |H| along ∂F, every path in F from a start with ‖H‖ < ρ₀ to ∂F crosses
    ‖H‖ = ρ₀ (continuity), where d_0 = 0 and β_0 = ∞: property 1 of Def. 3 (φ → ∞ on the
    boundary of the point world) holds on the sublevel sets the Lyapunov argument uses, and Proposition 1's
    construction is unchanged with the unit disk replaced by the disk of radius ρ₀.  ρ₀ = 1 is the paper's φ.

    A generalisation of Def. 3 with Proposition 1 applied per barrier (our choice, see
    :func:`local_barriers`): the paper's single τ < r̄² is set by the two closest points b_ℓ of the whole
    map, which in an office are ~1e-3 apart (rooms are squeezed against the unit circle), giving
    τ ~ 1e-7 everywhere — thinner than the panel map's own error around holes (1e-4 to 3e-3) and along the
    circle (1e-4 median), so entities slipped through walls and into obstacles in the property tests.
    Per-barrier τ_ℓ keep the properties the proof uses: each β_ℓ satisfies properties 1 and 4, the
    barrier regions are pairwise disjoint and exclude χ_d (property 3, Prop. 1), and φ(χ_d) = 0.
    Same interface as :class:`mrodrake.control.navfunc.NavigationFunction` (``evaluate``).
    """

    goal: np.ndarray
    obstacles: np.ndarray
    taus: np.ndarray  # (L + 1,): τ_0 (circle of radius rho0), τ_1..τ_L (holes)
    k1: float = 1.0
    k2: float = 1.0
    rho0: float = 1.0

    @property
    def tau(self) -> float:
        """The smallest region of influence."""
        return float(self.taus.min())

    def __post_init__(self):
        b = self.obstacles
        object.__setattr__(self, "_bar", Barriers.make(_ORIGIN, self.rho0, b, np.zeros(len(b)), self.taus))

    def evaluate(self, chi) -> tuple[float, np.ndarray, np.ndarray]:
        """(φ, ∇φ, ∇²φ) at χ (shape (2,))."""
        return phi_terms(np.asarray(chi, dtype=float), self.goal, self._bar, self.k1, self.k2)


def local_barriers(goal, obstacles, starts=(), *, rho_cap: float, tau_cap: float,
                   fraction: float = TAU_FRACTION, rho0: float = 1.0) -> np.ndarray:
    """Regions of influence (τ_0, τ_1..τ_L) for :class:`LocalBarrierNavigationFunction` (Prop. 1 per barrier),
    circle of radius ρ₀ ≤ 1 (``rho0``).

    Hole ℓ gets radius ρ_ℓ = √τ_ℓ = min(√f · g_ℓ, √f ‖χ_d − b_ℓ‖, √f ‖χ_s − b_ℓ‖, ρ_cap, √τ_cap) with
    g_ℓ = min(½ min_m ‖b_ℓ − b_m‖, ½ |ρ₀ − ‖b_ℓ‖|) (f = ``fraction``), so barrier disks are pairwise disjoint
    and leave room to the circle; the circle band {ρ₀² − ‖χ‖² < τ_0} gets
    τ_0 = min(f min_ℓ (ρ₀² − (‖b_ℓ‖ + ρ_ℓ)²), f (ρ₀² − ‖χ_d‖²), f (ρ₀² − ‖χ_s‖²), τ_cap) (ℓ over the holes
    with ‖b_ℓ‖ < ρ₀), disjoint from every hole barrier.  χ_d and the starts χ_s lie outside every region
    (β' = β'' = 0 there); a ValueError is raised unless they lie strictly inside the circle of radius ρ₀.
    A hole with ‖b_ℓ‖ > ρ₀ (its neighbourhood in F is squeezed against ∂F beyond the circle barrier, so
    unreachable) gets a disk outside the circle of radius ρ₀, where it never acts.
    """
    if not 0.0 < rho0 <= 1.0:
        raise ValueError(f"circle radius rho0 must be in (0, 1], got {rho0!r}")
    g = np.asarray(goal, dtype=float).reshape(2)
    b = np.asarray(obstacles, dtype=float).reshape(-1, 2)
    pts = [g] + [np.asarray(p, dtype=float).reshape(2) for p in starts]
    r2 = rho0 * rho0
    for p in pts:
        if not p @ p < r2:
            raise ValueError(f"point {p.tolist()} (‖χ‖ = {math.sqrt(p @ p):.6g}) is not inside the circle barrier "
                             f"ρ₀ = {rho0:.6g} (ρ₀ = 1 − κ δ_max, δ_max the map's circle deficit)")
        if len(b) and np.min(np.linalg.norm(b - p, axis=1)) <= 0.0:
            raise ValueError(f"point {p.tolist()} is not inside the point world")
    sf = math.sqrt(fraction)
    nb = np.linalg.norm(b, axis=1)
    rho = np.full(len(b), min(rho_cap, math.sqrt(tau_cap)))
    if len(b):
        gap = 0.5 * np.abs(rho0 - nb)
        if len(b) > 1:
            dist = np.linalg.norm(b[:, None, :] - b[None, :, :], axis=-1)
            np.fill_diagonal(dist, np.inf)
            gap = np.minimum(gap, 0.5 * dist.min(axis=1))
        rho = np.minimum(rho, sf * gap)
        for p in pts:
            rho = np.minimum(rho, sf * np.linalg.norm(b - p, axis=1))
    tau0 = tau_cap
    inner = nb < rho0
    if np.any(inner):
        tau0 = min(tau0, fraction * float(np.min(r2 - (nb[inner] + rho[inner]) ** 2)))
    for p in pts:
        tau0 = min(tau0, fraction * (r2 - float(p @ p)))
    return np.concatenate([[tau0], rho * rho])


class ControlEval(NamedTuple):
    """Everything one evaluation of the law produces (per state and estimates).

    ``fault`` is empty where the law is defined; otherwise it says why not (the state is past a barrier's
    pole, i.e. outside the free set, or the map is degenerate there), the rates are zero and u is a stiff
    brake −:data:`FAULT_DAMPING` ẋ: finite (Drake accepts steps with a NaN error estimate and shrinks the next
    step forever on a NaN derivative at its start), but a jump that makes an error-controlled integrator
    reject a trial step that gets there.  A step that still *ends* there is caught by the mission's monitor,
    which ends the primitive after that step or the next (the controller system's ``fault``).
    """

    u: np.ndarray  # entity input (2,)
    m_hat_dot: float
    alpha_hat_dot: float
    v_d: np.ndarray
    vdot_d: np.ndarray
    e_v: np.ndarray
    fault: str = ""


_ZERO2 = np.zeros(2)
#: Damping (N s/m) of the brake applied where the law is undefined (:class:`ControlEval`).
FAULT_DAMPING = 1e6


@dataclass(frozen=True)
class NavigationTask:
    """One transition's precomputed control data: the point-world map H of the entity's free space, φ
    (goal χ_d = H(x_d), b_ℓ, τ per Prop. 1), the workspace goal, gains and load sharing (``cf`` has one
    entry per robot driving the entity: [1.0] for a navigation).  Built once when the transition starts;
    :meth:`evaluate` is the hot path."""

    pw_map: object
    nf: LocalBarrierNavigationFunction
    goal: np.ndarray
    gains: AdaptiveGains
    cf: np.ndarray
    v_max: float = V_MAX
    label: str = ""

    @classmethod
    def build(cls, pw_map, goal, gains: AdaptiveGains, *, k1: float, k2: float, r_bar_cap: float,
              tau_cap: float, cf: Sequence[float] | int = 1, start=None, v_max: float = V_MAX,
              label: str = "") -> NavigationTask:
        """Task for workspace goal x_d on map H: χ_d = H(x_d), b_ℓ the map's hole points, φ with per-barrier
        regions of influence (:func:`local_barriers`, caps ρ ≤ r_bar_cap, τ ≤ tau_cap) and the circle
        barrier at ρ₀ = 1 − κ δ_max (:func:`circle_radius`, δ_max the map's ``circle_deficit``).

        With ``start`` given, χ_s = H(start) is also kept outside every barrier region: entities packed by
        P_s sit ~10 cm apart, and a start inside a barrier region makes ∇φ, hence v_d and u, astronomically
        large at t = 0.
        """
        goal = np.asarray(goal, dtype=float).reshape(2)
        if not v_max > 0.0:
            raise ValueError(f"v_max must be > 0, got {v_max!r}")
        chi_d = pw_map(goal)
        starts = [] if start is None else [pw_map(np.asarray(start, dtype=float).reshape(2))]
        rho0 = circle_radius(pw_map)
        taus = local_barriers(chi_d, pw_map.hole_points, starts, rho_cap=r_bar_cap, tau_cap=tau_cap, rho0=rho0)
        nf = LocalBarrierNavigationFunction(chi_d, np.asarray(pw_map.hole_points, dtype=float).reshape(-1, 2),
                                            taus, float(k1), float(k2), rho0)
        return cls(pw_map, nf, goal, gains, load_sharing(cf), float(v_max), label)

    def evaluate(self, x: np.ndarray, xdot: np.ndarray, m_hat: float, alpha_hat: float) -> ControlEval:
        """The entity's law u and the adaptation rates at state (x, ẋ) and estimates (m̂, α̂); a
        :class:`ControlEval` with a ``fault`` where the law is undefined.  Computed by the compiled
        :func:`_law_point` (on the map's treecode) or :func:`_law_values` (other maps)."""
        x0, x1 = np.asarray(x, dtype=float).reshape(2).tolist()
        w0, w1 = np.asarray(xdot, dtype=float).reshape(2).tolist()
        return self.evaluate_floats(x0, x1, w0, w1, float(m_hat), float(alpha_hat))

    def evaluate_floats(self, x0: float, x1: float, w0: float, w1: float, m_hat: float,
                        alpha_hat: float) -> ControlEval:
        """:meth:`evaluate` at x = (x0, x1), ẋ = (w0, w1) given as Python floats (a controller's hot path)."""
        out = np.empty(11)
        if self._tree is not None:
            status = _law_point(x0, x1, w0, w1, m_hat, alpha_hat, *self._tree, *self._consts, out)
        else:
            chi, J, Hs = self.pw_map.evaluate(np.array([x0, x1]))
            h = [float(chi[0]), float(chi[1]), *J.ravel().tolist(), Hs[0, 0, 0], Hs[0, 0, 1], Hs[1, 0, 0], Hs[1, 0, 1]]
            status = _law_values(*h, w0, w1, m_hat, alpha_hat, *self._consts, out)
        if status == _OUTSIDE:
            return self._fault((x0, x1), (w0, w1),
                               "is outside the free set (past a barrier of the navigation function)")
        if status == _DEGENERATE:
            return self._fault((x0, x1), (w0, w1), f"is where the point-world map is degenerate "
                                                   f"(det J_H = {out[10]:.3g}): the entity left the region the map "
                                                   f"resolves")
        return ControlEval(out[0:2], float(out[2]), float(out[3]), out[4:6], out[6:8], out[8:10])

    def __post_init__(self):
        g, nf = self.gains, self.nf
        bar = nf._bar
        gd0, gd1 = np.asarray(nf.goal, dtype=float).reshape(2).tolist()
        consts = (gd0, gd1, bar.centers, bar.rho2, bar.sign, bar.taus, bar.cnorm, float(nf.k1), float(nf.k2),
                  float(g.k_phi), float(g.k_v), float(g.k_m), float(g.k_alpha), float(self.v_max))
        tree = getattr(self.pw_map, "tree", None)
        object.__setattr__(self, "_consts", consts)
        object.__setattr__(self, "_tree", None if tree is None else (tree.vert, tree.links, tree.nodef, tree.nodei,
                                                                     tree.coef, tree.params))

    def _fault(self, x, xdot, why: str) -> ControlEval:
        where = f"x = ({x[0]:.4f}, {x[1]:.4f}) {why}"
        return ControlEval(-FAULT_DAMPING * np.asarray(xdot, dtype=float), 0.0, 0.0, _ZERO2, _ZERO2, _ZERO2, where)

    def __deepcopy__(self, memo):
        """Tasks are immutable once built: Drake's abstract-value clones share them instead of copying."""
        return self

    def member_inputs(self, u: np.ndarray) -> np.ndarray:
        """u_ℓ = cf_ℓ u, one row per team member."""
        return transport_inputs(u, self.cf)
