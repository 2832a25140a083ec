"""Transition system (paper Def. 4): rules against an independent oracle, implicit vs explicit, labels, costs."""

from __future__ import annotations

import itertools
import math
from collections import deque
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from mrodrake.errors import UserError
from mrodrake.geometry import grasp_layout
from mrodrake.packing import entities_fit, verify_packing
from mrodrake.planning.generate import generate_scenario
from mrodrake.scenario import load_scenario, scenario_from_dict
from mrodrake.ts import Grasp, Navigate, Release, TransitionSystem, Transport

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tiny():
    return TransitionSystem(load_scenario(ROOT / "scenarios" / "tiny.yaml"))


@pytest.fixture(scope="module")
def case1():
    return TransitionSystem(load_scenario(ROOT / "scenarios" / "case_study_1.yaml"))


# ---------------------------------------------------------------------------------------------- oracle
def oracle_put_down(sc, j: int, k: int) -> float | None:
    """An ungrasped object outside its initial region was put down by a team able to carry it: the smallest
    covering radius of such a team (None in its initial region, or when no team can carry it)."""
    if sc.region_names[k] == sc.objects[j].initial_region:
        return None
    covers = [grasp_layout(sc.objects[j].radius, [sc.robots[i].radius for i in team], sc.layout.grasp_gap)
              .covering_radius for n in range(1, len(sc.robots) + 1)
              for team in itertools.combinations(range(len(sc.robots)), n)
              if sum(sc.robots[i].power for i in team) >= sc.objects[j].required_power]
    return min(covers, default=None)


def oracle_fit(sc, k: int, G, inside) -> bool:
    """The entities ``inside`` region k (robot or object indices into R + O) fit, under the grasps G."""
    N = len(sc.robots)
    radii, bounds = [], []
    for e in inside:
        if e < N:
            if G[e] < 0:
                radii.append(sc.robots[e].radius)
                bounds.append(None)
            continue
        j = e - N
        team = [sc.robots[i].radius for i in range(N) if G[i] == j]
        radii.append(grasp_layout(sc.objects[j].radius, team, sc.layout.grasp_gap).covering_radius
                     if team else sc.objects[j].radius)
        bounds.append(None if team else oracle_put_down(sc, j, k))
    return not radii or entities_fit(sc.regions[k].radius, radii, sc.layout.spacing, bounds)


def oracle_valid(ts: TransitionSystem, s) -> bool:
    """Validity written directly from the issue: grasps co-located, each region's entities fit (an object
    lying outside its initial region where a team that can carry it fits around it)."""
    N, M = ts.N, ts.M
    R, O, G = s[:N], s[N : N + M], s[N + M :]
    if any(g >= 0 and R[i] != O[g] for i, g in enumerate(G)):
        return False
    return all(oracle_fit(ts.scenario, k, G, [e for e in range(N + M) if s[e] == k]) for k in range(ts.K))


def oracle_transition(ts: TransitionSystem, s, t) -> bool:
    """The transition rules of the issue, one by one, independent of the implementation."""
    if not (oracle_valid(ts, s) and oracle_valid(ts, t)):
        return False
    N, M = ts.N, ts.M
    R, O, G = s[:N], s[N : N + M], s[N + M :]
    R2, O2, G2 = t[:N], t[N : N + M], t[N + M :]
    for i in range(N):
        a, b = G[i], G2[i]
        if a < 0 and b < 0:
            continue  # free robot: stays or navigates anywhere
        if a < 0 <= b:  # grasp
            if not (R[i] == O[b] and R2[i] == R[i] and O2[b] == O[b]):
                return False
        elif b < 0 <= a:  # release
            if not (R2[i] == R[i] and O2[a] == O[a]):
                return False
        else:
            if a != b:
                return False  # never switch objects in one step
            if (R2[i] != R[i]) != (O2[a] != O[a]) or R2[i] != O2[a]:
                return False
    for j in range(M):
        if O2[j] != O[j]:
            team = {i for i in range(N) if G[i] == j}
            team2 = {i for i in range(N) if G2[i] == j}
            if not team or team != team2:
                return False
            if sum(ts.scenario.robots[i].power for i in team) < ts.scenario.objects[j].required_power:
                return False
    return oracle_step_fits(ts, s, t)


