"""One mission to one row: plan, simulate, classify the outcome, measure; never raises for a failing mission."""

from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path

import numpy as np

from mrodrake.campaign.draws import randomized_scenario
from mrodrake.campaign.failures import DEFAULT_KINDS, classify, first_line
from mrodrake.campaign.metrics import primitive_records, trajectory_metrics
from mrodrake.campaign.spec import MissionTask
from mrodrake.errors import UserError
from mrodrake.scenario import Scenario

#: Environment of every worker process: single-threaded BLAS.  A mission's outcome depends on the last bits
#: of its linear solves, and multi-threaded OpenBLAS sums in a thread-count dependent order, so without this
#: the rows would depend on the engine (Ray sets OMP_NUM_THREADS=1 itself) and the machine's core count;
#: one thread per mission is also what a pool of one mission per core wants.
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

#: Row columns that measure time on the machine (they differ between runs and engines).
TIMING_COLUMNS = ("plan_wall_seconds", "sim_wall_seconds", "wall_seconds", "cpu_seconds", "real_time_factor")


def base_row(task: MissionTask) -> dict:
    """The row's identification and drawn-parameter columns, outcome columns empty."""
    s = task.instance.scenario
    factors = np.array([p["factors"] for p in task.params.values()]).reshape(-1, 3)
    return {
        "index": task.index, "mission_id": task.mission_id, "family": task.instance.family,
        "scenario": task.instance.key, "source": task.instance.source, "robots": len(s.robots),
        "objects": len(s.objects), "regions": len(s.regions), "planner": task.planner,
        "plan_seed": task.plan_seed, "layout_seed": task.layout_seed, "draw": task.draw,
        "suffix_cycles": task.suffix_cycles, "execution": task.execution,
        "mass_factor_min": float(factors[:, 0].min()), "mass_factor_max": float(factors[:, 0].max()),
        "friction_factor_min": float(factors[:, 1].min()), "friction_factor_max": float(factors[:, 1].max()),
        "frequency_factor_min": float(factors[:, 2].min()), "frequency_factor_max": float(factors[:, 2].max()),
        "params": json.dumps({n: [p["mass"], p["friction_scale"], p["friction_frequency"]]
                              for n, p in task.params.items()}),
        "ok": False, "failure_kind": "", "failure_message": "", "steps_done": None, "steps_total": None,
        "sim_seconds": None, "plan_wall_seconds": None, "sim_wall_seconds": None, "wall_seconds": None,
        "cpu_seconds": None, "real_time_factor": None, "min_clearance": None, "min_clearance_entity": "",
        "min_gap": None,
        "min_gap_pair": "", "max_speed": None, "max_speed_entity": "", "nan_seen": False,
    }


def failure_row(task: MissionTask, kind: str, message: str, wall: float) -> dict:
    """The row of a mission that produced no result of its own (killed, crashed worker)."""
    row = base_row(task)
    row.update(failure_kind=kind, failure_message=first_line(message), wall_seconds=float(wall))
    return row


def _record_log(row: dict, task: MissionTask, scenario: Scenario, log, stopped: bool) -> None:
    """Fill ``row`` from a mission log: progress, timings, the outcome (unless an exception already set
    the failure), the trajectory metrics; write the mission's outputs with ``--keep-runs``."""
    row.update(steps_done=int(log.steps_done), steps_total=int(log.steps_total), sim_seconds=float(log.sim_seconds),
               sim_wall_seconds=float(log.wall_seconds),
               real_time_factor=float(log.sim_seconds / log.wall_seconds) if log.wall_seconds > 0 else None)
    if not row["failure_kind"]:
        row["ok"] = bool(log.ok)
        if stopped and not log.ok:
            row.update(failure_kind="timeout", failure_message=(
                f"time limit {task.time_limit:g} s reached after {log.steps_done}/{log.steps_total} plan steps "
                f"(simulated {log.sim_seconds:.0f} s)"))
        elif not log.ok:
            msg = first_line(log.message)
            kind = getattr(log, "failure_kind", None) or classify("mission", msg, DEFAULT_KINDS["log"])
            row.update(failure_kind=str(kind), failure_message=msg)
    row.update(trajectory_metrics(scenario, log.trajectory))
    row["primitives"] = primitive_records(scenario, log)
    if task.run_dir is not None:
        from mrodrake.viz.outputs import write_mission

        write_mission(log, task.run_dir)


def execute(task: MissionTask) -> dict:
    """Plan and simulate one mission and return its row; never raises for a failing mission."""
    from mrodrake.planning.plan import plan_scenario
    from mrodrake.systems.mission import Mission

    t0, cpu0 = time.perf_counter(), time.process_time()
    row = base_row(task)
    if task.inject == "crash":
        os.abort()
    if task.inject == "hang":
        while True:
            time.sleep(1.0)
    scenario = randomized_scenario(task.instance.scenario, task.params)
    stage, mission, log, timer, stopped = "plan", None, None, None, threading.Event()
    try:
        seed = None if task.planner == "exact" else task.plan_seed
        limit = task.plan_time_limit if task.planner == "stylus" else None
        plan = plan_scenario(scenario, task.planner, seed=seed, iterations=task.iterations, time_limit=limit,
                             suffix_cycles=task.suffix_cycles, layout_seed=task.layout_seed)
        row["plan_wall_seconds"] = time.perf_counter() - t0
        stage = "mission"
        if task.inject == "raise":
            raise RuntimeError(f"injected failure (spec inject[{task.index}])")
        mission = Mission(scenario, plan, suffix_cycles=task.suffix_cycles, seed=task.layout_seed,
                          execution=task.execution, prefetch=False)  # the campaign runs a mission per core

        def stop() -> None:
            stopped.set()
            mission.request_stop()

        if task.inject == "slow":  # simulated time at most wall time: a mission that outlives its soft limit
            mission.simulator.set_target_realtime_rate(1.0)
        elapsed = time.perf_counter() - t0 if task.dispatched is None else time.time() - task.dispatched
        timer = threading.Timer(max(0.0, task.time_limit - elapsed), stop)
        timer.daemon = True
        timer.start()
        log = mission.run()
    except UserError as e:
        msg = first_line(e)
        if stage == "plan" and time.perf_counter() - t0 >= task.time_limit:
            row.update(failure_kind="timeout", failure_message=f"planning: {msg}")
        else:
            kind = classify(stage, msg, DEFAULT_KINDS["plan" if stage == "plan" else "exception"])
            row.update(failure_kind=kind, failure_message=msg if stage == "plan" else f"UserError: {msg}")
    except Exception as e:  # a mission's exception is a recorded failure, never a campaign stop
        msg = f"{type(e).__name__}: {first_line(e)}"
        row.update(failure_kind=classify(stage, msg, DEFAULT_KINDS["exception"]), failure_message=msg)
    finally:
        if timer is not None:
            timer.cancel()
    try:
        if log is None and mission is not None:
            log = mission.log()  # what was simulated before the exception
        if log is not None:
            _record_log(row, task, scenario, log, stopped.is_set())
    except Exception as e:  # the metrics or outputs of a finished mission: still a row, never a lost worker
        row.update(ok=False, failure_kind=row["failure_kind"] or "exception",
                   failure_message=row["failure_message"] or f"recording: {type(e).__name__}: {first_line(e)}")
    row["wall_seconds"], row["cpu_seconds"] = time.perf_counter() - t0, time.process_time() - cpu0
    if task.run_dir is not None:
        Path(task.run_dir).mkdir(parents=True, exist_ok=True)
        (Path(task.run_dir) / "row.json").write_text(json.dumps(row, indent=1, default=str), encoding="utf-8")
    return row
