"""Multi-robot graph TS (STyLuS*'s setting): task files (inline edges, edge lists, GraphML, networkx) and
their one-line errors, the exact planner against an independent networkx search, STyLuS* on undirected and
directed graphs (verified, never below the optimum), plan JSON, the CLI, and STyLuS*'s default problem."""

from __future__ import annotations

import itertools
import json
import math

import networkx as nx
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrodrake import cli
from mrodrake.errors import UserError
from mrodrake.logic.translate import translate
from mrodrake.planning.graph import (
    graph_ts_from_dict,
    graph_ts_from_networkx,
    is_graph_task,
    load_graph_ts,
    write_graph_task,
)
from mrodrake.planning.plan import Plan, graph_task_nba, plan_graph
from mrodrake.planning.stylus_default import PREDICATES, stylus_default_ts


def _task(**changes) -> dict:
    data = {
        "format": "mrodrake.graph", "name": "square",
        "graphs": {"g": {"edges": [["a", "b"], ["b", "c"], ["c", "d"], ["d", "a"], ["a", "c", 5.0]],
                         "positions": {"a": [0, 0], "b": [2, 0], "c": [2, 2], "d": [0, 2]}}},
        "robots": [{"name": "r1", "graph": "g", "initial": "a"}, {"name": "r2", "graph": "g", "initial": "c"}],
        "propositions": {"p1": {"all": {"r1": ["c"], "r2": ["a"]}}, "p2": {"any": {"r1": ["b"], "r2": ["b"]}},
                         "p3": {"all": {"r1": ["d"]}}},
        "task": "G F p1 & G F p2 & G !(p3)",
    }
    data.update(changes)
    return data


def test_inline_task_weights_and_labels():
    ts = graph_ts_from_dict(_task())
    a, b, c, d = range(4)
    assert ts.weight(a, b) == 2.0 and ts.weight(b, a) == 2.0 and ts.weight(a, c) == 5.0 and ts.weight(a, a) == 0.0
    assert math.isinf(ts.weight(b, d)) and ts.symmetric
    assert ts.label((c, a)) == {"p1"} and ts.label((b, d)) == {"p2"} and ts.label((d, b)) == {"p2", "p3"}
    assert "no edge b -> d" in ts.check_transition((b, a), (d, a))


@pytest.mark.parametrize("change, where", [
    ({"format": "x"}, "format: expected 'mrodrake.graph'"),
    ({"robots": [{"name": "r1", "graph": "h", "initial": "a"}]}, "robots[0].graph: unknown graph 'h'"),
    ({"robots": [{"name": "r1", "graph": "g", "initial": "z"}]}, "robots[0].initial: 'z' is not a vertex"),
    ({"propositions": {"p1": {"all": {"r9": ["a"]}}}}, "propositions.p1.all.r9: unknown robot"),
    ({"propositions": {"p1": {"some": {"r1": ["a"]}}}}, "propositions.p1: expected {all:"),
    ({"propositions": {"p1": {"all": {"r1": ["q"]}}}}, "propositions.p1.all.r1: 'q' is not a vertex"),
    ({"graphs": {"g": {"edges": [["a", "b", -1]]}}}, "graphs.g: edge a -> b: weight must be finite and >= 0"),
    ({"graphs": {"g": {"edges": [["a"]]}}}, "graphs.g.edges[0]: expected [u, v]"),
    ({"planning": {"speed": 1}}, "planning.speed: unknown field"),
    ({"planning": {"seed": "x"}}, "planning.seed: expected an integer, got 'x'"),
    ({"colour": 1}, "colour: unknown field"),
])
def test_task_file_errors_name_the_field(change, where):
    with pytest.raises(UserError) as e:
        graph_ts_from_dict(_task(**change), source="t.yaml")
    assert str(e.value) == f"t.yaml: {where}" or str(e.value).startswith(f"t.yaml: {where}")
    assert "\n" not in str(e.value)


def test_unknown_proposition_in_the_task():
    ts = graph_ts_from_dict(_task(task="G F p9"))
    with pytest.raises(UserError, match="task: unknown proposition 'p9'"):
        plan_graph(ts)


