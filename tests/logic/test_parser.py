"""LTL parser and printer: Spot syntax, precedence, aliases, errors with carets, macros, round trips."""

import copy
import pickle

import pytest
from hypothesis import given, settings

from mrodrake.errors import UserError
from mrodrake.logic.formula import (
    FALSE,
    TRUE,
    And,
    Ap,
    Equiv,
    F,
    G,
    Implies,
    M,
    Not,
    Or,
    R,
    U,
    W,
    X,
    Xor,
    atoms,
    to_str,
)
from mrodrake.logic.parse import MAX_DEPTH, parse
from mrodrake.logic.translate import translate

from .strategies import formulas

a, b, c, d = Ap("a"), Ap("b"), Ap("c"), Ap("d")


@pytest.mark.parametrize("text, expected", [
    ("a U b U c", U(a, U(b, c))),                  # U is right-associative
    ("a R b W c M d", R(a, W(b, M(c, d)))),
    ("a -> b -> c", Implies(a, Implies(b, c))),    # -> is right-associative
    ("a -> b <-> c", Implies(a, Equiv(b, c))),     # -> and <-> share a level (Spot)
    ("a <-> b -> c", Equiv(a, Implies(b, c))),
    ("a | b & c", Or(a, And(b, c))),               # & binds tighter than |
    ("a & b U c", And(a, U(b, c))),                # U binds tighter than &
    ("a U b & c", And(U(a, b), c)),
    ("!a U b", U(Not(a), b)),                      # unary binds tightest
    ("X a U b", U(X(a), b)),
    ("G a -> F b", Implies(G(a), F(b))),
    ("a | b -> c", Implies(Or(a, b), c)),
    ("a xor b | c", Or(Xor(a, b), c)),             # xor between & and | (Spot)
    ("a xor b & c", Xor(a, And(b, c))),
    ("a xor b xor c", Xor(Xor(a, b), c)),          # xor is left-associative
    ("a U b -> c", Implies(U(a, b), c)),
    ("(a -> b) -> c", Implies(Implies(a, b), c)),
    ("!(a & b)", Not(And(a, b))),
    ("X X a", X(X(a))),
])
def test_precedence_and_associativity(text, expected):
    assert parse(text) is expected


@pytest.mark.parametrize("text, same_as", [
    ("[]<>a", "G F a"),
    ("<>[] a", "F G a"),
    ("~a && b || c", "!a & b | c"),
    ("a /\\ b \\/ c", "a & b | c"),
    ("a => b", "a -> b"),
    ("a --> b", "a -> b"),
    ("a <=> b", "a <-> b"),
    ("a <--> b", "a <-> b"),
    ("a ^ b", "a xor b"),
    ("a V b", "a R b"),
    ("1", "true"),
    ("0 | a", "a"),
    ("GFa", "G F a"),              # Spot's glued unary operators
    ("XFGa_b", "X F G a_b"),
    ("G!a", "G !a"),
    ("Fab", "F ab"),
    ('"Fab" & "x y"', '"x y" & "Fab"'),
    ("F1a", '"F1a"'),                # a digit after the operator letters keeps one name (Spot)
    ("XU", '"XU"'),
    ("r1_p3 & o2_p1", "o2_p1 & r1_p3"),
])
def test_aliases_and_spot_lexing(text, same_as):
    assert parse(text) is parse(same_as)


def test_glued_operators_and_names():
    assert parse("GFa") is G(F(a))
    assert parse("Fab") is F(Ap("ab"))
    assert parse("F1a") is Ap("F1a")
    assert parse("GFx1") is G(F(Ap("x1")))
    assert parse('"a b"') is Ap("a b")
    assert parse("task.psi") is Ap("task.psi")


def test_constant_folding_and_trivial_identities():
    assert parse("a & true") is a
    assert parse("a & false") is FALSE
    assert parse("a | true") is TRUE
    assert parse("!!a") is a
    assert parse("F F a") is F(a)
    assert parse("G G a") is G(a)
    assert parse("X true") is TRUE
    assert parse("true U a") is F(a)
    assert parse("false R a") is G(a)
    assert parse("a W false") is G(a)
    assert parse("a M true") is F(a)
    assert parse("false -> a") is TRUE
    assert parse("a & b & a") is parse("b & a")


def test_formulas_are_interned_immutable_and_picklable():
    f = parse("G (a -> F b)")
    g = parse("G(a->F b)")
    assert f is g and hash(f) == hash(g)
    assert parse("a & b") is parse("b & a")
    with pytest.raises(AttributeError):
        f.kind = "F"
    assert pickle.loads(pickle.dumps(f)) is f
    assert copy.deepcopy(f) is f
    assert {f: 1}[g] == 1


def test_atoms():
    assert atoms(parse("G(r1_p1 -> F o2_p3) & X true")) == frozenset({"r1_p1", "o2_p3"})
    assert atoms(TRUE) == frozenset()


