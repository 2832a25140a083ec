"""Tests for P_s (mrodrake.packing): soundness, known optimal ratios, unequal radii, place(), cache."""

import itertools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize

from mrodrake import packing
from mrodrake.packing import SLACK, can_place, fits, pack, place, verify_packing

# Proven optimal container ratios R/r for n = 2..10 equal circles (Specht's packing tables).
EQUAL_OPT = dict(zip(range(2, 11), [2.0, 2.1547, 2.4142, 2.7013, 3.0, 3.0, 3.3047, 3.6131, 3.8130]))
NO_FIXED = (np.empty((0, 2)), np.empty(0))

# Computed gaps carry round-off of a few ulps of R (one hypot and two subtractions of numbers <= 2R),
# far below SLACK * R = 1e-9 R; half the slack is therefore a safe independent acceptance threshold.
SAFE = 0.5 * SLACK


def min_gap(R, centres, radii, fixed_c=(), fixed_r=()):
    """Smallest gap (pairwise, to fixed disks, to the rim) in plain Python, independent of the module."""
    gaps = []
    for i, (c, r) in enumerate(zip(centres, radii)):
        gaps.append(R - math.hypot(c[0], c[1]) - r)
        for j in range(i + 1, len(radii)):
            gaps.append(math.hypot(c[0] - centres[j][0], c[1] - centres[j][1]) - r - radii[j])
        for f, fr in zip(fixed_c, fixed_r):
            gaps.append(math.hypot(c[0] - f[0], c[1] - f[1]) - r - fr)
    return min(gaps) if gaps else math.inf


def dense_packing(radii, seed):
    """A locally densest packing built independently of mrodrake.packing: minimise the container radius
    over the centres with SLSQP, then scale the centres by 1 + 1e-6 (every pairwise gap grows by
    1e-6 |c_i - c_j|, which absorbs SLSQP's constraint residuals) and take the enclosing radius.
    Returns (centres, R) with pairwise gaps >= 0 and all disks inside R, or None if SLSQP failed."""
    rng = np.random.default_rng(seed)
    r = np.asarray(radii, dtype=float)
    n = len(r)
    i, j = np.triu_indices(n, 1)

    def cons(z):
        c, R = z[:-1].reshape(-1, 2), z[-1]
        d2 = np.sum((c[i] - c[j]) ** 2, axis=1)
        return np.concatenate([d2 - (r[i] + r[j]) ** 2, (R - r) ** 2 - np.sum(c * c, axis=1), R - r])

    z0 = np.concatenate([rng.uniform(-1.0, 1.0, 2 * n) * r.sum(), [2.0 * r.sum()]])
    grad = np.zeros(2 * n + 1)
    grad[-1] = 1.0
    res = minimize(lambda z: z[-1], z0, jac=lambda z: grad, method="SLSQP",
                   constraints=[{"type": "ineq", "fun": cons}], options={"maxiter": 500, "ftol": 1e-12})
    c = res.x[:-1].reshape(-1, 2) * (1.0 + 1e-6)
    R = max(math.hypot(*ci) + ri for ci, ri in zip(c, r))
    if min_gap(R, c, r) < 0.0:
        return None
    return c, R


# ---------------------------------------------------------------------------------------- known ratios


@pytest.mark.parametrize("n", sorted(EQUAL_OPT))
@pytest.mark.parametrize("r", [1.0, 0.3])
def test_equal_circles_fit_at_102_percent_of_optimum(n, r):
    R = 1.02 * EQUAL_OPT[n] * r
    c = pack(R, [r] * n)
    assert c is not None and c.shape == (n, 2)
    assert min_gap(R, c, [r] * n) >= SAFE * R
    assert fits(R, [r] * n)


@pytest.mark.parametrize("n", sorted(EQUAL_OPT))
def test_equal_circles_rejected_below_optimum(n):
    R = 0.99 * EQUAL_OPT[n]
    assert not fits(R, [1.0] * n)
    assert pack(R, [1.0] * n) is None
    # Rejected by the necessary conditions, and the search alone cannot certify an impossible packing.
    assert not packing._necessary(np.ones(n) / R)
    assert next(packing._solutions(np.ones(n) / R, *NO_FIXED, 0.0, 0), None) is None