def test_edge_list_graphml_and_networkx_give_the_same_ts(tmp_path):
    ref = graph_ts_from_dict(_task())
    path = tmp_path / "square.yaml"
    write_graph_task(ref, path)
    assert is_graph_task(path)
    back = load_graph_ts(path)
    g = nx.Graph()
    for name, (x, y) in {"a": (0, 0), "b": (2, 0), "c": (2, 2), "d": (0, 2)}.items():
        g.add_node(name, x=float(x), y=float(y))
    g.add_edges_from([("a", "b"), ("b", "c"), ("c", "d"), ("d", "a")])
    g.add_edge("a", "c", weight=5.0)
    nx.write_graphml(g, tmp_path / "square.graphml")
    data = _task()
    data["graphs"] = {"g": {"file": "square.graphml"}}
    (tmp_path / "gml.yaml").write_text(yaml.safe_dump(data))
    gml = load_graph_ts(tmp_path / "gml.yaml")
    props = {"p1": ("all", {"r1": ["c"], "r2": ["a"]}), "p2": ("any", {"r1": ["b"], "r2": ["b"]}),
             "p3": ("all", {"r1": ["d"]})}
    api = graph_ts_from_networkx({"g": g}, {"r1": ("g", "a"), "r2": ("g", "c")}, props)
    for ts in (back, gml, api):
        assert (ts.adj != ref.adj).nnz == 0 and ts.initial == ref.initial and ts.region_names == ref.region_names
        assert [p.name for p in ts.predicates] == ["p1", "p2", "p3"]
        for s in itertools.product(range(4), repeat=2):
            assert ts.label_mask(s) == ref.label_mask(s)


def networkx_optimum(ts, nba) -> float:
    """Cheapest lasso of the product built with networkx from the robots' out-edges (independent of the
    planners' graphs): the NBA reads the source label."""
    g = nx.DiGraph()
    init = (ts.initial, nba.initial)
    todo, seen = [init], {init}
    while todo:
        s, q = todo.pop()
        lab = ts.label_mask(s)
        for t in itertools.product(*[ts.neighbours(u) for u in s]):
            t = tuple(int(x) for x in t)
            for q2 in nba.successors(q, lab):
                g.add_edge((s, q), (t, q2), w=ts.cost(s, t))
                if (t, q2) not in seen:
                    seen.add((t, q2))
                    todo.append((t, q2))
    g.add_node(init)
    d0 = nx.single_source_dijkstra_path_length(g, init, weight="w")
    best = math.inf
    for a, da in d0.items():
        if a[1] in nba.accepting:
            back = nx.single_source_dijkstra_path_length(g, a, weight="w")
            best = min(best, da + min((back[p] + g[p][a]["w"] for p in g.predecessors(a) if p in back),
                                      default=math.inf))
    return best


FORMULAS = ["G F p1 & G F p2", "G F p1 & G !p3", "F G p2", "(!p1 U p3) & G F p2", "G (p1 -> X p2) & G F p1",
            "G F p3 & G F p1 & G !p2", "F p1 & G (p2 -> X !p2)"]


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(3, 5), seed=st.integers(0, 10**6), formula=st.sampled_from(FORMULAS),
       directed=st.booleans(), loops=st.booleans())
