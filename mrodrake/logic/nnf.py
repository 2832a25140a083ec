"""Negation normal form of LTL formulas."""

from __future__ import annotations

from mrodrake.logic.formula import (
    ALWAYS,
    AND,
    AP,
    EQUIV,
    EVENTUALLY,
    FF,
    IMPLIES,
    NEXT,
    NOT,
    OR,
    RELEASE,
    STRONG_RELEASE,
    TT,
    UNTIL,
    WEAK_UNTIL,
    XOR,
    And,
    F,
    Formula,
    G,
    M,
    Not,
    Or,
    R,
    U,
    W,
    X,
    rebuild,
)

__all__ = ["nnf", "is_nnf"]


_NNF_CACHE: dict[tuple[Formula, bool], Formula] = {}
_DUAL = {UNTIL: R, RELEASE: U, WEAK_UNTIL: M, STRONG_RELEASE: W}


def nnf(f: Formula, negate: bool = False) -> Formula:
    """Negation normal form of ``f`` (or of ``!f``): only ``true false a !a & | X F G U R W M`` remain.

    Uses the dualities ``!X a = X !a``, ``!F a = G !a``, ``!(a U b) = !a R !b``, ``!(a W b) = !a M !b``;
    ``->``, ``<->`` and ``xor`` are expanded.
    """
    key = (f, negate)
    r = _NNF_CACHE.get(key)
    if r is not None:
        return r
    k, a = f.kind, f.args
    if k in (TT, FF):
        r = Not(f) if negate else f
    elif k == AP:
        r = Not(f) if negate else f
    elif k == NOT:
        r = nnf(a[0], not negate)
    elif k == AND:
        r = (Or if negate else And)(*(nnf(g, negate) for g in a))
    elif k == OR:
        r = (And if negate else Or)(*(nnf(g, negate) for g in a))
    elif k == IMPLIES:
        r = And(nnf(a[0]), nnf(a[1], True)) if negate else Or(nnf(a[0], True), nnf(a[1]))
    elif k in (EQUIV, XOR):
        same = (k == EQUIV) != negate
        p, q, np_, nq = nnf(a[0]), nnf(a[1]), nnf(a[0], True), nnf(a[1], True)
        r = Or(And(p, q), And(np_, nq)) if same else Or(And(p, nq), And(np_, q))
    elif k == NEXT:
        r = X(nnf(a[0], negate))
    elif k == EVENTUALLY:
        r = (G if negate else F)(nnf(a[0], negate))
    elif k == ALWAYS:
        r = (F if negate else G)(nnf(a[0], negate))
    else:
        args = (nnf(a[0], negate), nnf(a[1], negate))
        r = _DUAL[k](*args) if negate else rebuild(k, args)
    _NNF_CACHE[key] = r
    return r


def is_nnf(f: Formula) -> bool:
    """True iff negations apply only to propositions and no ``-> <-> xor`` occurs."""
    if f.kind in (IMPLIES, EQUIV, XOR):
        return False
    if f.kind == NOT:
        return f.args[0].kind == AP
    return all(is_nnf(g) for g in f.args)