def oracle_step_fits(ts: TransitionSystem, s, t) -> bool:
    """Sequential execution: where a region loses and gains entities in one step, or a robot grasps or releases
    there, all its entities of the start and of the end fit together, with the teams of s and with those of t."""
    N, M, sc = ts.N, ts.M, ts.scenario
    for k in range(ts.K):
        leaves = any(s[e] == k != t[e] for e in range(N + M))
        enters = any(t[e] == k != s[e] for e in range(N + M))
        holds = any(k in (s[i], t[i]) and s[N + M + i] != t[N + M + i] for i in range(N))
        if not (leaves and enters) and not holds:
            continue
        for G in (s[N + M:], t[N + M:]):
            if not oracle_fit(sc, k, G, [e for e in range(N + M) if k in (s[e], t[e])]):
                return False
    return True


def all_states(ts: TransitionSystem):
    for r in itertools.product(range(ts.K), repeat=ts.N):
        for o in itertools.product(range(ts.K), repeat=ts.M):
            for g in itertools.product(range(-1, ts.M), repeat=ts.N):
                yield r + o + g


def random_scenario(n, m, k, region_radius, robot_radii, object_radii, powers, required, gap):
    regions = [{"name": f"p{q + 1}", "center": [10.0 + 20.0 * q, 10.0], "radius": region_radius}
               for q in range(k)]
    robots = [{"name": f"r{i + 1}", "mass": 1.0, "radius": robot_radii[i], "power": powers[i],
               "initial_region": f"p{i % k + 1}"} for i in range(n)]
    objects = [{"name": f"o{j + 1}", "mass": 0.3, "radius": object_radii[j], "required_power": required[j],
                "initial_region": f"p{(j + 1) % k + 1}"} for j in range(m)]
    data = {
        "name": "random",
        "workspace": {"boundary": [[0.0, 0.0], [20.0 * k, 0.0], [20.0 * k, 20.0], [0.0, 20.0]]},
        "regions": regions, "robots": robots, "objects": objects,
        "task": {"formula": "G F r1_p1"},
        "layout": {"grasp_gap": gap, "spacing": 0.1},
    }
    return scenario_from_dict(data)


scenarios = st.builds(
    lambda n, m, k, rr, data: (n, m, k, rr, data),
    st.integers(1, 3), st.integers(0, 2), st.integers(1, 3), st.floats(1.0, 3.5), st.data(),
)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenarios)
def test_successors_match_oracle(params):
    n, m, k, rr, data = params
    robot_radii = data.draw(st.lists(st.floats(0.3, 0.9), min_size=n, max_size=n))
    object_radii = data.draw(st.lists(st.floats(0.1, 0.5), min_size=m, max_size=m))
    powers = data.draw(st.lists(st.integers(1, 4), min_size=n, max_size=n))
    required = data.draw(st.lists(st.integers(1, 8), min_size=m, max_size=m))
    gap = data.draw(st.floats(0.0, 0.3))
    try:
        sc = random_scenario(n, m, k, rr, robot_radii, object_radii, powers, required, gap)
    except UserError:
        assume(False)
    ts = TransitionSystem(sc)
    universe = list(all_states(ts))
    valid = [s for s in universe if oracle_valid(ts, s)]
    sources = data.draw(st.lists(st.sampled_from(valid), min_size=1, max_size=4, unique=True))
    for s in sources:
        assert ts.is_valid(s)
        expected = {t for t in universe if oracle_transition(ts, s, t)}
        got = list(ts.successor_states(s))
        assert len(got) == len(set(got)), "duplicate successors"
        assert set(got) == expected
        for t in got:
            assert ts.check_transition(s, t) is None
        for t in set(universe) - expected:
            assert ts.check_transition(s, t) is not None


