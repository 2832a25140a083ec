"""What makes STyLuS* scale on the object TS: the sampler travels along routes of connected regions, guards
with many cubes are evaluated as bit tables per group of propositions (same answers), and large systems focus the
selection."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrodrake.planning.generate import generate_scenario
from mrodrake.planning.plan import plan_scenario, task_nba
from mrodrake.planning.sampler import Goal, SuccessorSampler
from mrodrake.planning.semantics import GuardTable, relevant_mask
from mrodrake.planning.stylus import FOCUS_ENTITIES, Stylus
from mrodrake.scenario import scenario_from_dict
from mrodrake.ts import TransitionSystem


def corridor(formula: str) -> dict:
    """p1, p2, p3 in a row in a 10 m corridor: p2 is in the way between p1 and p3."""
    return {
        "name": "corridor",
        "workspace": {"boundary": [[0, 0], [60, 0], [60, 10], [0, 10]]},
        "regions": [{"name": "p1", "center": [5.0, 5.0], "radius": 3.0},
                    {"name": "p2", "center": [30.0, 5.0], "radius": 3.0},
                    {"name": "p3", "center": [55.0, 5.0], "radius": 3.0}],
        "robots": [{"name": "r1", "mass": 1.0, "radius": 0.75, "power": 2, "initial_region": "p1"}],
        "objects": [],
        "task": {"formula": formula},
    }


def test_the_sampler_takes_the_route_through_the_region_in_the_way():
    ts = TransitionSystem(scenario_from_dict(corridor("G F r1_p3 & G F r1_p1")))
    assert not ts.connected(0.75, 0, 2) and ts.connected(0.75, 0, 1) and ts.connected(0.75, 1, 2)
    sampler = SuccessorSampler(ts, np.random.default_rng(0))
    t = sampler.toward(ts.initial, Goal({0: 2}))
    assert t[0] == 1 and ts.check_transition(ts.initial, t) is None
    assert sampler.toward(t, Goal({0: 2}))[0] == 2
    plan = plan_scenario(scenario_from_dict(corridor("G F r1_p3 & G F r1_p1")), iterations=300)
    assert plan.total_cost > 0


@pytest.fixture(scope="module")
def big_nba():
    sc = generate_scenario(12, 6, 8, 0, full=True)
    ts = TransitionSystem(sc)
    f, nba = task_nba(sc, ts)
    return ts, nba


@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_guard_table_agrees_with_the_nba(big_nba, data):
    ts, nba = big_nba
    table = GuardTable(nba)
    q = data.draw(st.sampled_from([0, 0, 0] + list(range(nba.num_states))))
    cubes = [p for g, _ in nba.edges[q] for p, _ in g]
    base = data.draw(st.sampled_from(cubes)) if cubes and data.draw(st.booleans()) else 0
    flips = data.draw(st.lists(st.integers(0, len(ts.propositions) - 1), max_size=12))
    letter = base
    for b in flips:
        letter ^= 1 << b
    assert table.successors_mask(q, letter) == sum(1 << d for d in nba.successors(q, letter))
    assert dict(table.columns(letter)).get(q, 0) == sum(1 << d for d in nba.successors(q, letter))
    assert (table._table(q) is not None) == (len(cubes) > GuardTable.min_cubes)


def test_the_packed_table_is_used_for_the_big_guards(big_nba):
    ts, nba = big_nba
    table = GuardTable(nba)
    assert sum(len(g) for g, _ in nba.edges[0]) > GuardTable.min_cubes and table._table(0) is not None


def test_large_systems_focus_and_find_a_first_plan():
    sc = generate_scenario(12, 6, 8, 1, full=True)
    ts = TransitionSystem(sc)
    assert ts.N + ts.M > FOCUS_ENTITIES
    f, nba = task_nba(sc, ts)
    planner = Stylus(ts, nba, relevant_mask(ts, f), seed=1)
    assert planner.focus > 0
    res = planner.run(1, stop_at_first=True, extend_iterations=2000)
    assert res.stats["first_plan_seconds"] is not None and res.stats["iterations"] <= 2001


def test_the_vectorised_transition_test_blocks_untravelled_moves_without_objects():
    ts = TransitionSystem(scenario_from_dict(corridor("F r1_p3")))
    planner = Stylus(ts, task_nba(ts.scenario, ts)[1], 0, seed=0)
    X = np.array([[0, -1], [1, -1], [2, -1]], dtype=np.int16)
    assert planner.trans.mask(X, (2, -1)).tolist() == [False, True, True]
    assert [ts.check_transition((k, -1), (2, -1)) is None for k in range(3)] == [False, True, True]