def test_exact_optimal_and_stylus_never_below_it(n, seed, formula, directed, loops):
    import random

    rnd = random.Random(seed)
    V = [f"v{k}" for k in range(n)]
    edges = [[V[k], V[(k + 1) % n], rnd.randint(1, 5)] for k in range(n)]
    edges += [[rnd.choice(V), rnd.choice(V), rnd.randint(1, 5)] for _ in range(n)]
    props = {"p1": {"all": {"r1": [rnd.choice(V)], "r2": [rnd.choice(V)]}},
             "p2": {"any": {"r1": [rnd.choice(V)], "r2": [rnd.choice(V)]}},
             "p3": {"all": {"r2": rnd.sample(V, 2)}}}
    data = _task(graphs={"g": {"edges": edges, "undirected": not directed, "self_loops": loops}},
                 robots=[{"name": "r1", "initial": V[0]}, {"name": "r2", "initial": rnd.choice(V)}],
                 propositions=props, task=formula)
    ts = graph_ts_from_dict(data)
    f, nba = graph_task_nba(ts)
    opt = networkx_optimum(ts, nba)
    if math.isinf(opt):
        with pytest.raises(UserError, match="^task is unsatisfiable"):
            plan_graph(ts, planner="exact")
        return
    exact = plan_graph(ts, planner="exact")
    assert exact.total_cost == pytest.approx(opt, abs=1e-9)
    plan = plan_graph(ts, seed=seed % 7, iterations=300)
    assert plan.total_cost >= opt - 1e-9


def test_directed_graph_plans_are_verified():
    """A one-way ring (the STyLuS* trees' rewiring must not assume symmetric edges)."""
    n = 6
    edges = [[f"v{k}", f"v{(k + 1) % n}", 1 + k % 3] for k in range(n)]
    data = _task(graphs={"g": {"edges": edges, "undirected": False}},
                 robots=[{"name": "r1", "initial": "v0"}, {"name": "r2", "initial": "v3"}],
                 propositions={"p1": {"all": {"r1": ["v2"]}}, "p2": {"all": {"r2": ["v5"], "r1": ["v4"]}}},
                 task="G F p1 & G F p2")
    ts = graph_ts_from_dict(data)
    assert not ts.symmetric
    f, nba = graph_task_nba(ts)
    opt = plan_graph(ts, planner="exact").total_cost
    for seed in range(3):
        plan = plan_graph(ts, seed=seed, iterations=600)
        assert plan.total_cost >= opt - 1e-9
        assert all(ts.check_transition(a[0], b[0]) is None for _, _, _, _, a, b, _, _ in plan.steps())


def test_plan_json_round_trip_and_cli(tmp_path, capsys):
    path = tmp_path / "square.yaml"
    path.write_text(yaml.safe_dump(_task()))
    out = tmp_path / "plan.json"
    assert cli.main(["plan", str(path), "-o", str(out), "--seed", "1"]) == 0
    text = capsys.readouterr().out
    assert "verified:" in text and "step" in text
    ts = load_graph_ts(path)
    f, nba = graph_task_nba(ts)
    plan = Plan.from_json(out.read_text(), ts)
    plan.verify(ts, nba, f)
    d = json.loads(out.read_text())
    assert d["format"] == "mrodrake.plan" and d["version"] == 2 and d["scenario"] == "square"
    assert set(d["prefix"][0] if d["prefix"] else d["suffix"][0]) == {"robots", "objects", "grasps", "nba"}
    assert all(a["type"] == "navigate" for x in d["actions"] for a in x["actions"])
    path.write_text(yaml.safe_dump(_task(task="F p3 & G !p3")))
    assert cli.main(["plan", str(path)]) == 2
    assert "task is unsatisfiable" in capsys.readouterr().err


def test_an_unreachable_vertex_makes_the_task_unsatisfiable():
    data = _task(graphs={"g": {"edges": [["a", "b"], ["c", "d"]]}})
    ts = graph_ts_from_dict(data)
    with pytest.raises(UserError) as e:
        plan_graph(ts, iterations=50)
    assert str(e.value).startswith("task is unsatisfiable") and "\n" not in str(e.value)


def test_stylus_default_problem_first_plan():
    ts = stylus_default_ts(0)
    assert ts.N == 100 and ts.K == 1000 and ts.initial[:3] == (0, 1, 2)
    deg = ts.adj.getnnz(axis=1) - 1
    assert 25 < deg.mean() < 29
    assert ts.predicates[5].mode == "any" and len(PREDICATES) == 8
    f, nba = graph_task_nba(ts)
    assert nba.num_states <= 21
    plan = plan_graph(ts, iterations=200)
    assert plan.stats["first_plan_seconds"] is not None and plan.stats["iterations"] <= 200
    assert translate(f).num_states == nba.num_states
