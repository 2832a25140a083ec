"""Nondeterministic Büchi automata (paper Def. 2) and a pure-Python LTL -> NBA translator.

Guards are symbolic.  In an :class:`NBA` a guard is a DNF, a tuple of cubes ``(pos_mask, neg_mask)`` over
the automaton's atomic propositions (bit ``1 << i`` <-> ``ap[i]``); a letter (integer mask of the true
propositions) satisfies a cube iff all ``pos`` bits are set and no ``neg`` bit is.  Inside the translator
guards are reduced ordered BDDs (canonical, so equivalence and implication are cheap); they are turned
into irredundant DNFs (Minato–Morreale ISOP) only at the end.  Nothing enumerates the ``2^|AP|`` letters.

Translation (:func:`translate`) follows Gastin & Oddoux, "Fast LTL to Büchi automata translation"
(CAV 2001): formula simplification (:func:`mrodrake.logic.ltl.simplify`) -> very weak alternating
automaton -> generalized Büchi automaton (with the paper's transition-domination simplification and
merging of bisimilar states) -> counter-based degeneralization to a state-based Büchi automaton, followed
by the usual reductions: removal of states that cannot reach an accepting cycle, quotienting by
direct-simulation equivalence and removal of transitions to direct-simulation "little brothers" (Somenzi
& Bloem, CAV 2000), with parallel edges merged into one guard.  For obligation properties (recognised
syntactically, or checked against the automaton of the negation, as Spot does) the minimal weak
deterministic Büchi automaton (Dax, Eisinger & Klaedtke, ATVA 2007; Löding, IPL 2001) is used when smaller.
"""

from __future__ import annotations

import itertools
import re
from typing import Iterable, Sequence

from mrodrake.errors import UserError
from mrodrake.logic import ltl
from mrodrake.logic.ltl import Formula

__all__ = ["NBA", "translate", "simplify_guard", "guard_implies", "guard_to_str", "TRUE_GUARD"]

Cube = tuple[int, int]
Guard = tuple[Cube, ...]
TRUE_GUARD: Guard = ((0, 0),)


def _popcount(x: int) -> int:
    return bin(x).count("1")


# -------------------------------------------------------------------------------------------------- BDDs

class _BDD:
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
        return tuple(sorted(cubes, key=lambda c: (_popcount(c[0] | c[1]), c)))

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


# ------------------------------------------------------------------------------------------------ guards

def simplify_guard(cubes: Iterable[Cube]) -> Guard:
    """An equivalent irredundant DNF (via a BDD and Minato–Morreale ISOP); canonical for a fixed
    variable order, so equivalent guards simplify to the same tuple."""
    cubes = list(cubes)
    if len(cubes) <= 1:
        return tuple(c for c in cubes if not c[0] & c[1])
    bdd = _BDD()
    return bdd.isop(bdd.from_cubes(cubes))


def guard_implies(g1: Iterable[Cube], g2: Iterable[Cube]) -> bool:
    """Does the DNF ``g1`` imply the DNF ``g2``?"""
    bdd = _BDD()
    return bdd.implies(bdd.from_cubes(g1), bdd.from_cubes(g2))


def guard_to_str(guard: Sequence[Cube], ap: Sequence[str] | None = None, hoa: bool = True) -> str:
    """HOA label text (``0&!1 | 2``, ``t``, ``f``) or, with ``hoa=False``, LTL text over ``ap`` names."""
    if not guard:
        return "f" if hoa else "false"
    parts = []
    for p, n in guard:
        lits = []
        m = p | n
        i = 0
        while m >> i:
            if m >> i & 1:
                name = str(i) if hoa else ltl.to_str(ltl.Ap(ap[i]))
                lits.append(name if p >> i & 1 else "!" + name)
            i += 1
        if not lits:
            return "t" if hoa else "true"
        parts.append("&".join(lits) if hoa else " & ".join(lits))
    if hoa:
        return " | ".join(parts)
    if len(parts) == 1:
        return parts[0]
    return " | ".join(f"({x})" if "&" in x else x for x in parts)


def _guard_holds(guard: Sequence[Cube], label: int) -> bool:
    for p, n in guard:
        if label & p == p and not label & n:
            return True
    return False


# --------------------------------------------------------------------------------------------------- NBA