# ---------------------------------------------------------------------------------------------- rules
def test_each_rule_violation_is_absent(tiny):
    ts = tiny  # r1 (power 2) in p1 with o1 (needs 4); r2 (power 3) in p2.  p1=0, p2=1, p3=2.
    s0 = ts.initial
    assert s0 == (0, 1, 0, -1, -1)
    succ = set(ts.successor_states(s0))
    cases = {
        "grasp an object in another region": (0, 1, 0, -1, 0),
        "grasp while navigating": (1, 1, 0, 0, -1),
        "object moves without a team": (0, 1, 2, -1, -1),
    }
    for why, t in cases.items():
        assert t not in succ, why
        assert ts.check_transition(s0, t) is not None, why
    s1 = (0, 1, 0, 0, -1)  # r1 grasps o1 in p1
    assert s1 in succ
    succ1 = set(ts.successor_states(s1))
    for why, t in {
        "team lacks power (2 < 4)": (2, 1, 2, 0, -1),
        "grasping robot navigates without its object": (1, 1, 0, 0, -1),
        "release while navigating": (1, 1, 0, -1, -1),
    }.items():
        assert t not in succ1, why
        assert ts.check_transition(s1, t) is not None, why
    s2 = (0, 0, 0, 0, 0)  # both grasp o1 in p1: power 5 >= 4
    assert ts.is_valid(s2)
    succ2 = set(ts.successor_states(s2))
    assert (2, 2, 2, 0, 0) in succ2  # transport p1 -> p3 by {r1, r2}
    for why, t in {
        "team changes while transporting": (2, 0, 2, 0, -1),
        "release while transporting": (2, 2, 2, 0, -1),
        "member stays behind": (0, 2, 2, 0, 0),
        "members go to different regions": (2, 1, 2, 0, 0),
    }.items():
        assert t not in succ2, why
        assert ts.check_transition(s2, t) is not None, why
    assert ts.actions(s2, (2, 2, 2, 0, 0)) == (Transport(0, (0, 1), 0, 2),)
    s3 = (0, 0, 0, 0, -1)
    assert (0, 0, 1, 0, 0) not in set(ts.successor_states(s3)), "grasp while the object moves"
    assert (0, 0, 0, -1, 0) in set(ts.successor_states(s3)), "simultaneous release and grasp of one object"


def test_switching_objects_is_absent():
    sc = random_scenario(1, 2, 1, 3.0, [0.5], [0.2, 0.2], [5], [1, 1], 0.1)
    ts = TransitionSystem(sc)
    s = (0, 0, 0, 0)
    t = (0, 0, 0, 1)
    assert ts.is_valid(s) and ts.is_valid(t)
    assert t not in set(ts.successor_states(s))
    assert "switches" in ts.check_transition(s, t)


def test_packing_limits_states():
    sc = random_scenario(3, 0, 2, 1.7, [0.75, 0.75, 0.75], [], [1, 1, 1], [], 0.1)
    ts = TransitionSystem(sc)
    free = (-1, -1, -1)
    assert not ts.is_valid((0, 0, 0) + free)  # three 0.75 m robots do not fit in a 1.7 m region
    assert ts.is_valid((0, 0, 1) + free)  # two do: 2 (0.75 + 0.05) <= 1.7 - 0.05
    ets = ts.build()
    assert ets.num_states == 6  # the 2^3 placements minus the two with all three together
    for u in range(ets.num_states):
        assert len(set(ets.state(u)[:3])) > 1


def test_self_loop_and_actions(tiny):
    s = tiny.initial
    out = {t: (a, c) for t, a, c in tiny.successors(s)}
    assert out[s] == ((), 0.0)
    acts, cost = out[(2, 1, 0, -1, -1)]
    assert acts == (Navigate(0, 0, 2),)
    assert cost == pytest.approx(math.dist((6, 6), (33, 22)))
    acts, cost = out[(0, 1, 0, 0, -1)]
    assert acts == (Grasp(0, 0),) and cost == pytest.approx(1.0)
    assert tiny.actions((0, 0, 0, 0, 0), (0, 0, 0, -1, 0)) == (Release(0, 0),)


# ---------------------------------------------------------------------------------------------- labels, costs
def test_labels(case1):
    ts = case1
    s = ts.initial
    assert ts.label(s) == {"r1_p1", "r2_p3", "r3_p4", "o1_p2", "o2_p1"}
    mask = ts.label_mask(s)
    assert {p for b, p in enumerate(ts.propositions) if mask >> b & 1} == ts.label(s)
    assert len(ts.propositions) == (3 + 2) * 4


def test_costs(case1):
    ts = case1
    ets = ts.build()
    rng = np.random.default_rng(0)
    for e in rng.integers(0, ets.num_transitions, size=300):
        u = int(np.searchsorted(ets.indptr, e, side="right") - 1)
        s, t = ets.state(u), ets.state(int(ets.targets[e]))
        R, R2 = s[: ts.N], t[: ts.N]
        G, G2 = s[ts.N + ts.M :], t[ts.N + ts.M :]
        centers = [g.center for g in ts.scenario.regions]
        expect = sum(math.dist(centers[a], centers[b]) for a, b in zip(R, R2))
        expect += ts.scenario.planning.grasp_cost * sum(a != b for a, b in zip(G, G2))
        assert ets.costs[e] == pytest.approx(expect)
        assert ts.cost(s, t) == pytest.approx(expect)


