"""``mrodrake bench ts|ltl|plan|control|replay|run``: benchmarks that print a table (never run by the tests).

One module per subcommand (:mod:`~mrodrake.bench.ts`, :mod:`~mrodrake.bench.ltl`, :mod:`~mrodrake.bench.plan`,
:mod:`~mrodrake.bench.control`, :mod:`~mrodrake.bench.replay`, :mod:`~mrodrake.bench.run`); this module
registers them on the command line and imports a benchmark only when it runs.
"""

from __future__ import annotations

import argparse
import sys

from mrodrake.errors import UserError

__all__ = ["add_subparser"]


def _ts(args: argparse.Namespace) -> int:
    from mrodrake.bench.ts import bench_ts

    bench_ts()
    return 0


def _ltl(args: argparse.Namespace) -> int:
    from mrodrake.bench.ltl import run_ltl_benchmark

    run_ltl_benchmark()
    return 0


def _plan(args: argparse.Namespace) -> int:
    from mrodrake.bench.plan import run_plan_benchmark, run_stylus_default_benchmark

    if args.seeds is not None and args.seeds < 1:
        raise UserError(f"--seeds: must be >= 1, got {args.seeds}")
    if args.stylus_default:
        run_stylus_default_benchmark(sys.stdout, seeds=args.seeds or 3)
    else:
        run_plan_benchmark(sys.stdout, seeds=args.seeds or 3)
    return 0


def _control(args: argparse.Namespace) -> int:
    from mrodrake.bench.control import run_control_benchmark

    run_control_benchmark(sys.stdout)
    return 0


def _replay(args: argparse.Namespace) -> int:
    from mrodrake.bench.replay import bench_replay

    bench_replay()
    return 0


def _run(args: argparse.Namespace) -> int:
    from mrodrake.bench.run import run_mission_benchmark

    run_mission_benchmark(sys.stdout, scenario_path=args.scenario)
    return 0


def add_subparser(subparsers) -> argparse.ArgumentParser:
    """Register ``bench`` and its subcommands on the top-level CLI's subparsers."""
    p = subparsers.add_parser("bench", help="benchmarks (not tests)", description="Run a benchmark and print a "
                              "table: ts (TS construction), ltl (LTL->NBA vs Spot), plan (planners), control (map "
                              "and one navigation), replay (HTML replay), run (whole mission; case I unless "
                              "--scenario).")
    sub = p.add_subparsers(dest="what", metavar="BENCHMARK")
    sub.required = True
    q = sub.add_parser("ts", help="TS construction", description="Build the case studies' reachable transition "
                       "systems in fresh processes; print the best and median build time and the peak memory.")
    q.set_defaults(func=_ts)
    q = sub.add_parser("ltl", help="LTL -> NBA vs Spot", description="Translate the 55 Dwyer et al. patterns and "
                       "the case-study formulas; print automaton sizes and times next to Spot's (when installed).")
    q.set_defaults(func=_ltl)
    q = sub.add_parser("plan", help="planners", description="Exact optimum and STyLuS* anytime runs on the case "
                       "studies, STyLuS* on generated scenarios of growing size (or --stylus-default).")
    q.add_argument("--stylus-default", action="store_true",
                   help="STyLuS*'s default problem (100 robots, 1000-state random TS) instead")
    q.add_argument("--seeds", type=int, default=None, metavar="N", help="seeds per problem (default 3)")
    q.set_defaults(func=_plan)
    q = sub.add_parser("control", help="map and one navigation", description="Point-world map construction and "
                       "evaluation times and one simulated navigation of case study I.")
    q.set_defaults(func=_control)
    q = sub.add_parser("replay", help="HTML replay", description="Time the HTML replay writer on synthetic "
                       "missions of case study I (200, 1000, 3000 simulated seconds).")
    q.set_defaults(func=_replay)
    q = sub.add_parser("run", help="whole mission", description="Plan and simulate a whole mission (prefix + one "
                       "suffix cycle); print wall time, simulated time, real-time factor and per-primitive times.")
    q.add_argument("--scenario", metavar="FILE", default=None,
                   help="scenario (default: scenarios/case_study_1.yaml)")
    q.set_defaults(func=_run)
    return p
