"""Negation normal form and simplification rewrites preserve semantics and reach the expected forms."""

import pytest
from hypothesis import given, settings

from mrodrake.logic.lasso import evaluate_lasso
from mrodrake.logic.nnf import is_nnf, nnf
from mrodrake.logic.parse import parse
from mrodrake.logic.simplify import simplify

from .strategies import formulas, lassos


@pytest.mark.parametrize("text, expected", [
    ("F F a", "F a"),
    ("G F G a", "F G a"),
    ("F G F a", "G F a"),
    ("!X a", "X !a"),
    ("!(a U b)", "!a R !b"),
    ("!(a W b)", "!a M !b"),
    ("!F a", "G !a"),
    ("X G F a", "G F a"),
    ("F(a U b)", "F b"),
    ("G(a R b)", "G b"),
    ("F(a M b)", "F(a & b)"),
    ("G(a W b)", "G(a | b)"),
    ("a U F b", "F b"),
    ("a R G b", "G b"),
    ("F(a & G F b)", "F a & G F b"),
    ("G(a | F G b)", "G a | F G b"),
    ("a & !a", "false"),
    ("a | !a | b", "true"),
    ("G a & G b", "G(a & b)"),
    ("F a | F b", "F(a | b)"),
    ("X a & X b", "X(a & b)"),
    ("(a U c) & (b U c)", "(a & b) U c"),
    ("(a R b) & (a R c)", "a R (b & c)"),
    ("G F a | G F b", "G F(a | b)"),
    ("F G a & F G b", "F G(a & b)"),
    ("a U (b | G a)", "a W b"),
    ("a R (b & F a)", "a M b"),
    ("G a | (a U b)", "a W b"),
    ("G !a | F(a & F b)", "!a W (a & F b)"),
    ("a -> b", "!a | b"),
])
def test_rewrites(text, expected):
    assert simplify(parse(text)) is parse(expected)


def test_simplify_accepts_text_and_is_idempotent():
    f = simplify("G(a -> F b) & G F G c")
    assert simplify(f) is f
    assert is_nnf(f)


@settings(max_examples=200, deadline=None)
@given(formulas(), lassos())
def test_nnf_and_simplify_preserve_semantics(f, word):
    prefix, cycle = word
    expected = evaluate_lasso(f, prefix, cycle)
    n = nnf(f)
    s = simplify(f)
    assert is_nnf(n) and is_nnf(s)
    assert evaluate_lasso(n, prefix, cycle) == expected
    assert evaluate_lasso(s, prefix, cycle) == expected
    assert evaluate_lasso(nnf(f, negate=True), prefix, cycle) != expected


@settings(max_examples=200, deadline=None)
@given(formulas())
def test_simplify_does_not_grow_much(f):
    # NNF expands <-> and xor, so compare with the NNF size; the rewrites themselves never grow a formula
    # by more than one node per rule application (e.g. F(a & s) -> F a & s).
    assert simplify(f).size <= 2 * nnf(f).size