@pytest.mark.parametrize("text, col, what", [
    ("a & ", 5, "end of formula"),
    ("G (a | b", 3, "unclosed '('"),
    ("a $ b", 3, "unexpected character"),
    ("a b", 3, "expected an operator"),
    ("(a))", 4, "unmatched ')'"),
    ("", 1, "empty formula"),
    ("a U", 4, "end of formula"),
    ("a & ()", 6, "empty parentheses"),
    ("2 U a", 1, "only 0 and 1"),
    ('"abc', 1, "unterminated"),
    ("a & | b", 5, "expected a formula"),
])
def test_syntax_errors_report_column_and_caret(text, col, what):
    with pytest.raises(UserError) as ei:
        parse(text, source="task.formula")
    err = ei.value
    msg = str(err)
    assert "\n" not in msg
    assert msg.startswith(f"task.formula:{col}: ")
    assert what in msg
    shown, caret = err.detail.split("\n")
    assert shown == text
    assert caret == " " * (col - 1) + "^"


def test_macros_expand_recursively():
    macros = {"psi1": "r1_p1 & o1_p2", "psi2": "F psi1 | r2_p3"}
    f = parse("G F psi2 & !psi1", macros)
    p1 = And(Ap("r1_p1"), Ap("o1_p2"))
    assert f is And(G(F(Or(F(p1), Ap("r2_p3")))), Not(p1))
    assert "psi1" not in atoms(f)


def test_macro_syntax_error_names_the_macro():
    macros = {"psi1": "r1_p1 & ", "psi2": "psi1 | a"}
    with pytest.raises(UserError) as ei:
        parse("G psi2", macros, source="task.formula", macro_prefix="task.propositions.")
    assert str(ei.value).startswith("task.propositions.psi1:9: ")
    assert ei.value.detail.split("\n") == ["r1_p1 & ", " " * 8 + "^"]
    with pytest.raises(UserError) as ei:
        parse("psi1", {"psi1": "a &"})
    assert str(ei.value).startswith("psi1:4: ")


def test_cyclic_macros_are_an_error_naming_the_cycle():
    with pytest.raises(UserError) as ei:
        parse("G psi1", {"psi1": "F psi2", "psi2": "a & psi3", "psi3": "psi1 | b"})
    assert "psi1 -> psi2 -> psi3 -> psi1" in str(ei.value)
    with pytest.raises(UserError, match="psi -> psi"):
        parse("psi", {"psi": "X psi"})


def test_unused_macros_are_not_parsed():
    assert parse("a", {"junk": "a &&& b"}) is a


def test_printer_uses_minimal_readable_parentheses():
    assert str(parse("a U (b U c)")) == "a U (b U c)"
    assert str(parse("(a U b) & c")) == "c & (a U b)"
    assert str(parse("G F a")) == "G F a"
    assert str(parse("G(a | b)")) == "G(a | b)"
    assert str(parse("!(a & b)")) == "!(a & b)"
    assert str(parse("(a -> b) -> c")) == "(a -> b) -> c"
    assert str(parse('F ab | "x y"')) == '"x y" | F ab'


@settings(max_examples=300, deadline=None)
@given(formulas())
def test_printer_round_trips(f):
    text = to_str(f)
    assert text == str(f)
    assert parse(text) is f


def test_deep_parentheses_parse_without_recursion():
    """Parentheses add no depth to the syntax tree; the parser uses explicit stacks, so 3,000 of them parse."""
    assert parse("(" * 3000 + "a" + ")" * 3000) is a
    assert parse("(" * 3000 + "a U b" + ")" * 3000 + " & c") is And(U(a, b), c)
    with pytest.raises(UserError, match=r"formula:3000: unclosed '\('"):  # the innermost one
        parse("(" * 3000 + "a")


def test_trees_up_to_the_depth_limit_translate_and_deeper_ones_are_rejected_at_their_operator():
    f = parse("X " * (MAX_DEPTH - 1) + "a")
    assert f.depth == MAX_DEPTH
    assert translate(f).num_states == MAX_DEPTH + 1  # X^199 a: a chain of 200 states plus the sink
    with pytest.raises(UserError) as ei:
        parse("X " * MAX_DEPTH + "a")
    assert str(ei.value) == (f"formula:1: formula nested deeper than {MAX_DEPTH} operators "
                             "(the limit of the LTL translation)")
    assert ei.value.detail.splitlines()[1] == "^"  # the outermost X, at column 1


def test_deep_macro_chains_are_rejected_with_the_macro_named():
    macros = {f"m{i}": f"m{i + 1}" for i in range(MAX_DEPTH + 5)}
    macros[f"m{MAX_DEPTH + 5}"] = "a"
    with pytest.raises(UserError, match=r"^task\.propositions\.m\d+: macros nested deeper than"):
        parse("m0", macros, macro_prefix="task.propositions.")
