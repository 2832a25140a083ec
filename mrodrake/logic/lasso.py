"""Direct LTL semantics on lasso words ``u v^omega`` (paper Sec. II-A), independent of any automaton.

A lasso word has ``n = |u| + |v|`` distinct positions ``0..n-1``; the successor of position ``i`` is
``i + 1``, except the last position whose successor is ``|u|`` (the start of the cycle).  Every LTL
formula's truth on such a word depends only on the position, so each subformula's truth is computed as a
bit set over the ``n`` positions: ``X`` shifts along the successor map, ``U``/``M`` are least and
``R``/``W``/``G`` greatest fixpoints of their one-step unfoldings (Baier & Katoen, Sec. 5.1).
"""

from __future__ import annotations

from collections.abc import Sequence

from mrodrake.errors import UserError
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
    Formula,
)
from mrodrake.logic.parse import parse

__all__ = ["evaluate_lasso", "holds_at"]


def _letters_to_sets(word: Sequence, ap: Sequence[str] | None) -> list[frozenset[str]]:
    out = []
    for letter in word:
        if isinstance(letter, int):
            if ap is None:
                raise ValueError("integer letters need the proposition order `ap`")
            out.append(frozenset(name for i, name in enumerate(ap) if letter >> i & 1))
        else:
            out.append(frozenset(letter))
    return out


def holds_at(f: Formula | str, prefix: Sequence, cycle: Sequence, ap: Sequence[str] | None = None) -> list[bool]:
    """Truth value of ``f`` at every position ``0..|u|+|v|-1`` of the lasso word ``prefix cycle^omega``.

    Letters are sets of the propositions that hold, or integer masks (bit ``i`` <-> ``ap[i]``).
    """
    if isinstance(f, str):
        f = parse(f)
    if len(cycle) == 0:
        raise UserError("lasso: the cycle of a lasso word must not be empty")
    letters = _letters_to_sets(list(prefix) + list(cycle), ap)
    n = len(letters)
    loop = len(prefix)
    full = (1 << n) - 1
    last = n - 1

    def succ(bits: int) -> int:
        """Bit i of the result is bit succ(i) of ``bits``."""
        return (bits >> 1) | (((bits >> loop) & 1) << last)

    def lfp(a: int, b: int) -> int:
        """Least fixpoint of ``Z = b | (a & succ(Z))`` (a U b)."""
        z = b
        while True:
            nz = b | (a & succ(z))
            if nz == z:
                return z
            z = nz

    def gfp(a: int, b: int) -> int:
        """Greatest fixpoint of ``Z = b & (a | succ(Z))`` (a R b)."""
        z = full
        while True:
            nz = b & (a | succ(z))
            if nz == z:
                return z
            z = nz

    memo: dict[Formula, int] = {}

    def ev(g: Formula) -> int:
        r = memo.get(g)
        if r is not None:
            return r
        k = g.kind
        if k == TT:
            r = full
        elif k == FF:
            r = 0
        elif k == AP:
            r = 0
            for i, letter in enumerate(letters):
                if g.name in letter:
                    r |= 1 << i
        elif k == NOT:
            r = full & ~ev(g.args[0])
        elif k == AND:
            r = full
            for h in g.args:
                r &= ev(h)
        elif k == OR:
            r = 0
            for h in g.args:
                r |= ev(h)
        elif k == IMPLIES:
            r = (full & ~ev(g.args[0])) | ev(g.args[1])
        elif k == EQUIV:
            r = full & ~(ev(g.args[0]) ^ ev(g.args[1]))
        elif k == XOR:
            r = ev(g.args[0]) ^ ev(g.args[1])
        elif k == NEXT:
            r = succ(ev(g.args[0]))
        elif k == EVENTUALLY:
            r = lfp(full, ev(g.args[0]))
        elif k == ALWAYS:
            r = gfp(0, ev(g.args[0]))
        elif k == UNTIL:
            r = lfp(ev(g.args[0]), ev(g.args[1]))
        elif k == RELEASE:
            r = gfp(ev(g.args[0]), ev(g.args[1]))
        elif k == WEAK_UNTIL:
            a, b = ev(g.args[0]), ev(g.args[1])
            r = gfp(b, a | b)  # a W b = b R (a | b)
        elif k == STRONG_RELEASE:
            a, b = ev(g.args[0]), ev(g.args[1])
            r = lfp(b, a & b)  # a M b = b U (a & b)
        else:
            raise ValueError(f"unknown operator {k!r}")
        memo[g] = r
        return r

    bits = ev(f)
    return [bool(bits >> i & 1) for i in range(n)]


def evaluate_lasso(f: Formula | str, prefix: Sequence, cycle: Sequence, ap: Sequence[str] | None = None) -> bool:
    """Does the lasso word ``prefix cycle^omega`` satisfy ``f`` (at position 0)?"""
    return holds_at(f, prefix, cycle, ap)[0]
