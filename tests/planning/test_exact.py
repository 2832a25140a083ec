"""Exact optimal planning: optimality against an independent networkx search, unsatisfiability proofs
and the insufficient-power diagnosis (one-line UserErrors)."""

from __future__ import annotations

import itertools
import math

import networkx as nx
import pytest
import yaml

from mrodrake.errors import UserError
from mrodrake.logic.formula import atoms
from mrodrake.planning.exact import check_power, immovable_objects, max_team_power, solve_exact
from mrodrake.planning.plan import Plan, plan_scenario, task_nba
from mrodrake.planning.semantics import ExecutedWords, relevant_mask
from mrodrake.scenario import Scenario, scenario_from_dict
from mrodrake.ts import Navigate, TransitionSystem, Transport
from tests.planning.conftest import SCENARIOS


def brute_force_successors(ts, nba, formula, s, q, t) -> set[int]:
    """NBA states q' of product edges (s, q) → (t, q') by enumeration: every order of the region-changing
    actions, every interleaving of their bodies' rim crossings, letters projected onto the formula's atoms
    and read at each visible crossing (or the source label once).  Independent of mrodrake.planning.semantics."""
    names = atoms(formula)
    rel = sum(1 << b for b, p in enumerate(ts.propositions) if p in names)
    K = ts.K
    movers = [a for a in ts.actions(s, t) if isinstance(a, (Navigate, Transport))]
    base = ts.label_mask(s) & rel
    out = set()
    for order in itertools.permutations(movers):
        words = [[]]
        mask_after = [base]
        for a in order:
            bodies = [a.robot] if isinstance(a, Navigate) else [ts.N + a.obj, *a.team]
            events = [(b * K + a.src, -1, b) for b in bodies] + [(b * K + a.dst, +1, b) for b in bodies]
            new_words, new_masks = [], []
            for w, m0 in zip(words, mask_after):
                for perm in itertools.permutations(events):
                    pos = {id(e): i for i, e in enumerate(perm)}
                    if any(pos[id(e)] > pos[id(f)] for e in perm for f in perm
                           if e[2] == f[2] and e[1] < 0 < f[1]):
                        continue  # a body enters its destination before it has left its source
                    w2, m = list(w), m0
                    for bit, sign, _ in perm:
                        if not rel >> bit & 1:
                            continue
                        w2.append(m)
                        m = m | (1 << bit) if sign > 0 else m & ~(1 << bit)
                    new_words.append(w2)
                    new_masks.append(m)
            words, mask_after = new_words, new_masks
        common = None
        for w in words:
            S = {q}
            for letter in (w or [base]):
                S = {d for x in S for d in nba.successors(x, letter)}
            common = S if common is None else common & S
        out |= common or set()
    return out


def networkx_optimum(ts, nba, formula) -> float:
    """min over accepting a of d(init, a) + shortest non-empty cycle through a, on the product built
    by enumerating TS successors one by one and the executed words by brute force (no shared code with
    the exact planner's graph or the semantics module)."""
    g = nx.DiGraph()
    init = (ts.initial, nba.initial)
    todo, seen = [init], {init}
    while todo:
        s, q = todo.pop()
        for t in ts.successor_states(s):
            for q2 in brute_force_successors(ts, nba, formula, s, q, t):
                g.add_edge((s, q), (t, q2), w=ts.cost(s, t))
                if (t, q2) not in seen:
                    seen.add((t, q2))
                    todo.append((t, q2))
    g.add_node(init)
    d0 = nx.single_source_dijkstra_path_length(g, init, weight="w")
    best = math.inf
    for a, da in d0.items():
        if a[1] not in nba.accepting:
            continue
        back = nx.single_source_dijkstra_path_length(g, a, weight="w")
        cyc = min((back[p] + g[p][a]["w"] for p in g.predecessors(a) if p in back), default=math.inf)
        best = min(best, da + cyc)
    return best


def _variant(formula: str, props: dict | None = None, **changes) -> Scenario:
    data = yaml.safe_load((SCENARIOS / "tiny.yaml").read_text())
    data["task"] = {"formula": formula, "propositions": props or {}}
    for key, value in changes.items():
        data[key] = value
    return scenario_from_dict(data)


@pytest.mark.parametrize("formula", [
    "F G o1_p3 & G F (r1_p1 & r2_p1)",
    "G F r1_p2 & G F r1_p3 & G !(r2_p1)",
    "(!o1_p2 U o1_p3) & G F o1_p2",
    "G F (r1_p3 & r2_p3 & o1_p3) & G F r1_p1",
])
def test_exact_is_optimal_against_networkx(formula):
    sc = _variant(formula)
    ts = TransitionSystem(sc)
    f, nba = task_nba(sc, ts)
    rel = relevant_mask(ts, f)
    res = solve_exact(ts, nba, rel)
    plan = Plan.from_runs(ts, sc.name, str(f), "exact", None, res.prefix, res.suffix, ExecutedWords(ts, nba, rel))
    plan.verify(ts, nba, f)
    assert plan.total_cost == pytest.approx(res.prefix_cost + res.suffix_cost, rel=1e-12)
    assert plan.total_cost == pytest.approx(networkx_optimum(ts, nba, f), rel=1e-9, abs=1e-9)