@pytest.mark.parametrize("n", sorted(EQUAL_OPT))
def test_equal_circles_pass_necessary_conditions_at_optimum(n):
    # The table entries are lower bounds of the true optima, so the exact optimum must not be rejected.
    assert packing._necessary(np.ones(n) / (EQUAL_OPT[n] * (1.0 + 1e-4)))


@pytest.mark.parametrize("n", [14, 16, 19, 30])
def test_necessary_conditions_accept_dense_equal_packings(n, monkeypatch):
    # Folkman-Graham (k > 13) and the table (k <= 13) must never reject a packing that exists.  Dense
    # packings come from bisection on R with the necessary conditions disabled; each one is checked
    # independently.  They reach within 0.1 % of the best known ratios (14: 4.3284, 16: 4.6154,
    # 19: 4.8637 proven optimal, 30: 6.197), so a bound that is too strong by a few % is caught.
    necessary = packing._necessary
    monkeypatch.setattr(packing, "_necessary", lambda rs: True)
    fits.cache_clear()
    lo, hi, best = math.sqrt(n), 2.0 * math.sqrt(n) + 1.0, None
    for _ in range(12):
        mid = 0.5 * (lo + hi)
        c = pack(mid, [1.0] * n)
        if c is None:
            lo = mid
        else:
            hi, best = mid, c
    fits.cache_clear()
    assert best is not None and min_gap(hi, best, [1.0] * n) >= 0.0
    assert necessary(np.ones(n) / hi)


@pytest.mark.parametrize("R,radii", [
    (4.0, [4.1]),                   # largest disk
    (4.0, [2.5, 1.6]),              # r1 + r2 > R (the k = 2 table entry alone would pass: 4 / 1.6 > 2)
    (1.0, [0.69] + [0.3] * 6),      # area: 0.4761 + 0.54 > 1, every other condition passes
    (1.0, [0.3] * 9),               # table: 1 / 0.3 < 3.6131 for k = 9, area 0.81 passes
    (5.71, [1.0] * 30),             # Folkman-Graham: bound 28.5 < 30, area 0.92 and table (k <= 13) pass
])
def test_cheap_necessary_conditions_reject(R, radii):
    assert not packing._necessary(np.sort(radii)[::-1] / R)
    assert not fits(R, radii)


# ---------------------------------------------------------------------------------------- soundness

# radii as fractions of R: half small (many disks fit), half large (rejections and tight fits)
RADIUS_FRACTION = st.one_of(st.floats(0.02, 0.3), st.floats(0.3, 1.05))


