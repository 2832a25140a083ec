"""The Plan contract: JSON round trip and schema, Table I shape and costs, independent verification
catches corrupted plans, malformed JSON is a one-line UserError, and the ``plan`` subcommand."""

from __future__ import annotations

import argparse
import json

import pandas as pd
import pytest

from mrodrake.errors import UserError
from mrodrake.planning import cli as plan_cli
from mrodrake.planning.plan import Plan, PlanVerificationError, plan_scenario
from mrodrake.ts import Transport


@pytest.fixture(scope="module")
def plan1(case1):
    return plan_scenario(case1.scenario, seed=1, iterations=1500)


def test_json_round_trip(case1, plan1):
    text = plan1.to_json()
    back = Plan.from_json(text, case1.ts)
    assert back == plan1
    back.verify(case1.ts, case1.nba, case1.formula)
    assert json.loads(back.to_json()) == json.loads(text)


def test_json_schema(case1, plan1):
    d = json.loads(plan1.to_json())
    assert d["format"] == "mrodrake.plan" and d["version"] == 2
    assert d["scenario"] == "case_study_1" and d["planner"] == "stylus" and d["seed"] == 1
    assert d["costs"]["total"] == pytest.approx(d["costs"]["prefix"] + d["costs"]["suffix"])
    s0 = d["prefix"][0] if d["prefix"] else d["suffix"][0]
    assert s0 == {"robots": {"r1": "p1", "r2": "p3", "r3": "p4"}, "objects": {"o1": "p2", "o2": "p1"},
                  "grasps": {"r1": None, "r2": None, "r3": None}, "nba": case1.nba.initial}
    steps = d["actions"]
    assert len(steps) == len(d["prefix"]) + len(d["suffix"])
    assert [x["step"] for x in steps] == list(range(1, len(steps) + 1))
    assert steps[-1]["to"] == len(d["prefix"]) + 1  # the last step closes the cycle
    kinds = {a["type"] for x in steps for a in x["actions"]}
    assert kinds == {"navigate", "grasp", "release", "transport"}
    transports = [a for x in steps for a in x["actions"] if a["type"] == "transport"]
    assert all(len(a["team"]) >= 1 and a["paper"].startswith("π") for a in transports)


def test_table_is_table_one(case1, plan1):
    t = plan1.table()
    assert isinstance(t, pd.DataFrame)
    assert list(t.columns) == ["step", "part", "from", "to", "actions", "actions_names", "cost"]
    assert len(t) == len(plan1.prefix) + len(plan1.suffix)
    assert (t["part"] == "prefix").sum() == len(plan1.prefix)
    by_part = t.groupby("part")["cost"].sum()
    assert by_part["prefix"] == pytest.approx(plan1.prefix_cost)
    assert by_part["suffix"] == pytest.approx(plan1.suffix_cost)
    row = next(r for r, acts in zip(t.itertuples(), plan1.actions) if any(isinstance(a, Transport) for a in acts))
    assert "→T_{" in row.actions and "transport" in row.actions_names


def test_table_csv(tmp_path, plan1):
    path = tmp_path / "plan.csv"
    plan1.table().to_csv(path, index=False)
    back = pd.read_csv(path)
    assert back.shape == plan1.table().shape


def _corrupt(plan: Plan, **changes) -> Plan:
    data = {f: getattr(plan, f) for f in ("scenario", "formula", "planner", "seed", "prefix", "suffix",
                                          "actions", "step_costs", "ts", "stats")}
    data.update(changes)
    return Plan(**data)


def test_verify_catches_corruption(case1, plan1):
    ts, nba = case1.ts, case1.nba
    run = plan1.run
    # a suffix state replaced by a far-away state: some step is no longer a TS transition
    s, q = plan1.suffix[-1]
    moved = list(s)
    moved[ts.N] = (moved[ts.N] + 1) % ts.K  # teleport object o1
    bad = _corrupt(plan1, suffix=plan1.suffix[:-1] + [(tuple(moved), q)])
    with pytest.raises(PlanVerificationError):
        bad.verify(ts, nba, case1.formula)
    # wrong NBA state
    k = len(plan1.prefix) // 2
    prefix = list(plan1.prefix)
    prefix[k] = (prefix[k][0], (prefix[k][1] + 1) % nba.num_states)
    with pytest.raises(PlanVerificationError):
        _corrupt(plan1, prefix=prefix).verify(ts, nba, case1.formula)
    # tampered cost
    costs = list(plan1.step_costs)
    costs[0] += 1.0
    with pytest.raises(PlanVerificationError, match="cost"):
        _corrupt(plan1, step_costs=costs).verify(ts, nba, case1.formula)
    # dropped action
    acts = list(plan1.actions)
    i = next(i for i, a in enumerate(acts) if a)
    acts[i] = acts[i][1:]
    with pytest.raises(PlanVerificationError, match="actions"):
        _corrupt(plan1, actions=acts).verify(ts, nba, case1.formula)
    assert issubclass(PlanVerificationError, AssertionError)
    assert len(run) == len(plan1.actions)


@pytest.mark.parametrize("text,where", [
    ("{not json", "malformed JSON"),
    ('{"format": "other"}', "not an mrodrake plan"),
    ('{"format": "mrodrake.plan", "version": 9}', "version"),
    ('{"format": "mrodrake.plan", "version": 2, "scenario": "x", "formula": "", "planner": "exact", '
     '"prefix": [], "suffix": [], "actions": []}', "scenario"),
])
def test_from_json_errors_are_one_line(case1, text, where):
    with pytest.raises(UserError) as e:
        Plan.from_json(text, case1.ts, source="p.json")
    assert where in str(e.value) and "\n" not in str(e.value) and str(e.value).startswith("p.json")


def _parse(argv):
    parser = argparse.ArgumentParser(prog="mrodrake")
    plan_cli.add_subparser(parser.add_subparsers(dest="command"))
    return parser.parse_args(argv)


def test_cli_plan_writes_json_and_table(tmp_path, capsys, case1):
    out, csv = tmp_path / "p.json", tmp_path / "p.csv"
    args = _parse(["plan", str(case1.path), "--seed", "4", "--iterations", "1200", "-o", str(out),
                   "--table", str(csv)])
    assert args.func(args) == 0
    text = capsys.readouterr().out
    assert "cost:" in text and "prefix" in text and "→" in text
    plan = Plan.from_json(out.read_text(), case1.ts)
    plan.verify(case1.ts, case1.nba, case1.formula)
    assert plan.seed == 4
    assert len(pd.read_csv(csv)) == len(plan.prefix) + len(plan.suffix)


def test_cli_rejects_stylus_options_for_exact(case1):
    args = _parse(["plan", str(case1.path), "--planner", "exact", "--iterations", "5"])
    with pytest.raises(UserError, match="--iterations"):
        args.func(args)
