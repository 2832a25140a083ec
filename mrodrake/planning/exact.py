"""Exact optimal prefix-suffix planning on the explicit product (paper Sec. III-B, graph search).

The optimal plan in prefix-suffix form minimises ``cost(prefix) + cost(suffix)`` over the accepting
product states ``a``: the prefix is a shortest path from the initial product state to ``a`` and the
suffix a shortest non-empty cycle through ``a`` (Smith et al. 2011; Ulusoy et al. 2014).  We

1. prune the NBA (guards no TS label satisfies) and keep the NBA states on some path from the initial
   state to an accepting cycle (:func:`~mrodrake.planning.product.useful_states`);
2. build the reachable product as a CSR graph (:class:`~mrodrake.planning.product.ExplicitProduct`)
   and run one Dijkstra from the initial node (``scipy.sparse.csgraph``);
3. keep the reachable accepting nodes that lie in a non-trivial strongly connected component and give
   each a lower bound on its cycle, ``LB(a) = min_{a→y} χ(a, y) + d(y, A)`` (distance back to *any*
   accepting node: one multi-source Dijkstra on the reversed graph);
4. visit candidates by increasing ``d(init, a) + LB(a)`` and stop once that bound reaches the best
   total found; each cycle is a Dijkstra from ``a`` limited to ``best − d(init, a)``.

When no candidate exists the task is unsatisfiable on this TS (a proof: the whole reachable product was
searched).  :func:`check_power` detects the common cause "an object must move but no team is powerful
enough" before any search.
"""

from __future__ import annotations

import itertools
import time
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from mrodrake.errors import NoPlanFound, UserError
from mrodrake.logic.nba import NBA
from mrodrake.planning.confine import task_regions
from mrodrake.planning.interval import interval_accepts
from mrodrake.planning.product import Product, optimal_lasso, prune_nba, restrict_nba, useful_states
from mrodrake.planning.universal import is_deterministic, solve_families
from mrodrake.ts import ExplicitTS, TransitionSystem


# ---------------------------------------------------------------------------------------------- power
def max_team_power(ts: TransitionSystem, j: int, among: Sequence[int] | None = None,
                   region: int | None = None) -> tuple[float, tuple[int, ...]]:
    """Largest power Σζ_i of a team that can grasp object j in some region (its covering disk fits), with the
    team; ``among``: the robots it may draw on (default all), ``region``: only that region.  Enumerates teams
    of up to 16 candidate robots; beyond that the bound Σ_i ζ_i over them."""
    robots = tuple(range(ts.N)) if among is None else tuple(sorted(among))
    if len(robots) > 16:
        return float(sum(ts.power[i] for i in robots)), robots
    regions = range(ts.K) if region is None else (region,)
    teams = []
    for n in range(1, len(robots) + 1):
        for team in itertools.combinations(robots, n):
            teams.append((sum(ts.power[i] for i in team), team))
    teams.sort(key=lambda x: (-x[0], len(x[1]), x[1]))
    fitted: dict[tuple, bool] = {}
    for power, team in teams:
        key = tuple(sorted(ts.robot_radius[i] for i in team))
        ok = fitted.get(key)
        if ok is None:
            r = ts.covering_radius(j, team)
            ok = any(ts.region_fits(k, [r]) for k in regions)
            fitted[key] = ok
        if ok:
            return float(power), team
    return 0.0, ()


_IMMOVABLE: weakref.WeakKeyDictionary[TransitionSystem, dict] = weakref.WeakKeyDictionary()


def immovable_objects(ts: TransitionSystem) -> dict[int, tuple[float, tuple[int, ...]]]:
    """Objects no team can transport (Λ fails for every team that fits): j -> (max power, that team)
    (computed once per TS)."""
    out = _IMMOVABLE.get(ts)
    if out is None:
        out = {}
        for j in range(ts.M):
            power, team = max_team_power(ts, j)
            if power < ts.required_power[j]:
                out[j] = (power, team)
        _IMMOVABLE[ts] = out
    return dict(out)


