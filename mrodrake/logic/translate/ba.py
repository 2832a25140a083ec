"""The translator's working automaton: a mutable state-based Büchi automaton whose guards are BDDs of one
shared :class:`~mrodrake.logic.bdd.BDD` manager, with trimming, product emptiness and export to an
immutable :class:`~mrodrake.logic.nba.NBA` (guards as irredundant DNFs)."""

from __future__ import annotations

from mrodrake.logic.bdd import BDD
from mrodrake.logic.graph import LazySucc, reachable, sccs
from mrodrake.logic.nba import NBA

__all__ = ["BA", "intersection_empty"]


class BA:
    """Mutable state-based BA used during translation: ``edges[q]`` maps destination -> BDD guard."""

    def __init__(self, edges: list[dict[int, int]], acc: list[bool], init: int, bdd: BDD):
        self.edges = edges
        self.acc = acc
        self.init = init
        self.bdd = bdd

    @property
    def n(self) -> int:
        return len(self.edges)

    def size(self) -> tuple[int, int]:
        return (self.n, sum(len(e) for e in self.edges))

    def copy(self) -> BA:
        return BA([dict(e) for e in self.edges], list(self.acc), self.init, self.bdd)

    def restrict(self, keep: list[int]) -> BA:
        """Sub-automaton on ``keep`` (which contains ``init``), renumbered in the order of ``keep``."""
        new = {q: i for i, q in enumerate(keep)}
        edges = [{new[d]: g for d, g in self.edges[q].items() if d in new} for q in keep]
        return BA(edges, [self.acc[q] for q in keep], new[self.init], self.bdd)

    def trivial_states(self) -> set[int]:
        """States on no cycle (alone in their SCC, without self-loop)."""
        succ = [list(e) for e in self.edges]
        out = set()
        for comp in sccs(list(range(self.n)), succ):
            if len(comp) == 1 and comp[0] not in self.edges[comp[0]]:
                out.add(comp[0])
        return out

    def prune(self, trivial_accepting: bool) -> BA | None:
        """Keep reachable states that can reach an accepting cycle (None if the language is empty).

        A state in a trivial SCC is visited at most once by any run, so its acceptance is irrelevant; it
        is normalised to ``trivial_accepting``."""
        succ = [list(e) for e in self.edges]
        reach = reachable([self.init], succ)
        good: set[int] = set()
        trivial = []
        for comp in sccs(reach, succ):  # successors' components come first
            q0 = comp[0]
            nontrivial = len(comp) > 1 or q0 in self.edges[q0]
            if not nontrivial:
                trivial.append(q0)
            if (nontrivial and any(self.acc[q] for q in comp)) or any(
                    d in good for q in comp for d in self.edges[q]):
                good.update(comp)
        if self.init not in good:
            return None
        for q in trivial:
            self.acc[q] = trivial_accepting
        return self.restrict([q for q in reach if q in good])

    def to_nba(self, ap: tuple[str, ...]) -> NBA:
        """Export with breadth-first numbering from the initial state (state 0) and ISOP guards."""
        order = reachable([self.init], [sorted(e) for e in self.edges])
        new = {q: i for i, q in enumerate(order)}
        edges = [[(self.bdd.isop(self.edges[q][d]), new[d]) for d in sorted(self.edges[q], key=lambda d: new[d])]
                 for q in order]
        return NBA(ap, 0, [new[q] for q in order if self.acc[q]], edges)


def intersection_empty(a: BA, b: BA) -> bool:
    """Is ``L(a) & L(b)`` empty?  (Same BDD manager; a reachable product cycle must visit accepting
    states of both.)"""
    bdd = a.bdd
    succ: dict = {}

    def step(v):
        x, y = v
        return [(d1, d2) for d1, g1 in a.edges[x].items() for d2, g2 in b.edges[y].items() if bdd.sat(g1, g2)]

    order = reachable([(a.init, b.init)], LazySucc(succ, step))
    for comp in sccs(order, succ):
        if len(comp) == 1 and comp[0] not in succ[comp[0]]:
            continue
        if any(a.acc[x] for x, _ in comp) and any(b.acc[y] for _, y in comp):
            return False
    return True