class NBA:
    """A nondeterministic Büchi automaton with state-based acceptance and symbolic guards (paper Def. 2).

    * states are ``0..num_states-1``; ``initial`` is the single initial state;
    * ``accepting`` is the frozenset of accepting (final) states;
    * ``ap`` is the tuple of atomic propositions, ``ap[i]`` <-> bit ``1 << i`` of letters and cube masks;
    * ``edges[q]`` is a tuple of ``(guard, dst)`` with one entry per destination (parallel edges are
      merged); ``guard`` is a DNF: a tuple of cubes ``(pos_mask, neg_mask)``.

    Run convention (as in HOA and Spot): a run over the word ``L0 L1 L2 ...`` is
    ``q0 -L0-> q1 -L1-> q2 ...`` with ``q0 = initial``; each step reads the label of the *source* position
    (in the product with a transition system, the label ``L(s_k)`` of the TS state being left).  A run is
    accepting iff it visits ``accepting`` infinitely often; a lasso word ``u v^omega`` is accepted iff
    some run over it is accepting.
    """

    __slots__ = ("ap", "initial", "accepting", "edges", "_flat", "_cache", "_full", "_index")

    def __init__(self, ap: Sequence[str], initial: int, accepting: Iterable[int],
                 edges: Sequence[Iterable[tuple[Sequence[Cube], int]]]):
        ap = tuple(ap)
        if len(set(ap)) != len(ap):
            raise ValueError(f"duplicate atomic propositions in {ap}")
        n = len(edges)
        if n == 0:
            raise ValueError("an NBA needs at least one state")
        if not 0 <= initial < n:
            raise ValueError(f"initial state {initial} out of range 0..{n - 1}")
        full = (1 << len(ap)) - 1
        acc = frozenset(accepting)
        if any(not 0 <= q < n for q in acc):
            raise ValueError("accepting state out of range")
        norm = []
        for q, es in enumerate(edges):
            merged: dict[int, list[Cube]] = {}
            for guard, dst in es:
                if not 0 <= dst < n:
                    raise ValueError(f"edge {q}->{dst}: destination out of range")
                for p, ng in guard:
                    if (p | ng) & ~full:
                        raise ValueError(f"edge {q}->{dst}: guard uses a proposition outside ap")
                    merged.setdefault(dst, []).append((p, ng))
            row = []
            for dst in sorted(merged):
                g = simplify_guard(merged[dst])
                if g:
                    row.append((g, dst))
            norm.append(tuple(row))
        s = object.__setattr__
        s(self, "ap", ap)
        s(self, "initial", initial)
        s(self, "accepting", acc)
        s(self, "edges", tuple(norm))
        s(self, "_full", full)
        s(self, "_index", {name: i for i, name in enumerate(ap)})
        s(self, "_flat", tuple(tuple((p, ng, dst) for g, dst in row for p, ng in g) for row in norm))
        s(self, "_cache", {})

    def __setattr__(self, key, value):
        raise AttributeError("NBA is immutable")

    def __reduce__(self):
        return (NBA, (self.ap, self.initial, sorted(self.accepting), self.edges))

    def __repr__(self) -> str:
        return (f"NBA(states={self.num_states}, edges={self.num_edges}, "
                f"accepting={sorted(self.accepting)}, ap={self.ap})")

    def __eq__(self, other) -> bool:
        return (isinstance(other, NBA) and self.ap == other.ap and self.initial == other.initial
                and self.accepting == other.accepting and self.edges == other.edges)

    def __hash__(self) -> int:
        return hash((self.ap, self.initial, self.accepting, self.edges))

    @property
    def num_states(self) -> int:
        return len(self.edges)

    @property
    def num_edges(self) -> int:
        """Number of (source, destination) pairs with a non-false (merged) guard."""
        return sum(len(row) for row in self.edges)

    # -- letters ---------------------------------------------------------------------------------------
    def mask(self, letter: int | Iterable[str]) -> int:
        """Mask of a letter given as a mask or as the set of true propositions (unknown names ignored)."""
        if isinstance(letter, int):
            return letter & self._full
        idx = self._index
        m = 0
        for name in letter:
            i = idx.get(name)
            if i is not None:
                m |= 1 << i
        return m

    @staticmethod
    def guard_holds(guard: Sequence[Cube], label_mask: int) -> bool:
        """Does the letter ``label_mask`` satisfy the DNF ``guard``?"""
        return _guard_holds(guard, label_mask)

    def successors(self, q: int, label_mask: int) -> list[int]:
        """States reachable from ``q`` by reading the letter ``label_mask`` (memoised per (q, letter))."""
        label_mask &= self._full
        key = label_mask * len(self._flat) + q
        r = self._cache.get(key)
        if r is None:
            out = []
            for p, n, dst in self._flat[q]:
                if label_mask & p == p and not label_mask & n and (not out or out[-1] != dst):
                    out.append(dst)
            r = tuple(out)
            self._cache[key] = r
        return list(r)

    # -- lasso acceptance ------------------------------------------------------------------------------
    def accepts_lasso(self, prefix: Sequence, cycle: Sequence) -> bool:
        """Is the lasso word ``prefix cycle^omega`` accepted?  Letters: sets of true AP names, or masks."""
        if len(cycle) == 0:
            raise UserError("lasso: the cycle of a lasso word must not be empty")
        pre = [self.mask(x) for x in prefix]
        cyc = [self.mask(x) for x in cycle]
        cur = {self.initial}
        for letter in pre:
            nxt: set[int] = set()
            for q in cur:
                nxt.update(self.successors(q, letter))
            cur = nxt
            if not cur:
                return False
        k = len(cyc)
        # Product nodes (q, i): automaton in q, about to read cyc[i].
        succ: dict[tuple[int, int], list[tuple[int, int]]] = {}
        order = _reachable([(q, 0) for q in sorted(cur)],
                           _LazySucc(succ, lambda v: [(r, (v[1] + 1) % k)
                                                      for r in self.successors(v[0], cyc[v[1]])]))
        for comp in _sccs(order, succ):
            if len(comp) == 1 and comp[0] not in succ[comp[0]]:
                continue
            if any(q in self.accepting for q, _ in comp):
                return True
        return False

    def is_empty(self) -> bool:
        """True iff the automaton accepts no word (no reachable accepting cycle)."""
        succ = [[d for _, d in row] for row in self.edges]
        reach = _reachable([self.initial], succ)
        for comp in _sccs(reach, succ):
            if len(comp) == 1 and comp[0] not in succ[comp[0]]:
                continue
            if any(q in self.accepting for q in comp):
                return False
        return True

    # -- conversions ------------------------------------------------------------------------------------
    def with_ap(self, ap: Sequence[str], missing: str = "error") -> "NBA":
        """The same automaton over the proposition order ``ap`` (masks re-indexed).

        Propositions of ``ap`` that the automaton does not use simply never appear in guards.  A
        proposition used by the automaton but absent from ``ap`` raises a UserError
        (``missing="error"``) or is taken as always false (``missing="false"``).
        """
        if missing not in ("error", "false"):
            raise ValueError("missing must be 'error' or 'false'")
        ap = tuple(ap)
        index = {name: i for i, name in enumerate(ap)}
        if len(index) != len(ap):
            raise ValueError(f"duplicate atomic propositions in {ap}")
        used = 0
        for row in self.edges:
            for g, _ in row:
                for p, n in g:
                    used |= p | n
        absent = [name for i, name in enumerate(self.ap) if used >> i & 1 and name not in index]
        if absent and missing == "error":
            raise UserError(f"proposition '{absent[0]}' of the formula is not one of the propositions {list(ap)}")
        remap = [index.get(name, -1) for name in self.ap]

        def move(mask: int) -> tuple[int, bool]:
            out, dropped = 0, False
            while mask:
                b = mask & -mask
                mask ^= b
                j = remap[b.bit_length() - 1]
                if j < 0:
                    dropped = True
                else:
                    out |= 1 << j
            return out, dropped

        edges = []
        for row in self.edges:
            new_row = []
            for g, dst in row:
                cubes = []
                for p, n in g:
                    np_, lost = move(p)
                    if lost:
                        continue  # a positive literal of an always-false proposition
                    cubes.append((np_, move(n)[0]))
                if cubes:
                    new_row.append((cubes, dst))
            edges.append(new_row)
        return NBA(ap, self.initial, self.accepting, edges)

    def to_hoa(self, name: str = "") -> str:
        """HOA v1 text: ``Acceptance: 1 Inf(0)``, ``acc-name: Buchi``, state-based, explicit labels."""
        lines = ["HOA: v1"]
        if name:
            lines.append("name: " + _quote(name))
        lines.append(f"States: {self.num_states}")
        lines.append(f"Start: {self.initial}")
        lines.append(" ".join([f"AP: {len(self.ap)}"] + [_quote(a) for a in self.ap]))
        lines.append("acc-name: Buchi")
        lines.append("Acceptance: 1 Inf(0)")
        lines.append("properties: trans-labels explicit-labels state-acc")
        lines.append("--BODY--")
        for q, row in enumerate(self.edges):
            lines.append(f"State: {q}" + (" {0}" if q in self.accepting else ""))
            for g, dst in row:
                lines.append(f"[{guard_to_str(g)}] {dst}")
        lines.append("--END--")
        return "\n".join(lines) + "\n"

    @classmethod
    def from_hoa(cls, text: str, source: str = "HOA") -> "NBA":
        """Read one HOA v1 Büchi automaton (``Inf(0)``, or ``t``/``f``), with state- or transition-based
        acceptance, explicit, implicit or state labels and aliases.  Transition-based acceptance becomes
        state-based by splitting each state into a copy entered by accepting edges and one entered by
        the others; several start states get a fresh initial state."""
        return _read_hoa(text, source)