@dataclass(frozen=True)
class Pinned:
    """Object ``obj`` cannot leave its initial region: the robots the task lets into it (``crew``;
    ``kept_out``: those that could get there but the task keeps out) muster at most ``power`` with a team
    (``team``) that fits there."""

    obj: int
    region: int
    power: float
    team: tuple[int, ...]
    crew: tuple[int, ...]
    kept_out: tuple[int, ...]

    def reason(self, ts: TransitionSystem) -> str:
        """Object, region, power needed, the robots let in and those kept out."""
        rn, k = ts.robot_names, ts.region_names[self.region]
        crew = ", ".join(rn[i] for i in self.crew) or "none"
        best = f"team {'+'.join(rn[i] for i in self.team)}" if self.team else "no team of them fits"
        return (f"object {ts.object_names[self.obj]} must leave region {k} but needs power "
                f"{ts.required_power[self.obj]:g} and the robots the task lets into {k} ({crew}) reach at most "
                f"power {self.power:g} ({best}; the task keeps {', '.join(rn[i] for i in self.kept_out)} out of "
                f"{k} on every accepted run)")


def pinned_objects(ts: TransitionSystem, nba: NBA, skip=(), pruned: NBA | None = None) -> dict[int, Pinned]:
    """Objects (not in ``skip``) that no team of the robots the task lets into their initial region can grasp
    there with enough power (:func:`~mrodrake.planning.confine.task_regions`), when the task keeps out some
    robot that could get there (``pruned``: ``prune_nba(nba, ts, transit=True)`` if at hand)."""
    regions = task_regions(ts, nba, pruned)
    if regions is None:
        return {}
    out = {}
    where = ts.robot_regions()
    for j in range(ts.M):
        k = ts.initial[ts.N + j]
        crew = tuple(i for i in range(ts.N) if k in regions[i])
        kept_out = tuple(i for i in range(ts.N) if k in where[i] and k not in regions[i])
        if j in skip or not kept_out:
            continue
        power, team = max_team_power(ts, j, among=crew, region=k)
        if power < ts.required_power[j]:
            out[j] = Pinned(j, k, power, team, crew, kept_out)
    return out


def check_power(ts: TransitionSystem, nba: NBA) -> None:
    """Raise a one-line UserError when the task needs an object to move that no team can move.

    Static check: with every object fixed in its initial region that no team can move
    (:func:`immovable_objects`) or that no team of the robots the task lets into that region can
    (:func:`pinned_objects`), the pruned NBA has no accepting cycle reachable from its initial state, while
    without fixing them it has one.
    """
    stuck = immovable_objects(ts)
    pruned = prune_nba(nba, ts, transit=True)
    if not useful_states(pruned):
        return  # unsatisfiable for another reason; the planner reports it
    pinned = pinned_objects(ts, nba, skip=stuck, pruned=pruned)
    if not stuck and not pinned:
        return
    N = ts.N
    init = ts.initial

    def empty_with(js) -> bool:
        fixed = {N + j: init[N + j] for j in js}
        return not useful_states(prune_nba(nba, ts, fixed, transit=True))

    held = sorted(set(stuck) | set(pinned))
    if not empty_with(held):
        return
    culprits = [j for j in held if empty_with([j])] or held
    j = culprits[0]
    others = f" (also: {', '.join(ts.object_names[c] for c in culprits[1:])})" if len(culprits) > 1 else ""
    if j in pinned:
        raise UserError(f"task is unsatisfiable: {pinned[j].reason(ts)}{others}")
    power, team = stuck[j]
    who = "+".join(ts.robot_names[i] for i in team) if team else "none"
    why = ""
    best = ts.smallest_team(j)
    if best is not None:  # strong teams exist, but none fits in a region with the object
        why = (f"; no team strong enough fits in any region ({ts.team_size_note(best[1])}, largest region radius "
               f"{max(ts.region_radius):.2f} m)")
    raise UserError(
        f"task is unsatisfiable: object {ts.object_names[j]} must leave region "
        f"{ts.region_names[init[N + j]]} but needs power {ts.required_power[j]:g} and the maximum team "
        f"power is {power:g} (team {who}){others}{why}"
    )


# ---------------------------------------------------------------------------------------------- search
@dataclass
class ExactResult:
    """Optimal lasso as product nodes; ``stats`` holds sizes and timings."""

    prefix: list
    suffix: list
    prefix_cost: float
    suffix_cost: float
    stats: dict = field(default_factory=dict)


