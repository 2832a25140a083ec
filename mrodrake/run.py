"""Run a mission end to end (top of the pipeline: planning, execution, outputs): :func:`run_mission` and the
``mrodrake run SCENARIO`` command.

``mrodrake run`` plans (unless ``--plan``), executes the plan in one Drake diagram and writes plan.json,
plan.csv, trajectory.csv, signals.csv, events.csv, replay.html and figures/ to ``--out`` (default
``out/<scenario name>``); a progress bar over plan steps goes to stderr; Ctrl-C stops the simulation cleanly
and still writes what was recorded.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from mrodrake.errors import UserError

if TYPE_CHECKING:
    from mrodrake.systems.mission import MissionLog


def run_mission(scenario, plan=None, planner: str = "stylus", suffix_cycles: int = 1, seed: int | None = None,
                out_dir=None, progress: Callable[[int, int], None] | None = None, **mission_options) -> MissionLog:
    """Plan (unless ``plan`` is given: a Plan or a plan.json path), simulate the prefix and ``suffix_cycles``
    suffix cycles in one diagram, write the outputs to ``out_dir`` (if given) and return the log.  ``seed``: of
    the planner and of the layout (default: the scenario's ``planning.seed``; for a given plan, its own layout)."""
    from mrodrake.planning.plan import plan_scenario
    from mrodrake.scenario import Scenario, load_scenario
    from mrodrake.systems.mission import Mission, load_plan
    from mrodrake.viz.outputs import ensure_output_dir, write_mission

    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    if plan is None:
        plan = plan_scenario(scenario, planner, seed=None if planner == "exact" else seed,
                             suffix_cycles=suffix_cycles, layout_seed=seed)
    elif not hasattr(plan, "steps"):
        plan = load_plan(scenario, plan)
    if out_dir is not None:
        ensure_output_dir(out_dir, "out_dir")
    mission = Mission(scenario, plan, suffix_cycles=suffix_cycles, seed=seed, **mission_options)
    log = mission.run(progress)
    if out_dir is not None:
        write_mission(log, out_dir)
    return log


def add_subparser(subparsers) -> argparse.ArgumentParser:
    """Register ``run`` on the top-level CLI's subparsers."""
    p = subparsers.add_parser(
        "run", help="plan and simulate a mission, write logs, replay and figures",
        description="Plan the scenario's task (or read --plan), simulate the prefix and N suffix cycles in one "
        "Drake diagram with a supervisor (paper Sec. III-A, sequential execution), and write plan.json, "
        "plan.csv, trajectory.csv, signals.csv, events.csv, replay.html and figures/ to the output directory.")
    p.add_argument("scenario", metavar="SCENARIO", help="scenario YAML file")
    p.add_argument("--out", metavar="DIR", default=None, help="output directory (default: out/<scenario name>)")
    p.add_argument("--planner", choices=["stylus", "exact"], default="stylus", help="planner (default stylus)")
    p.add_argument("--plan", metavar="PLAN.json", default=None, help="execute this plan instead of planning")
    p.add_argument("--suffix-cycles", type=int, default=1, metavar="N", help="suffix cycles to simulate (default 1)")
    p.add_argument("--seed", type=int, default=None, help="seed of the planner and of P_s goal points (default: "
                   "planning.seed; with --plan, the plan's own layout)")
    p.add_argument("--execution", choices=["sequential", "concurrent"], default="sequential",
                   help="one primitive at a time (the paper, default), or every primitive as soon as the "
                   "primitives it depends on are done, concurrent motions on reserved corridors")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    from mrodrake.planning.plan import plan_scenario
    from mrodrake.scenario import load_scenario
    from mrodrake.systems.mission import Mission, load_plan
    from mrodrake.viz.outputs import OutputError, ensure_output_dir, write_mission

    if args.suffix_cycles < 0:
        raise UserError(f"--suffix-cycles: must be >= 0, got {args.suffix_cycles}")
    if args.seed is not None and args.seed < 0:
        raise UserError(f"--seed: must be >= 0, got {args.seed}")
    warnings: list[str] = []
    scenario = load_scenario(args.scenario, warnings=warnings)
    for w in warnings:  # outside the controllers' design range: the mission runs, without their guarantees
        print(f"warning: {w}", file=sys.stderr)
    plan = load_plan(scenario, args.plan) if args.plan else None
    out = ensure_output_dir(Path(args.out) if args.out else Path("out") / scenario.name)
    t0 = time.perf_counter()
    if plan is None:
        print(f"planning {scenario.name} with {args.planner} ...", file=sys.stderr)
        plan = plan_scenario(scenario, args.planner, seed=None if args.planner == "exact" else args.seed,
                             suffix_cycles=args.suffix_cycles, layout_seed=args.seed)
    print(plan.summary(), file=sys.stderr)
    mission = Mission(scenario, plan, suffix_cycles=args.suffix_cycles, seed=args.seed, execution=args.execution)

    from tqdm import tqdm

    bar = tqdm(total=mission.total_steps, desc="plan steps", unit="step", file=sys.stderr)

    def progress(done: int, total: int) -> None:
        bar.n = done
        bar.set_postfix(t=f"{mission.simulator.get_context().get_time():.0f}s", refresh=False)
        bar.refresh()

    previous = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, lambda *_: mission.request_stop())
    try:
        log = mission.run(progress)
    finally:
        signal.signal(signal.SIGINT, previous)
        bar.close()
    try:
        files, write_error = write_mission(log, out), None
    except OutputError as exc:
        files, write_error = exc.written, str(exc)
    prim = log.primitive_events
    print(f"{scenario.name}: {'ok' if log.ok else 'FAILED: ' + log.message}")
    print(f"  primitives ok: {int(prim['ok'].sum())}/{len(prim)}   plan steps: {log.steps_done}/{log.steps_total}")
    print(f"  simulated time: {log.sim_seconds:.1f} s   wall: {log.wall_seconds:.1f} s (simulation), "
          f"{time.perf_counter() - t0:.1f} s total")
    print(f"  output: {out}/ ({', '.join(str(f.relative_to(out)) for f in files)})")
    if write_error:
        print(f"error: {write_error}", file=sys.stderr)
        return 1
    return 0 if log.ok else 1
