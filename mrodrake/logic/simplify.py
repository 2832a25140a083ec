"""LTL simplification: syntactic eventualities and universals, and rewriting to a smaller NNF formula."""

from __future__ import annotations

from collections.abc import Callable

from mrodrake.logic.formula import (
    ALWAYS,
    AND,
    AP,
    EVENTUALLY,
    FALSE,
    FF,
    NEXT,
    NOT,
    OR,
    RELEASE,
    STRONG_RELEASE,
    TRUE,
    TT,
    UNTIL,
    WEAK_UNTIL,
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
from mrodrake.logic.nnf import nnf
from mrodrake.logic.parse import parse

__all__ = ["simplify", "is_eventual", "is_universal"]


_EVENTUAL: dict[Formula, bool] = {}
_UNIVERSAL: dict[Formula, bool] = {}


def is_eventual(f: Formula) -> bool:
    """Syntactic pure eventuality (``f`` equivalent to ``F f``; Etessami & Holzmann 2000)."""
    r = _EVENTUAL.get(f)
    if r is None:
        k = f.kind
        if k in (TT, FF, EVENTUALLY):
            r = True
        elif k in (AND, OR):
            r = all(is_eventual(g) for g in f.args)
        elif k in (NEXT, ALWAYS):
            r = is_eventual(f.args[0])
        elif k == UNTIL:
            r = is_eventual(f.args[1])
        elif k == STRONG_RELEASE:
            r = is_eventual(f.args[0]) and is_eventual(f.args[1])
        else:
            r = False
        _EVENTUAL[f] = r
    return r


def is_universal(f: Formula) -> bool:
    """Syntactic purely universal formula (``f`` equivalent to ``G f``)."""
    r = _UNIVERSAL.get(f)
    if r is None:
        k = f.kind
        if k in (TT, FF, ALWAYS):
            r = True
        elif k in (AND, OR):
            r = all(is_universal(g) for g in f.args)
        elif k in (NEXT, EVENTUALLY):
            r = is_universal(f.args[0])
        elif k == RELEASE:
            r = is_universal(f.args[1])
        elif k == WEAK_UNTIL:
            r = is_universal(f.args[0]) and is_universal(f.args[1])
        else:
            r = False
        _UNIVERSAL[f] = r
    return r


def _suffix_independent(f: Formula) -> bool:
    return is_eventual(f) and is_universal(f)


def _complement_literal(f: Formula) -> Formula | None:
    if f.kind == AP:
        return Not(f)
    if f.kind == NOT and f.args[0].kind == AP:
        return f.args[0]
    return None


_SIMP_CACHE: dict[Formula, Formula] = {}


def simplify(f: Formula | str) -> Formula:
    """An equivalent, usually smaller formula in NNF.

    Rewrites (Somenzi & Bloem 2000; Etessami & Holzmann 2000; Spot's basic rules), applied bottom-up to
    the NNF of ``f`` until a fixpoint: constant folding; ``F F a = F a``; ``G F G a = F G a``;
    ``!X a = X !a``; ``F e = e`` for pure eventualities and ``G u = u`` for purely universal ``u``;
    ``a U e = e``, ``a R u = u``; ``X s = s`` for suffix-independent ``s``; ``F(a U b) = F b``,
    ``G(a R b) = G b``, ``F(a M b) = F(a & b)``, ``G(a W b) = G(a | b)``; ``F X a = X F a``;
    ``F(a & s) = F a & s`` and ``G(a | s) = G a | s`` for suffix-independent ``s``; ``a & !a = false``;
    ``G a & G b = G(a & b)``; ``F a | F b = F(a | b)``; ``X a & X b = X(a & b)``, ``X a | X b = X(a | b)``;
    ``(a U c) & (b U c) = (a & b) U c``; ``(a R b) & (a R c) = a R (b & c)``; ``G F a | G F b = G F(a | b)``;
    ``F G a & F G b = F G(a & b)``; ``a U (b | G a) = a W b``, ``a R (b & F a) = a M b``;
    ``G a | a U c = a W c``; ``G a | F(!a & e) = a W (!a & e)`` for pure eventualities ``e``.
    """
    if isinstance(f, str):
        f = parse(f)
    g = nnf(f)
    while True:
        h = _simp(g)
        if h is g:
            return g
        g = h


def _simp(f: Formula) -> Formula:
    r = _SIMP_CACHE.get(f)
    if r is not None:
        return r
    k = f.kind
    if not f.args:
        r = f
    else:
        args = tuple(_simp(a) for a in f.args)
        r = _simp_node(k, args)
    _SIMP_CACHE[f] = r
    return r


def _merge_by(parts: list[Formula], outer: str, combine: Callable) -> list[Formula]:
    """Merge the operands of kind ``outer`` into one: e.g. X a & X b -> X(a & b)."""
    group = [p for p in parts if p.kind == outer]
    if len(group) < 2:
        return parts
    rest = [p for p in parts if p.kind != outer]
    return rest + [combine(group)]


def _simp_node(k: str, a: tuple[Formula, ...]) -> Formula:
    if k in (AND, OR):
        base = rebuild(k, a)
        if base.kind != k:
            return base
        parts = list(base.args)
        pset = set(parts)
        for p in parts:
            c = _complement_literal(p)
            if c is not None and c in pset:
                return FALSE if k == AND else TRUE
        if k == AND:
            gs = [p for p in parts if p.kind == ALWAYS and not is_eventual(p.args[0])]
            if len(gs) >= 2:
                parts = [p for p in parts if p not in gs] + [G(And(*(p.args[0] for p in gs)))]
            parts = _merge_by(parts, NEXT, lambda g: X(And(*(x.args[0] for x in g))))
            fg = [p for p in parts if p.kind == EVENTUALLY and p.args[0].kind == ALWAYS]
            if len(fg) >= 2:
                parts = [p for p in parts if p not in fg] + [F(G(And(*(p.args[0].args[0] for p in fg))))]
            parts = _merge_binary(parts, k, UNTIL, 1, lambda x, y: U(And(x, y.args[0]), y.args[1]))
            parts = _merge_binary(parts, k, RELEASE, 0, lambda x, y: R(y.args[0], And(x, y.args[1])))
        else:
            fs = [p for p in parts if p.kind == EVENTUALLY and not is_universal(p.args[0])]
            if len(fs) >= 2:
                parts = [p for p in parts if p not in fs] + [F(Or(*(p.args[0] for p in fs)))]
            parts = _merge_by(parts, NEXT, lambda g: X(Or(*(x.args[0] for x in g))))
            gf = [p for p in parts if p.kind == ALWAYS and p.args[0].kind == EVENTUALLY]
            if len(gf) >= 2:
                parts = [p for p in parts if p not in gf] + [G(F(Or(*(p.args[0].args[0] for p in gf))))]
            parts = _merge_binary(parts, k, UNTIL, 0, lambda x, y: U(y.args[0], Or(x, y.args[1])))
            parts = _merge_binary(parts, k, RELEASE, 1, lambda x, y: R(Or(x, y.args[0]), y.args[1]))
            parts = _weak_until_from_or(parts)
        return rebuild(k, parts)
    if k == NEXT:
        x = a[0]
        if _suffix_independent(x):
            return x
        return X(x)
    if k == EVENTUALLY:
        x = a[0]
        if is_eventual(x):
            return x
        if x.kind == UNTIL:
            return _simp_node(EVENTUALLY, (x.args[1],))
        if x.kind == STRONG_RELEASE:
            return _simp_node(EVENTUALLY, (And(*x.args),))
        if x.kind == NEXT:
            return X(_simp_node(EVENTUALLY, (x.args[0],)))
        if x.kind in (AND, OR):
            inner = [g for g in x.args if not _suffix_independent(g)]
            outer = [g for g in x.args if _suffix_independent(g)]
            if outer and inner:
                return rebuild(x.kind, [_simp_node(EVENTUALLY, (rebuild(x.kind, inner),))] + outer)
        return F(x)
    if k == ALWAYS:
        x = a[0]
        if is_universal(x):
            return x
        if x.kind == RELEASE:
            return _simp_node(ALWAYS, (x.args[1],))
        if x.kind == WEAK_UNTIL:
            return _simp_node(ALWAYS, (Or(*x.args),))
        if x.kind == NEXT:
            return X(_simp_node(ALWAYS, (x.args[0],)))
        if x.kind in (AND, OR):
            inner = [g for g in x.args if not _suffix_independent(g)]
            outer = [g for g in x.args if _suffix_independent(g)]
            if outer and inner:
                return rebuild(x.kind, [_simp_node(ALWAYS, (rebuild(x.kind, inner),))] + outer)
        return G(x)
    if k == UNTIL:
        x, y = a
        if is_eventual(y):
            return y
        if y is G(x):
            return y
        if y.kind == OR and G(x) in y.args:  # a U (b | G a) = a W b
            return W(x, Or(*(z for z in y.args if z is not G(x))))
        return U(x, y)
    if k == RELEASE:
        x, y = a
        if is_universal(y):
            return y
        if y is F(x):
            return y
        if y.kind == AND and F(x) in y.args:  # a R (b & F a) = a M b
            return M(x, And(*(z for z in y.args if z is not F(x))))
        return R(x, y)
    return rebuild(k, a)


def _weak_until_from_or(parts: list[Formula]) -> list[Formula]:
    """``G a | a U c = a W c``; ``G a | F(!a & e) = a W (!a & e)`` for pure eventualities ``e``."""
    for gpart in parts:
        if gpart.kind != ALWAYS:
            continue
        a = gpart.args[0]
        na = nnf(a, True)
        for upart in parts:
            if upart.kind == UNTIL and upart.args[0] is a:  # G a | a U c = a W c
                rest = [x for x in parts if x is not gpart and x is not upart]
                return rest + [W(a, upart.args[1])]
        for fpart in parts:
            if fpart.kind != EVENTUALLY:
                continue
            c = fpart.args[0]
            conj = c.args if c.kind == AND else (c,)
            if na in conj and all(x is na or is_eventual(x) for x in conj):
                rest = [x for x in parts if x is not gpart and x is not fpart]
                return rest + [W(a, c)]
    return parts


def _merge_binary(parts: list[Formula], outer: str, kind: str, shared: int, combine) -> list[Formula]:
    """Merge binary temporal operands that share argument ``shared`` (e.g. (a U c) & (b U c))."""
    groups: dict[Formula, list[Formula]] = {}
    order: list = []
    for p in parts:
        if p.kind == kind:
            key = p.args[shared]
            if key not in groups:
                groups[key] = []
                order.append(("g", key))
            groups[key].append(p)
        else:
            order.append(("p", p))
    if all(len(v) < 2 for v in groups.values()):
        return parts
    out = []
    for tag, x in order:
        if tag == "p":
            out.append(x)
            continue
        g = groups[x]
        acc = g[0]
        for y in g[1:]:
            if acc.kind == kind and acc.args[shared] is y.args[shared]:
                acc = combine(acc.args[1 - shared], y)
            else:
                acc = rebuild(outer, (acc, y))
        out.append(acc)
    return out
