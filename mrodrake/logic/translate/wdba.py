"""Minimal weak deterministic Büchi automaton (WDBA) of an obligation property: powerset construction with
the SCC acceptance of Dax, Eisinger & Klaedtke, "Mechanizing the powerset construction for restricted
classes of ω-automata", ATVA 2007, then Löding's normal colouring and minimization ("Efficient
minimization of deterministic weak ω-automata", Inf. Process. Lett. 79(3), 2001); obligation formulas are
recognised syntactically after Černá & Pelánek, "Relating hierarchy of temporal properties to model
checking", MFCS 2003."""

from __future__ import annotations

from mrodrake.logic.formula import ALWAYS, AND, EVENTUALLY, NEXT, NOT, OR, RELEASE, STRONG_RELEASE, UNTIL, Formula
from mrodrake.logic.graph import sccs
from mrodrake.logic.translate.ba import BA

__all__ = ["syntactic_class", "minimal_wdba"]


def syntactic_class(f: Formula, memo: dict) -> tuple[bool, bool, bool]:
    """(safety, guarantee, obligation) membership of the NNF formula ``f`` in the syntactic classes of
    Černá & Pelánek (MFCS 2003): safety is closed under ``& | X G R W``, guarantee under ``& | X F U M``;
    obligation adds ``F`` of guarantee, ``G`` of safety, ``o U g``, ``o R s``, ``s W o``, ``g M o``."""
    r = memo.get(f)
    if r is not None:
        return r
    k = f.kind
    if not f.args or k == NOT:
        r = (True, True, True)
    else:
        sub = [syntactic_class(g, memo) for g in f.args]
        if k in (AND, OR, NEXT):
            r = (all(c[0] for c in sub), all(c[1] for c in sub), all(c[2] for c in sub))
        elif k == ALWAYS:
            r = (sub[0][0], False, sub[0][0])
        elif k == EVENTUALLY:
            r = (False, sub[0][1], sub[0][1])
        else:
            a, b = sub
            if k == UNTIL:
                r = (False, a[1] and b[1], a[2] and b[1])
            elif k == STRONG_RELEASE:
                r = (False, a[1] and b[1], a[1] and b[2])
            elif k == RELEASE:
                r = (a[0] and b[0], False, a[2] and b[0])
            else:  # W
                r = (a[0] and b[0], False, a[0] and b[2])
    memo[f] = r
    return r


def minimal_wdba(ba: BA, limit: int) -> tuple[BA, BA] | None:
    """Minimal weak deterministic Büchi automaton by the powerset construction with the SCC acceptance of
    Dax, Eisinger & Klaedtke (ATVA 2007) and Löding's minimization (IPL 2001).  Correct only if the
    language is an obligation (the caller checks).  Returns ``(wdba, complement)`` — the complement is
    the same complete DBA with complemented acceptance — or None if the powerset exceeds ``limit``."""
    bdd = ba.bdd
    index = {1 << ba.init: 0}
    sets = [1 << ba.init]
    trans: list[dict[int, int]] = []
    head = 0
    while head < len(sets):
        S = sets[head]
        head += 1
        regions: dict[int, int] = {0: 1}  # successor set -> letters leading exactly there
        m = S
        while m:
            low = m & -m
            m ^= low
            for d, g in ba.edges[low.bit_length() - 1].items():
                new: dict[int, int] = {}
                for dm, r in regions.items():
                    inside = bdd.conj(r, g)
                    if inside:
                        key = dm | 1 << d
                        new[key] = bdd.disj(new.get(key, 0), inside)
                    outside = bdd.diff(r, g)
                    if outside:
                        new[dm] = bdd.disj(new.get(dm, 0), outside)
                regions = new
        row = {}
        for dm, r in sorted(regions.items()):
            j = index.get(dm)
            if j is None:
                j = index[dm] = len(sets)
                sets.append(dm)
                if len(sets) > limit:
                    return None
            row[j] = r
        trans.append(row)
    n = len(sets)
    comps = sccs(list(range(n)), [list(t) for t in trans])
    comp_of = [0] * n
    for ci, comp in enumerate(comps):
        for S in comp:
            comp_of[S] = ci
    # An SCC is accepting iff the NBA, run inside it, has an accepting cycle (Dax et al., Lemma 2).
    accepting_comp = [False] * len(comps)
    for ci, comp in enumerate(comps):
        if len(comp) == 1 and comp[0] not in trans[comp[0]]:
            continue
        nodes = [(q, S) for S in comp for q in range(ba.n) if sets[S] >> q & 1]
        psucc = {}
        for q, S in nodes:
            psucc[(q, S)] = [(q2, S2) for S2, h in trans[S].items() if comp_of[S2] == ci
                             for q2, g in ba.edges[q].items() if sets[S2] >> q2 & 1 and bdd.sat(g, h)]
        for pc in sccs(nodes, psucc):
            if (len(pc) > 1 or pc[0] in psucc[pc[0]]) and any(ba.acc[q] for q, _ in pc):
                accepting_comp[ci] = True
                break
    # Löding's normal colouring: colours never increase along edges, even = accepting, maximal.
    color = [0] * len(comps)
    for ci, comp in enumerate(comps):  # successors first
        c = 2 * len(comps) + 2
        for S in comp:
            for S2 in trans[S]:
                if comp_of[S2] != ci:
                    c = min(c, color[comp_of[S2]])
        nontrivial = len(comp) > 1 or comp[0] in trans[comp[0]]
        if nontrivial and (c % 2 == 0) != accepting_comp[ci]:
            c -= 1
        color[ci] = c
    even = [color[comp_of[S]] % 2 == 0 for S in range(n)]
    # Moore minimization (canonical BDD guards make signatures hashable).
    block = [int(e) for e in even]
    nblocks = len(set(block))
    while True:
        sigs: dict = {}
        new_block = []
        for S in range(n):
            merged: dict[int, int] = {}
            for S2, g in trans[S].items():
                merged[block[S2]] = bdd.disj(merged.get(block[S2], 0), g)
            new_block.append(sigs.setdefault((block[S], frozenset(merged.items())), len(sigs)))
        block = new_block
        if len(sigs) == nblocks:
            break
        nblocks = len(sigs)
    reps: dict[int, int] = {}
    for S in range(n):
        reps.setdefault(block[S], S)
    edges = []
    for b in range(nblocks):
        row: dict[int, int] = {}
        for S2, g in trans[reps[b]].items():
            row[block[S2]] = bdd.disj(row.get(block[S2], 0), g)
        edges.append(row)
    acc = [even[reps[b]] for b in range(nblocks)]
    wdba = BA(edges, acc, block[0], bdd)
    comp = BA([dict(e) for e in edges], [not x for x in acc], block[0], bdd)
    return wdba, comp
