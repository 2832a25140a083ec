"""HOA v1 reader: one Büchi automaton in the Hanoi Omega-Automata format (Babiak et al., "The Hanoi
Omega-Automata Format", CAV 2015; specification at https://adl.github.io/hoaf/) as an :class:`NBA`.
The writer is :meth:`mrodrake.logic.nba.NBA.to_hoa`."""

from __future__ import annotations

import re

from mrodrake.errors import UserError
from mrodrake.logic.bdd import BDD, Cube
from mrodrake.logic.nba import NBA, empty_nba

__all__ = ["read_hoa"]

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


def read_hoa(text: str, source: str = "HOA") -> NBA:
    """Read one HOA v1 Büchi automaton (``Inf(0)``, or ``t``/``f``), with state- or transition-based
    acceptance, explicit, implicit or state labels and aliases.  Transition-based acceptance becomes
    state-based by splitting each state into a copy entered by accepting edges and one entered by
    the others; several start states get a fresh initial state.  ``source`` prefixes error messages."""
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

    bdd = BDD()

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
        return empty_nba(ap_t)
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

    def __init__(self, items: list, aliases: dict[str, list], nap: int, err, bdd: BDD, depth: int = 0):
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
