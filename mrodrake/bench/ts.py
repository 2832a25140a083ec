"""``mrodrake bench ts``: reachable-TS construction of the case studies (time, memory), and P_s decision times."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from mrodrake.packing import fits, place

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"

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


def bench_packing(repeats: int = 5) -> list[tuple[str, float, float]]:
    """Time uncached P_s decisions and one typical place(): rows (case, median ms, max ms) over ``repeats``
    runs, the cache cleared before every decision (not printed by ``mrodrake bench ts``)."""
    typical = [list(t) + [0.75] * nr + [0.2] * no
               for k in range(3) for t in itertools.combinations_with_replacement((1.7, 1.8, 1.9), k)
               for nr in range(5) for no in range(4) if k + nr + no > 0]
    cases = [
        (f"typical R=4 (all {len(typical)} multisets)", [(4.0, t) for t in typical]),
        ("10 equal, R/r = 1.02 x 3.8130", [(3.8130 * 1.02, [1.0] * 10)]),
        ("10 equal, R/r = 0.99 x 3.8130", [(3.8130 * 0.99, [1.0] * 10)]),
        ("14 equal, R/r = 0.99 x 4.3284 (search exhausts)", [(4.3284 * 0.99, [1.0] * 14)]),
    ]
    rows = []
    fc = np.array([[2.1, 0.0], [-2.1, 0.0]])
    times = []
    for seed in range(repeats):
        t0 = time.perf_counter()
        place(4.0, fc, [1.85, 1.85], [0.75, 0.75, 0.2], seed=seed, margin=0.05)
        times.append(time.perf_counter() - t0)
    rows.append(("place 3 new next to 2 fixed, margin 0.05", 1e3 * float(np.median(times)), 1e3 * max(times)))
    for name, calls in cases:
        times = []
        for _ in range(repeats):
            for R, radii in calls:
                fits.cache_clear()
                t0 = time.perf_counter()
                fits(R, radii)
                times.append(time.perf_counter() - t0)
        rows.append((name, 1e3 * float(np.median(times)), 1e3 * float(np.max(times))))
    return rows