def blocked_note(ts: TransitionSystem) -> str:
    """``"; blocked: ..."`` naming the travels no passage allows (:meth:`TransitionSystem.unreachable`), or ""."""
    lines = ts.unreachable()
    return "; blocked: " + "; ".join(lines) if lines else ""


def solve_exact(ts: TransitionSystem, nba: NBA, relevant: int,
                progress: Callable[[str], None] | None = None, ets: ExplicitTS | None = None,
                banned=()) -> ExactResult:
    """Optimal prefix-suffix plan on the executed-word semantics (``relevant``: the task's AP_φ mask; see the
    module docstring).  Without one, the over-approximating product decides: UserError when it has no
    accepting cycle either (the task is unsatisfiable), else NoPlanFound.  ``ets``: the explicit TS if already
    built; ``banned``: TS transitions (state pairs, both directions) the plan must not use."""
    t0 = time.perf_counter()
    check_power(ts, nba)
    pruned = prune_nba(nba, ts, transit=True)
    useful = useful_states(pruned)
    stats: dict = {"nba_states": nba.num_states, "nba_useful_states": len(useful)}
    if nba.initial not in useful:
        raise UserError(f"task is unsatisfiable: the NBA ({nba.num_states} states) has no accepting cycle "
                        "whose guards a TS label can satisfy (searched the pruned NBA)")
    small = restrict_nba(pruned, useful)
    product = Product(ts, small, relevant)
    if progress:
        progress("building the transition system")
    if ets is None:
        ets = ts.build()
    if progress:
        progress("building the product")
    ep = product.build(ets.without(banned))
    g = ep.graph
    n = ep.num_nodes
    stats.update(ts_states=ets.num_states, ts_transitions=ets.num_transitions, product_nodes=n,
                 product_edges=ep.num_edges, build_seconds=time.perf_counter() - t0)
    if progress:
        progress("shortest paths from the initial state")
    found = optimal_lasso(g, ep.initial, ep.accepting_mask(), stats)
    if found is None:
        return _without_common_states(ts, nba, small, product, ets, banned, stats, progress, t0)
    prefix_ids, suffix_ids = found
    node = ep.node
    prefix = [node(v) for v in prefix_ids]
    suffix = [node(v) for v in suffix_ids]
    pc = sum(ts.cost(a[0], b[0]) for a, b in zip(prefix, prefix[1:] + suffix[:1]))
    sc = sum(ts.cost(a[0], b[0]) for a, b in zip(suffix, suffix[1:] + suffix[:1]))
    stats["seconds"] = time.perf_counter() - t0
    return ExactResult(prefix, suffix, pc, sc, stats)


def _unsat(ts: TransitionSystem, what: str) -> UserError:
    stuck = immovable_objects(ts)
    note = "; immovable objects: " + ", ".join(ts.object_names[j] for j in sorted(stuck)) if stuck else ""
    return UserError("task is unsatisfiable: " + what + note + blocked_note(ts))


def _without_common_states(ts, nba, small, product, ets, banned, stats, progress, t0):
    """The planning product has no lasso: decide on the over-approximations, or plan on word families."""
    sizes = f"TS ({ets.num_states} states, {ets.num_transitions} transitions) and the NBA ({nba.num_states} states)"
    if progress:
        progress("checking the interval product")
    if not interval_accepts(ts, small, product.words.relevant, ets):
        raise _unsat(ts, f"no accepting cycle is reachable in the interval product of the {sizes}: no execution, "
                         "in any order and crossing interleaving, produces a word the task accepts")
    if progress:
        progress("searching the word-family product")
    try:
        fam = solve_families(ts, product.words, ets.without(banned))
    except MemoryError as e:
        raise NoPlanFound(f"no plan found: the task is accepted only on some crossing interleavings and the "
                          f"{e}; satisfiability unknown") from None
    stats.update(fam.stats)
    if fam.suffix:
        fam.stats = {**stats, "seconds": time.perf_counter() - t0}
        return fam
    if banned:
        raise NoPlanFound(f"no plan found: every plan of the exact planner needs one of the {len(banned)} steps "
                          "placement rejected; satisfiability unknown")
    if is_deterministic(small) and not fam.stats["family_orders_truncated"]:
        raise _unsat(ts, f"for every plan some executed word violates the task (the word-family product of the "
                         f"{sizes}, deterministic, has no accepting cycle: every TS run the task could accept needs "
                         "a crossing order that execution does not control)")
    if progress:
        progress("checking the lattice product")
    some = product.build(ets, some=True)
    if not some.has_accepting_cycle():
        raise _unsat(ts, f"no accepting cycle is reachable in the product of the {sizes} over every execution "
                         f"order and crossing interleaving; searched all {int(some.reachable().sum())} reachable "
                         "product states")
    raise NoPlanFound(
        "no plan found: the task is accepted only on some crossing interleavings of the TS runs that reach an "
        f"accepting cycle, and no plan of the word-family product ({fam.stats['family_nodes']} nodes) accepts "
        "every interleaving; satisfiability unknown (the NBA is not deterministic)")


