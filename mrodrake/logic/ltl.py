"""LTL formulas (paper Sec. II-A): immutable interned values, a Spot-syntax parser, NNF and simplification.

Grammar (paper Sec. II-A, after Baier & Katoen): ``phi ::= true | a | phi & phi | !phi | X phi | phi U phi``
plus the usual derived operators.  The concrete syntax is Spot's:

* constants ``true``/``1``, ``false``/``0``; atomic propositions are identifiers
  (``[A-Za-z_][A-Za-z0-9_.]*``) or double-quoted strings;
* unary ``!`` (``~``), ``X``, ``F`` (``<>``), ``G`` (``[]``); like Spot, ``GFa`` is ``G F a``;
* binary, from loosest to tightest: ``->`` ``<->`` (same level, right-associative; aliases ``=>``,
  ``<=>``), ``|`` (``||``, ``\\/``), ``xor`` (``^``), ``&`` (``&&``, ``/\\``), ``U R W M``
  (right-associative; ``V`` is an alias of ``R``).

Formulas are hash-consed: structurally equal formulas are the same object, so ``==`` and hashing are
identity-based and O(1).  The smart constructors apply Spot's trivial identities (flattening, sorting and
de-duplication of ``&``/``|``, constant folding, ``!!a = a``, ``F F a = F a``, ``G G a = G a``), so
``parse(str(f)) is f`` for every formula ``f``.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable

from mrodrake.errors import UserError

__all__ = [
    "Formula", "TRUE", "FALSE", "Ap", "Not", "And", "Or", "Implies", "Equiv", "Xor",
    "X", "F", "G", "U", "R", "W", "M",
    "parse", "atoms", "nnf", "simplify", "to_str", "is_nnf",
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
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_.]*")

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
    if _IDENT.fullmatch(name) and name not in _KEYWORDS and _split_fgx(name) is None:
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


# ------------------------------------------------------------------------------------------------ parser

def _split_fgx(word: str) -> tuple[str, str] | None:
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


_SYMBOLS = [
    ("<-->", EQUIV), ("-->", IMPLIES), ("<->", EQUIV), ("<=>", EQUIV), ("->", IMPLIES), ("=>", IMPLIES),
    ("&&", AND), ("||", OR), ("/\\", AND), ("\\/", OR), ("[]", ALWAYS), ("<>", EVENTUALLY),
    ("&", AND), ("|", OR), ("^", XOR), ("!", NOT), ("~", NOT), ("(", "("), (")", ")"),
]
_WORD_OPS = {"xor": XOR, "U": UNTIL, "R": RELEASE, "V": RELEASE, "W": WEAK_UNTIL, "M": STRONG_RELEASE,
             "X": NEXT, "F": EVENTUALLY, "G": ALWAYS}


def _syntax_error(source: str, text: str, col: int, what: str) -> UserError:
    shown = text.replace("\n", " ").replace("\t", " ")
    return UserError(f"{source}:{col}: {what}\n{shown}\n{' ' * (col - 1)}^")


def _tokenize(text: str, source: str) -> list[tuple[str, object, int]]:
    """Tokens ``(type, value, column)``; types: ``op``, ``ap``, ``const``, ``eof``."""
    toks: list[tuple[str, object, int]] = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c.isspace():
            i += 1
            continue
        col = i + 1
        if c == '"':
            j = i + 1
            buf = []
            while j < n and text[j] != '"':
                if text[j] == "\\" and j + 1 < n:
                    j += 1
                buf.append(text[j])
                j += 1
            if j >= n:
                raise _syntax_error(source, text, col, "unterminated quoted proposition")
            if not buf:
                raise _syntax_error(source, text, col, "empty quoted proposition")
            toks.append(("ap", "".join(buf), col))
            i = j + 1
            continue
        if c.isdigit():
            m = re.compile(r"[0-9]+").match(text, i)
            word = m.group(0)
            if word not in ("0", "1"):
                raise _syntax_error(source, text, col, f"unexpected number '{word}' (only 0 and 1 are constants)")
            toks.append(("const", word == "1", col))
            i = m.end()
            continue
        m = _IDENT.match(text, i)
        if m:
            word = m.group(0)
            i = m.end()
            if word in ("true", "false"):
                toks.append(("const", word == "true", col))
            elif word in _WORD_OPS:
                toks.append(("op", _WORD_OPS[word], col))
            else:
                split = _split_fgx(word)
                if split is None:
                    toks.append(("ap", word, col))
                else:
                    ops, rest = split
                    for k, letter in enumerate(ops):
                        toks.append(("op", letter, col + k))
                    if rest:
                        rcol = col + len(ops)
                        if rest in ("true", "false"):
                            toks.append(("const", rest == "true", rcol))
                        else:
                            toks.append(("ap", rest, rcol))
            continue
        for sym, kind in _SYMBOLS:
            if text.startswith(sym, i):
                toks.append(("op", kind, col))
                i += len(sym)
                break
        else:
            raise _syntax_error(source, text, col, f"unexpected character {c!r}")
    toks.append(("eof", None, n + 1))
    return toks


#: Deepest syntax tree the parser accepts.  Parsing itself is iterative (no limit on parentheses, which add
#: no depth), but NNF, simplification and the translation recurse once per level of the tree.
MAX_DEPTH = 200

# Binary operators: (precedence, right-associative); unary operators bind tighter than all of them.
_BINARY = {IMPLIES: (1, True), EQUIV: (1, True), OR: (2, False), XOR: (3, False), AND: (4, False),
           UNTIL: (5, True), RELEASE: (5, True), WEAK_UNTIL: (5, True), STRONG_RELEASE: (5, True)}
_PREFIX = (NOT, NEXT, EVENTUALLY, ALWAYS)


class _Parser:
    """Operator-precedence parser with explicit stacks (no recursion, whatever the nesting)."""

    def __init__(self, text: str, source: str, resolve: Callable[[str, int], Formula | None]):
        self.text = text
        self.source = source
        self.toks = _tokenize(text, source)
        self.resolve = resolve

    def error(self, tok, what: str) -> UserError:
        return _syntax_error(self.source, self.text, tok[2], what)

    @staticmethod
    def describe(t) -> str:
        if t[0] == "eof":
            return "end of formula"
        if t[0] == "ap":
            return f"proposition '{t[1]}'"
        if t[0] == "const":
            return "constant"
        return f"'{t[1]}'"

    def build(self, tok, f: Formula) -> Formula:
        if f.depth > MAX_DEPTH:
            raise self.error(tok, f"formula nested deeper than {MAX_DEPTH} operators (the limit of the LTL "
                                  "translation)")
        return f

    def parse(self) -> Formula:
        toks = self.toks
        if toks[0][0] == "eof":
            raise self.error(toks[0], "empty formula")
        out: list[Formula] = []
        ops: list[tuple] = []  # operator and '(' tokens

        def reduce_top() -> None:
            tok = ops.pop()
            if tok[1] in _PREFIX:
                out.append(self.build(tok, _BUILD[tok[1]](out.pop())))
            else:
                rhs = out.pop()
                out.append(self.build(tok, _BUILD[tok[1]](out.pop(), rhs)))

        def open_paren() -> tuple | None:
            return next((t for t in reversed(ops) if t[1] == "("), None)

        operand = True  # expecting an operand
        prev = None
        for t in toks:
            typ, val, _ = t
            if operand:
                if typ == "op" and val in _PREFIX:
                    ops.append(t)
                elif typ == "op" and val == "(":
                    ops.append(t)
                elif typ == "op" and val == ")" and prev is not None and prev[1] == "(":
                    raise self.error(t, "empty parentheses")
                elif typ == "const":
                    out.append(TRUE if val else FALSE)
                    operand = False
                elif typ == "ap":
                    g = self.resolve(val, t[2])
                    out.append(g if g is not None else Ap(val))
                    operand = False
                elif typ == "eof":
                    raise self.error(t, "unexpected end of formula, expected a formula")
                else:
                    raise self.error(t, f"unexpected {self.describe(t)}, expected a formula")
            elif typ == "op" and val in _BINARY:
                prec, right = _BINARY[val]
                while ops and ops[-1][1] != "(":
                    top = ops[-1][1]
                    top_prec = 6 if top in _PREFIX else _BINARY[top][0]
                    if top_prec > prec or (top_prec == prec and not right):
                        reduce_top()
                    else:
                        break
                ops.append(t)
                operand = True
            elif typ == "op" and val == ")":
                while ops and ops[-1][1] != "(":
                    reduce_top()
                if not ops:
                    raise self.error(t, "unmatched ')'")
                ops.pop()
            elif typ == "eof":
                while ops and ops[-1][1] != "(":
                    reduce_top()
                if ops:
                    raise self.error(open_paren(), "unclosed '('")
            else:
                expected = "')'" if open_paren() is not None else "an operator or the end"
                raise self.error(t, f"unexpected {self.describe(t)}, expected {expected}")
            prev = t
        return out[0]


def parse(text: str, macros: dict[str, str] | None = None, source: str = "formula", *,
          macro_prefix: str = "") -> Formula:
    """Parse Spot-syntax LTL ``text``; identifiers naming a macro expand to the macro's parsed body.

    Syntax errors raise ``UserError("{source}:{col}: ...")`` (1-based column) whose detail is the text and a
    caret line.  A syntax error inside macro ``m`` is reported with source ``f"{macro_prefix}{m}"`` (e.g.
    ``macro_prefix="task.propositions."``); cyclic macro definitions raise a UserError naming the cycle.
    """
    if not isinstance(text, str):
        raise UserError(f"{source}: formula must be a string, got {type(text).__name__}")
    macros = macros or {}
    cache: dict[str, Formula] = {}
    stack: list[str] = []

    def expand(name: str) -> Formula:
        if name in cache:
            return cache[name]
        if name in stack:
            cycle = stack[stack.index(name):] + [name]
            raise UserError(f"{macro_prefix}{cycle[0]}: cyclic macro definition: {' -> '.join(cycle)}")
        body = macros[name]
        if not isinstance(body, str):
            raise UserError(f"{macro_prefix}{name}: macro body must be a string, got {type(body).__name__}")
        if len(stack) >= MAX_DEPTH:
            raise UserError(f"{macro_prefix}{name}: macros nested deeper than {MAX_DEPTH} levels")
        stack.append(name)
        f = _Parser(body, f"{macro_prefix}{name}", resolve).parse()
        stack.pop()
        cache[name] = f
        return f

    def resolve(name: str, col: int) -> Formula | None:
        return expand(name) if name in macros else None

    return _Parser(text, source, resolve).parse()


# ------------------------------------------------------------------------------------------ traversals

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


_NNF_CACHE: dict[tuple[Formula, bool], Formula] = {}


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
        dual = {UNTIL: R, RELEASE: U, WEAK_UNTIL: M, STRONG_RELEASE: W}
        ctor = dual[k] if negate else _BUILD[k]
        r = ctor(nnf(a[0], negate), nnf(a[1], negate))
    _NNF_CACHE[key] = r
    return r


def is_nnf(f: Formula) -> bool:
    """True iff negations apply only to propositions and no ``-> <-> xor`` occurs."""
    if f.kind in (IMPLIES, EQUIV, XOR):
        return False
    if f.kind == NOT:
        return f.args[0].kind == AP
    return all(is_nnf(g) for g in f.args)


# ------------------------------------------------------------------------------------- simplification

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