def test_case_study_1_exact_plan_verified(case1):
    plan = plan_scenario(case1.scenario, planner="exact")
    assert plan.planner == "exact" and plan.seed is None
    plan.verify(case1.ts, case1.nba, case1.formula)
    assert plan.total_cost > 0


def test_unsatisfiable_task_one_line():
    # o1 must leave its initial region p1 in the very first step, but nothing grasps it there yet:
    # every guard is satisfiable by some label, only the TS dynamics make the task impossible
    sc = _variant("o1_p1 & X !o1_p1 & G F r1_p2")
    with pytest.raises(UserError) as e:
        plan_scenario(sc, planner="exact")
    msg = str(e.value)
    assert msg.startswith("task is unsatisfiable: no accepting cycle is reachable")
    assert "\n" not in msg and "interval product of the TS (48 states" in msg


def test_unsatisfiable_at_nba_level_one_line():
    sc = _variant("F (r1_p1 & r1_p2)")
    for planner in ("exact", "stylus"):
        with pytest.raises(UserError) as e:
            plan_scenario(sc, planner=planner)
        assert str(e.value).startswith("task is unsatisfiable") and "\n" not in str(e.value)


def test_insufficient_power_names_object_and_powers():
    objects = [{"name": "o1", "mass": 0.25, "radius": 0.2, "required_power": 6, "initial_region": "p1"}]
    sc = _variant("F o1_p3 & G F r1_p2", objects=objects)
    ts = TransitionSystem(sc)
    assert max_team_power(ts, 0) == (5.0, (0, 1))
    assert immovable_objects(ts) == {0: (5.0, (0, 1))}
    for planner in ("exact", "stylus"):
        with pytest.raises(UserError) as e:
            plan_scenario(sc, planner=planner)
        msg = str(e.value)
        assert "\n" not in msg
        assert "object o1" in msg and "power 6" in msg and "maximum team power is 5" in msg


def test_power_check_is_silent_when_the_object_need_not_move():
    objects = [{"name": "o1", "mass": 0.25, "radius": 0.2, "required_power": 6, "initial_region": "p1"}]
    sc = _variant("G F r1_p2 & G F o1_p1", objects=objects)
    ts = TransitionSystem(sc)
    f, nba = task_nba(sc, ts)
    check_power(ts, nba)
    plan = plan_scenario(sc, planner="exact")
    assert all(s[ts.N] == 0 for s, _ in plan.run)


@pytest.mark.slow
def test_case_study_2_exact_plan_verified(case2):
    plan = plan_scenario(case2.scenario, planner="exact")
    plan.verify(case2.ts, case2.nba, case2.formula)


def test_real_valued_powers_are_summed_against_the_required_power():
    robots = [{"name": "r1", "mass": 1.0, "radius": 0.75, "power": 1.5, "initial_region": "p1"},
              {"name": "r2", "mass": 1.2, "radius": 0.75, "power": 2.5, "initial_region": "p2"}]
    objects = [{"name": "o1", "mass": 0.25, "radius": 0.2, "required_power": 4.0, "initial_region": "p1"}]
    plan = plan_scenario(_variant("F o1_p3", robots=robots, objects=objects), planner="exact")
    assert any(isinstance(a, Transport) and a.team == (0, 1) for acts in plan.actions for a in acts)
    objects[0]["required_power"] = 4.25
    with pytest.raises(UserError) as e:
        plan_scenario(_variant("F o1_p3", robots=robots, objects=objects), planner="exact")
    assert "needs power 4.25 and the maximum team power is 4 (team r1+r2)" in str(e.value)


def test_a_team_whose_decimal_powers_add_up_to_the_required_power_is_strong_enough():
    """0.7 + 0.1 < 0.8 in floating point: Λ allows for the rounding of the sum (ts.POWER_SLACK), so the team
    carries the object; a team 1e-6 short still does not."""
    robots = [{"name": "r1", "mass": 1.0, "radius": 0.75, "power": 0.7, "initial_region": "p1"},
              {"name": "r2", "mass": 1.2, "radius": 0.75, "power": 0.1, "initial_region": "p2"}]
    objects = [{"name": "o1", "mass": 0.25, "radius": 0.2, "required_power": 0.8, "initial_region": "p1"}]
    assert 0.7 + 0.1 < 0.8
    plan = plan_scenario(_variant("F o1_p3", robots=robots, objects=objects), planner="exact")
    assert any(isinstance(a, Transport) and a.team == (0, 1) for acts in plan.actions for a in acts)
    objects[0]["required_power"] = 0.800001
    with pytest.raises(UserError, match="needs power 0.800001 and the maximum team power is 0.8"):
        plan_scenario(_variant("F o1_p3", robots=robots, objects=objects), planner="exact")
