"""Nondeterministic Büchi automata with symbolic guards (paper Def. 5), DNF guards and the HOA v1 writer.

In an :class:`NBA` a guard is a DNF, a tuple of cubes ``(pos_mask, neg_mask)`` over the automaton's atomic
propositions (bit ``1 << i`` <-> ``ap[i]``); a letter (integer mask of the true propositions) satisfies a
cube iff all ``pos`` bits are set and no ``neg`` bit is.  Guards are kept irredundant through BDDs
(:mod:`mrodrake.logic.bdd`); nothing enumerates the ``2^|AP|`` letters.  :meth:`NBA.to_hoa` writes the
Hanoi Omega-Automata format v1 (Babiak et al., "The Hanoi Omega-Automata Format", CAV 2015; specification
at https://adl.github.io/hoaf/); :mod:`mrodrake.logic.hoa` reads it.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from mrodrake.errors import UserError
from mrodrake.logic.bdd import BDD, Cube, Guard
from mrodrake.logic.formula import Ap, to_str
from mrodrake.logic.graph import LazySucc, reachable, sccs

__all__ = ["NBA", "TRUE_GUARD", "simplify_guard", "guard_implies", "guard_to_str", "empty_nba"]

TRUE_GUARD: Guard = ((0, 0),)


def simplify_guard(cubes: Iterable[Cube]) -> Guard:
    """An equivalent irredundant DNF (via a BDD and Minato–Morreale ISOP); canonical for a fixed
    variable order, so equivalent guards simplify to the same tuple."""
    cubes = list(cubes)
    if len(cubes) <= 1:
        return tuple(c for c in cubes if not c[0] & c[1])
    bdd = BDD()
    return bdd.isop(bdd.from_cubes(cubes))


def guard_implies(g1: Iterable[Cube], g2: Iterable[Cube]) -> bool:
    """Does the DNF ``g1`` imply the DNF ``g2``?"""
    bdd = BDD()
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
                name = str(i) if hoa else to_str(Ap(ap[i]))
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


class NBA:
    """A nondeterministic Büchi automaton with state-based acceptance and symbolic guards (paper Def. 5).

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
        order = reachable([(q, 0) for q in sorted(cur)],
                           LazySucc(succ, lambda v: [(r, (v[1] + 1) % k)
                                                      for r in self.successors(v[0], cyc[v[1]])]))
        for comp in sccs(order, succ):
            if len(comp) == 1 and comp[0] not in succ[comp[0]]:
                continue
            if any(q in self.accepting for q, _ in comp):
                return True
        return False

    def is_empty(self) -> bool:
        """True iff the automaton accepts no word (no reachable accepting cycle)."""
        succ = [[d for _, d in row] for row in self.edges]
        reach = reachable([self.initial], succ)
        for comp in sccs(reach, succ):
            if len(comp) == 1 and comp[0] not in succ[comp[0]]:
                continue
            if any(q in self.accepting for q in comp):
                return False
        return True

    # -- conversions ------------------------------------------------------------------------------------
    def with_ap(self, ap: Sequence[str], missing: str = "error") -> NBA:
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


def _quote(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def empty_nba(ap: Sequence[str]) -> NBA:
    """The one-state automaton over ``ap`` without edges (empty language)."""
    return NBA(tuple(ap), 0, (), [[]])
