"""Language-preserving state-space reductions: the GBA's quotient by its coarsest bisimulation, and on the
state-based BA direct simulation (the greatest-fixpoint relation of Dill, Hu & Wong-Toi, CAV 1991),
quotienting by direct-simulation equivalence (Etessami & Holzmann, "Optimizing Büchi automata", CONCUR
2000; Somenzi & Bloem, "Efficient Büchi automata from LTL formulae", CAV 2000) and the removal of edges
to "little brothers" (Somenzi & Bloem 2000)."""

from __future__ import annotations

from mrodrake.logic.bdd import BDD
from mrodrake.logic.translate.ba import BA

__all__ = ["merge_bisimilar_gba", "direct_simulation", "quotient", "prune_little_brothers", "reduce_ba"]


def merge_bisimilar_gba(trans: list[list[tuple]], bdd: BDD) -> list[list[tuple]]:
    """Quotient of the GBA by its coarsest bisimulation (guards merged per target class and acceptance);
    the initial state stays 0."""
    n = len(trans)
    cls = [0] * n
    nblocks = 1
    while True:
        sigs: dict = {}
        new = []
        for s in range(n):
            merged: dict[tuple[int, int], int] = {}
            for g, d, a in trans[s]:
                key = (cls[d], a)
                merged[key] = bdd.disj(merged.get(key, 0), g)
            sig = (cls[s], frozenset(merged.items()))
            new.append(sigs.setdefault(sig, len(sigs)))
        cls = new
        if len(sigs) == nblocks:
            break
        nblocks = len(sigs)
    rep: dict[int, int] = {}
    for s in range(n):
        rep.setdefault(cls[s], s)
    newid = {c: i for i, c in enumerate(sorted(rep, key=lambda c: rep[c]))}
    out = []
    for c in sorted(rep, key=lambda c: rep[c]):
        merged = {}
        for g, d, a in trans[rep[c]]:
            key = (newid[cls[d]], a)
            merged[key] = bdd.disj(merged.get(key, 0), g)
        out.append(sorted(((g, d, a) for (d, a), g in merged.items()), key=lambda t: (t[1], t[2])))
    return out


def direct_simulation(ba: BA) -> list[int]:
    """Direct simulation: bit ``q`` of ``rel[p]`` is set iff ``q`` simulates ``p`` (greatest fixpoint:
    ``q`` is accepting if ``p`` is, and matches every edge ``p -a-> p'`` by edges ``q -a-> q'`` with
    ``q'`` simulating ``p'``).  Worklist iteration: ``p`` is re-examined only when the simulators of
    one of its successors shrank."""
    n = ba.n
    bdd = ba.bdd
    acc = ba.acc
    edges = [list(e.items()) for e in ba.edges]
    enabled = [0] * n
    preds: list[set[int]] = [set() for _ in range(n)]
    for p in range(n):
        for d, g in edges[p]:
            enabled[p] = bdd.disj(enabled[p], g)
            preds[d].add(p)
    accmask = sum(1 << q for q in range(n) if acc[q])
    rel = []
    for p in range(n):
        m = accmask if acc[p] else (1 << n) - 1
        for q in range(n):
            if m >> q & 1 and q != p and not bdd.implies(enabled[p], enabled[q]):
                m &= ~(1 << q)
        rel.append(m)
    covers: dict[tuple[int, int], int] = {}
    dirty = list(range(n))
    in_dirty = [True] * n
    while dirty:
        p = dirty.pop()
        in_dirty[p] = False
        cand = rel[p]
        qs = cand & ~(1 << p)
        while qs:
            low = qs & -qs
            qs ^= low
            q = low.bit_length() - 1
            for d, g in edges[p]:
                sim = rel[d]
                key = (q, sim)
                cover = covers.get(key)
                if cover is None:
                    cover = 0
                    for d2, g2 in edges[q]:
                        if sim >> d2 & 1:
                            cover = bdd.disj(cover, g2)
                    covers[key] = cover
                if cover != 1 and bdd.conj(g, bdd.neg(cover)):
                    cand &= ~low
                    break
        if cand != rel[p]:
            rel[p] = cand
            for x in preds[p]:
                if not in_dirty[x]:
                    in_dirty[x] = True
                    dirty.append(x)
    return rel


def quotient(ba: BA, rel: list[int]) -> BA:
    """Merge direct-simulation-equivalent states (language preserving)."""
    n = ba.n
    rep = list(range(n))
    for p in range(n):
        if rep[p] != p:
            continue
        for q in range(p + 1, n):
            if rep[q] == q and rel[p] >> q & 1 and rel[q] >> p & 1:
                rep[q] = p
    if all(rep[q] == q for q in range(n)):
        return ba
    keep = [q for q in range(n) if rep[q] == q]
    new = {q: i for i, q in enumerate(keep)}
    edges: list[dict[int, int]] = [dict() for _ in keep]
    for q in range(n):
        row = edges[new[rep[q]]]
        for d, g in ba.edges[q].items():
            t = new[rep[d]]
            row[t] = ba.bdd.disj(row.get(t, 0), g)
    return BA(edges, [ba.acc[q] for q in keep], new[rep[ba.init]], ba.bdd)


def prune_little_brothers(ba: BA, rel: list[int]) -> None:
    """Remove from the guard of ``q -> t`` the letters that also lead from ``q`` to a state strictly
    simulating ``t`` (little brothers; Somenzi & Bloem 2000).  Sound because strict simulation is
    well-founded: every removed letter still leads to a maximal simulating state."""
    bdd = ba.bdd
    for q in range(ba.n):
        row = ba.edges[q]
        if len(row) < 2:
            continue
        new_row = {}
        for t, g in row.items():
            bigger = 0
            for t2, g2 in row.items():
                if t2 != t and rel[t] >> t2 & 1 and not rel[t2] >> t & 1:
                    bigger = bdd.disj(bigger, g2)
            if bigger:
                g = bdd.diff(g, bigger)
            if g:
                new_row[t] = g
        ba.edges[q] = new_row


def reduce_ba(ba: BA, trivial_accepting: bool) -> BA | None:
    """Trim, quotient by direct-simulation equivalence and prune little brothers until the size is stable
    (None if the language is empty).  May modify ``ba``: pass a copy to keep it."""
    cur: BA | None = ba
    while True:
        cur = cur.prune(trivial_accepting)
        if cur is None:
            return None
        before = cur.size()
        rel = direct_simulation(cur)
        merged = quotient(cur, rel)
        if merged is not cur:
            cur = merged
            rel = direct_simulation(cur)
        prune_little_brothers(cur, rel)
        cur = cur.prune(trivial_accepting)
        if cur is None:
            return None
        if cur.size() == before:
            return cur