def _quote(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


# ----------------------------------------------------------------------------------------- graph helpers

class _LazySucc:
    """Mapping-like successor function that records what it computed in ``store``."""

    def __init__(self, store: dict, fn):
        self.store = store
        self.fn = fn

    def __getitem__(self, v):
        r = self.store.get(v)
        if r is None:
            r = self.store[v] = self.fn(v)
        return r


def _reachable(starts: Iterable, succ) -> list:
    seen = set()
    order = []
    for s in starts:
        if s not in seen:
            seen.add(s)
            order.append(s)
    head = 0
    while head < len(order):
        v = order[head]
        head += 1
        for w in succ[v]:
            if w not in seen:
                seen.add(w)
                order.append(w)
    return order


def _sccs(nodes: Sequence, succ) -> list[list]:
    """Tarjan's strongly connected components (iterative), successors' components first."""
    index: dict = {}
    low: dict = {}
    on_stack: set = set()
    stack: list = []
    out: list[list] = []
    counter = 0
    for root in nodes:
        if root in index:
            continue
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        work = [(root, iter(succ[root]))]
        while work:
            v, it = work[-1]
            advanced = False
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(succ[w])))
                    advanced = True
                    break
                if w in on_stack and index[w] < low[v]:
                    low[v] = index[w]
            if advanced:
                continue
            work.pop()
            if work:
                u = work[-1][0]
                if low[v] < low[u]:
                    low[u] = low[v]
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                out.append(comp)
    return out


# ------------------------------------------------------------------------------- LTL -> VWAA -> GBA

_UNTIL_KINDS = (ltl.UNTIL, ltl.EVENTUALLY, ltl.STRONG_RELEASE)


def _dominance_reduce(ts: list[tuple]) -> list[tuple]:
    """Remove transitions ``(pos, neg, conf[, sat])`` dominated by another: weaker or equal label, subset
    target configuration (and superset ``sat``) — Gastin & Oddoux, Sec. 4."""
    if len(ts) <= 1:
        return ts
    with_acc = len(ts[0]) == 4
    keyed = sorted(set(ts), key=lambda t: (_popcount(t[0] | t[1]) + _popcount(t[2])
                                           - (_popcount(t[3]) if with_acc else 0), t))
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
    for c in sorted(set(cs), key=lambda c: (_popcount(c), c)):
        if not any(not (k & ~c) for k in out):
            out.append(c)
    return out


