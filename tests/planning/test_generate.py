"""Generated scenarios (office and shipped maps): valid, deterministic per seed, movable objects, tasks not
violated at once."""

from __future__ import annotations

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from mrodrake.logic.formula import atoms
from mrodrake.logic.lasso import holds_at
from mrodrake.logic.parse import parse
from mrodrake.planning.exact import immovable_objects
from mrodrake.planning.generate import MAPS, MAX_K, generate_scenario, generate_scenario_data, load_map, shipped_maps
from mrodrake.scenario import ControlGains
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


MAP_NAMES = shipped_maps()


def test_shipped_maps():
    assert {"warehouse", "narrow", "lab"} <= set(MAP_NAMES)


@pytest.mark.parametrize("map_name", MAP_NAMES)
@settings(max_examples=8, deadline=None)
@given(n=st.integers(1, 5), m=st.integers(0, 3), k=st.integers(3, 5), seed=st.integers(0, 10**6),
       full=st.booleans())
def test_generated_on_maps_are_valid(map_name, n, m, k, seed, full):
    sc = generate_scenario(n, m, k, seed, full=full, map=map_name)
    base = load_map(map_name)
    assert (len(sc.robots), len(sc.objects), len(sc.regions)) == (n, m, k)
    assert sc.workspace == base.workspace
    by_name = {g.name: g for g in base.regions}
    assert all(by_name[g.name] == g for g in sc.regions)
    assert {r.radius for r in sc.robots} == {max(r.radius for r in base.robots)}
    ts = TransitionSystem(sc)
    assert ts.is_valid(ts.initial)
    assert not immovable_objects(ts)
    label = ts.label(ts.initial)
    for name in ("psid", "psif"):
        if name in sc.task.propositions:
            assert not holds_at(parse(sc.task.propositions[name]), [], [label])[0], f"{name} holds initially"
    assert generate_scenario(n, m, k, seed, full=full, map=map_name) == sc


@pytest.mark.parametrize("map_name", MAP_NAMES)
def test_map_given_by_name_path_or_scenario(map_name):
    path = MAPS / f"{map_name}.yaml"
    sc = generate_scenario(3, 2, 4, 11, map=map_name)
    assert generate_scenario(3, 2, 4, 11, map=str(path)) == sc
    assert generate_scenario(3, 2, 4, 11, map=load_map(path)) == sc
    assert sc.name == f"gen_{map_name}_n3_m2_k4_s11"
    assert generate_scenario(3, 2, 4, 12, map=map_name) != sc


def test_map_region_limits():
    k = len(load_map("lab").regions)
    assert len(generate_scenario(2, 1, k, 0, map="lab").regions) == k
    with pytest.raises(ValueError):
        generate_scenario(2, 1, k + 1, 0, map="lab")


def test_lab_entities_are_scaled():
    sc = generate_scenario(3, 3, 5, 4, map="lab")
    assert {r.radius for r in sc.robots} == {0.5}
    assert all(0.13 <= o.radius <= 0.27 for o in sc.objects)


def test_a_map_keeps_its_control_settings(tmp_path):
    """A small floor's map with ``control.margin: 0.1`` (its doors pass teams only with it) gives generated
    scenarios that margin; the shipped maps, with the default control settings, give none."""
    from tests.systems.test_scale import closet

    path = tmp_path / "closet.yaml"
    path.write_text(yaml.safe_dump(closet(0.1)))
    sc = generate_scenario(3, 1, 4, 0, map=str(path))
    assert sc.control.margin == 0.1 and sc.control.k1 == ControlGains().k1
    assert "control" not in generate_scenario_data(3, 1, 4, 0, map="lab")
