"""Very weak alternating automaton (VWAA) of an LTL formula in negation normal form, after Gastin &
Oddoux, "Fast LTL to Büchi automata translation", CAV 2001, LNCS 2102, Sec. 3 (states, transitions of
Def. 2, here extended to ``F G W M``), with the transition-domination simplification of their Sec. 4."""

from __future__ import annotations

from mrodrake.logic.bdd import Cube
from mrodrake.logic.formula import (
    ALWAYS,
    AND,
    AP,
    EVENTUALLY,
    FF,
    NEXT,
    NOT,
    OR,
    RELEASE,
    STRONG_RELEASE,
    TT,
    UNTIL,
    WEAK_UNTIL,
    Formula,
)

__all__ = ["VWAA", "UNTIL_KINDS"]

# The until-like states: the VWAA's co-Büchi final states, the GBA's acceptance sets.
UNTIL_KINDS = (UNTIL, EVENTUALLY, STRONG_RELEASE)


def _dominance_reduce(ts: list[tuple]) -> list[tuple]:
    """Remove transitions ``(pos, neg, conf[, sat])`` dominated by another: weaker or equal label, subset
    target configuration (and superset ``sat``) — Gastin & Oddoux, Sec. 4."""
    if len(ts) <= 1:
        return ts
    with_acc = len(ts[0]) == 4
    keyed = sorted(set(ts), key=lambda t: ((t[0] | t[1]).bit_count() + t[2].bit_count()
                                           - (t[3].bit_count() if with_acc else 0), t))
    kept: list[tuple] = []
    for t in keyed:
        p, n, c = t[0], t[1], t[2]
        for k in kept:
            if not (k[0] & ~p) and not (k[1] & ~n) and not (k[2] & ~c) and (not with_acc or not (t[3] & ~k[3])):
                break
        else:
            kept.append(t)
    return kept


def _product(t1: list[tuple], t2: list[tuple]) -> list[tuple]:
    out = []
    for p1, n1, c1 in t1:
        for p2, n2, c2 in t2:
            p, n = p1 | p2, n1 | n2
            if not p & n:
                out.append((p, n, c1 | c2))
    return _dominance_reduce(out)


def _minimal_sets(cs: list[int]) -> list[int]:
    out: list[int] = []
    for c in sorted(set(cs), key=lambda c: (c.bit_count(), c)):
        if not any(not (k & ~c) for k in out):
            out.append(c)
    return out


class VWAA:
    """Very weak alternating automaton of an NNF formula (Gastin & Oddoux, Sec. 3): states are the
    temporal subformulas and the literals under ``X``; configurations are bit sets of states; a
    transition is ``(pos, neg, conf)``."""

    def __init__(self, ap_index: dict[str, int]):
        self.ap_index = ap_index
        self.states: list[Formula] = []
        self.index: dict[Formula, int] = {}
        self.delta_cache: dict[int, list[tuple]] = {}
        self.dprime_cache: dict[Formula, list[tuple]] = {}
        self.bar_cache: dict[Formula, list[int]] = {}

    def state(self, f: Formula) -> int:
        i = self.index.get(f)
        if i is None:
            i = len(self.states)
            self.states.append(f)
            self.index[f] = i
        return i

    def literal(self, f: Formula) -> Cube:
        if f.kind == AP:
            return (1 << self.ap_index[f.name], 0)
        return (0, 1 << self.ap_index[f.args[0].name])

    def bar(self, f: Formula) -> list[int]:
        """Configurations (a DNF over states) equivalent to ``f``."""
        r = self.bar_cache.get(f)
        if r is not None:
            return r
        k = f.kind
        if k == TT:
            r = [0]
        elif k == FF:
            r = []
        elif k == AND:
            r = [0]
            for g in f.args:
                r = _minimal_sets([a | b for a in r for b in self.bar(g)])
        elif k == OR:
            r = _minimal_sets([c for g in f.args for c in self.bar(g)])
        else:
            r = [1 << self.state(f)]
        self.bar_cache[f] = r
        return r

    def dprime(self, f: Formula) -> list[tuple]:
        """Transitions of an arbitrary NNF formula (the paper's Delta-bar)."""
        r = self.dprime_cache.get(f)
        if r is not None:
            return r
        k = f.kind
        if k == TT:
            r = [(0, 0, 0)]
        elif k == FF:
            r = []
        elif k in (AP, NOT):
            p, n = self.literal(f)
            r = [(p, n, 0)]
        elif k == AND:
            r = [(0, 0, 0)]
            for g in f.args:
                r = _product(r, self.dprime(g))
        elif k == OR:
            r = _dominance_reduce([t for g in f.args for t in self.dprime(g)])
        else:
            r = self.delta(self.state(f))
        self.dprime_cache[f] = r
        return r

    def delta(self, i: int) -> list[tuple]:
        """Transitions of state ``i`` (Gastin & Oddoux, Def. 2, extended to F G W M)."""
        r = self.delta_cache.get(i)
        if r is not None:
            return r
        f = self.states[i]
        k = f.kind
        me = [(0, 0, 1 << i)]
        if k in (AP, NOT):
            p, n = self.literal(f)
            r = [(p, n, 0)]
        elif k == NEXT:
            r = [(0, 0, c) for c in self.bar(f.args[0])]
        elif k == EVENTUALLY:
            r = _dominance_reduce(self.dprime(f.args[0]) + me)
        elif k == ALWAYS:
            r = _product(self.dprime(f.args[0]), me)
        elif k in (UNTIL, WEAK_UNTIL):
            a, b = f.args
            r = _dominance_reduce(self.dprime(b) + _product(self.dprime(a), me))
        elif k == RELEASE:
            a, b = f.args
            r = _product(self.dprime(b), _dominance_reduce(self.dprime(a) + me))
        elif k == STRONG_RELEASE:
            a, b = f.args
            r = _dominance_reduce(_product(self.dprime(a), self.dprime(b)) + _product(self.dprime(b), me))
        else:
            raise ValueError(f"formula not in NNF: {f}")
        self.delta_cache[i] = r
        return r
