"""``mrodrake bench plan``: planning performance (never part of the default test run).

``mrodrake bench plan --stylus-default`` runs :func:`run_stylus_default_benchmark` instead: STyLuS*'s own
default problem (:mod:`mrodrake.planning.stylus_default`) next to the published MATLAB times.

Three tables:

1. the exact optimum of case studies I and II (explicit TS and product sizes, time);
2. STyLuS* on the case studies per seed: time to the first plan, then the best cost (as a ratio to the
   exact optimum) after 1, 5, 10 and 30 s of one anytime run, and the time it first reaches the optimum;
3. STyLuS* on generated scenarios of growing size (N robots, M objects, K regions on the case-study
   office, tasks of the paper's shape with complete configurations, see
   :func:`~mrodrake.planning.generate.generate_scenario`), where the explicit TS is far too large:
   an upper bound on its states, time to the first plan, first and final cost.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from mrodrake.errors import UserError

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
CHECKPOINTS = (1.0, 5.0, 10.0, 30.0)
SIZES = ((4, 2, 3), (6, 3, 4), (8, 4, 6), (10, 5, 8), (12, 6, 8), (30, 15, 12))


def _best_at(history, t: float) -> float:
    costs = [c for s, _, c in history if s <= t]
    return min(costs) if costs else float("nan")


def run_plan_benchmark(stream=sys.stdout, seeds: int = 3, horizon: float = 30.0,
                       sizes=SIZES, generated_limit: float = 60.0, generated_seconds: float = 10.0) -> dict:
    """Run the three benchmarks, print their tables to ``stream`` and return the rows."""
    from mrodrake.planning.exact import solve_exact
    from mrodrake.planning.generate import generate_scenario
    from mrodrake.planning.plan import task_nba
    from mrodrake.planning.semantics import relevant_mask
    from mrodrake.planning.stylus import Stylus
    from mrodrake.scenario import load_scenario
    from mrodrake.ts import TransitionSystem

    out: dict = {"exact": [], "stylus": [], "generated": []}

    def say(line: str = "") -> None:
        print(line, file=stream, flush=True)

    say("exact optimum (shortest prefix to an accepting product state + shortest cycle through it)")
    say(f"{'scenario':<14} {'TS states':>10} {'TS trans.':>11} {'prod. nodes':>12} {'prod. edges':>12} "
        f"{'cycles':>7} {'cost':>10} {'prefix':>9} {'suffix':>9} {'seconds':>8}")
    cases = {}
    for name in ("case_study_1", "case_study_2"):
        sc = load_scenario(SCENARIOS / f"{name}.yaml")
        ts = TransitionSystem(sc)
        formula, nba = task_nba(sc, ts)
        rel = relevant_mask(ts, formula)
        t0 = time.perf_counter()
        res = solve_exact(ts, nba, rel)
        secs = time.perf_counter() - t0
        opt = res.prefix_cost + res.suffix_cost
        cases[name] = (ts, nba, rel, opt)
        st = res.stats
        row = {"scenario": name, "cost": opt, "prefix": res.prefix_cost, "suffix": res.suffix_cost,
               "seconds": secs, **{k: st[k] for k in ("ts_states", "ts_transitions", "product_nodes",
                                                       "product_edges", "cycle_searches")}}
        out["exact"].append(row)
        say(f"{name:<14} {st['ts_states']:>10} {st['ts_transitions']:>11} {st['product_nodes']:>12} "
            f"{st['product_edges']:>12} {st['cycle_searches']:>7} {opt:>10.1f} {res.prefix_cost:>9.1f} "
            f"{res.suffix_cost:>9.1f} {secs:>8.2f}")
    say()
    marks = [t for t in CHECKPOINTS if t <= horizon]
    say(f"STyLuS* anytime runs of {horizon:g} s: best cost / exact optimum after t seconds")
    say(f"{'scenario':<14} {'seed':>4} {'first s':>8} {'first':>7} "
        + " ".join(f"{f'@{t:g}s':>7}" for t in marks) + f" {'opt s':>7} {'iters':>8} {'nodes':>8}")
    for name, (ts, nba, rel, opt) in cases.items():
        for seed in range(seeds):
            res = Stylus(ts, nba, rel, seed=seed).run(10**9, time_limit=horizon)
            h = res.history
            row = {"scenario": name, "seed": seed, "first_seconds": res.stats["first_plan_seconds"],
                   "first_ratio": h[0][2] / opt, "iterations": res.stats["iterations"],
                   "ratios": {t: _best_at(h, t) / opt for t in marks}, "history": h,
                   "optimum_seconds": next((s for s, _, c in h if c <= opt * (1 + 1e-9)), None)}
            out["stylus"].append(row)
            say(f"{name:<14} {seed:>4} {row['first_seconds']:>8.2f} {row['first_ratio']:>7.3f} "
                + " ".join(f"{row['ratios'][t]:>7.3f}" for t in marks)
                + (f" {row['optimum_seconds']:>7.2f}" if row["optimum_seconds"] is not None else f" {'-':>7}")
                + f" {row['iterations']:>8} {res.stats['prefix_nodes'] + res.stats['suffix_nodes']:>8}")
    say("targets: first plan <= 5 s (paper: 1.23+0.64 min, 3.73+1.43 min); within 1.2x of the optimum by 30 s; "
        "case II at the optimum (1.000) by 10 s")
    say()
    say(f"STyLuS* on generated office scenarios (complete-configuration tasks): first plan (limit "
        f"{generated_limit:g} s), then the cost of a {generated_seconds:g} s anytime run")
    say(f"{'N':>3} {'M':>3} {'K':>3} {'seed':>4} {'TS states <=':>13} {'NBA':>4} {'first s':>8} "
        f"{'first cost':>11} {f'cost@{generated_seconds:g}s':>10} {'iters':>7}")
    for n, m, k in sizes:
        for seed in range(max(1, seeds - 1)):
            sc = generate_scenario(n, m, k, seed, full=True)
            ts = TransitionSystem(sc)
            formula, nba = task_nba(sc, ts)
            rel = relevant_mask(ts, formula)
            bound = k ** (n + m) * (m + 1) ** n
            row = {"N": n, "M": m, "K": k, "seed": seed, "ts_bound": bound, "nba_states": nba.num_states}
            try:
                first = Stylus(ts, nba, rel, seed=seed).run(10**9, time_limit=generated_limit, stop_at_first=True)
                res = Stylus(ts, nba, rel, seed=seed).run(10**9, time_limit=generated_seconds)
                row.update(first_seconds=first.stats["first_plan_seconds"], first_cost=first.history[0][2],
                           final_cost=res.history[-1][2], iterations=res.stats["iterations"])
                say(f"{n:>3} {m:>3} {k:>3} {seed:>4} {bound:>13.2e} {nba.num_states:>4} "
                    f"{row['first_seconds']:>8.2f} {row['first_cost']:>11.1f} {row['final_cost']:>10.1f} "
                    f"{row['iterations']:>7}")
            except UserError as e:
                row.update(error=str(e))
                say(f"{n:>3} {m:>3} {k:>3} {seed:>4} {bound:>13.2e} {nba.num_states:>4} no plan: {e}")
            out["generated"].append(row)
    say("targets: a plan for N=10, M=5, K=8 within 60 s; a first plan for N=30, M=15, K=12 within 10 s")
    return out


def run_stylus_default_benchmark(stream=sys.stdout, seeds: int = 3, horizon: float = 30.0) -> list[dict]:
    """STyLuS*'s default problem per seed (one random TS each): NBA size and time, pruning, the first plan
    (prefix + suffix time of one anytime run, its cost) and the cost after ``horizon`` seconds; the final
    plan is verified (:meth:`~mrodrake.planning.plan.Plan.verify`)."""
    from mrodrake.planning.plan import Plan, graph_task_nba
    from mrodrake.planning.semantics import SourceWords, relevant_mask
    from mrodrake.planning.stylus import Stylus
    from mrodrake.planning.stylus_default import REFERENCE, TASK, stylus_default_ts

    def say(line: str = "") -> None:
        print(line, file=stream, flush=True)

    ref = REFERENCE
    say(f"STyLuS* default problem: 100 robots, one random TS of 1000 states (average degree 28), {TASK}")
    say(f"reference (MATLAB, first plan): NBA {ref['nba_seconds']} s ({ref['nba_states']} states, ltl2ba), pruning "
        f"{ref['prune_seconds']} s, prefix {ref['prefix_seconds']} s + suffix {ref['suffix_seconds']} s = "
        f"{ref['prefix_seconds'] + ref['suffix_seconds']:.1f} s")
    say(f"{'seed':>4} {'TS s':>6} {'NBA':>4} {'vs':>3} {'NBA s':>6} {'prune s':>8} {'first s':>8} {'first cost':>11} "
        f"{'cost@10s':>10} {f'cost@{horizon:g}s':>10} {'iters':>7} {'verified':>8}")
    rows = []
    for seed in range(seeds):
        t0 = time.perf_counter()
        ts = stylus_default_ts(seed)
        ts_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        f, nba = graph_task_nba(ts)
        nba_s = time.perf_counter() - t0
        rel = relevant_mask(ts, f)
        t0 = time.perf_counter()
        planner = Stylus(ts, nba, rel, seed=seed)
        prune_s = time.perf_counter() - t0
        res = planner.run(10**9, time_limit=horizon)
        h = res.history
        plan = Plan.from_runs(ts, ts.name, str(f), "stylus", seed, res.prefix, res.suffix, SourceWords(ts, nba, rel))
        plan.verify(ts, nba, f)
        row = {"seed": seed, "ts_seconds": ts_s, "nba_states": nba.num_states, "nba_seconds": nba_s,
               "prune_seconds": prune_s, "first_seconds": h[0][0], "first_cost": h[0][2],
               "cost_10": _best_at(h, 10.0), "cost_horizon": plan.total_cost, "iterations": res.stats["iterations"]}
        rows.append(row)
        say(f"{seed:>4} {ts_s:>6.2f} {nba.num_states:>4} {ref['nba_states']:>3} {nba_s:>6.2f} {prune_s:>8.2f} "
            f"{row['first_seconds']:>8.2f} {row['first_cost']:>11.0f} {row['cost_10']:>10.0f} "
            f"{row['cost_horizon']:>10.0f} {row['iterations']:>7} {'yes':>8}")
    say("target: first prefix + suffix <= 10 s (MATLAB reference 37.8 s); 'first s' counts from the start of "
        "sampling (pruning and NBA listed apart, as in the reference)")
    return rows
