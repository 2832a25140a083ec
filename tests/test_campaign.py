"""``mrodrake campaign``: spec validation, parameter draws, metrics, failure kinds, both engines, isolation,
resume and Ctrl-C."""

import importlib.util
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mrodrake import cli
from mrodrake.campaign import (
    TIMING_COLUMNS,
    classify,
    load_campaign,
    randomized_scenario,
    run_campaign,
    trajectory_metrics,
)
from mrodrake.campaign.mission import WORKER_ENV
from mrodrake.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "scenarios" / "tiny.yaml"

#: 4 tiny missions (2 plan seeds x 2 draws), mission 1 raises: 3 simulated missions.  The wall-clock limit is
#: far above what they need (~15 s each when idle): under Ray at load 4-6 a cold worker took ~50 s to start and
#: the missions ran at a tenth of their idle speed, and a 120 s limit turned them into timeouts (ok only in
#: the local rows); the engines must agree on missions that run to completion.
FOUR = f"""
name: four
scenarios:
  - file: {TINY}
time_limit: 900
seeds:
  plan: {{start: 0, count: 2}}
  draws: 2
randomize:
  seed: 3
  robot_mass: [0.5, 2.0]
  object_mass: [0.5, 2.0]
  friction_scale: [0.0, 2.0]
  friction_frequency: [0.5, 2.0]
  initial_positions: true
inject: {{1: raise}}
"""

#: 3 tiny missions with a 2 s time limit: a crash, a hang (killed), a real mission (stopped by the monitor).
CRASH_SPEC = f"""
name: crash
scenarios:
  - file: {TINY}
seeds:
  plan: {{start: 0, count: 1}}
inject: {{0: crash}}
"""


def isolation_spec(startup: float = 0.0) -> tuple[str, int]:
    """The hang / soft-time-limit spec and its time limit: at least 30 s, and 6x the wall time this machine
    takes now to start a cold worker (a fresh interpreter importing Drake and mrodrake: a Ray worker) and to
    plan and build the tiny mission, so that a worker starting on busy cores (three Ray workers starting at once
    on two busy cores took 3x) starts simulating well inside it.  The slowed mission 1 simulates at most real
    time (442 s simulated), so the soft limit, counted from dispatch, falls inside its simulation.  A crash is
    checked in a campaign of its own without a short limit (:data:`CRASH_SPEC`): on busy cores Ray took
    longer than any such limit to report one.  ``startup``: seconds an engine took just now to start a worker
    and import the mission code in it (the limit is at least 6x that too)."""
    from mrodrake.planning.plan import plan_scenario
    from mrodrake.systems.mission import Mission

    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import mrodrake.campaign, mrodrake.systems.mission"], check=True)
    sc = load_scenario(TINY)
    Mission(sc, plan_scenario(sc, "stylus", seed=2), seed=0)
    limit = max(30, math.ceil(6.0 * max(startup, time.perf_counter() - t0)))
    return f"""
name: isolation
scenarios:
  - file: {TINY}
time_limit: {limit}
seeds:
  plan: {{start: 0, count: 2}}
inject: {{0: hang, 1: slow}}
""", limit


