"""``mrodrake ltl2nba``: translate LTL formulas to Büchi automata and print them in HOA v1 format."""

from __future__ import annotations

import argparse
import sys

from mrodrake.errors import UserError
from mrodrake.logic.formula import to_str
from mrodrake.logic.parse import parse
from mrodrake.logic.translate import translate

__all__ = ["add_subparser", "run"]

_HELP = """\
Translate LTL formulas (Spot syntax: true false ! & | -> <-> xor X F G U R W M, aliases [] <> ~ && ||)
into state-based Büchi automata, printed as HOA v1 (Acceptance: 1 Inf(0), acc-name: Buchi, explicit
labels), one automaton per formula, in order.  Run convention: the automaton reads the label of the
state being left (q0 -L(s0)-> q1 -L(s1)-> ...), as in Spot and HOA."""


def add_subparser(subparsers) -> argparse.ArgumentParser:
    """Register the ``ltl2nba`` subcommand on an ``argparse`` subparsers object."""
    p = subparsers.add_parser("ltl2nba", help="translate LTL formulas to Büchi automata (HOA output)",
                              description=_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("formulas", nargs="*", metavar="FORMULA", help="LTL formula(s)")
    p.add_argument("-f", "--file", action="append", default=[], metavar="FILE",
                   help="read formulas from FILE, one per line (blank lines and lines starting with # are "
                        "skipped); may be repeated")
    p.add_argument("--translator", choices=("builtin", "spot"), default="builtin",
                   help="builtin (default, pure Python) or spot (needs the optional spottl package)")
    p.set_defaults(func=run)
    return p


def _collect(args) -> list[tuple[str, str]]:
    """``(source, text)`` of every formula: command-line ones first, then the files' lines."""
    items = [(f"formula {i + 1}", text) for i, text in enumerate(args.formulas)]
    for path in args.file:
        try:
            with open(path, encoding="utf-8") as fh:
                lines = fh.read().splitlines()
        except OSError as exc:
            raise UserError(f"{path}: cannot read formula file ({exc.strerror})") from exc
        for lineno, line in enumerate(lines, start=1):
            if line.strip() and not line.lstrip().startswith("#"):
                items.append((f"{path}:{lineno}", line))
    if not items:
        raise UserError("ltl2nba: no formula given (pass FORMULA arguments or -f FILE)")
    return items


def run(args, out=None) -> int:
    """Handler of ``mrodrake ltl2nba``: print one HOA automaton per formula; returns the exit status."""
    out = out if out is not None else sys.stdout
    formulas = [parse(text, source=source) for source, text in _collect(args)]
    for f in formulas:
        out.write(translate(f, backend=args.translator).to_hoa(name=to_str(f)))
    out.flush()
    return 0
