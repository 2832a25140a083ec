"""The domain-aware successor sampler: every sample is a TS transition, the random mode reaches every
successor, and the biased mode forms teams with enough power and delivers objects."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrodrake.planning.sampler import Goal, SuccessorSampler
from mrodrake.ts import Transport


@pytest.fixture(scope="module")
def case1_ets(case1):
    return case1.ts.build()


@settings(max_examples=80)
@given(st.data())
def test_samples_are_transitions(case1, case1_ets, data):
    ts, ets = case1.ts, case1_ets
    s = ets.state(data.draw(st.integers(0, ets.num_states - 1)))
    n_ent = ts.N + ts.M
    ents = data.draw(st.lists(st.integers(0, n_ent - 1), max_size=n_ent, unique=True))
    region = {e: data.draw(st.integers(0, ts.K - 1)) for e in ents}
    forbidden = {e: data.draw(st.integers(1, 2**ts.K - 2)) for e in
                 data.draw(st.lists(st.integers(0, n_ent - 1), max_size=2, unique=True)) if e not in region}
    goal = Goal(region, forbidden)
    sampler = SuccessorSampler(ts, np.random.default_rng(data.draw(st.integers(0, 2**32 - 1))))
    for t in (sampler.random(s), sampler.toward(s, goal), sampler.sample(s, goal, 0.8)):
        if t is not None:
            assert ts.check_transition(s, t) is None


def test_random_mode_reaches_every_successor(tiny):
    ts = tiny.ts
    s0 = ts.initial
    sampler = SuccessorSampler(ts, np.random.default_rng(0))
    want = set(ts.successor_states(s0))
    got = {sampler.random(s0) for _ in range(3000)}
    assert got == want


def test_biased_mode_delivers_an_object_with_a_powerful_team(case1):
    """o2 (needs power 6) from p1 to p4: robots r1 (2), r2 (3), r3 (4) start in p1, p3, p4."""
    ts = case1.ts
    N = ts.N
    goal = Goal({N + 1: 3})  # o2 in p4
    for seed in range(5):
        sampler = SuccessorSampler(ts, np.random.default_rng(seed))
        s = ts.initial
        transported = []
        for _ in range(8):
            t = sampler.toward(s, goal)
            assert t is not None and ts.check_transition(s, t) is None
            transported += [a for a in ts.actions(s, t) if isinstance(a, Transport)]
            s = t
            if s[N + 1] == 3:
                break
        assert s[N + 1] == 3, f"seed {seed}: o2 not delivered"
        assert len(transported) == 1 and ts.team_power_ok(transported[0].team, 1)


def test_biased_mode_sends_free_robots_directly(case1):
    ts = case1.ts
    sampler = SuccessorSampler(ts, np.random.default_rng(1))
    t = sampler.toward(ts.initial, Goal({0: 2, 1: 0}))  # r1 to p3, r2 to p1 in one step
    assert t[0] == 2 and t[1] == 0
    assert t[2:] == ts.initial[2:]


def test_goal_with_target_state_sets_grasps(case1):
    ts = case1.ts
    s = ts.initial  # r1 is in p1 with o2
    target = list(s)
    target[ts.N + ts.M + 0] = 1  # r1 grasps o2 (index 1)
    goal = Goal.from_cube({}, {}, tuple(target), ts)
    t = SuccessorSampler(ts, np.random.default_rng(0)).toward(s, goal)
    assert t == tuple(target)