class _VWAA:
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
        if f.kind == ltl.AP:
            return (1 << self.ap_index[f.name], 0)
        return (0, 1 << self.ap_index[f.args[0].name])

    def bar(self, f: Formula) -> list[int]:
        """Configurations (a DNF over states) equivalent to ``f``."""
        r = self.bar_cache.get(f)
        if r is not None:
            return r
        k = f.kind
        if k == ltl.TT:
            r = [0]
        elif k == ltl.FF:
            r = []
        elif k == ltl.AND:
            r = [0]
            for g in f.args:
                r = _minimal_sets([a | b for a in r for b in self.bar(g)])
        elif k == ltl.OR:
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
        if k == ltl.TT:
            r = [(0, 0, 0)]
        elif k == ltl.FF:
            r = []
        elif k in (ltl.AP, ltl.NOT):
            p, n = self.literal(f)
            r = [(p, n, 0)]
        elif k == ltl.AND:
            r = [(0, 0, 0)]
            for g in f.args:
                r = _product(r, self.dprime(g))
        elif k == ltl.OR:
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
        if k in (ltl.AP, ltl.NOT):
            p, n = self.literal(f)
            r = [(p, n, 0)]
        elif k == ltl.NEXT:
            r = [(0, 0, c) for c in self.bar(f.args[0])]
        elif k == ltl.EVENTUALLY:
            r = _dominance_reduce(self.dprime(f.args[0]) + me)
        elif k == ltl.ALWAYS:
            r = _product(self.dprime(f.args[0]), me)
        elif k in (ltl.UNTIL, ltl.WEAK_UNTIL):
            a, b = f.args
            r = _dominance_reduce(self.dprime(b) + _product(self.dprime(a), me))
        elif k == ltl.RELEASE:
            a, b = f.args
            r = _product(self.dprime(b), _dominance_reduce(self.dprime(a) + me))
        elif k == ltl.STRONG_RELEASE:
            a, b = f.args
            r = _dominance_reduce(_product(self.dprime(a), self.dprime(b)) + _product(self.dprime(b), me))
        else:
            raise ValueError(f"formula not in NNF: {f}")
        self.delta_cache[i] = r
        return r


def _build_gba(f: Formula, ap_index: dict[str, int], bdd: _BDD):
    """Generalized Büchi automaton of the NNF formula ``f`` (Gastin & Oddoux, Sec. 4).

    Returns ``(trans, nacc)`` or None if ``f`` is false: GBA state 0 is initial, ``trans[s]`` is a list
    of ``(guard_bdd, dst, accmask)``, one per (destination, acceptance) pair; ``nacc`` acceptance sets,
    one per until state occurring in a reachable configuration.  A transition is in the set of until
    state ``b`` iff ``b`` is not in the target configuration, or ``b``'s own component did not loop, or
    some transition of ``b`` that avoids ``b`` witnesses it (the paper's condition).  Letters of a
    transition dominated by another one (subset target, superset acceptance) are removed.
    """
    vw = _VWAA(ap_index)
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
                is_until = vw.states[q].kind in _UNTIL_KINDS
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
    untils = [i for i, g in enumerate(vw.states) if g.kind in _UNTIL_KINDS and present >> i & 1]
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


def _merge_bisimilar_gba(trans: list[list[tuple]], bdd: _BDD) -> list[list[tuple]]:
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


def _degeneralize(trans: list[list[tuple]], nacc: int, order: Sequence[int], bdd: _BDD,
                  scc_aware: bool = False) -> "_BA":
    """Counter-based degeneralization to a state-based BA (Gastin & Oddoux, Sec. 5): BA states are pairs
    (GBA state, level ``0..nacc``); level ``nacc`` is accepting; acceptance sets are visited in ``order``.

    With ``scc_aware`` (as in Spot's degeneralization), levels only matter inside an SCC: a transition
    entering another SCC goes to the level with which its target was first created ("level cache"),
    and states of SCCs that cannot be accepting keep level 0."""
    if nacc == 0:
        edges = []
        for ts in trans:
            row: dict[int, int] = {}
            for g, d, _ in ts:
                row[d] = bdd.disj(row.get(d, 0), g)
            edges.append(row)
        return _BA(edges, [True] * len(trans), 0, bdd)
    comp_of: list[int] = [0] * len(trans)
    live_comp: list[bool] = []
    if scc_aware:
        succ = [[d for _, d, _ in ts] for ts in trans]
        full = (1 << nacc) - 1
        for ci, comp in enumerate(_sccs(list(range(len(trans))), succ)):
            marks = 0
            for s in comp:
                comp_of[s] = ci
            inside = set(comp)
            for s in comp:
                for _, d, a in trans[s]:
                    if d in inside:
                        marks |= a
            live_comp.append(marks == full and (len(comp) > 1 or any(d == comp[0] for d in succ[comp[0]])))

    def nxt(j: int, a: int) -> int:
        if j == nacc:
            j = 0
        while j < nacc and a >> order[j] & 1:
            j += 1
        return j

    ids = {(0, 0): 0}
    states = [(0, 0)]
    first_level: dict[int, int] = {0: 0}
    edges = []
    head = 0
    while head < len(states):
        s, j = states[head]
        head += 1
        row = {}
        for g, d, a in trans[s]:
            if not scc_aware:
                key = (d, nxt(j, a))
            elif not live_comp[comp_of[d]]:
                key = (d, 0)
            elif comp_of[d] != comp_of[s]:
                key = (d, first_level.setdefault(d, nxt(0, a)))
            else:
                key = (d, nxt(j, a))
            first_level.setdefault(d, key[1])
            q = ids.get(key)
            if q is None:
                q = ids[key] = len(states)
                states.append(key)
            row[q] = bdd.disj(row.get(q, 0), g)
        edges.append(row)
    return _BA(edges, [j == nacc for _, j in states], 0, bdd)


