"""The ``mrodrake`` command line: validate, ts, draw, ltl2nba, plan, run, campaign, bench.

User errors print ``error: <one line>`` (plus a caret line for formula errors) and exit with status 2
(status 3 when a planner ran out of budget without deciding satisfiability); Ctrl-C exits with status 130
without a traceback.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading

from mrodrake import __version__
from mrodrake.errors import UserError


def _cmd_validate(args: argparse.Namespace) -> int:
    from mrodrake.scenario import load_scenario
    from mrodrake.ts import TransitionSystem

    for path in args.scenarios:
        warnings: list[str] = []
        s = load_scenario(path, warnings=warnings)
        for w in warnings:  # true parameters outside the controllers' design range: warn, never fail
            print(f"warning: {w}", file=sys.stderr)
        print(f"{path}: ok ({s.name}: {len(s.robots)} robots, {len(s.objects)} objects, "
              f"{len(s.regions)} regions, {len(s.workspace.obstacles)} obstacles)")
        for line in TransitionSystem(s).unreachable():
            print(f"{path}: {line}")
    return 0


#: Default ``mrodrake ts --max-transitions``: about 3 GB of memory while the TS is built.
MAX_TRANSITIONS = 10_000_000
#: Peak memory per transition of :meth:`~mrodrake.ts.TransitionSystem.build` (bytes, measured).
_BYTES_PER_TRANSITION = 300


def _cmd_ts(args: argparse.Namespace) -> int:
    from mrodrake.scenario import load_scenario
    from mrodrake.ts import TransitionSystem

    scenario = load_scenario(args.scenario)
    ts = TransitionSystem(scenario)
    limit = args.max_transitions
    est = ts.estimate_size()
    if est.transitions > limit:
        gb = est.transitions * _BYTES_PER_TRANSITION / 1e9
        raise UserError(f"{args.scenario}: the transition system would have about {est.transitions:.2g} transitions "
                        f"({est.states:.2g} states, about {gb:.2g} GB to build), more than --max-transitions "
                        f"{limit}; raise --max-transitions to build it anyway")
    try:
        ets = ts.build(progress=_progress_callback("building TS") if not args.json else None,
                       max_transitions=limit)
    except RuntimeError as e:
        raise UserError(f"{args.scenario}: {e} (estimated {est.transitions:.2g}); raise --max-transitions "
                        "to build it anyway") from None
    if args.json:
        _write_ts_json(ets, sys.stdout)
        return 0
    print(f"scenario:     {scenario.name}")
    print(f"robots:       {ts.N}  objects: {ts.M}  regions: {ts.K}  propositions: {len(ts.propositions)}")
    print(f"initial:      {json.dumps(ts.state_dict(ts.initial))}")
    print(f"states:       {ets.num_states}  (reachable from the initial state)")
    print(f"transitions:  {ets.num_transitions}  (including {ets.num_states} self-loops)")
    print(f"build time:   {ets.build_seconds:.3f} s")
    return 0


def _cmd_draw(args: argparse.Namespace) -> int:
    from pathlib import Path

    from mrodrake.scenario import load_scenario
    from mrodrake.viz.mapview import write_map

    out = Path(args.output) if args.output else Path(Path(args.file).stem + ".png")
    if out.suffix.lower() not in (".png", ".html"):
        raise UserError(f"-o: expected a .png or .html file name, got '{out}'")
    path = write_map(load_scenario(args.file), out)
    print(f"wrote {path}")
    return 0


def _write_ts_json(ets, out) -> None:
    ts = ets.ts
    name, props = json.dumps(ts.scenario.name), json.dumps(ts.propositions)
    out.write(f'{{"scenario": {name}, "propositions": {props}, "initial": 0,\n "states": [\n')
    for u in range(ets.num_states):
        s = ets.state(u)
        d = ts.state_dict(s)
        d = {"id": u, **d, "label": sorted(ts.label(s))}
        out.write(("  " if u == 0 else " ,") + json.dumps(d) + "\n")
    out.write(' ],\n "transitions": [\n')
    first = True
    for u in range(ets.num_states):
        s = ets.state(u)
        for e in range(int(ets.indptr[u]), int(ets.indptr[u + 1])):
            v = int(ets.targets[e])
            acts = [ts.format_action(a, "names") for a in ts.actions(s, ets.state(v))]
            rec = {"src": u, "dst": v, "cost": round(float(ets.costs[e]), 6), "actions": acts}
            out.write(("  " if first else " ,") + json.dumps(rec) + "\n")
            first = False
    out.write(" ]}\n")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def _progress_callback(desc: str):
    """A tqdm-backed progress callback ``(done, total)`` for long builds (stderr, only on a TTY)."""
    if not sys.stderr.isatty():
        return None
    from tqdm import tqdm

    bar = tqdm(desc=desc, unit="state", leave=False)

    def update(done: int, total: int) -> None:
        bar.total = total
        bar.n = done
        bar.refresh()

    return update


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line naming the command and the option (exit status 2)."""

    def error(self, message: str):
        self.exit(2, f"error: {self.prog}: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="mrodrake",
        description="Plan and control multi-robot-object systems under LTL tasks (Verginis, Kantaros, Dimarogonas).",
    )
    parser.add_argument("--version", action="version", version=f"mrodrake {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("validate", help="check scenario files", description="Validate scenario YAML files; "
                       "print one line per file, or one error line and exit 2.  True masses and frictions outside "
                       "the controllers' design range give warning lines on stderr (exit status unchanged).")
    p.add_argument("scenarios", nargs="+", metavar="SCENARIO")
    p.set_defaults(func=_cmd_validate)

    p = sub.add_parser("ts", help="build the reachable transition system",
                       description="Build the coupled transition system (paper Def. 4) reachable from the "
                       "initial state; print its size and build time, or everything as JSON.")
    p.add_argument("scenario", metavar="SCENARIO")
    p.add_argument("--json", action="store_true", help="print states (with labels) and transitions "
                   "(with costs and actions) as JSON")
    p.add_argument("--max-transitions", type=_positive_int, default=MAX_TRANSITIONS, metavar="N",
                   help="refuse to build when the estimated or counted transitions exceed N "
                   f"(default {MAX_TRANSITIONS}, about {MAX_TRANSITIONS * _BYTES_PER_TRANSITION / 1e9:.0f} GB)")
    p.set_defaults(func=_cmd_ts)

    p = sub.add_parser("draw", help="draw a scenario's or map's map",
                       description="Draw the workspace, obstacles, regions (names, radii), the initial layout "
                       "(P_s) and, for each robot radius and each object's smallest strong-enough team, the "
                       "passages it cannot use (walls and obstacles grown by its radius plus the control margin).")
    p.add_argument("file", metavar="FILE", help="a scenario or map file (YAML)")
    p.add_argument("-o", "--output", metavar="OUT", help="map.png (matplotlib) or map.html (self-contained "
                   "page with an inline SVG); default: FILE's stem + .png in the current directory")
    p.set_defaults(func=_cmd_draw)

    from mrodrake import bench, campaign
    from mrodrake import run as run_cli
    from mrodrake.logic import cli as logic_cli
    from mrodrake.planning import cli as plan_cli

    logic_cli.add_subparser(sub)
    plan_cli.add_subparser(sub)
    run_cli.add_subparser(sub)
    campaign.add_subparser(sub)
    bench.add_subparser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    if threading.current_thread() is threading.main_thread():
        # Ctrl-C stops every command cleanly, also when the shell started it with SIGINT ignored (background)
        signal.signal(signal.SIGINT, signal.default_int_handler)
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except UserError as e:
        print(f"error: {e}", file=sys.stderr)
        if e.detail:
            print(e.detail, file=sys.stderr)
        return getattr(e, "exit_status", 2)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    sys.exit(main())
