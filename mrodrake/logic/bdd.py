"""Reduced ordered binary decision diagrams, the guard algebra of the translator and of the HOA reader.

ROBDDs after Bryant, "Graph-based algorithms for Boolean function manipulation", IEEE Trans. Computers
C-35(8), 1986; :meth:`BDD.isop` extracts an irredundant sum of products by Minato's algorithm ("Fast
generation of prime-irredundant covers from binary decision diagrams", IEICE Trans. Fundamentals E76-A(6),
1993), which follows Morreale's recursive operator (IEEE Trans. Computers C-19(6), 1970).

A cube ``(pos_mask, neg_mask)`` is a conjunction of literals (bit ``1 << i`` <-> variable ``i``); a
:data:`Guard` is a DNF, a tuple of cubes.
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["BDD", "Cube", "Guard"]

Cube = tuple[int, int]
Guard = tuple[Cube, ...]


class BDD:
    """Reduced ordered binary decision diagrams over variables ``0, 1, ...`` (variable ``i`` <-> AP bit
    ``i``; lower indices nearer the root).  Nodes are integers; 0 is false, 1 is true."""

    _LEAF = 1 << 30

    def __init__(self):
        self.var = [self._LEAF, self._LEAF]
        self.lo = [0, 1]
        self.hi = [0, 1]
        self.unique: dict[tuple[int, int, int], int] = {}
        self.and_memo: dict[tuple[int, int], int] = {}
        self.or_memo: dict[tuple[int, int], int] = {}
        self.not_memo: dict[int, int] = {0: 1, 1: 0}
        self.isop_memo: dict[tuple[int, int], tuple[list[Cube], int]] = {}
        self.cube_memo: dict[Cube, int] = {}

    def mk(self, v: int, lo: int, hi: int) -> int:
        if lo == hi:
            return lo
        key = (v, lo, hi)
        r = self.unique.get(key)
        if r is None:
            r = len(self.var)
            self.var.append(v)
            self.lo.append(lo)
            self.hi.append(hi)
            self.unique[key] = r
        return r

    def neg(self, a: int) -> int:
        r = self.not_memo.get(a)
        if r is None:
            r = self.mk(self.var[a], self.neg(self.lo[a]), self.neg(self.hi[a]))
            self.not_memo[a] = r
        return r

    def conj(self, a: int, b: int) -> int:
        if a == 0 or b == 0:
            return 0
        if a == 1:
            return b
        if b == 1 or a == b:
            return a
        if a > b:
            a, b = b, a
        key = (a, b)
        r = self.and_memo.get(key)
        if r is None:
            va, vb = self.var[a], self.var[b]
            if va == vb:
                r = self.mk(va, self.conj(self.lo[a], self.lo[b]), self.conj(self.hi[a], self.hi[b]))
            elif va < vb:
                r = self.mk(va, self.conj(self.lo[a], b), self.conj(self.hi[a], b))
            else:
                r = self.mk(vb, self.conj(a, self.lo[b]), self.conj(a, self.hi[b]))
            self.and_memo[key] = r
        return r

    def disj(self, a: int, b: int) -> int:
        if a == 1 or b == 1:
            return 1
        if a == 0:
            return b
        if b == 0 or a == b:
            return a
        if a > b:
            a, b = b, a
        key = (a, b)
        r = self.or_memo.get(key)
        if r is None:
            va, vb = self.var[a], self.var[b]
            if va == vb:
                r = self.mk(va, self.disj(self.lo[a], self.lo[b]), self.disj(self.hi[a], self.hi[b]))
            elif va < vb:
                r = self.mk(va, self.disj(self.lo[a], b), self.disj(self.hi[a], b))
            else:
                r = self.mk(vb, self.disj(a, self.lo[b]), self.disj(a, self.hi[b]))
            self.or_memo[key] = r
        return r

    def diff(self, a: int, b: int) -> int:
        """``a & !b``."""
        return self.conj(a, self.neg(b))

    def implies(self, a: int, b: int) -> bool:
        return self.conj(a, self.neg(b)) == 0

    def cube(self, p: int, n: int) -> int:
        key = (p, n)
        r = self.cube_memo.get(key)
        if r is None:
            if p & n:
                r = 0
            else:
                r = 1
                m = p | n
                while m:
                    v = m.bit_length() - 1
                    m ^= 1 << v
                    r = self.mk(v, 0, r) if p >> v & 1 else self.mk(v, r, 0)
            self.cube_memo[key] = r
        return r

    def from_cubes(self, cubes: Iterable[Cube]) -> int:
        r = 0
        for p, n in cubes:
            r = self.disj(r, self.cube(p, n))
        return r

    def isop(self, f: int) -> Guard:
        """Irredundant sum of products of ``f`` (Minato–Morreale), sorted."""
        cubes, _ = self._isop(f, f)
        return tuple(sorted(cubes, key=lambda c: ((c[0] | c[1]).bit_count(), c)))

    def _isop(self, lower: int, upper: int) -> tuple[list[Cube], int]:
        if lower == 0:
            return [], 0
        if upper == 1:
            return [(0, 0)], 1
        key = (lower, upper)
        r = self.isop_memo.get(key)
        if r is not None:
            return r
        v = min(self.var[lower], self.var[upper])
        l0, l1 = (self.lo[lower], self.hi[lower]) if self.var[lower] == v else (lower, lower)
        u0, u1 = (self.lo[upper], self.hi[upper]) if self.var[upper] == v else (upper, upper)
        c0, f0 = self._isop(self.diff(l0, u1), u0)
        c1, f1 = self._isop(self.diff(l1, u0), u1)
        rest_lower = self.disj(self.diff(l0, f0), self.diff(l1, f1))
        cs, fs = self._isop(rest_lower, self.conj(u0, u1))
        bit = 1 << v
        cubes = [(p, n | bit) for p, n in c0] + [(p | bit, n) for p, n in c1] + cs
        f = self.disj(self.disj(self.mk(v, f0, 0), self.mk(v, 0, f1)), fs)
        r = (cubes, f)
        self.isop_memo[key] = r
        return r

    def sat(self, a: int, b: int) -> bool:
        """Is ``a & b`` satisfiable?"""
        return self.conj(a, b) != 0