# ------------------------------------------------------------------------------------------ BA reduction

class _BA:
    """Mutable state-based BA used during translation: ``edges[q]`` maps destination -> BDD guard."""

    def __init__(self, edges: list[dict[int, int]], acc: list[bool], init: int, bdd: _BDD):
        self.edges = edges
        self.acc = acc
        self.init = init
        self.bdd = bdd

    @property
    def n(self) -> int:
        return len(self.edges)

    def size(self) -> tuple[int, int]:
        return (self.n, sum(len(e) for e in self.edges))

    def copy(self) -> "_BA":
        return _BA([dict(e) for e in self.edges], list(self.acc), self.init, self.bdd)

    def restrict(self, keep: list[int]) -> "_BA":
        """Sub-automaton on ``keep`` (which contains ``init``), renumbered in the order of ``keep``."""
        new = {q: i for i, q in enumerate(keep)}
        edges = [{new[d]: g for d, g in self.edges[q].items() if d in new} for q in keep]
        return _BA(edges, [self.acc[q] for q in keep], new[self.init], self.bdd)

    def trivial_states(self) -> set[int]:
        """States on no cycle (alone in their SCC, without self-loop)."""
        succ = [list(e) for e in self.edges]
        out = set()
        for comp in _sccs(list(range(self.n)), succ):
            if len(comp) == 1 and comp[0] not in self.edges[comp[0]]:
                out.add(comp[0])
        return out

    def prune(self, trivial_accepting: bool) -> "_BA | None":
        """Keep reachable states that can reach an accepting cycle (None if the language is empty).

        A state in a trivial SCC is visited at most once by any run, so its acceptance is irrelevant; it
        is normalised to ``trivial_accepting``."""
        succ = [list(e) for e in self.edges]
        reach = _reachable([self.init], succ)
        good: set[int] = set()
        trivial = []
        for comp in _sccs(reach, succ):  # successors' components come first
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

    def simulation(self) -> list[int]:
        """Direct simulation: bit ``q`` of ``rel[p]`` is set iff ``q`` simulates ``p`` (greatest fixpoint:
        ``q`` is accepting if ``p`` is, and matches every edge ``p -a-> p'`` by edges ``q -a-> q'`` with
        ``q'`` simulating ``p'``).  Worklist iteration: ``p`` is re-examined only when the simulators of
        one of its successors shrank."""
        n = self.n
        bdd = self.bdd
        acc = self.acc
        edges = [list(e.items()) for e in self.edges]
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

    def quotient(self, rel: list[int]) -> "_BA":
        """Merge direct-simulation-equivalent states (language preserving)."""
        n = self.n
        rep = list(range(n))
        for p in range(n):
            if rep[p] != p:
                continue
            for q in range(p + 1, n):
                if rep[q] == q and rel[p] >> q & 1 and rel[q] >> p & 1:
                    rep[q] = p
        if all(rep[q] == q for q in range(n)):
            return self
        keep = [q for q in range(n) if rep[q] == q]
        new = {q: i for i, q in enumerate(keep)}
        edges: list[dict[int, int]] = [dict() for _ in keep]
        for q in range(n):
            row = edges[new[rep[q]]]
            for d, g in self.edges[q].items():
                t = new[rep[d]]
                row[t] = self.bdd.disj(row.get(t, 0), g)
        return _BA(edges, [self.acc[q] for q in keep], new[rep[self.init]], self.bdd)

    def prune_little_brothers(self, rel: list[int]) -> None:
        """Remove from the guard of ``q -> t`` the letters that also lead from ``q`` to a state strictly
        simulating ``t`` (little brothers; Somenzi & Bloem 2000).  Sound because strict simulation is
        well-founded: every removed letter still leads to a maximal simulating state."""
        bdd = self.bdd
        for q in range(self.n):
            row = self.edges[q]
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
            self.edges[q] = new_row

    def reduce(self, trivial_accepting: bool) -> "_BA | None":
        ba: _BA | None = self
        while True:
            ba = ba.prune(trivial_accepting)
            if ba is None:
                return None
            before = ba.size()
            rel = ba.simulation()
            merged = ba.quotient(rel)
            if merged is not ba:
                ba = merged
                rel = ba.simulation()
            ba.prune_little_brothers(rel)
            ba = ba.prune(trivial_accepting)
            if ba is None:
                return None
            if ba.size() == before:
                return ba

    def to_nba(self, ap: tuple[str, ...]) -> NBA:
        """Export with breadth-first numbering from the initial state (state 0) and ISOP guards."""
        order = _reachable([self.init], [sorted(e) for e in self.edges])
        new = {q: i for i, q in enumerate(order)}
        edges = [[(self.bdd.isop(self.edges[q][d]), new[d]) for d in sorted(self.edges[q], key=lambda d: new[d])]
                 for q in order]
        return NBA(ap, 0, [new[q] for q in order if self.acc[q]], edges)


# ------------------------------------------------------------------------------- WDBA minimization

