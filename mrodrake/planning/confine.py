"""Regions the task keeps entities out of for good, read off the NBA.

Every letter of an accepted executed word is read on an NBA edge between useful states of the pruned NBA
(:func:`~mrodrake.planning.product.planning_nba`) and satisfies one cube of its guard.  A proposition
``e_k`` that every such cube negates is therefore false at every position of every accepted word; state
labels are letters of the word (:mod:`~mrodrake.planning.semantics`), so on every accepted run entity e is
never in region k: a robot never stands there (it never grasps, carries or releases an object there) and an
object never lies there.  A constraint that holds only for a while (``!r_p U ...``, ``F G !r_p``, ``!r_p``
at the start) leaves some useful edge with a cube that allows ``r_p`` and keeps nobody out.
"""

from __future__ import annotations

from mrodrake.logic.nba import NBA
from mrodrake.planning.product import prune_nba, useful_states
from mrodrake.ts import TransitionSystem, reachable


def never_true(ts: TransitionSystem, nba: NBA, pruned: NBA | None = None) -> int | None:
    """Bit mask of the entity propositions false throughout every accepted executed word (module docstring);
    None when the pruned NBA accepts nothing or the initial label has such a proposition (the task is
    unsatisfiable for a reason other checks name); ``pruned``: ``prune_nba(nba, ts, transit=True)`` if at hand."""
    pruned = prune_nba(nba, ts, transit=True) if pruned is None else pruned
    useful = useful_states(pruned)
    if not useful:
        return None
    full = (1 << ((ts.N + ts.M) * ts.K)) - 1
    maybe = 0
    for q in sorted(useful):
        for guard, d in pruned.edges[q]:
            if d in useful:
                for _p, n in guard:
                    maybe |= full & ~n
    never = full & ~maybe
    if never & ts.label_mask(ts.initial):
        return None
    return never


def task_regions(ts: TransitionSystem, nba: NBA, pruned: NBA | None = None) -> list[set[int]] | None:
    """Per entity (robots, then objects) the regions it can be in on an accepted run: robots travel only
    through regions the task lets them into (from where they start, for their radius); objects lie only in
    regions the task lets them into (where a team can take them is :func:`carry_connections`).  None when
    the task keeps no entity out of a region (``pruned`` as in :func:`never_true`)."""
    never = never_true(ts, nba, pruned)
    if not never:
        return None
    K = ts.K
    out: list[set[int]] = []
    for e in range(ts.N + ts.M):
        allowed = [not never >> (e * K + k) & 1 for k in range(K)]
        if e < ts.N:
            C = ts.connections(ts.robot_radius[e]).copy()
            for k in range(K):
                if not allowed[k]:
                    C[k, :] = C[:, k] = False
            out.append(reachable(C, ts.initial[e]))
        else:
            out.append({k for k in range(K) if allowed[k]})
    return out


def carry_connections(ts: TransitionSystem, j: int, regions: list[set[int]] | None):
    """:meth:`~mrodrake.ts.TransitionSystem.carry_connections` of object j with teams of robots in the regions
    the task lets them into and only between regions it lets j into (``regions`` of :func:`task_regions`)."""
    if regions is None:
        return ts.carry_connections(j)
    C = ts.carry_connections(j, where=regions[: ts.N])
    if C is None:
        return None
    C = C.copy()
    for k in range(ts.K):
        if k not in regions[ts.N + j]:
            C[k, :] = C[:, k] = False
    return C
