"""``mrodrake plan FILE``: plan a scenario or a multi-robot graph task, print a summary and the Table-I plan.

FILE is a scenario YAML or a graph task (``format: mrodrake.graph``, :mod:`mrodrake.planning.graph`).  Exit
status 0 with a verified plan; 2 for user errors (an unsatisfiable task with its reason, an object no team can
move, bad options); 3 when the budget ran out before a plan was found and satisfiability is undecided.
"""

from __future__ import annotations

import argparse
import sys


def add_subparser(subparsers) -> argparse.ArgumentParser:
    """Register ``plan`` on the top-level CLI's subparsers."""
    p = subparsers.add_parser(
        "plan", help="plan a prefix-suffix run that satisfies the task",
        description="Plan an infinite TS run prefix (suffix)^ω that satisfies the scenario's task (paper "
        "Sec. III-B) with STyLuS* or the exact optimal graph search, verify it, and print it as the "
        "paper's Table I.")
    p.add_argument("scenario", metavar="FILE", help="scenario YAML file, or a graph task (format: mrodrake.graph)")
    p.add_argument("--planner", choices=["stylus", "exact"], default="stylus",
                   help="STyLuS* sampling planner (default) or exact optimal search on the explicit product")
    p.add_argument("--seed", type=int, default=None, help="random seed (default: planning.seed)")
    p.add_argument("--iterations", type=int, default=None,
                   help="STyLuS* tree iterations (default: planning.iterations; without a plan by then, the "
                   "satisfiability decision runs; if it is undecided, STyLuS* samples longer before reporting unknown)")
    p.add_argument("--time-limit", type=float, default=None, metavar="S", help="STyLuS* wall-clock limit (s)")
    p.add_argument("-o", "--output", metavar="PLAN.json", help="write the plan as JSON")
    p.add_argument("--table", metavar="PLAN.csv", help="write the plan table as CSV")
    p.set_defaults(func=run)
    return p


def _progress_bar(planner: str):
    """A tqdm progress callback on stderr (None when stderr is not a terminal)."""
    if not sys.stderr.isatty():
        return None, None
    from tqdm import tqdm

    bar = tqdm(desc=planner, unit="it", leave=False, file=sys.stderr)

    def update(info: dict) -> None:
        if "message" in info:
            bar.set_description(f"{planner}: {info['message']}")
            bar.refresh()
            return
        bar.total = max(info["iterations"], info["iteration"])
        bar.n = info["iteration"]
        best = info.get("best")
        if best is not None and best < float("inf"):
            bar.set_postfix(best=f"{best:.1f}", refresh=False)
        bar.refresh()

    return update, bar


def run(args: argparse.Namespace) -> int:
    from mrodrake.errors import UserError
    from mrodrake.planning.graph import is_graph_task
    from mrodrake.planning.plan import plan_graph, plan_scenario

    if args.planner == "exact" and (args.iterations is not None or args.time_limit is not None):
        raise UserError("--iterations/--time-limit: only apply to --planner stylus")
    graph = is_graph_task(args.scenario)
    update, bar = _progress_bar(args.planner)
    try:
        plan = (plan_graph if graph else plan_scenario)(args.scenario, planner=args.planner, seed=args.seed,
                                                        iterations=args.iterations, time_limit=args.time_limit,
                                                        progress=update)
    finally:
        if bar is not None:
            bar.close()
    if args.output:
        try:
            plan.write(args.output)
        except OSError as e:
            raise UserError(f"-o: cannot write {args.output}: {e.strerror}") from None
    table = plan.table()
    if args.table:
        try:
            table.to_csv(args.table, index=False)
        except OSError as e:
            raise UserError(f"--table: cannot write {args.table}: {e.strerror}") from None
    st = plan.stats
    print(f"scenario:   {plan.scenario}")
    print(f"formula:    {plan.formula}")
    seed = f" (seed {plan.seed})" if plan.seed is not None else ""
    print(f"planner:    {plan.planner}{seed}")
    print(f"cost:       {plan.total_cost:.2f} = prefix {plan.prefix_cost:.2f} + suffix {plan.suffix_cost:.2f}")
    print(f"lengths:    prefix {len(plan.prefix)} steps, suffix {len(plan.suffix)} steps")
    timing = f"{st.get('total_seconds', 0.0):.2f} s"
    if st.get("first_plan_seconds") is not None:
        timing += f", {st.get('iterations')} iterations (first plan after {st['first_plan_seconds']:.2f} s)"
    print(f"time:       {timing}")
    if graph:
        print("verified:   every step an edge of each robot's graph; the lasso of labels satisfies the task")
    else:
        print("verified:   every step re-derived from the TS rules; planned on the executed words (each step's "
              "actions run in the order listed, every crossing interleaving reaches the NBA state), and every word "
              "executing the lasso can produce satisfies the task")
    import pandas as pd

    with pd.option_context("display.max_rows", None, "display.max_colwidth", None, "display.width", 200):
        print(table[["step", "part", "from", "to", "actions", "cost"]].to_string(index=False,
                                                                               float_format=lambda x: f"{x:.2f}"))
    return 0