# ---------------------------------------------------------------------------------------------- explicit TS
def implicit_reachable(ts: TransitionSystem) -> tuple[set, int]:
    seen = {ts.initial}
    queue = deque([ts.initial])
    edges = 0
    while queue:
        s = queue.popleft()
        for t in ts.successor_states(s):
            edges += 1
            if t not in seen:
                seen.add(t)
                queue.append(t)
    return seen, edges


@pytest.mark.parametrize("name", ["tiny", "case_study_1", "case_study_2"])
def test_implicit_and_explicit_agree(name):
    ts = TransitionSystem(load_scenario(ROOT / "scenarios" / f"{name}.yaml"))
    ets = ts.build()
    seen, edges = implicit_reachable(ts)
    assert {ets.state(u) for u in range(ets.num_states)} == seen
    assert ets.num_transitions == edges
    rng = np.random.default_rng(1)
    for u in rng.integers(0, ets.num_states, size=50):
        s = ets.state(int(u))
        assert {ets.state(int(v)) for v in ets.successors(int(u))} == set(ts.successor_states(s))


def test_closed_form_state_count():
    """With roomy regions and strong robots every state is reachable: Σ_{R,O} Π_i (1 + #objects with i)."""
    n, m, k = 3, 2, 3
    sc = random_scenario(n, m, k, 6.0, [0.5] * n, [0.2] * m, [10] * n, [1] * m, 0.1)
    ts = TransitionSystem(sc)
    expect = 0
    for r in itertools.product(range(k), repeat=n):
        for o in itertools.product(range(k), repeat=m):
            expect += math.prod(1 + sum(oj == ri for oj in o) for ri in r)
    assert ts.build().num_states == expect


def test_encode_decode_roundtrip(case1):
    for s in itertools.islice(all_states(case1), 0, None, 97):
        assert case1.decode(case1.encode(s)) == s


def test_state_dict_roundtrip(case1):
    s = (0, 0, 2, 0, 0, 1, -1, 0)
    d = case1.state_dict(s)
    assert d == {"robots": {"r1": "p1", "r2": "p1", "r3": "p3"}, "objects": {"o1": "p1", "o2": "p1"},
                 "grasps": {"r1": "o2", "r2": None, "r3": "o1"}}
    assert case1.state_from_dict(d) == s


def test_table_notation(case1):
    f = case1.format_action
    assert f(Grasp(0, 1)) == "1 →g 2"
    assert f(Navigate(2, 3, 0)) == "π4 →3 π1"
    assert f(Transport(1, (0, 2), 0, 3)) == "π1 →T_{1,3},2 π4"
    assert f(Release(1, 0)) == "2 →r 1"


def test_covering_radius_contains_team():
    for n in range(1, 6):
        lay = grasp_layout(0.2, [0.75] * n, 0.1)
        centres = np.vstack([[0.0, 0.0], lay.offsets])
        radii = [0.2] + [0.75] * n
        assert verify_packing(lay.covering_radius + 1e-9, centres, radii)
        gaps = np.linalg.norm(lay.offsets, axis=1) - 0.2 - 0.75
        assert np.all(gaps >= 0.1 - 1e-12)


def test_cli_ts_json_matches_build():
    import json
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "mrodrake", "ts", "--json", str(ROOT / "scenarios" / "tiny.yaml")],
                         capture_output=True, text=True, check=True, timeout=120)
    data = json.loads(out.stdout)
    ts = TransitionSystem(load_scenario(ROOT / "scenarios" / "tiny.yaml"))
    ets = ts.build()
    assert len(data["states"]) == ets.num_states and len(data["transitions"]) == ets.num_transitions
    states = [ts.state_from_dict(d) for d in data["states"]]
    assert states[0] == ts.initial
    for d, s in zip(data["states"], states):
        assert set(d["label"]) == ts.label(s)
    for tr in data["transitions"][::7]:
        s, t = states[tr["src"]], states[tr["dst"]]
        assert ts.check_transition(s, t) is None
        assert tr["cost"] == pytest.approx(ts.cost(s, t), abs=1e-6)
        assert tr["actions"] == [ts.format_action(a, "names") for a in ts.actions(s, t)]