def _syntactic_class(f: Formula, memo: dict) -> tuple[bool, bool, bool]:
    """(safety, guarantee, obligation) membership of the NNF formula ``f`` in the syntactic classes of
    Černá & Pelánek (MFCS 2003): safety is closed under ``& | X G R W``, guarantee under ``& | X F U M``;
    obligation adds ``F`` of guarantee, ``G`` of safety, ``o U g``, ``o R s``, ``s W o``, ``g M o``."""
    r = memo.get(f)
    if r is not None:
        return r
    k = f.kind
    if not f.args or k == ltl.NOT:
        r = (True, True, True)
    else:
        sub = [_syntactic_class(g, memo) for g in f.args]
        if k in (ltl.AND, ltl.OR, ltl.NEXT):
            r = (all(c[0] for c in sub), all(c[1] for c in sub), all(c[2] for c in sub))
        elif k == ltl.ALWAYS:
            r = (sub[0][0], False, sub[0][0])
        elif k == ltl.EVENTUALLY:
            r = (False, sub[0][1], sub[0][1])
        else:
            a, b = sub
            if k == ltl.UNTIL:
                r = (False, a[1] and b[1], a[2] and b[1])
            elif k == ltl.STRONG_RELEASE:
                r = (False, a[1] and b[1], a[1] and b[2])
            elif k == ltl.RELEASE:
                r = (a[0] and b[0], False, a[2] and b[0])
            else:  # W
                r = (a[0] and b[0], False, a[0] and b[2])
    memo[f] = r
    return r


def _intersection_empty(a: _BA, b: _BA) -> bool:
    """Is ``L(a) & L(b)`` empty?  (Same BDD manager; a reachable product cycle must visit accepting
    states of both.)"""
    bdd = a.bdd
    succ: dict = {}

    def step(v):
        x, y = v
        return [(d1, d2) for d1, g1 in a.edges[x].items() for d2, g2 in b.edges[y].items() if bdd.sat(g1, g2)]

    order = _reachable([(a.init, b.init)], _LazySucc(succ, step))
    for comp in _sccs(order, succ):
        if len(comp) == 1 and comp[0] not in succ[comp[0]]:
            continue
        if any(a.acc[x] for x, _ in comp) and any(b.acc[y] for _, y in comp):
            return False
    return True


def _wdba(ba: _BA, limit: int) -> tuple[_BA, _BA] | None:
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
    comps = _sccs(list(range(n)), [list(t) for t in trans])
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
        for pc in _sccs(nodes, psucc):
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
    wdba = _BA(edges, acc, block[0], bdd)
    comp = _BA([dict(e) for e in edges], [not x for x in acc], block[0], bdd)
    return wdba, comp


# ---------------------------------------------------------------------------------------------- translate

def _empty_nba(ap: tuple[str, ...]) -> NBA:
    return NBA(ap, 0, (), [[]])


def translate(f: Formula | str, backend: str = "builtin") -> NBA:
    """LTL -> state-based NBA.  ``backend="builtin"`` (see the module docstring) or ``"spot"``
    (``spot.translate(f, "BA", "sbacc")``; needs the optional ``spottl`` package).

    ``ap`` of the result is the sorted tuple of the formula's propositions.
    """
    if isinstance(f, str):
        f = ltl.parse(f)
    if backend == "spot":
        from mrodrake.logic.spot_backend import translate_spot
        return translate_spot(f)
    if backend != "builtin":
        raise UserError(f"translator: unknown backend '{backend}' (expected 'builtin' or 'spot')")
    ap = tuple(sorted(ltl.atoms(f)))
    ap_index = {a: i for i, a in enumerate(ap)}
    g = ltl.simplify(f)
    bdd = _BDD()
    ba = _translate_core(g, ap_index, bdd)
    if ba is None:
        return _empty_nba(ap)
    if ba.n > 1:
        wd = _try_wdba(g, ba, ap_index)
        if wd is not None and wd.size() < ba.size():
            ba = wd
    return ba.to_nba(ap)


def _translate_core(g: Formula, ap_index: dict[str, int], bdd: _BDD) -> _BA | None:
    """Simplified NNF formula -> reduced state-based BA (None if the language is empty)."""
    built = _build_gba(g, ap_index, bdd)
    if built is None:
        return None
    trans, nacc = built
    trans = _merge_bisimilar_gba(trans, bdd)
    # The degeneralized size depends on the order of the acceptance sets and on SCC-awareness: for small
    # GBAs try every order of up to three sets (identity and reverse otherwise), with and without
    # SCC-aware levels, and keep the smallest reduced automaton.
    if len(trans) * (nacc + 1) > 64:
        variants = [(tuple(range(nacc)), True)]  # large: one good variant only
    else:
        if nacc <= 3:
            orders = list(itertools.permutations(range(nacc)))
        else:
            orders = [tuple(range(nacc)), tuple(reversed(range(nacc)))]
        variants = [(order, scc) for order in orders for scc in (False, True)]
    best = None
    for order, scc_aware in variants:
        deg = _degeneralize(trans, nacc, order, bdd, scc_aware)
        for trivial_accepting in ((False, True) if deg.trivial_states() else (False,)):
            ba = deg.copy().reduce(trivial_accepting)
            if ba is None:
                return None
            if best is None or ba.size() < best.size():
                best = ba
    return best


def _try_wdba(g: Formula, ba: _BA, ap_index: dict[str, int]) -> _BA | None:
    """The minimal WDBA of ``g`` if its language is an obligation: syntactically (Černá & Pelánek), or
    checked semantically against ``ba`` and the automaton of ``!g`` (as Spot does); None otherwise."""
    res = _wdba(ba, limit=max(32, 4 * ba.n))
    if res is None:
        return None
    wd, comp = res
    if not _syntactic_class(g, {})[2]:
        if not _intersection_empty(ba, comp):
            return None
        neg = _translate_core(ltl.simplify(ltl.Not(g)), ap_index, ba.bdd)
        if neg is not None and not _intersection_empty(wd, neg):
            return None
    return wd.prune(False)


