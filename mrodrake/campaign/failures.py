"""Failure kinds of a mission's row, from one table of message patterns."""

from __future__ import annotations

#: Failure kinds by message: (stage, kind, substrings); the first row whose stage matches (``*``: any)
#: and whose substring occurs in the message wins.  Stages: ``plan`` (UserError from planning) and
#: ``mission`` (a failed mission log or an exception raised while building or simulating the mission).
FAILURE_PATTERNS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("plan", "plan_not_found", ("no plan found",)),  # it may end "... no relaxation proves ... unsatisfiable"
    ("plan", "plan_unsat", ("unsatisfiable",)),
    ("mission", "no_order", ("no order of the concurrent actions",)),
    ("mission", "nba_run", ("monitored NBA run",)),
    ("mission", "state_mismatch", ("differs from the plan",)),
    ("mission", "integrator", ("integrator", "step smaller than minimum", "minimum step")),
    ("mission", "primitive_time_limit", ("time limit",)),
    ("mission", "goal_unreachable", ("goal unreachable",)),
    ("mission", "no_grasp_point", ("no reachable grasp point",)),
    ("mission", "no_room", ("no room for an entity", "do not fit")),
    ("mission", "placement", ("no free grasp layout", "no layout keeps the room", "no room to back off",
                              "no room for")),
    ("mission", "outside_free_space", ("not in the free space",)),
    ("mission", "degenerate_map", ("degenerate",)),
    ("mission", "non_finite", ("non-finite", "not finite")),
    ("mission", "controller_fault", ("controller fault",)),
    ("mission", "exception", ("inside the simulation",)),
)
#: Kind when no pattern matches: per stage, and for an exception or a failed mission log.
DEFAULT_KINDS = {"plan": "plan_error", "exception": "exception", "log": "mission_failed"}


def classify(stage: str, message: str, default: str) -> str:
    """The failure kind of ``message`` raised or reported in ``stage`` (``plan`` or ``mission``)."""
    low = message.lower()
    for st, kind, needles in FAILURE_PATTERNS:
        if st in (stage, "*") and any(n.lower() in low for n in needles):
            return kind
    return default


#: Longest failure message a campaign row keeps (an unsatisfiability verdict with its blocked passages runs to
#: several hundred characters; the reason comes last).
MESSAGE_LIMIT = 2000


def first_line(text: str, limit: int = MESSAGE_LIMIT) -> str:
    """The first line of ``text``, cut to ``limit`` characters (marked "...")."""
    line = (str(text).strip().splitlines() or [""])[0]
    return line if len(line) <= limit else line[: limit - 3] + "..."
