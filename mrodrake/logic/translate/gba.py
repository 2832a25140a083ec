"""Generalized Büchi automaton (GBA) of a VWAA, after Gastin & Oddoux, "Fast LTL to Büchi automata
translation", CAV 2001, LNCS 2102, Sec. 4: states are VWAA configurations, one acceptance set per until
state, dominated transitions removed.  Guards are BDDs."""

from __future__ import annotations

from mrodrake.logic.bdd import BDD
from mrodrake.logic.formula import Formula
from mrodrake.logic.translate.vwaa import UNTIL_KINDS, VWAA

__all__ = ["build_gba"]


def build_gba(f: Formula, ap_index: dict[str, int], bdd: BDD):
    """Generalized Büchi automaton of the NNF formula ``f`` (Gastin & Oddoux, Sec. 4).

    Returns ``(trans, nacc)`` or None if ``f`` is false: GBA state 0 is initial, ``trans[s]`` is a list
    of ``(guard_bdd, dst, accmask)``, one per (destination, acceptance) pair; ``nacc`` acceptance sets,
    one per until state occurring in a reachable configuration.  A transition is in the set of until
    state ``b`` iff ``b`` is not in the target configuration, or ``b``'s own component did not loop, or
    some transition of ``b`` that avoids ``b`` witnesses it (the paper's condition).  Letters of a
    transition dominated by another one (subset target, superset acceptance) are removed.
    """
    vw = VWAA(ap_index)
    inits = vw.bar(f)
    if not inits:
        return None
    conf_trans: dict[int, list[tuple[int, int, int]]] = {}
    delta_bdd: dict[int, list[tuple[int, int]]] = {}

    def dominate(groups: dict[tuple[int, int], int]) -> dict[tuple[int, int], int]:
        """Remove from each group ``(conf, good)`` the letters of groups with a subset configuration and a
        superset ``good`` set (domination, letter by letter; sound since the order is well-founded)."""
        if len(groups) < 2:
            return groups
        out = {}
        for (c, s), g in groups.items():
            better = 0
            for (c2, s2), g2 in groups.items():
                if (c2, s2) != (c, s) and not (c2 & ~c) and not (s & ~s2):
                    better = bdd.disj(better, g2)
            if better:
                g = bdd.diff(g, better)
            if g:
                out[(c, s)] = g
        return out

    def delta_of(q: int) -> list[tuple[int, int]]:
        r = delta_bdd.get(q)
        if r is None:
            groups: dict[tuple[int, int], int] = {}
            for p, n, c in vw.delta(q):
                groups[(c, 0)] = bdd.disj(groups.get((c, 0), 0), bdd.cube(p, n))
            r = delta_bdd[q] = [(g, c) for (c, _), g in dominate(groups).items()]
        return r

    def trans_of(conf: int) -> list[tuple[int, int, int]]:
        """Product of the states' transitions as ``(guard, dst_conf, sat)``; ``sat`` holds the until states
        of ``conf`` whose own component did not loop.  Partial products are pruned by domination, which
        is monotone in the final acceptance (``b`` accepted if ``b`` not in ``dst`` or in ``sat``)."""
        r = conf_trans.get(conf)
        if r is None:
            groups: dict[tuple[int, int], int] = {(0, 0): 1}
            c = conf
            while c:
                low = c & -c
                c ^= low
                q = low.bit_length() - 1
                is_until = vw.states[q].kind in UNTIL_KINDS
                new: dict[tuple[int, int], int] = {}
                for (c1, s1), g1 in groups.items():
                    for g2, c2 in delta_of(q):
                        g = bdd.conj(g1, g2)
                        if g:
                            key = (c1 | c2, s1 | low if is_until and not c2 & low else s1)
                            new[key] = bdd.disj(new.get(key, 0), g)
                groups = dominate(new)
            r = conf_trans[conf] = [(g, d, st) for (d, st), g in groups.items()]
        return r

    todo = list(inits)
    seen = set(todo)
    while todo:
        c = todo.pop()
        for _, d, _ in trans_of(c):
            if d not in seen:
                seen.add(d)
                todo.append(d)
    present = 0
    for c in seen:
        present |= c
    untils = [i for i, g in enumerate(vw.states) if g.kind in UNTIL_KINDS and present >> i & 1]
    witness = [(1 << b, [(bdd.cube(p, n), c) for p, n, c in vw.delta(b) if not c >> b & 1]) for b in untils]

    def gtrans(confs: list[int]) -> list[tuple[int, int, int]]:
        groups: dict[tuple[int, int], int] = {}
        for conf in confs:
            for g, d, st in trans_of(conf):
                regions = {0: g}
                for k, (bit, wit) in enumerate(witness):
                    if not d & bit or st & bit:
                        regions = {a | 1 << k: r for a, r in regions.items()}
                        continue
                    w = 0
                    for wg, wc in wit:
                        if not wc & ~d:
                            w = bdd.disj(w, wg)
                    if w:
                        split: dict[int, int] = {}
                        for a, r in regions.items():
                            inside, outside = bdd.conj(r, w), bdd.diff(r, w)
                            if inside:
                                split[a | 1 << k] = bdd.disj(split.get(a | 1 << k, 0), inside)
                            if outside:
                                split[a] = bdd.disj(split.get(a, 0), outside)
                        regions = split
                for a, r in regions.items():
                    groups[(d, a)] = bdd.disj(groups.get((d, a), 0), r)
        return [(g, d, a) for (d, a), g in dominate(groups).items()]

    ids: dict = {}
    order: list = []
    start = inits[0] if len(inits) == 1 else -1
    ids[start] = 0
    order.append(start)
    raw = []
    head = 0
    while head < len(order):
        key = order[head]
        head += 1
        ts = gtrans(inits if key == -1 else [key])
        raw.append(ts)
        for _, d, _ in sorted(ts, key=lambda t: (t[1], t[2])):
            if d not in ids:
                ids[d] = len(order)
                order.append(d)
    trans = [sorted(((g, ids[d], a) for g, d, a in ts), key=lambda t: (t[1], t[2])) for ts in raw]
    return trans, len(untils)