# ----------------------------------------------------------------------------------------------- HOA in

_HOA_TOKEN = re.compile(r"""
    (?P<ws>\s+|/\*.*?\*/)
  | (?P<header>[A-Za-z@][A-Za-z0-9_-]*:)
  | (?P<body>--BODY--|--END--|--ABORT--)
  | (?P<string>"(?:[^"\\]|\\.)*")
  | (?P<int>[0-9]+)
  | (?P<alias>@[A-Za-z0-9_-]+)
  | (?P<ident>[A-Za-z_][A-Za-z0-9_-]*)
  | (?P<punct>[!&|()\[\]{}])
""", re.VERBOSE | re.DOTALL)


def _hoa_tokens(text: str, source: str) -> list[tuple[str, str, int]]:
    toks = []
    i = 0
    line = 1
    while i < len(text):
        m = _HOA_TOKEN.match(text, i)
        if not m:
            raise UserError(f"{source}:{line}: unexpected character {text[i]!r} in HOA input")
        kind = m.lastgroup
        val = m.group(kind)
        if kind != "ws":
            toks.append((kind, val, line))
        line += val.count("\n")
        i = m.end()
    return toks


def _read_hoa(text: str, source: str) -> NBA:
    toks = _hoa_tokens(text, source)
    pos = 0

    def err(what: str, at: int | None = None) -> UserError:
        line = toks[min(at if at is not None else pos, len(toks) - 1)][2] if toks else 1
        return UserError(f"{source}:{line}: {what}")

    if not toks or toks[0] != ("header", "HOA:", toks[0][2]) or len(toks) < 2 or toks[1][1] != "v1":
        raise err("not a HOA v1 automaton (expected 'HOA: v1')", 0)
    pos = 2
    n_states = None
    starts: list[int] = []
    ap: list[str] = []
    acceptance: list[tuple[str, str, int]] = []
    aliases: dict[str, list] = {}
    while pos < len(toks) and toks[pos][0] != "body":
        kind, val, _ = toks[pos]
        if kind != "header":
            raise err(f"unexpected '{val}' in the HOA header")
        pos += 1
        start = pos
        while pos < len(toks) and toks[pos][0] not in ("header", "body"):
            pos += 1
        items = toks[start:pos]
        if val == "States:":
            n_states = int(items[0][1])
        elif val == "Start:":
            if any(t[1] == "&" for t in items):
                raise err("alternating automata (conjunctive Start) are not supported", start)
            starts.append(int(items[0][1]))
        elif val == "AP:":
            count = int(items[0][1])
            ap = [_unquote(t[1]) for t in items[1:]]
            if len(ap) != count:
                raise err(f"AP: declares {count} propositions but lists {len(ap)}", start)
        elif val == "Acceptance:":
            acceptance = items
        elif val == "Alias:":
            name = items[0][1]
            aliases[name] = items[1:]
    if pos >= len(toks) or toks[pos][1] != "--BODY--":
        raise err("missing --BODY--")
    pos += 1
    acc_text = " ".join(t[1] for t in acceptance)
    acc_norm = acc_text.replace(" ", "")
    if acc_norm in ("1Inf(0)",):
        all_acc = False
    elif acc_norm == "0t":
        all_acc = True
    elif acc_norm == "0f":
        all_acc = None
    else:
        raise err(f"only Büchi acceptance ('1 Inf(0)') is supported, got '{acc_text}'")
    nap = len(ap)

    bdd = _BDD()

    def parse_label(items: list, at: int) -> list[Cube]:
        return list(bdd.isop(_LabelParser(items, aliases, nap, lambda what: err(what, at), bdd).parse()))

    def read_marks() -> set[int]:
        nonlocal pos
        marks = set()
        if pos < len(toks) and toks[pos][1] == "{":
            pos += 1
            while pos < len(toks) and toks[pos][1] != "}":
                if toks[pos][0] != "int":
                    raise err("acceptance marks must be integers")
                marks.add(int(toks[pos][1]))
                pos += 1
            if pos >= len(toks):
                raise err("unclosed '{'")
            pos += 1
        return marks

    def read_bracket() -> tuple[list, int] | None:
        nonlocal pos
        if pos < len(toks) and toks[pos][1] == "[":
            at = pos
            pos += 1
            start = pos
            while pos < len(toks) and toks[pos][1] != "]":
                pos += 1
            if pos >= len(toks):
                raise err("unclosed '['", at)
            items = toks[start:pos]
            pos += 1
            return items, at
        return None

    raw: dict[int, tuple[bool, list[tuple[list[Cube], int, bool]]]] = {}
    while pos < len(toks) and toks[pos][1] != "--END--":
        if toks[pos][1] == "--ABORT--":
            raise err("HOA stream aborted (--ABORT--)")
        if toks[pos][1] != "State:":
            raise err(f"expected 'State:', got '{toks[pos][1]}'")
        pos += 1
        state_label = read_bracket()
        if pos >= len(toks) or toks[pos][0] != "int":
            raise err("expected a state number")
        q = int(toks[pos][1])
        pos += 1
        if pos < len(toks) and toks[pos][0] == "string":
            pos += 1
        state_marks = read_marks()
        if q in raw:
            raise err(f"state {q} defined twice")
        slabel = parse_label(*state_label) if state_label else None
        out: list[tuple[list[Cube], int, bool]] = []
        implicit = 0
        labelled = 0
        state_at = pos
        while pos < len(toks) and toks[pos][1] not in ("State:", "--END--", "--ABORT--"):
            lab = read_bracket()
            if pos >= len(toks) or toks[pos][0] != "int":
                raise err("expected a destination state")
            dst = int(toks[pos][1])
            pos += 1
            if pos < len(toks) and toks[pos][1] == "&":
                raise err("alternating automata (conjunctive destinations) are not supported")
            marks = read_marks()
            if lab is not None:
                if slabel is not None:
                    raise err("a state label and edge labels cannot be mixed")
                labelled += 1
                cubes = parse_label(*lab)
            elif slabel is not None:
                cubes = slabel
            else:
                if nap > 20:
                    raise err("implicit labels over more than 20 propositions are not supported")
                letter = implicit
                implicit += 1
                fullm = (1 << nap) - 1
                cubes = [(letter, fullm & ~letter)]
            if any(m != 0 for m in marks | state_marks):
                raise err("only acceptance set 0 exists in a Büchi automaton")
            out.append((cubes, dst, bool(marks)))
        if implicit and labelled:
            raise err(f"state {q} mixes labelled edges and edges with implicit labels", state_at)
        if implicit and implicit != 1 << nap:
            raise err(f"state {q} has {implicit} implicit-label edges, expected {1 << nap}", state_at)
        raw[q] = (bool(state_marks), out)
    if pos >= len(toks):
        raise err("missing --END--")
    if n_states is None:
        n_states = max([q + 1 for q in raw] + [d + 1 for _, es in raw.values() for _, d, _ in es] + [1])
    for q, (_, es) in raw.items():
        for _, d, _ in es:
            if not 0 <= d < n_states:
                raise err(f"edge {q}->{d}: destination out of range (States: {n_states})")
    if not starts:
        starts = []
    if any(not 0 <= s < n_states for s in starts):
        raise err("Start state out of range")

    # Every edge is accepting if its source state or the edge itself carries mark 0.
    acc_edges = []
    for q in range(n_states):
        smark, es = raw.get(q, (False, []))
        acc_edges.append([(c, d, (smark or m) if all_acc is False else bool(all_acc)) for c, d, m in es])
    ap_t = tuple(ap)
    if not starts:
        return _empty_nba(ap_t)
    state_based = all(len({a for _, _, a in es}) <= 1 for es in acc_edges)
    if state_based:
        accepting = [q for q in range(n_states) if acc_edges[q] and acc_edges[q][0][2]]
        edges = [[(c, d) for c, d, _ in es] for es in acc_edges]
        if len(starts) == 1:
            return NBA(ap_t, starts[0], accepting, edges)
        init = n_states
        edges.append([(c, d) for s in starts for c, d in edges[s]])
        return NBA(ap_t, init, accepting, edges)
    # Transition-based: state (q, b) where b says whether the entering edge was accepting.
    ids: dict[tuple[int, bool], int] = {}
    order: list[tuple] = []

    def sid(key) -> int:
        i = ids.get(key)
        if i is None:
            i = ids[key] = len(order)
            order.append(key)
        return i

    init_key = ("start",) if len(starts) > 1 else (starts[0], False)
    sid(init_key)
    rows: list[list] = []
    head = 0
    while head < len(order):
        key = order[head]
        head += 1
        srcs = starts if key == ("start",) else [key[0]]
        rows.append([(c, sid((d, a))) for s in srcs for c, d, a in acc_edges[s]])
    accepting = [i for i, key in enumerate(order) if len(key) == 2 and key[1]]
    return NBA(ap_t, 0, accepting, rows)


