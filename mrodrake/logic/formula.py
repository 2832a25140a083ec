"""LTL formulas (paper Sec. II-A): immutable interned values, their smart constructors and Spot-syntax text.

Grammar (paper Sec. II-A, after Baier & Katoen): ``phi ::= true | a | phi & phi | !phi | X phi | phi U phi``
plus the usual derived operators; :mod:`mrodrake.logic.parse` reads the concrete (Spot) syntax.

Formulas are hash-consed: structurally equal formulas are the same object, so ``==`` and hashing are
identity-based and O(1).  The smart constructors apply Spot's trivial identities (flattening, sorting and
de-duplication of ``&``/``|``, constant folding, ``!!a = a``, ``F F a = F a``, ``G G a = G a``), so
``parse(str(f)) is f`` for every formula ``f``.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable

__all__ = [
    "Formula", "TRUE", "FALSE", "Ap", "Not", "And", "Or", "Implies", "Equiv", "Xor",
    "X", "F", "G", "U", "R", "W", "M", "rebuild", "atoms", "to_str",
]

# Operator kinds.
TT, FF, AP, NOT, AND, OR, XOR, IMPLIES, EQUIV = "tt", "ff", "ap", "!", "&", "|", "xor", "->", "<->"
NEXT, EVENTUALLY, ALWAYS, UNTIL, RELEASE, WEAK_UNTIL, STRONG_RELEASE = "X", "F", "G", "U", "R", "W", "M"
UNARY_TEMPORAL = (NEXT, EVENTUALLY, ALWAYS)
BINARY_TEMPORAL = (UNTIL, RELEASE, WEAK_UNTIL, STRONG_RELEASE)

# Printing precedence (higher binds tighter).
_PREC = {IMPLIES: 1, EQUIV: 1, OR: 2, XOR: 3, AND: 4, UNTIL: 5, RELEASE: 5, WEAK_UNTIL: 5,
         STRONG_RELEASE: 5, NOT: 6, NEXT: 6, EVENTUALLY: 6, ALWAYS: 6, TT: 7, FF: 7, AP: 7}
_KEYWORDS = frozenset({"true", "false", "xor", "X", "F", "G", "U", "R", "W", "M", "V"})
#: An unquoted atomic proposition.
IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_.]*")

_TABLE: dict[tuple, Formula] = {}


class Formula:
    """An LTL formula node.  Immutable and interned: build formulas with the constructors, never directly.

    ``kind`` is one of ``tt ff ap ! & | xor -> <-> X F G U R W M``; ``args`` the operand tuple (sorted for
    ``&``/``|``); ``name`` the proposition name for ``ap`` nodes.
    """

    __slots__ = ("kind", "args", "name", "_text", "_sortkey", "_size", "_depth")

    kind: str
    args: tuple[Formula, ...]
    name: str | None

    def __setattr__(self, key, value):
        raise AttributeError("Formula is immutable")

    def __reduce__(self):
        return (_rebuild, (self.kind, self.name, self.args))

    def __str__(self) -> str:
        return self._text

    def __repr__(self) -> str:
        return f"Formula({self._text!r})"

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self

    @property
    def size(self) -> int:
        """Number of nodes of the syntax tree."""
        return self._size

    @property
    def depth(self) -> int:
        """Height of the syntax tree (1 for a proposition or a constant)."""
        return self._depth

    # Convenience operators for building formulas in Python code.
    def __and__(self, other: Formula) -> Formula:
        return And(self, other)

    def __or__(self, other: Formula) -> Formula:
        return Or(self, other)

    def __invert__(self) -> Formula:
        return Not(self)


def _rebuild(kind: str, name: str | None, args: tuple) -> Formula:
    return _make(kind, args, name)


def _make(kind: str, args: tuple = (), name: str | None = None) -> Formula:
    key = (kind, name, args)
    f = _TABLE.get(key)
    if f is not None:
        return f
    f = object.__new__(Formula)
    s = object.__setattr__
    s(f, "kind", kind)
    s(f, "args", args)
    s(f, "name", name)
    s(f, "_size", 1 + sum(a._size for a in args))
    s(f, "_depth", 1 + max((a._depth for a in args), default=0))
    text = _render(kind, args, name)
    s(f, "_text", text)
    # Operand order of & and |: constants, then literals by proposition name, then the rest by text.
    if kind in (TT, FF):
        order = (0, "", 0)
    elif kind == AP:
        order = (1, name, 0)
    elif kind == NOT and args[0].kind == AP:
        order = (1, args[0].name, 1)
    elif kind in (AND, OR, XOR, IMPLIES, EQUIV, NOT):
        order = (2, text, 0)
    else:
        order = (3, text, 0)
    s(f, "_sortkey", order)
    _TABLE[key] = f
    return f


# ----------------------------------------------------------------------------------------------- printer

def _quote_ap(name: str) -> str:
    if IDENT.fullmatch(name) and name not in _KEYWORDS and split_unary_prefix(name) is None:
        return name
    return '"' + name.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _wrap(child: Formula, min_prec: int) -> str:
    if _PREC[child.kind] >= min_prec and not (min_prec <= 5 and child.kind in BINARY_TEMPORAL):
        return child._text
    return "(" + child._text + ")"


def _render(kind: str, args: tuple, name: str | None) -> str:
    if kind == TT:
        return "true"
    if kind == FF:
        return "false"
    if kind == AP:
        return _quote_ap(name)
    if kind == NOT:
        return "!" + _wrap(args[0], 6)
    if kind in UNARY_TEMPORAL:
        c = args[0]
        if _PREC[c.kind] >= 6:
            return kind + " " + c._text
        return kind + "(" + c._text + ")"
    p = _PREC[kind]
    if kind in (AND, OR):
        return f" {kind} ".join(_wrap(a, p + 1) for a in args)
    if kind == XOR:
        return f"{_wrap(args[0], p)} xor {_wrap(args[1], p + 1)}"
    # right-associative binary operators
    return f"{_wrap(args[0], p + 1)} {kind} {_wrap(args[1], p)}"


def to_str(f: Formula) -> str:
    """Spot-syntax text of ``f`` with minimal parentheses; ``parse(to_str(f)) is f``."""
    return f._text


# ------------------------------------------------------------------------------------------ constructors

TRUE = _make(TT)
FALSE = _make(FF)


def Ap(name: str) -> Formula:
    """Atomic proposition ``name``."""
    if not isinstance(name, str) or not name:
        raise ValueError("atomic proposition names are non-empty strings")
    return _make(AP, (), name)


def Not(f: Formula) -> Formula:
    """``!f`` with ``!true = false``, ``!false = true``, ``!!f = f``."""
    k = f.kind
    if k == TT:
        return FALSE
    if k == FF:
        return TRUE
    if k == NOT:
        return f.args[0]
    return _make(NOT, (f,))


def _nary(kind: str, fs: Iterable[Formula]) -> Formula:
    unit, zero = (TRUE, FALSE) if kind == AND else (FALSE, TRUE)
    seen: dict[Formula, None] = {}
    for f in fs:
        if f is zero:
            return zero
        if f is unit:
            continue
        if f.kind == kind:
            for g in f.args:
                seen[g] = None
        else:
            seen[f] = None
    if not seen:
        return unit
    if len(seen) == 1:
        return next(iter(seen))
    return _make(kind, tuple(sorted(seen, key=lambda g: g._sortkey)))


def And(*fs: Formula) -> Formula:
    """Conjunction (flattened, sorted, de-duplicated, constants folded)."""
    return _nary(AND, fs)


def Or(*fs: Formula) -> Formula:
    """Disjunction (flattened, sorted, de-duplicated, constants folded)."""
    return _nary(OR, fs)


def Implies(a: Formula, b: Formula) -> Formula:
    if a is FALSE or b is TRUE:
        return TRUE
    if a is TRUE:
        return b
    if b is FALSE:
        return Not(a)
    if a is b:
        return TRUE
    return _make(IMPLIES, (a, b))


def Equiv(a: Formula, b: Formula) -> Formula:
    if a is TRUE:
        return b
    if b is TRUE:
        return a
    if a is FALSE:
        return Not(b)
    if b is FALSE:
        return Not(a)
    if a is b:
        return TRUE
    return _make(EQUIV, (a, b))


def Xor(a: Formula, b: Formula) -> Formula:
    if a is FALSE:
        return b
    if b is FALSE:
        return a
    if a is TRUE:
        return Not(b)
    if b is TRUE:
        return Not(a)
    if a is b:
        return FALSE
    return _make(XOR, (a, b))


def X(f: Formula) -> Formula:
    if f.kind in (TT, FF):
        return f
    return _make(NEXT, (f,))


def F(f: Formula) -> Formula:
    if f.kind in (TT, FF, EVENTUALLY):
        return f
    return _make(EVENTUALLY, (f,))


def G(f: Formula) -> Formula:
    if f.kind in (TT, FF, ALWAYS):
        return f
    return _make(ALWAYS, (f,))


def U(a: Formula, b: Formula) -> Formula:
    """``a U b``; folds ``a U true = true``, ``a U false = false``, ``false U b = b``, ``true U b = F b``."""
    if b.kind in (TT, FF) or a is FALSE or a is b:
        return b
    if a is TRUE:
        return F(b)
    return _make(UNTIL, (a, b))


def R(a: Formula, b: Formula) -> Formula:
    """``a R b``; folds ``a R true = true``, ``a R false = false``, ``true R b = b``, ``false R b = G b``."""
    if b.kind in (TT, FF) or a is TRUE or a is b:
        return b
    if a is FALSE:
        return G(b)
    return _make(RELEASE, (a, b))


def W(a: Formula, b: Formula) -> Formula:
    """``a W b``; folds ``a W true = true``, ``true W b = true``, ``false W b = b``, ``a W false = G a``."""
    if b is TRUE or a is TRUE:
        return TRUE
    if a is FALSE or a is b:
        return b
    if b is FALSE:
        return G(a)
    return _make(WEAK_UNTIL, (a, b))


def M(a: Formula, b: Formula) -> Formula:
    """``a M b``; folds ``a M false = false``, ``false M b = false``, ``true M b = b``, ``a M true = F a``."""
    if b is FALSE or a is FALSE:
        return FALSE
    if a is TRUE or a is b:
        return b
    if b is TRUE:
        return F(a)
    return _make(STRONG_RELEASE, (a, b))


_BUILD: dict[str, Callable[..., Formula]] = {
    NOT: Not, AND: And, OR: Or, XOR: Xor, IMPLIES: Implies, EQUIV: Equiv,
    NEXT: X, EVENTUALLY: F, ALWAYS: G, UNTIL: U, RELEASE: R, WEAK_UNTIL: W, STRONG_RELEASE: M,
}


def rebuild(kind: str, args: Iterable[Formula]) -> Formula:
    """Apply the smart constructor of ``kind`` to ``args``."""
    return _BUILD[kind](*args)


def split_unary_prefix(word: str) -> tuple[str, str] | None:
    """Spot's lexing of glued unary operators: ``GFa`` -> (``GF``, ``a``); None if ``word`` is one name."""
    i = 0
    while i < len(word) and word[i] in "FGX":
        i += 1
    if i == 0:
        return None
    rest = word[i:]
    if rest == "":
        return (word, "")
    if rest[0].isdigit() or rest[0] == "." or rest in ("U", "R", "W", "M", "V", "xor"):
        return None
    return (word[:i], rest)


def atoms(f: Formula) -> frozenset[str]:
    """Names of the atomic propositions occurring in ``f``."""
    out: set[str] = set()
    seen: set[Formula] = set()
    todo = [f]
    while todo:
        g = todo.pop()
        if g in seen:
            continue
        seen.add(g)
        if g.kind == AP:
            out.add(g.name)
        todo.extend(g.args)
    return frozenset(out)
