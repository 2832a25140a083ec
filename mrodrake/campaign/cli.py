"""``mrodrake campaign SPEC.yaml``: the subcommand."""

from __future__ import annotations

import argparse

from mrodrake.campaign.run import run_campaign


def add_subparser(subparsers) -> argparse.ArgumentParser:
    """Register ``campaign`` on the top-level CLI's subparsers."""
    p = subparsers.add_parser(
        "campaign", help="run many plan + execute missions (randomized plants), summarize the failures",
        description="Run every mission of a campaign spec (scenarios x plan seeds x layout seeds x parameter "
        "draws) in isolated workers, append each row to DIR/journal.jsonl (a rerun resumes), and write "
        "results.csv (+ results.parquet with pyarrow), summary.md and figures/.")
    p.add_argument("spec", metavar="SPEC.yaml", help="campaign spec file")
    p.add_argument("--out", metavar="DIR", default=None, help="output directory (default: out/campaigns/<name>)")
    p.add_argument("--engine", choices=["local", "ray"], default="local",
                   help="local process pool (default) or Ray tasks")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="missions at a time (default: the core count; with Ray: the cluster's CPUs)")
    p.add_argument("--address", metavar="ADDR", default=None,
                   help="with --engine ray: join this cluster (auto or HOST:PORT) instead of starting Ray")
    p.add_argument("--keep-runs", action="store_true",
                   help="also write every mission's own outputs (logs, replay, figures) to DIR/runs/<mission>/")
    p.set_defaults(func=_cmd_campaign)
    return p


def _cmd_campaign(args: argparse.Namespace) -> int:
    res = run_campaign(args.spec, out=args.out, engine=args.engine, workers=args.workers, address=args.address,
                       keep_runs=args.keep_runs, progress=True)
    print(res.summary)
    print(f"results: {res.out}/results.csv, summary: {res.out}/summary.md, figures: {res.out}/figures/")
    return 0