@pytest.mark.parametrize("name", ["tiny", "case_study_1", "case_study_2"])
def test_estimate_is_close_to_the_built_size(name):
    ts = TransitionSystem(load_scenario(ROOT / "scenarios" / f"{name}.yaml"))
    est = ts.estimate_size()
    ets = ts.build()
    assert 0.8 < est.states / ets.num_states < 1.5
    assert 0.8 < est.transitions / ets.num_transitions < 1.5


def test_build_stops_beyond_max_transitions(case1):
    with pytest.raises(RuntimeError, match="more than 1000 transitions"):
        case1.build(max_transitions=1000)


def _run_ts(path, *extra):
    import subprocess
    import sys
    import time

    start = time.perf_counter()
    res = subprocess.run([sys.executable, "-m", "mrodrake", "ts", str(path), *extra], capture_output=True, text=True,
                         timeout=120, cwd=ROOT)
    return res, time.perf_counter() - start


def test_cli_ts_refuses_a_big_transition_system_on_its_estimate(tmp_path):
    import yaml

    from mrodrake.planning.generate import generate_scenario_data

    path = tmp_path / "yard.yaml"
    path.write_text(yaml.safe_dump(generate_scenario_data(6, 3, 5, seed=0), sort_keys=False), encoding="utf-8")
    res, _seconds = _run_ts(path)
    assert res.returncode == 2, res.stderr
    assert "would have about" in res.stderr  # refused on the estimate, before building
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.stderr
    assert "--max-transitions" in lines[0] and "transitions" in lines[0]
    assert "e+" in lines[0]  # the estimate, e.g. "about 1.8e+11 transitions"


def test_cli_ts_max_transitions_lowers_the_limit():
    res, _ = _run_ts(ROOT / "scenarios" / "tiny.yaml", "--max-transitions", "100")
    assert res.returncode == 2 and "more than --max-transitions 100" in res.stderr
    res, _ = _run_ts(ROOT / "scenarios" / "tiny.yaml", "--max-transitions", "1000")
    assert res.returncode == 0 and "transitions:  438" in res.stdout

def _explicit(ets):
    return ets.states.tolist(), ets.indptr.tolist(), ets.targets.tolist(), ets.costs.tolist()


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenarios)
def test_batched_build_matches_one_state_at_a_time(params):
    """The numpy batches number states and order transitions as the one-state-at-a-time search does, with
    the same costs, also with sorted code lookups, small batches and steps that do not fit."""
    n, m, k, rr, data = params
    robot_radii = data.draw(st.lists(st.floats(0.3, 1.2), min_size=n, max_size=n))
    object_radii = data.draw(st.lists(st.floats(0.1, 0.8), min_size=m, max_size=m))
    powers = data.draw(st.lists(st.integers(1, 4), min_size=n, max_size=n))
    required = data.draw(st.lists(st.integers(1, 6), min_size=m, max_size=m))
    try:
        sc = random_scenario(n, m, k, rr, robot_radii, object_radii, powers, required, data.draw(st.floats(0.0, 0.3)))
    except UserError:
        assume(False)
    ts = TransitionSystem(sc)
    arr, counts, targets, costs = ts._explore_codes(None, None)
    got = ts._explore(None, None)
    assert got[0].tolist() == arr.tolist() and got[1].tolist() == counts.tolist()
    assert got[2].tolist() == targets.tolist()
    ref = ts.build()
    ts.batch = 3
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("mrodrake.ts._DENSE_INDEX", 0)
        mp.setattr("mrodrake.ts._DENSE_CODES", 0)
        other = ts.build()
        mp.setattr(TransitionSystem, "_explore", TransitionSystem._explore_codes)
        slow = ts.build()
    assert _explicit(other) == _explicit(ref) == _explicit(slow)
    states = [tuple(int(x) for x in row) for row in arr]
    pairs = [(a, b) for a in states[:6] for b in states]
    want = [ts.step_fits(a, b) for a, b in pairs]
    assert ts.steps_fit(np.array([a for a, _ in pairs]), np.array([b for _, b in pairs])).tolist() == want
    assert [oracle_step_fits(ts, a, b) for a, b in pairs] == want