@settings(max_examples=150, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(R=st.floats(0.05, 200.0), fracs=st.lists(RADIUS_FRACTION, max_size=12), seed=st.integers(0, 99))
def test_pack_is_sound_on_random_inputs(R, fracs, seed):
    radii = [f * R for f in fracs]
    c = pack(R, radii, seed)
    if seed == 0:
        assert fits(R, radii) == (c is not None)
    if c is None:
        return
    assert c.shape == (len(radii), 2)
    assert min_gap(R, c, radii) >= SAFE * R
    assert verify_packing(R, c, radii, SLACK * R)


@settings(max_examples=60, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(fracs=st.lists(RADIUS_FRACTION, min_size=2, max_size=8), seed=st.integers(0, 99))
def test_optimisation_stage_is_sound_on_random_inputs(fracs, seed):
    # greedy disabled, so every answer comes from the penalty-energy search and its verification
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(packing, "_greedy", lambda rads, *args: (np.zeros((len(rads), 2)), 0))
        c = next(packing._solutions(np.sort(fracs)[::-1], *NO_FIXED, 0.0, seed), None)
    if c is not None:
        assert min_gap(1.0, c, np.sort(fracs)[::-1]) >= SAFE


@settings(max_examples=80, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    fixed=st.lists(st.tuples(st.floats(-4.0, 4.0), st.floats(-4.0, 4.0), st.floats(0.1, 1.5)), max_size=5),
    new=st.lists(st.floats(0.1, 1.5), max_size=6),
    margin=st.sampled_from([0.0, 0.05, 0.3]),
    seed=st.integers(0, 9),
)
def test_place_is_sound_on_random_inputs(fixed, new, margin, seed):
    fc = np.array([(x, y) for x, y, _ in fixed]).reshape(-1, 2)
    fr = [r for _, _, r in fixed]
    c = place(4.0, fc, fr, new, seed=seed, margin=margin)
    if c is None:
        return
    assert c.shape == (len(new), 2)
    assert min_gap(4.0, c, new, fc, fr) >= margin + SAFE * 4.0


@settings(max_examples=60, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    fixed=st.lists(st.tuples(st.floats(-4.0, 4.0), st.floats(-4.0, 4.0), st.floats(0.1, 1.5)), max_size=5),
    new=st.lists(st.floats(0.1, 1.5), min_size=1, max_size=4),
    margin=st.sampled_from([0.0, 0.3]),
    seed=st.integers(0, 9),
)
def test_can_place_answers_what_place_finds(fixed, new, margin, seed):
    # can_place runs place's search without spreading: every placement place returns is one it finds, and
    # fewer relaxations can only find less
    fc = np.array([(x, y) for x, y, _ in fixed]).reshape(-1, 2)
    fr = [r for _, _, r in fixed]
    found = can_place(4.0, fc, fr, new, seed=seed, margin=margin)
    if place(4.0, fc, fr, new, seed=seed, margin=margin) is not None:
        assert found
    if can_place(4.0, fc, fr, new, seed=seed, margin=margin, restarts=0):
        assert found


def test_can_place_on_the_two_lens_region():
    t_star = 8.2125 / 11.7  # see test_place_spreads_to_the_max_min_gap
    fc, fr = np.array([[2.1, 0.0], [-2.1, 0.0]]), [1.85, 1.85]
    assert can_place(4.0, fc, fr, [0.75, 0.75], margin=t_star - 0.01)
    assert not can_place(4.0, fc, fr, [0.75, 0.75], margin=t_star + 0.01)
    assert not can_place(4.0, np.zeros((1, 2)), [3.9], [0.2])
    assert can_place(4.0, fc, fr, [])


# ---------------------------------------------------------------------------------------- unequal radii


@settings(max_examples=40, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(radii=st.lists(st.floats(0.1, 1.0), min_size=2, max_size=9), seed=st.integers(0, 2**31))
def test_finds_unequal_packing_near_a_dense_constructed_one(radii, seed):
    res = dense_packing(radii, seed)
    assume(res is not None)
    _, R = res
    assert packing._necessary(np.sort(radii)[::-1] / R)
    c = pack(1.02 * R, radii)
    assert c is not None
    assert min_gap(1.02 * R, c, radii) >= SAFE * 1.02 * R


def test_finds_random_sequential_packings_in_their_tight_container():
    rng = np.random.default_rng(11)
    for _ in range(150):
        cs, rs = [], []
        for r in rng.uniform(0.05, 0.5, rng.integers(1, 13)):
            for _ in range(200):
                rad, th = (1.0 - r) * math.sqrt(rng.random()), rng.uniform(0.0, 2.0 * math.pi)
                c = (rad * math.cos(th), rad * math.sin(th))
                if all(math.hypot(c[0] - d[0], c[1] - d[1]) - r - q >= 1e-6 for d, q in zip(cs, rs)):
                    cs.append(c)
                    rs.append(r)
                    break
        R = max(math.hypot(*c) + r for c, r in zip(cs, rs)) + 1e-6
        got = pack(R, rs)
        assert got is not None
        assert min_gap(R, got, rs) >= SAFE * R


# ---------------------------------------------------------------------------------------- place()


def test_place_single_disk_goes_to_the_centre():
    c = place(4.0, np.empty((0, 2)), [], [0.75])
    assert np.hypot(*c[0]) < 1e-6
    assert min_gap(4.0, c, [0.75]) == pytest.approx(3.25, abs=1e-6)


def test_place_spreads_to_the_max_min_gap():
    # Two fixed teams (r = 1.85) at (+-2.1, 0) in R = 4 leave a lens above and one below.  One disk of
    # r = 0.75 per lens on the y axis balances rim gap 3.25 - y and fixed gap sqrt(2.1^2 + y^2) - 2.6:
    # (2.6 + t)^2 = 2.1^2 + (3.25 - t)^2  =>  t* = 8.2125 / 11.7.  Two disks in one lens do worse.
    t_star = 8.2125 / 11.7
    fc, fr = np.array([[2.1, 0.0], [-2.1, 0.0]]), [1.85, 1.85]
    c = place(4.0, fc, fr, [0.75, 0.75])
    assert min_gap(4.0, c, [0.75, 0.75], fc, fr) == pytest.approx(t_star, abs=1e-4)
    assert c[0, 1] * c[1, 1] < 0.0  # one per lens
    ok = place(4.0, fc, fr, [0.75, 0.75], margin=t_star - 0.01)
    assert ok is not None and min_gap(4.0, ok, [0.75, 0.75], fc, fr) >= t_star - 0.01
    assert place(4.0, fc, fr, [0.75, 0.75], margin=t_star + 0.01) is None


def test_place_respects_fixed_disks_and_margin_in_a_typical_region():
    fc = np.array([[1.5, 1.0], [-2.0, -1.0], [0.3, -2.6]])
    fr = [0.75, 0.75, 0.2]
    new = [1.8, 0.2, 0.2]
    c = place(4.0, fc, fr, new, margin=0.05)
    assert c is not None
    assert min_gap(4.0, c, new, fc, fr) >= 0.05


def test_place_returns_none_when_fixed_disks_block_the_region():
    assert place(4.0, np.zeros((1, 2)), [3.9], [0.2]) is None


# ---------------------------------------------------------------------------------------- API details


def test_determinism(monkeypatch):
    radii = [1.8, 0.75, 0.75, 0.2, 0.2, 0.2]
    fits.cache_clear()
    a = pack(4.0, radii, seed=3)
    fits.cache_clear()
    assert np.array_equal(a, pack(4.0, radii, seed=3))
    fc = np.array([[2.1, 0.0], [-2.1, 0.0]])
    assert np.array_equal(place(4.0, fc, [1.85, 1.85], [0.75, 0.75, 0.2], seed=2),
                          place(4.0, fc, [1.85, 1.85], [0.75, 0.75, 0.2], seed=2))
    # the seeded optimisation stage alone (greedy disabled)
    monkeypatch.setattr(packing, "_greedy", lambda rads, *args: (np.zeros((len(rads), 2)), 0))
    radii = [1.0] * 9
    fits.cache_clear()
    a = pack(1.05 * EQUAL_OPT[9], radii, seed=4)
    fits.cache_clear()
    b = pack(1.05 * EQUAL_OPT[9], radii, seed=4)
    fits.cache_clear()
    assert a is not None and np.array_equal(a, b)


def test_cache_is_keyed_on_sorted_radii_and_returns_independent_copies():
    fits.cache_clear()
    assert fits(4.0, [1.8, 0.75, 0.2])
    before = fits.cache_info()
    assert fits(4.0, [0.2, 1.8, 0.75])
    after = fits.cache_info()
    assert after.hits == before.hits + 1 and after.misses == before.misses
    p1 = pack(4.0, [1.8, 0.75, 0.2])
    p2 = pack(4.0, [0.2, 1.8, 0.75])
    assert np.array_equal(p2, p1[[2, 0, 1]])
    p1[:] = 99.0
    assert np.array_equal(pack(4.0, [0.2, 1.8, 0.75]), p2)


def test_empty_inputs():
    assert fits(4.0, [])
    assert pack(4.0, []).shape == (0, 2)
    assert place(4.0, np.empty((0, 2)), [], []).shape == (0, 2)
    assert verify_packing(4.0, np.empty((0, 2)), [])


@pytest.mark.parametrize("call", [
    lambda: fits(0.0, [1.0]),
    lambda: fits(-1.0, [1.0]),
    lambda: fits(float("inf"), [1.0]),
    lambda: fits(4.0, [0.0]),
    lambda: fits(4.0, [1.0, -0.5]),
    lambda: pack(4.0, [float("nan")]),
    lambda: place(4.0, np.zeros((1, 2)), [1.0], [0.5], margin=-0.1),
    lambda: place(4.0, np.zeros((2, 2)), [1.0], [0.5]),
    lambda: place(4.0, np.empty((0, 2)), [], [0.0]),
    lambda: place(4.0, np.zeros((1, 2)), [], [0.5]),
    lambda: verify_packing(4.0, np.zeros((1, 2)), [1.0, 1.0]),
])
def test_invalid_inputs_raise_value_error(call):
    with pytest.raises(ValueError):
        call()


def test_verify_packing():
    touching = np.array([[1.0, 0.0], [-1.0, 0.0]])
    assert verify_packing(2.0, touching, [1.0, 1.0])
    assert not verify_packing(2.0, touching, [1.0, 1.0], margin=1e-12)
    assert not verify_packing(2.0, touching * 0.999, [1.0, 1.0])           # overlap
    assert not verify_packing(2.0, touching * 1.001, [1.0, 1.0])           # protrusion
    assert verify_packing(2.5, touching * 1.1, [1.0, 1.0], margin=0.09)
    assert not verify_packing(2.0, np.array([[np.nan, 0.0], [1.0, 0.0]]), [0.5, 0.5])


# ---------------------------------------------------------------------------------------- speed


TYPICAL = [list(t) + [0.75] * nr + [0.2] * no
           for k in range(3) for t in itertools.combinations_with_replacement((1.7, 1.8, 1.9), k)
           for nr in range(5) for no in range(4) if k + nr + no > 0]


def test_typical_calls_are_decided_by_greedy_placement(monkeypatch):
    def no_optimisation(*args, **kwargs):
        raise AssertionError("optimisation stage reached")

    monkeypatch.setattr(packing, "_relax", no_optimisation)
    fits.cache_clear()
    assert all(fits(4.0, radii) for radii in TYPICAL)
    fits.cache_clear()


# ------------------------------------------------------------------------------------ disks bound inward


@settings(max_examples=120, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(R=st.floats(0.5, 20.0), fracs=st.lists(RADIUS_FRACTION, min_size=1, max_size=8),
       bound=st.lists(st.floats(0.0, 1.0), min_size=8, max_size=8))
def test_disks_bound_inward_are_packed_soundly_and_never_fit_where_unbound_ones_do_not(R, fracs, bound):
    radii = sorted((f * R for f in fracs), reverse=True)
    # disk i keeps inside a concentric rim between its own radius and R
    rims = [r + b * (R - r) for r, b in zip(radii, bound)]
    pairs = sorted(zip(radii, rims), key=lambda p: (-p[0], p[1]))
    c = packing._pack_sorted(R, tuple(p[0] for p in pairs), 0, tuple(p[1] for p in pairs))
    assert fits(R, radii, rims) == (c is not None)
    if c is None:
        return
    assert fits(R, radii)  # a bound only takes placements away
    for (r, rim), ci in zip(pairs, c):
        assert rim - math.hypot(*ci) - r >= SAFE * R
    assert min_gap(R, c, [p[0] for p in pairs]) >= SAFE * R


def test_rims_of_the_region_itself_change_nothing():
    for radii in ([1.0, 0.9, 0.5], [0.3] * 7, [2.0, 0.4]):
        assert fits(3.0, radii, [3.0] * len(radii)) == fits(3.0, radii)


def test_two_disks_bound_near_the_centre_fit_only_if_their_reaches_part_them():
    # centres within reach_i = rim_i - r_i of the centre are at most reach_1 + reach_2 apart
    assert not fits(2.5, [0.3, 1.95], [0.3 + 0.6, 2.5])  # 0.6 + 0.55 < 2.25
    assert fits(2.5, [0.3, 1.95], [0.3 + 1.8, 2.5])  # 1.8 + 0.55 > 2.25
    assert fits(2.5, [0.3, 1.95])


def test_an_object_put_down_by_a_team_is_bound_to_where_the_team_fitted():
    # R = 2.5, spacing 0.1: a free object of radius 0.3 and a team of covering radius 1.95 fit together;
    # an object a team of covering radius 1.9 put down (centre within 2.5 - 1.9 - 0.05 = 0.55) does not
    assert packing.entities_fit(2.5, [0.3, 1.95], 0.1)
    assert not packing.entities_fit(2.5, [0.3, 1.95], 0.1, [1.9, None])
    assert packing.entities_fit(2.5, [0.3], 0.1, [2.44]) and not packing.entities_fit(2.5, [0.3], 0.1, [2.46])
    assert packing.entities_fit(4.0, [0.3, 1.95], 0.1, [1.9, None])