def solve_exact_graph(ts, nba: NBA, relevant: int, max_states: int = 200_000) -> ExactResult:
    """Optimal prefix-suffix plan of a :class:`~mrodrake.planning.graph.GraphTS` (the NBA reads source
    labels); UserError when unsatisfiable or when more than ``max_states`` joint states are reachable."""
    t0 = time.perf_counter()
    Q = nba.num_states
    index = {ts.initial: 0}
    states = [ts.initial]
    src, dst, cost = [], [], []
    u = 0
    while u < len(states):
        s = states[u]
        for t in ts.successor_states(s):
            v = index.get(t)
            if v is None:
                v = index[t] = len(states)
                states.append(t)
                if len(states) > max_states:
                    raise UserError(f"--planner exact: more than {max_states} joint states are reachable; "
                                    "use --planner stylus")
            src.append(u)
            dst.append(v)
            cost.append(ts.cost(s, t))
        u += 1
    S = len(states)
    src_a, dst_a, cost_a = np.array(src, dtype=np.int64), np.array(dst, dtype=np.int64), np.array(cost)
    masks = [ts.label_mask(x) & relevant for x in states]
    lids: dict[int, int] = {}
    lid = np.array([lids.setdefault(m, len(lids)) for m in masks], dtype=np.int64)
    rows_all, cols_all, data_all = [], [], []
    for m, l in lids.items():
        qs, q2s = [], []
        for q in range(Q):
            for d in nba.successors(q, m):
                qs.append(q)
                q2s.append(d)
        e = np.flatnonzero(lid[src_a] == l)
        if not len(e) or not qs:
            continue
        qs_a, q2s_a = np.array(qs, dtype=np.int64), np.array(q2s, dtype=np.int64)
        rows_all.append((src_a[e, None] * Q + qs_a[None, :]).ravel())
        cols_all.append((dst_a[e, None] * Q + q2s_a[None, :]).ravel())
        data_all.append(np.repeat(cost_a[e], len(qs)))
    n = S * Q
    if rows_all:
        g = sp.csr_matrix((np.concatenate(data_all), (np.concatenate(rows_all), np.concatenate(cols_all))),
                          shape=(n, n))
    else:
        g = sp.csr_matrix((n, n))
    acc = np.zeros(Q, dtype=bool)
    acc[list(nba.accepting)] = True
    stats: dict = {"nba_states": Q, "ts_states": S, "ts_transitions": len(src), "product_nodes": n,
                   "product_edges": int(g.nnz)}
    found = optimal_lasso(g, nba.initial, np.tile(acc, S), stats)
    if found is None:
        raise UserError(f"task is unsatisfiable: no accepting cycle is reachable in the product of the TS "
                        f"({S} joint states, {len(src)} transitions) and the NBA ({Q} states); searched all "
                        f"{stats['product_reachable_nodes']} reachable product states")
    prefix = [(states[v // Q], v % Q) for v in found[0]]
    suffix = [(states[v // Q], v % Q) for v in found[1]]
    run = prefix + suffix
    pc = sum(ts.cost(a[0], b[0]) for a, b in zip(run[:len(prefix)], run[1:len(prefix) + 1]))
    sc = sum(ts.cost(a[0], b[0]) for a, b in zip(suffix, suffix[1:] + suffix[:1]))
    stats["seconds"] = time.perf_counter() - t0
    return ExactResult(prefix, suffix, pc, sc, stats)