class _LabelParser:
    """HOA label expressions (``t f ! & | ( ) <int> @alias``) to BDDs."""

    def __init__(self, items: list, aliases: dict[str, list], nap: int, err, bdd: _BDD, depth: int = 0):
        self.items = [t[1] for t in items]
        self.i = 0
        self.aliases = aliases
        self.nap = nap
        self.err = err
        self.bdd = bdd
        self.depth = depth

    def parse(self) -> int:
        if not self.items:
            raise self.err("empty label expression")
        r = self.expr()
        if self.i != len(self.items):
            raise self.err(f"unexpected '{self.items[self.i]}' in label expression")
        return r

    def peek(self):
        return self.items[self.i] if self.i < len(self.items) else None

    def expr(self) -> int:
        out = self.term()
        while self.peek() == "|":
            self.i += 1
            out = self.bdd.disj(out, self.term())
        return out

    def term(self) -> int:
        out = self.factor()
        while self.peek() == "&":
            self.i += 1
            out = self.bdd.conj(out, self.factor())
        return out

    def factor(self) -> int:
        t = self.peek()
        if t is None:
            raise self.err("incomplete label expression")
        self.i += 1
        if t == "!":
            return self.bdd.neg(self.factor())
        if t == "(":
            r = self.expr()
            if self.peek() != ")":
                raise self.err("missing ')' in label expression")
            self.i += 1
            return r
        if t == "t":
            return 1
        if t == "f":
            return 0
        if t.startswith("@"):
            if t not in self.aliases:
                raise self.err(f"undefined alias {t}")
            if self.depth > 32:
                raise self.err("recursive alias definitions")
            return _LabelParser(self.aliases[t], self.aliases, self.nap, self.err, self.bdd, self.depth + 1).parse()
        if t.isdigit():
            k = int(t)
            if k >= self.nap:
                raise self.err(f"proposition index {k} out of range (AP has {self.nap})")
            return self.bdd.cube(1 << k, 0)
        raise self.err(f"unexpected '{t}' in label expression")


def _unquote(s: str) -> str:
    if s.startswith('"') and s.endswith('"'):
        return re.sub(r"\\(.)", r"\1", s[1:-1])
    return s
