"""``mrodrake run``: plan files and the output directory are checked before any simulation (user errors exit 2);
failures inside the simulation end the mission cleanly with its logs (exit 1)."""

import json
import re
from pathlib import Path

import pandas as pd
import pytest

from mrodrake import cli
from mrodrake.control.adaptive import NavigationTask
from mrodrake.planning.plan import plan_scenario
from mrodrake.run import run_mission
from mrodrake.scenario import load_scenario
from mrodrake.systems.plants import MissionPlants

ROOT = Path(__file__).resolve().parents[2]
TINY = ROOT / "scenarios" / "tiny.yaml"


def test_missing_plan_file_is_a_user_error(tmp_path, capsys):
    assert cli.main(["run", str(TINY), "--plan", str(tmp_path / "nope.json"), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: --plan: file '{tmp_path / 'nope.json'}' not found"]


@pytest.mark.parametrize("args, option", [
    (["run", str(TINY), "--execution", "parallel"], "--execution"),
    (["ts", str(TINY), "--max-transitions", "-3"], "--max-transitions"),
    (["run", str(TINY), "--suffix-cycles", "two"], "--suffix-cycles"),
])
def test_a_bad_option_value_is_one_line_naming_the_option(args, option, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(args)
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and len(err) == 1 and err[0].startswith("error: mrodrake ") and option in err[0], err


@pytest.mark.parametrize("command", ["plan", "run"])
def test_a_negative_seed_is_one_line_naming_the_option(command, tmp_path, capsys):
    extra = ["--out", str(tmp_path)] if command == "run" else []
    assert cli.main([command, str(TINY), "--seed", "-3", *extra]) == 2
    assert capsys.readouterr().err.strip().splitlines() == ["error: --seed: must be >= 0, got -3"]


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


def test_unwritable_output_directory_fails_before_planning(capsys):
    assert cli.main(["run", str(TINY), "--out", "/proc/forbidden/out"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --out: cannot write to '/proc/forbidden/out'"), err
    assert "planning" not in captured.err  # nothing was planned or simulated


def _fail_transports(monkeypatch):
    """Make the first transport's plant raise Drake's integrator failure from inside the simulation."""
    original = MissionPlants.DoCalcTimeDerivatives

    def failing(self, context, derivatives):
        teams = {t for t, _, _ in self.teams}
        if teams.intersection(self.moving(context)) and context.get_time() > 1.0:
            raise RuntimeError("Error control wants to select step smaller than minimum allowed (2.0e-11)\nmore")
        original(self, context, derivatives)

    monkeypatch.setattr(MissionPlants, "DoCalcTimeDerivatives", failing)


def test_exception_inside_the_simulation_is_a_failed_primitive_with_logs(tmp_path, capsys, monkeypatch):
    """A mission that dies in the integrator fails in one line naming the primitive, its step and the
    simulated time, exits 1 without a traceback, and still writes every log."""
    _fail_transports(monkeypatch)
    out = tmp_path / "out"
    assert cli.main(["run", str(TINY), "--out", str(out)]) == 1
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err + captured.out
    line = next(x for x in captured.out.splitlines() if x.startswith("tiny: FAILED: "))
    assert re.search(r"FAILED: transport o1 by r1\+r2 p\d->p\d \(step \d+, plan step \d+\) failed at t = "
                     r"\d+\.\d\d s: integrator failure \(Error control wants to select step smaller than minimum "
                     r"allowed \(2\.0e-11\)\)$", line), line
    for name in ("plan.json", "trajectory.csv", "signals.csv", "events.csv", "replay.html", "figures/fig1_initial.png"):
        assert (out / name).is_file(), name
    ev = pd.read_csv(out / "events.csv")
    failed = ev[(ev["kind"] == "primitive") & (~ev["ok"].astype(bool))]
    assert len(failed) == 1 and failed.iloc[0]["action"].startswith("transport o1")


def test_controller_fault_ends_the_primitive(tmp_path, monkeypatch):
    """A state past a barrier's pole (here: faked beyond x = 20 m) ends the primitive at the next step with
    the controller's fault, instead of integrating on."""
    original = NavigationTask.evaluate_floats

    def evaluate_floats(self, x0, x1, w0, w1, m_hat, alpha_hat):
        if x0 > 20.0:
            return self._fault((x0, x1), (w0, w1), "is outside the free set (test)")
        return original(self, x0, x1, w0, w1, m_hat, alpha_hat)

    monkeypatch.setattr(NavigationTask, "evaluate_floats", evaluate_floats)
    log = run_mission(load_scenario(TINY), seed=0, out_dir=tmp_path)
    assert not log.ok
    assert re.search(r"failed at t = \d+\.\d\d s: controller fault of \S+: x = \(20\.\d{4}, [\d.]+\) is outside "
                     r"the free set \(test\)$", log.message), log.message
    last = log.trajectory[log.trajectory["t"] == log.trajectory["t"].max()].set_index("entity")
    moving = "o1" if "controller fault of o1_" in log.message else log.message.split("navigate ")[1].split()[0]
    assert 20.0 < last.loc[moving, "x"] < 20.5  # stopped right after crossing, not integrated on


def test_write_failure_keeps_what_it_can(tmp_path, capsys):
    out = tmp_path / "out"
    (out / "events.csv").mkdir(parents=True)  # a directory where a file should go
    assert cli.main(["run", str(TINY), "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"error: could not write 1 output file(s) to {out}/ (events.csv: ")
    assert (out / "trajectory.csv").is_file() and (out / "replay.html").is_file()


def test_a_mission_without_a_seed_executes_the_plans_own_layout(tmp_path):
    """A plan placed with seed 3 (``mrodrake plan --seed 3 -o plan.json``) is executed on that layout by a
    mission given no seed (``mrodrake run --plan plan.json``), from the plan or its file, not re-placed with 0."""
    from mrodrake.systems.mission import Mission, load_plan

    sc = load_scenario(TINY)
    plan = plan_scenario(sc, "stylus", seed=3)
    assert plan.stats["placement"]["seed"] == 3
    mission = Mission(sc, plan)
    assert mission.seed == 3 and mission.placement is plan.placement
    path = tmp_path / "plan.json"
    plan.write(path)
    loaded = Mission(sc, load_plan(sc, path))
    assert loaded.seed == 3 and loaded.placement.initial == plan.placement.initial
