"""Generated scenarios: valid, deterministic per seed, movable objects, tasks not violated at once."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrodrake.logic.lasso import holds_at
from mrodrake.logic.ltl import atoms, parse
from mrodrake.planning.exact import immovable_objects
from mrodrake.planning.generate import MAX_K, generate_scenario
from mrodrake.ts import TransitionSystem


@settings(max_examples=15, deadline=None)
@given(n=st.integers(1, 12), m=st.integers(0, 6), k=st.integers(3, 8), seed=st.integers(0, 10**6),
       full=st.booleans())
def test_generated_scenarios_are_valid(n, m, k, seed, full):
    sc = generate_scenario(n, m, k, seed, full=full)
    assert (len(sc.robots), len(sc.objects), len(sc.regions)) == (n, m, k)
    ts = TransitionSystem(sc)
    assert ts.is_valid(ts.initial)
    assert not immovable_objects(ts)
    macros = sc.task.propositions
    label = ts.label(ts.initial)
    for name in ("psid", "psif"):
        if name in macros:
            assert not holds_at(parse(macros[name]), [], [label])[0], f"{name} holds initially"
    if full:
        for name in ("psia", "psib", "psic"):
            assert len(atoms(parse(macros[name]))) == n + m
    assert generate_scenario(n, m, k, seed, full=full) == sc


def test_region_limits():
    assert len(generate_scenario(2, 1, MAX_K, 0).regions) == MAX_K
    with pytest.raises(ValueError):
        generate_scenario(2, 1, MAX_K + 1, 0)
