"""``mrodrake run --plan``: plan files are loaded and verified before any simulation; user errors exit 2."""

import json
from pathlib import Path

from mrodrake import cli
from mrodrake.planning.plan import plan_scenario
from mrodrake.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
TINY = ROOT / "scenarios" / "tiny.yaml"


def test_missing_plan_file_is_a_user_error(tmp_path, capsys):
    assert cli.main(["run", str(TINY), "--plan", str(tmp_path / "nope.json"), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: --plan: file '{tmp_path / 'nope.json'}' not found"]


def test_plan_that_does_not_verify_is_a_user_error(tmp_path, capsys):
    plan = plan_scenario(load_scenario(TINY), "stylus", seed=0)
    path = tmp_path / "plan.json"
    plan.write(path)
    data = json.loads(path.read_text())
    moved = data["prefix"][1]
    obj = next(iter(moved["objects"]))
    others = [g for g in ("p1", "p2", "p3") if g != moved["objects"][obj]]
    moved["objects"][obj] = others[0]  # the object changes region by itself: no TS transition does that
    moved["grasps"] = {r: None for r in moved["grasps"]}
    path.write_text(json.dumps(data))
    code = cli.main(["run", str(TINY), "--plan", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith(f"error: {path}: plan does not verify"), err
    assert not (tmp_path / "out").exists()
