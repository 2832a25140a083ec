"""Deciding satisfiability before sampling: the default planner's three answers.

``plan_scenario(..., planner="stylus")`` answers with a verified plan, "task is unsatisfiable: <reason>"
(UserError, exit status 2) or "no plan found within the budget; satisfiability unknown" (NoPlanFound, exit
status 3).  Before STyLuS* samples, :func:`decide` tries, cheapest first:

1. the static checks: the NBA has no accepting cycle over labels the TS can produce
   (:func:`~mrodrake.planning.product.prune_nba`), and an object that must move but no team can move
   (:func:`~mrodrake.planning.exact.check_power`);
2. the sound relaxations of :mod:`mrodrake.planning.relax` (each entity alone, pairs, all mentioned
   entities moving independently without packing, Λ or grasps);
3. the exact decision on the explicit product when it is small: the bound ``K^(N+M) (M+1)^N`` on the TS
   states times the useful NBA states is at most :data:`EXACT_BOUND`, and then the reachable TS has at most
   :data:`EXACT_EDGES` / (useful NBA states) transitions (about a second here).  Its optimal plan is kept and
   returned if STyLuS* finds none within its budget.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from mrodrake.errors import UserError
from mrodrake.logic.nba import NBA
from mrodrake.planning.exact import ExactResult, blocked_note, solve_exact
from mrodrake.planning.product import prune_nba, useful_states
from mrodrake.planning.relax import Relaxations
from mrodrake.ts import TransitionSystem

#: Exact decision only if K^(N+M) (M+1)^N × useful NBA states is at most this.
EXACT_BOUND = 100_000
#: ... and the reachable TS transitions × useful NBA states at most this.
EXACT_EDGES = 1_000_000


@dataclass
class Decision:
    """What :func:`decide` found out: ``exact`` is the optimal plan when the exact search ran (satisfiable);
    ``undecided`` says why the exact search did not run."""

    exact: ExactResult | None = None
    undecided: str = ""
    stats: dict = field(default_factory=dict)


def ts_state_bound(ts: TransitionSystem) -> int:
    """K^(N+M) (M+1)^N: every region per entity, every grasp per robot."""
    return ts.K ** (ts.N + ts.M) * (ts.M + 1) ** ts.N


def decide(ts: TransitionSystem, nba: NBA, relevant: int, relax_seconds: float = 1.0,
           exact_bound: int = EXACT_BOUND, exact_edges: int = EXACT_EDGES) -> Decision:
    """Raise UserError("task is unsatisfiable: ...") when a relaxation or the exact search proves it;
    otherwise the :class:`Decision` (see the module docstring)."""
    t0 = time.perf_counter()
    relax = Relaxations(ts, nba, relevant)
    proof = relax.prove(relax_seconds)
    stats = dict(relax.stats)
    if proof is not None:
        raise UserError(proof + blocked_note(ts))
    q = len(useful_states(prune_nba(nba, ts, transit=True)))
    bound = ts_state_bound(ts) * max(q, 1)
    stats["exact_bound"] = bound
    out = Decision(stats=stats)
    if bound > exact_bound:
        out.undecided = (f"the explicit product is too large to decide (up to {bound:.1e} states: "
                         f"{ts_state_bound(ts):.1e} TS states × {q} NBA states) and no relaxation proves the task "
                         "unsatisfiable")
    else:
        ets = ts.build()
        edges = ets.num_transitions * q
        stats["exact_edges"] = edges
        if edges > exact_edges:
            out.undecided = (f"the explicit product is too large to decide ({ets.num_states} TS states, "
                             f"{ets.num_transitions} transitions × {q} NBA states) and no relaxation proves the "
                             "task unsatisfiable")
        else:
            out.exact = solve_exact(ts, nba, relevant, ets=ets)
    stats["decide_seconds"] = time.perf_counter() - t0
    return out
