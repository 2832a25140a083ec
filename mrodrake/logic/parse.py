"""Spot-syntax LTL text to :class:`~mrodrake.logic.formula.Formula` values: tokenizer, parser, macros.

The concrete syntax is Spot's:

* constants ``true``/``1``, ``false``/``0``; atomic propositions are identifiers
  (``[A-Za-z_][A-Za-z0-9_.]*``) or double-quoted strings;
* unary ``!`` (``~``), ``X``, ``F`` (``<>``), ``G`` (``[]``); like Spot, ``GFa`` is ``G F a``;
* binary, from loosest to tightest: ``->`` ``<->`` (same level, right-associative; aliases ``=>``,
  ``<=>``), ``|`` (``||``, ``\\/``), ``xor`` (``^``), ``&`` (``&&``, ``/\\``), ``U R W M``
  (right-associative; ``V`` is an alias of ``R``).
"""

from __future__ import annotations

import re
from collections.abc import Callable

from mrodrake.errors import UserError
from mrodrake.logic.formula import (
    ALWAYS,
    AND,
    EQUIV,
    EVENTUALLY,
    FALSE,
    IDENT,
    IMPLIES,
    NEXT,
    NOT,
    OR,
    RELEASE,
    STRONG_RELEASE,
    TRUE,
    UNTIL,
    WEAK_UNTIL,
    XOR,
    Ap,
    Formula,
    rebuild,
    split_unary_prefix,
)

__all__ = ["parse", "MAX_DEPTH"]


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
        m = IDENT.match(text, i)
        if m:
            word = m.group(0)
            i = m.end()
            if word in ("true", "false"):
                toks.append(("const", word == "true", col))
            elif word in _WORD_OPS:
                toks.append(("op", _WORD_OPS[word], col))
            else:
                split = split_unary_prefix(word)
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
                out.append(self.build(tok, rebuild(tok[1], (out.pop(),))))
            else:
                rhs = out.pop()
                out.append(self.build(tok, rebuild(tok[1], (out.pop(), rhs))))

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
          macro_prefix: str = "", macro_source: Callable[[str], str] | None = None) -> Formula:
    """Parse Spot-syntax LTL ``text``; identifiers naming a macro expand to the macro's parsed body.

    Syntax errors raise ``UserError("{source}:{col}: ...")`` (1-based column) whose detail is the text and a
    caret line.  An error inside macro ``m`` is reported with source ``macro_source(m)`` if given (e.g. the
    macro's file and line), else ``f"{macro_prefix}{m}"`` (e.g. ``macro_prefix="task.propositions."``); cyclic
    macro definitions raise a UserError naming the cycle.
    """
    if not isinstance(text, str):
        raise UserError(f"{source}: formula must be a string, got {type(text).__name__}")
    macros = macros or {}
    where = macro_source or (lambda name: f"{macro_prefix}{name}")
    cache: dict[str, Formula] = {}
    stack: list[str] = []

    def expand(name: str) -> Formula:
        if name in cache:
            return cache[name]
        if name in stack:
            cycle = stack[stack.index(name):] + [name]
            raise UserError(f"{where(cycle[0])}: cyclic macro definition: {' -> '.join(cycle)}")
        body = macros[name]
        if not isinstance(body, str):
            raise UserError(f"{where(name)}: macro body must be a string, got {type(body).__name__}")
        if len(stack) >= MAX_DEPTH:
            raise UserError(f"{where(name)}: macros nested deeper than {MAX_DEPTH} levels")
        stack.append(name)
        f = _Parser(body, where(name), resolve).parse()
        stack.pop()
        cache[name] = f
        return f

    def resolve(name: str, col: int) -> Formula | None:
        return expand(name) if name in macros else None

    return _Parser(text, source, resolve).parse()
