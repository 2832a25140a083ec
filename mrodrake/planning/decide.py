"""Deciding satisfiability: the unsatisfiability proofs of the default planner.

``plan_scenario(..., planner="stylus")`` answers with a verified plan whose executed run places, "task is
unsatisfiable: <reason>" (UserError, exit status 2) or "no plan found ...; satisfiability unknown"
(NoPlanFound, exit status 3).  "Unsatisfiable" comes only from an over-approximation of what execution can do;
when STyLuS* finds no plan within its iterations, :func:`decide` tries, cheapest first:

1. the sound relaxations of :mod:`mrodrake.planning.relax` (each entity alone, pairs, all mentioned
   entities moving independently without packing, Λ or grasps; power-aware team radii);
2. the interval product on the explicit TS (:mod:`mrodrake.planning.interval`: every step reads its source
   label and then any letters between its source and target labels), when the reachable TS has at most
   :data:`EXPLICIT_STATES` states and :data:`EXPLICIT_TRANSITIONS` transitions;
3. the exact planner when the reachable TS transitions × useful NBA states are at most :data:`EXACT_EDGES`:
   :func:`~mrodrake.planning.exact.solve_exact` finds the optimal plan on the planning product, then on the
   word-family product (:mod:`mrodrake.planning.universal`), and otherwise decides with the over-approximating
   lattice product or, for a deterministic NBA, the word-family product itself.  Its plan is returned if
   STyLuS* finds none within its budget.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from mrodrake.errors import NoPlanFound, UserError
from mrodrake.logic.nba import NBA
from mrodrake.planning.exact import ExactResult, blocked_note, solve_exact
from mrodrake.planning.interval import interval_accepts
from mrodrake.planning.product import planning_nba, useful_states
from mrodrake.planning.relax import Relaxations
from mrodrake.ts import State, TransitionSystem

#: The graph planner decides exactly when its joint states × NBA states are at most this.
EXACT_BOUND = 100_000
#: The exact planner runs when the reachable TS transitions × useful NBA states are at most this.
EXACT_EDGES = 1_000_000
#: The explicit TS (interval product, exact planner) is built up to this many reachable states ...
EXPLICIT_STATES = 60_000
#: ... and used up to this many transitions.
EXPLICIT_TRANSITIONS = 6_000_000
#: ... and only when the candidate successors of the initial state × the state limit are at most this.
EXPLICIT_WORK = 200_000_000


@dataclass
class Decision:
    """What :func:`decide` found out: ``exact`` is the optimal plan when the exact search ran and found one;
    ``undecided`` says why no verdict was reached."""

    exact: ExactResult | None = None
    undecided: str = ""
    stats: dict = field(default_factory=dict)


def ts_state_bound(ts: TransitionSystem) -> int:
    """K^(N+M) (M+1)^N: every region per entity, every grasp per robot."""
    return ts.K ** (ts.N + ts.M) * (ts.M + 1) ** ts.N


def decide(ts: TransitionSystem, nba: NBA, relevant: int, exact_edges: int = EXACT_EDGES,
           banned: tuple[tuple[State, State], ...] = ()) -> Decision:
    """Raise UserError("task is unsatisfiable: ...") when a relaxation or the over-approximating product
    proves it; otherwise the :class:`Decision` (module docstring).  ``banned``: TS transitions the exact
    plan must avoid (placement rejected them); they never enter a proof."""
    t0 = time.perf_counter()
    relax = Relaxations(ts, nba, relevant)
    proof = relax.prove()
    stats = dict(relax.stats)
    if proof is not None:
        raise UserError(proof + blocked_note(ts))
    small = planning_nba(nba, ts)
    q = len(useful_states(small))
    out = Decision(stats=stats)
    ets = None
    if ts.candidate_count(ts.initial) * min(ts_state_bound(ts), EXPLICIT_STATES) <= EXPLICIT_WORK:
        try:
            ets = ts.build(max_states=EXPLICIT_STATES)
        except RuntimeError:
            pass
    if ets is None or ets.num_transitions > EXPLICIT_TRANSITIONS:
        size = (f"beyond {EXPLICIT_STATES} reachable TS states or their successors" if ets is None else
                f"{ets.num_transitions} TS transitions, more than {EXPLICIT_TRANSITIONS}")
        out.undecided = (f"the explicit TS is too large to decide ({size}) and no relaxation proves the task "
                         "unsatisfiable")
        stats["decide_seconds"] = time.perf_counter() - t0
        return out
    stats.update(ts_states=ets.num_states, ts_transitions=ets.num_transitions)
    if not interval_accepts(ts, small, relevant, ets):
        raise UserError(f"task is unsatisfiable: no accepting cycle is reachable in the interval product of the "
                        f"TS ({ets.num_states} states, {ets.num_transitions} transitions) and the NBA "
                        f"({nba.num_states} states): no execution, in any order and crossing interleaving, produces "
                        "a word the task accepts" + blocked_note(ts))
    edges = ets.num_transitions * q
    stats["exact_edges"] = edges
    if edges > exact_edges:
        out.undecided = (f"the explicit product is too large to decide exactly ({ets.num_states} TS states, "
                         f"{ets.num_transitions} transitions × {q} NBA states) and neither a relaxation nor the "
                         "interval product proves the task unsatisfiable")
    else:
        try:
            out.exact = solve_exact(ts, nba, relevant, ets=ets, banned=banned)
        except NoPlanFound as e:
            out.undecided = str(e)
    stats["decide_seconds"] = time.perf_counter() - t0
    return out
