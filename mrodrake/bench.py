"""``mrodrake bench ts|ltl|plan|control|replay|run``: benchmarks that print a table (never run by the tests)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from mrodrake.errors import UserError

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"

_TS_PROBE = r"""
import json, resource, sys, time
from mrodrake.scenario import load_scenario
from mrodrake.ts import TransitionSystem
sc = load_scenario(sys.argv[1])
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
ts = TransitionSystem(sc)
ets = ts.build()
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"states": ets.num_states, "transitions": ets.num_transitions,
                  "seconds": ets.build_seconds, "peak_mb": after / 1024, "delta_mb": (after - before) / 1024}))
"""


def bench_ts(repeats: int = 3, stream=sys.stdout) -> list[dict]:
    """Build the case studies' reachable TS in fresh processes; report best time and peak memory."""
    rows = []
    for name in ("case_study_1", "case_study_2"):
        runs = []
        for _ in range(repeats):
            out = subprocess.run([sys.executable, "-c", _TS_PROBE, str(SCENARIOS / f"{name}.yaml")],
                                 capture_output=True, text=True, check=True)
            runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
        best = min(runs, key=lambda r: r["seconds"])
        rows.append({"scenario": name, **best, "median_seconds": sorted(r["seconds"] for r in runs)[len(runs) // 2]})
    print(f"{'scenario':<14} {'states':>8} {'transitions':>12} {'best s':>8} {'median s':>9} "
          f"{'peak RSS MB':>12} {'build MB':>9}", file=stream)
    for r in rows:
        print(f"{r['scenario']:<14} {r['states']:>8} {r['transitions']:>12} {r['seconds']:>8.3f} "
              f"{r['median_seconds']:>9.3f} {r['peak_mb']:>12.0f} {r['delta_mb']:>9.0f}", file=stream)
    print("targets: case_study_2 <= 1 s and <= 1024 MB (paper: 1.52 h)", file=stream)
    return rows


def run(what: str, args=None) -> int:
    seeds = getattr(args, "seeds", None)
    if seeds is not None and seeds < 1:
        raise UserError(f"--seeds: must be >= 1, got {seeds}")
    if what == "ts":
        bench_ts()
    elif what == "ltl":
        from mrodrake.logic.bench import run_ltl_benchmark

        run_ltl_benchmark()
    elif what == "plan":
        from mrodrake.planning.bench import run_plan_benchmark, run_stylus_default_benchmark

        if getattr(args, "stylus_default", False):
            run_stylus_default_benchmark(sys.stdout, seeds=getattr(args, "seeds", None) or 3)
        else:
            run_plan_benchmark(sys.stdout, seeds=getattr(args, "seeds", None) or 3)
    elif what == "control":
        from mrodrake.control.bench import run_control_benchmark

        run_control_benchmark(sys.stdout)
    elif what == "replay":
        from mrodrake.viz.replay import bench_replay

        bench_replay()
    elif what == "run":
        from mrodrake.systems.bench_run import run_mission_benchmark

        run_mission_benchmark(sys.stdout, scenario_path=getattr(args, "scenario", None))
    return 0