def test_a_grasp_among_robots_about_to_leave_must_fit_with_them():
    """Generated lab task n3 m1 k3 seed 802: r1, r2, r3 and o1 start in p2 (radius 1.5 m).  In one step that
    grasps o1 by r2 while r1 and r3 leave for p4, the grasp runs first and forms the team (covering radius
    1.32 m) next to r1 and r3, which do not fit with it; placement rejected every such plan.  That step is no
    TS transition in either direction, whichever check decides it; leaving first and then grasping is."""
    sc = generate_scenario(3, 1, 3, 802, map="lab")
    ts = TransitionSystem(sc)
    p2, p4 = ts.region_names.index("p2"), ts.region_names.index("p4")
    s = (p2, p2, p2, p2, -1, -1, -1)
    t = (p4, p2, p4, p2, -1, 0, -1)
    mid = (p4, p2, p4, p2, -1, -1, -1)
    assert ts.is_valid(s) and ts.is_valid(t) and ts.is_valid(mid)
    for a, b in ((s, t), (t, s)):
        assert not ts.step_fits(a, b) and not oracle_step_fits(ts, a, b)
        assert not ts.steps_fit(np.array([a]), np.array(b))[0]
        assert not ts.steps_fit(np.array([a]), np.array([b]))[0]
        assert ts.check_transition(a, b) is not None
    assert t not in set(ts.successor_states(s))
    assert ts.step_fits(s, mid) and ts.step_fits(mid, t) and ts.check_transition(s, mid) is None
    assert ts.check_transition(mid, t) is None


def _put_down_floor():
    """p1 and p2 (radius 2.5 m) on an empty floor; o1 starts in p1 and o2 in p2, each carried by r1 or r2
    alone (power 4 >= 2.5; covering radius 1.9 m)."""
    return scenario_from_dict({
        "name": "put_down", "workspace": {"boundary": [[0, 0], [40, 0], [40, 20], [0, 20]]},
        "regions": [{"name": "p1", "center": [10, 10], "radius": 2.5},
                    {"name": "p2", "center": [30, 10], "radius": 2.5}],
        "robots": [{"name": "r1", "mass": 1.0, "radius": 0.75, "power": 4, "initial_region": "p1"},
                   {"name": "r2", "mass": 1.0, "radius": 0.75, "power": 4, "initial_region": "p2"}],
        "objects": [{"name": "o1", "mass": 0.3, "radius": 0.3, "required_power": 2.5, "initial_region": "p1"},
                    {"name": "o2", "mass": 0.3, "radius": 0.3, "required_power": 2.5, "initial_region": "p2"}],
        "task": {"formula": "G F r1_p1"}})


def test_an_object_put_down_by_a_team_leaves_no_room_beside_it_for_a_team_in_a_small_region():
    """Loop-map task n4 m2 k7 seed 1311: a robot put o2 down in p3 (radius 2.5 m), so o2's centre is within
    R − 1.9 − spacing/2 = 0.55 m of p3's centre, and no team of covering radius 1.95 m could come in beside it;
    a TS that counted o2 by its own radius anywhere in p3 let plans bring the team, and placement rejected
    every one of them (17 plans, "satisfiability unknown").  Outside its initial region an ungrasped object
    counts as put down by the smallest team able to carry it; in its initial region it lies anywhere."""
    ts = TransitionSystem(_put_down_floor())
    cover = ts.covering_radius(0, (0,))
    assert ts.smallest_team_radius(0) == cover and ts.smallest_team_radius(1) == cover
    R, half = 2.5, 0.5 * ts.spacing
    # a team beside a free object of radius 0.3 fits: on opposite sides, R - 0.3 - spacing + R - cover - half
    # >= 0.3 + cover + spacing; next to an object bound to R - cover - half of the centre it does not
    assert (R - 0.3 - 2 * half) + (R - cover - half) >= 0.3 + cover + 2 * half
    assert 2 * (R - cover - half) < 0.3 + cover + 2 * half
    # states (r1, r2, o1, o2, grasps of r1, r2); r2 waits in p1
    put_down = (1, 0, 1, 1, 1, -1)  # o1 (from p1) lies in p2 while r1 holds o2 there
    at_home = (1, 0, 1, 1, 0, -1)  # o2 lies at home in p2 while r1 holds o1 there
    assert not ts.is_valid(put_down) and not oracle_valid(ts, put_down)
    assert ts.is_valid(at_home) and oracle_valid(ts, at_home)
    # r1 in p2 next to both objects lying there may grasp o1 (o2 lies anywhere), not o2 (o1 is near the centre)
    s = (1, 0, 1, 1, -1, -1)
    assert ts.is_valid(s) and oracle_valid(ts, s)
    succ = set(ts.successor_states(s))
    assert at_home in succ and put_down not in succ
    assert ts.check_transition(s, put_down) is not None
