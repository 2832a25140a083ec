"""The makespan a job graph allows: the critical path of the earliest-start schedule, and the bounds of the
weaker graphs (shared bodies and the task chain; shared bodies only) on the same durations."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrodrake.execution.schedule import critical_path, makespan_bounds
from tests.helpers.jobs import generated_jobs


@st.composite
def _dags(draw):
    n = draw(st.integers(1, 12))
    preds = [sorted(draw(st.sets(st.integers(0, u - 1), max_size=u))) if u else [] for u in range(n)]
    durations = draw(st.lists(st.floats(0.0, 500.0), min_size=n, max_size=n))
    return preds, durations


def _longest_chain(preds, durations) -> float:
    """The heaviest path by enumerating it backwards from every job (independent of critical_path)."""
    memo: dict[int, float] = {}

    def ending_at(u: int) -> float:
        if u not in memo:
            memo[u] = durations[u] + max((ending_at(p) for p in preds[u]), default=0.0)
        return memo[u]

    return max((ending_at(u) for u in range(len(durations))), default=0.0)


@settings(max_examples=200, deadline=None)
@given(dag=_dags())
def test_the_critical_path_is_the_heaviest_chain_of_the_graph(dag):
    preds, durations = dag
    cp = critical_path(preds, durations)
    assert np.isclose(cp, _longest_chain(preds, durations))
    assert max(durations) - 1e-9 <= cp <= sum(durations) + 1e-9


def test_a_chain_takes_the_sum_and_independent_jobs_the_longest():
    d = [3.0, 5.0, 2.0]
    assert critical_path([[], [0], [1]], d) == 10.0
    assert critical_path([[], [], []], d) == 5.0
    assert critical_path([[], [0], [0]], d) == 8.0
    assert critical_path([], []) == 0.0


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(2, 4), m=st.integers(0, 2), seed=st.integers(0, 10_000))
def test_weaker_graphs_allow_no_longer_schedules(n, m, seed):
    planned = generated_jobs(n, m, 4, seed)
    if planned is None:
        return
    _plan, jobs = planned
    durations = np.random.default_rng(seed).uniform(1.0, 300.0, len(jobs)).tolist()
    b = makespan_bounds(jobs, durations)
    eps = 1e-9
    assert b["bodies"] <= b["bodies+task"] + eps <= b["graph"] + 2 * eps <= b["sequential"] + 3 * eps
    # every job's own bodies are a chain in every graph
    for body in {e for j in jobs for e in j.bodies}:
        own = sum(d for j, d in zip(jobs, durations) if body in j.bodies)
        assert own <= b["bodies"] + eps