def write(tmp_path, text, name="spec.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def comparable(df):
    return df.drop(columns=list(TIMING_COLUMNS)).reset_index(drop=True)


# ------------------------------------------------------------------------------------------ spec errors
ERRORS = [
    ("name: x\nscenarios:\n  - file: {tiny}\nseeds:\n  plans: {{count: 2}}\n", 5, "seeds.plans: unknown field"),
    ("name: x\n", 1, "scenarios: missing required field"),
    ("name: x\nscenarios:\n  - file: nope.yaml\n", 3,
     "scenarios[0].file: no such file 'nope.yaml' (relative to the spec)"),
    ("name: x\nscenarios:\n  - file: {tiny}\n    generate: {{robots: [2], objects: [1], regions: [3]}}\n", 3,
     "scenarios[0]: give exactly one of 'file' and 'generate'"),
    ("name: x\nscenarios:\n  - generate: {{robots: [2], objects: [1], regions: [13]}}\n", 3,
     "scenarios[0].generate.regions[0]: at most 12 regions, got 13"),
    ("name: x\nscenarios:\n  - generate: {{robots: [2], objects: [1], regions: [3], map: hangar}}\n", 3,
     "scenarios[0].generate.map: unknown map 'hangar' (a shipped map: corridor, lab, narrow, warehouse; or a "
     "scenario file relative to the spec)"),
    ("name: x\nscenarios:\n  - generate: {{robots: [2], objects: [1], regions: [6], map: lab}}\n", 3,
     "scenarios[0].generate.regions[0]: at most 5 regions, got 6"),
    ("name: x\nscenarios:\n  - file: {tiny}\nrandomize:\n  robot_mass: [2.0, 1.0]\n", 5,
     "randomize.robot_mass: min 2 is larger than max 1"),
    ("name: x\nscenarios:\n  - file: {tiny}\nrandomize:\n  robot_mass: [0.0, 1.0]\n", 5,
     "randomize.robot_mass[0]: must be > 0"),
    ("name: x\nscenarios:\n  - file: {tiny}\nrandomize:\n  friction_scale: [1.0]\n", 5,
     "randomize.friction_scale: expected [min, max] (2 numbers)"),
    ("name: x\nscenarios:\n  - file: {tiny}\ninject: {{4: crash}}\n", 4,
     "inject[4]: mission index 4 out of range (the campaign has 1 missions, 0..0)"),
    ("name: x\nscenarios:\n  - file: {tiny}\ntime_limit: -1\n", 4, "time_limit: must be > 0"),
    ("name: x\nscenarios:\n  - file: {tiny}\nplanner: exact\nseeds: {{plan: {{count: 2}}}}\n", 5,
     "seeds.plan.count: the exact planner takes no seed; use count 1"),
]


@pytest.mark.parametrize("text, line, message", ERRORS)
def test_spec_errors_are_one_line_naming_the_field(tmp_path, capsys, text, line, message):
    spec = write(tmp_path, text.format(tiny=TINY))
    assert cli.main(["campaign", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: {spec}:{line}: {message}"]
    assert not (tmp_path / "out").exists()


def test_option_errors(tmp_path, capsys):
    spec = write(tmp_path, f"name: x\nscenarios:\n  - file: {TINY}\n")
    assert cli.main(["campaign", str(spec), "--workers", "0"]) == 2
    assert cli.main(["campaign", str(spec), "--address", "auto"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: --workers: must be >= 1, got 0", "error: --address: only with --engine ray"]


def test_shipped_specs_load():
    smoke = load_campaign(ROOT / "scenarios" / "campaigns" / "smoke.yaml")
    assert 4 <= len(smoke.tasks) <= 8
    big = load_campaign(ROOT / "scenarios" / "campaigns" / "success_by_size.yaml")
    assert len(big.tasks) >= 200
    sizes = {(len(t.instance.scenario.robots), len(t.instance.scenario.objects), len(t.instance.scenario.regions))
             for t in big.tasks if t.instance.family != "tiny"}
    assert sizes and all(2 <= n <= 4 and 1 <= m <= 2 and 3 <= k <= 4 for n, m, k in sizes)
    assert len({t.mission_id for t in big.tasks}) == len(big.tasks)


# ------------------------------------------------------------------------------------------ draws
def test_draws_are_a_pure_function_of_seed_and_mission(tmp_path):
    spec = write(tmp_path, FOUR)
    a, b = load_campaign(spec), load_campaign(spec)
    assert [t.params for t in a.tasks] == [t.params for t in b.tasks]
    assert [t.layout_seed for t in a.tasks] == [t.layout_seed for t in b.tasks]
    assert len({t.layout_seed for t in a.tasks}) == 4
    base = load_scenario(TINY)
    for t in a.tasks:
        s = randomized_scenario(t.instance.scenario, t.params)
        for body, orig in zip(list(s.robots) + list(s.objects), list(base.robots) + list(base.objects)):
            fm, fs, ff = t.params[body.name]["factors"]
            assert 0.5 <= fm <= 2.0 and 0.0 <= fs <= 2.0 and 0.5 <= ff <= 2.0
            assert body.mass == pytest.approx(orig.mass * fm)
            assert body.friction.scale == pytest.approx(orig.friction.scale * fs)
            assert body.friction.frequency == pytest.approx(orig.friction.frequency * ff)
            assert (body.radius, body.friction.model) == (orig.radius, orig.friction.model)
        assert s.control == base.control and s.task == base.task
    other = load_campaign(write(tmp_path, FOUR.replace("seed: 3", "seed: 4"), "other.yaml"))
    assert [t.params for t in other.tasks] != [t.params for t in a.tasks]


def test_without_randomize_the_scenario_is_unchanged(tmp_path):
    camp = load_campaign(write(tmp_path, f"name: x\nscenarios:\n  - file: {TINY}\n"))
    (task,) = camp.tasks
    assert randomized_scenario(task.instance.scenario, task.params) == load_scenario(TINY)
    assert task.layout_seed == 0 and task.mission_id == "tiny-p0-l0-d0"


# ------------------------------------------------------------------------------------------ metrics, kinds
def test_metrics_recomputed_from_the_trajectory():
    s = load_scenario(TINY)  # room [0, 40] x [0, 30], desk_1 [14, 18] x [10, 20]; robots 0.75, o1 0.2
    rows = []
    for t, (x1, x2, xo) in enumerate([(5.0, 20.0, 30.0), (1.0, 12.0, 12.0 + 0.75 + 0.2 + 0.3), (10.0, 13.5, 30.0)]):
        rows += [(0.5 * t, "r1", x1, 5.0, 0.0, 0.0), (0.5 * t, "r2", x2, 15.0, 3.0, 4.0 * t),
                 (0.5 * t, "o1", xo, 15.0, 0.0, 0.0)]
    tr = pd.DataFrame(rows, columns=["t", "entity", "x", "y", "vx", "vy"])
    m = trajectory_metrics(s, tr)
    # r2 at x = 13.5 reaches 0.5 m into desk_1's rim (14 - 13.5 - 0.75 = -0.25), r1 at x = 1 is 0.25 m off the wall
    assert m["min_clearance"] == pytest.approx(-0.25, abs=1e-9) and m["min_clearance_entity"] == "r2"
    assert m["min_gap"] == pytest.approx(0.3, abs=1e-9) and m["min_gap_pair"] == "r2-o1"
    assert m["max_speed"] == pytest.approx(math.hypot(3.0, 8.0)) and m["max_speed_entity"] == "r2"
    assert m["nan_seen"] is False
    tr.loc[4, "vx"] = np.nan
    assert trajectory_metrics(s, tr)["nan_seen"] is True


def test_failure_kinds_table():
    assert classify("plan", "task is unsatisfiable: the NBA ...", "plan_error") == "plan_unsat"
    assert classify("plan", "no plan found within 2000 iterations", "plan_error") == "plan_not_found"
    assert classify("mission", "UserError: step 3 (plan step 3): region 'p2': no free grasp layout for r1+r3 around o1",
                    "exception") == "placement"
    assert classify("mission", "initial state: region 'p2': no layout keeps the room later steps need",
                    "exception") == "placement"
    assert classify("plan", "no plan found within 57185 iterations and 60.0 s; satisfiability unknown (...); the "
                    "explicit product is too large to decide (...) and no relaxation proves the task unsatisfiable",
                    "plan_error") == "plan_not_found"
    assert classify("plan", "object o1: no team can move it", "plan_error") == "plan_error"
    assert classify("mission", "the monitored NBA run died at t=3.00", "mission_failed") == "nba_run"
    assert classify("mission", "RuntimeError: Error control wants to select step smaller than minimum allowed",
                    "exception") == "integrator"
    assert classify("mission", "navigate of r1: time limit 300 s exceeded", "mission_failed") == "primitive_time_limit"
    assert classify("mission", "integrator failure (Error control wants to select step smaller than minimum)",
                    "mission_failed") == "integrator"
    assert classify("mission", "ValueError inside the simulation: bad", "mission_failed") == "exception"
    assert classify("mission", "controller fault of nav_r1: left the free set", "mission_failed") == "controller_fault"
    assert classify("mission", "something new", "mission_failed") == "mission_failed"


# ------------------------------------------------------------------------------------------ engines
@pytest.fixture(scope="module")
def local_four(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("four")
    spec = write(tmp, FOUR)
    res = run_campaign(spec, out=tmp / "out", engine="local", workers=2, progress=False)
    return spec, tmp / "out", res


def test_local_campaign_records_the_injected_failure_and_completes_the_rest(local_four):
    _, out, res = local_four
    df = pd.read_csv(out / "results.csv")
    assert res.ran == 4 and res.skipped == 0 and len(df) == 4
    assert list(df["mission_id"]) == ["tiny-p0-l0-d0", "tiny-p0-l0-d1", "tiny-p1-l0-d0", "tiny-p1-l0-d1"]
    bad = df.iloc[1]
    assert not bad["ok"] and bad["failure_kind"] == "exception"
    assert bad["failure_message"] == "RuntimeError: injected failure (spec inject[1])"
    rest = df.drop(index=1)
    assert rest["ok"].all() and (rest["steps_done"] == rest["steps_total"]).all()
    assert (rest["sim_seconds"] > 0).all() and (rest["min_gap"] > 0).all() and (rest["min_clearance"] > 0).all()
    assert not rest["nan_seen"].any()
    summary = (out / "summary.md").read_text()
    assert "| exception | 1 | `tiny-p0-l0-d1` | RuntimeError: injected failure (spec inject[1]) |" in summary
    assert "success: 3/4 (75.0%)" in summary
    for fig in ("success_by_size.png", "hist_wall.png", "hist_clearance.png"):
        assert (out / "figures" / fig).stat().st_size > 0
    if importlib.util.find_spec("pyarrow") is not None:
        pd.testing.assert_frame_equal(pd.read_parquet(out / "results.parquet"), res.rows)


def test_primitives_table_measures_every_primitive_against_truth(local_four):
    spec, out, res = local_four
    prims = pd.read_csv(out / "primitives.csv")
    camp = load_campaign(spec)
    for task, row in zip(camp.tasks, res.rows.itertuples()):
        mine = prims[prims["mission_id"] == row.mission_id]
        if not row.ok:
            assert mine.empty  # the injected failure raised before simulating
            continue
        assert len(mine) > 0 and mine["ok"].all()
        assert set(mine["kind"]) == {"navigate", "grasp", "transport", "release"}
        assert (mine["seconds"] > 0).all() and (mine["seconds"] <= mine["time_limit"]).all()
        sc = randomized_scenario(task.instance.scenario, task.params)
        bodies = {b.name: b for b in [*sc.robots, *sc.objects]}
        moving = mine[mine["kind"].isin(["navigate", "transport"])]
        for p in moving.itertuples():
            names = p.entities.split()
            assert math.isclose(p.m_true, sum(bodies[n].mass for n in names), rel_tol=1e-9)
            assert math.isclose(p.alpha_true, sum(bodies[n].friction.alpha_bound for n in names), rel_tol=1e-9)
            # α̂ starts at the design bound n·ᾱ and never decreases (the adaptation rate is ≥ 0)
            assert p.alpha_hat >= len(names) * sc.control.alpha_max * (1 - 1e-7)
            assert p.m_hat > 0
        assert mine[~mine["kind"].isin(["navigate", "transport"])][["m_hat", "alpha_hat"]].isna().all().all()
    summary = (out / "summary.md").read_text()
    assert "## Primitives" in summary and "## Final estimates against the true values" in summary
    n_transport = int((prims["kind"] == "transport").sum())
    assert f"| transport | {n_transport} | {n_transport} |" in summary


def test_rerun_resumes_without_rerunning(local_four):
    spec, out, first = local_four
    journal, results = (out / "journal.jsonl").read_text(), (out / "results.csv").read_text()
    res = run_campaign(spec, out=out, engine="local", workers=2, progress=False)
    assert res.ran == 0 and res.skipped == 4
    assert (out / "journal.jsonl").read_text() == journal and (out / "results.csv").read_text() == results
    pd.testing.assert_frame_equal(res.rows, first.rows)


def test_a_changed_mission_is_rerun_and_the_rest_resumed(local_four, tmp_path):
    spec, out, first = local_four
    shutil.copytree(out, tmp_path / "out")
    changed = write(tmp_path, spec.read_text().replace("inject: {1: raise}", "inject: {1: crash}"))
    res = run_campaign(changed, out=tmp_path / "out", engine="local", workers=2, progress=False)
    assert res.ran == 1 and res.skipped == 3
    row = res.rows.iloc[1]
    assert row["failure_kind"] == "worker_crash" and "SIGABRT" in row["failure_message"]
    assert comparable(res.rows.drop(index=1)).equals(comparable(first.rows.drop(index=1)))


def test_isolation_crash_hang_and_time_limit_local(tmp_path):
    crash = run_campaign(write(tmp_path, CRASH_SPEC, "crash.yaml"), out=tmp_path / "crash", engine="local",
                         workers=1, keep_runs=True, progress=False)
    assert list(crash.rows["failure_kind"]) == ["worker_crash"] and "SIGABRT" in crash.rows.iloc[0]["failure_message"]
    assert not (tmp_path / "crash" / "runs" / "tiny-p0-l0-d0" / "row.json").exists()
    out = tmp_path / "out"
    spec, limit = isolation_spec()
    res = run_campaign(write(tmp_path, spec), out=out, engine="local", workers=2, keep_runs=True,
                       progress=False)
    check_isolation(res.rows, limit)
    soft = out / "runs" / "tiny-p1-l0-d0"
    assert json.loads((soft / "row.json").read_text())["failure_kind"] == "timeout"
    assert len(pd.read_csv(soft / "trajectory.csv")) > 0 and (soft / "worker.log").is_file()


def check_isolation(df, limit):
    kinds = list(df["failure_kind"])
    assert kinds == ["timeout", "timeout"], df[["mission_id", "failure_kind", "failure_message"]]
    assert df.iloc[0]["failure_message"].startswith("killed after")
    assert df.iloc[0]["wall_seconds"] < limit + 5 + 10  # the kill comes at limit + grace (5 s)
    soft = df.iloc[1]
    assert soft["failure_message"].startswith(f"time limit {limit} s reached after")
    assert soft["steps_done"] < soft["steps_total"] and soft["sim_seconds"] > 0


@pytest.fixture(scope="module")
def ray_session():
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def test_ray_rows_agree_with_the_local_engine(local_four, ray_session, tmp_path):
    spec, _, local = local_four
    res = run_campaign(spec, out=tmp_path / "ray", engine="ray", progress=False)
    assert res.ran == 4
    pd.testing.assert_frame_equal(comparable(res.rows), comparable(local.rows))
    assert run_campaign(spec, out=tmp_path / "ray", engine="ray", progress=False).ran == 0


def test_isolation_crash_hang_and_time_limit_ray(ray_session, tmp_path):
    crash = run_campaign(write(tmp_path, CRASH_SPEC, "crash.yaml"), out=tmp_path / "crash", engine="ray",
                         progress=False)
    assert list(crash.rows["failure_kind"]) == ["worker_crash"]
    assert "WorkerCrashedError" in crash.rows.iloc[0]["failure_message"]
    def import_mission() -> None:  # nested: Ray ships it by value
        import mrodrake.campaign.mission  # noqa: F401

    t0 = time.perf_counter()
    ray_session.get(ray_session.remote(num_cpus=1, runtime_env={"env_vars": WORKER_ENV})(import_mission).remote())
    spec, limit = isolation_spec(time.perf_counter() - t0)
    res = run_campaign(write(tmp_path, spec), out=tmp_path / "out", engine="ray", progress=False)
    check_isolation(res.rows, limit)


# ------------------------------------------------------------------------------------------ Ctrl-C
@pytest.mark.parametrize("engine", ["local", "ray"])
def test_ctrl_c_keeps_finished_missions_and_exits_130(tmp_path, engine):
    if engine == "ray":
        pytest.importorskip("ray")
    spec = write(tmp_path, f"""
name: interrupt
scenarios:
  - file: {TINY}
seeds:
  plan: {{start: 0, count: 3}}
inject: {{0: raise, 1: hang, 2: hang}}
""")
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "mrodrake", "campaign", str(spec), "--out", str(out),
                             "--workers", "2", "--engine", engine], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    journal = out / "journal.jsonl"
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline and not (journal.is_file() and journal.read_text().count("\n") >= 1):
        time.sleep(0.2)
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    t0 = time.monotonic()
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and time.monotonic() - t0 < 30, err
    assert "Traceback" not in err and "interrupted: 1/3 missions finished" in err
    rows = [json.loads(line)["row"] for line in journal.read_text().splitlines()]
    assert [r["mission_id"] for r in rows] == ["tiny-p0-l0-d0"]
    assert len(pd.read_csv(out / "results.csv")) == 1 and (out / "summary.md").is_file()


def test_entry_seeds_override_the_campaign_seeds(tmp_path):
    camp = load_campaign(write(tmp_path, f"""
name: x
scenarios:
  - file: {TINY}
    seeds: {{plan: {{start: 5, count: 2}}, layout: {{count: 2}}}}
  - generate: {{robots: [2], objects: [1], regions: [3, 4], seeds: {{start: 7, count: 1}}}}
seeds: {{draws: 2}}
"""))
    assert [t.mission_id for t in camp.tasks] == [
        "tiny-p5-l0-d0", "tiny-p5-l1-d0", "tiny-p6-l0-d0", "tiny-p6-l1-d0",
        "gen_n2_m1_k3_s7-p0-l0-d0", "gen_n2_m1_k3_s7-p0-l0-d1", "gen_n2_m1_k4_s7-p0-l0-d0", "gen_n2_m1_k4_s7-p0-l0-d1"]
    assert [t.index for t in camp.tasks] == list(range(8))
    assert {t.instance.family for t in camp.tasks} == {"tiny", "gen_n2_m1_k3", "gen_n2_m1_k4"}
    assert camp.tasks[4].instance.source == "generate_scenario(2, 1, 3, 7)"


def test_generated_scenarios_on_a_map(tmp_path):
    camp = load_campaign(write(tmp_path, """
name: x
scenarios:
  - generate: {robots: [2], objects: [1], regions: [3], seeds: {start: 4, count: 2}, map: lab}
"""))
    assert [t.mission_id for t in camp.tasks] == ["gen_lab_n2_m1_k3_s4-p0-l0-d0", "gen_lab_n2_m1_k3_s5-p0-l0-d0"]
    assert {t.instance.family for t in camp.tasks} == {"gen_lab_n2_m1_k3"}
    assert camp.tasks[0].instance.source == "generate_scenario(2, 1, 3, 4, map='lab')"
    assert {g.name for g in camp.tasks[0].instance.scenario.regions} <= {
        g.name for g in load_scenario(ROOT / "scenarios" / "maps" / "lab.yaml").regions}


def test_an_exception_during_the_simulation_keeps_what_was_simulated(tmp_path, monkeypatch):
    from mrodrake.campaign import execute
    from mrodrake.systems import mission

    run = mission.Mission.run

    def failing_run(self, progress=None, t_max=1e7):
        def fail_at_step_2(done, total):
            if done >= 2:
                raise RuntimeError("Error control wants to select step smaller than minimum allowed (1e-14)")
        return run(self, fail_at_step_2, t_max)

    monkeypatch.setattr(mission.Mission, "run", failing_run)
    (task,) = load_campaign(write(tmp_path, f"name: x\nscenarios:\n  - file: {TINY}\n")).tasks
    row = execute(task)
    assert not row["ok"] and row["failure_kind"] == "integrator"
    assert "Error control wants to select step smaller than minimum allowed" in row["failure_message"]
    assert row["steps_done"] == 2 and row["steps_total"] > 2 and row["sim_seconds"] > 0
    assert row["min_clearance"] > 0 and row["cpu_seconds"] > 0
