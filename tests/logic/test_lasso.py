"""The direct LTL evaluator on lasso words u v^omega (the oracle for the translator tests)."""

import pytest
from hypothesis import given, settings

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
    TT,
    UNTIL,
    WEAK_UNTIL,
    XOR,
)
from mrodrake.logic.lasso import evaluate_lasso, holds_at

from .strategies import formulas, lassos

A, B, E = frozenset("a"), frozenset("b"), frozenset()
AB = frozenset("ab")


@pytest.mark.parametrize("text, prefix, cycle, expected", [
    ("G F a", [], [A, E], True),
    ("F G a", [], [A, E], False),
    ("F G a", [E, E], [A], True),
    ("a U b", [A, A], [B], True),
    ("a U b", [A, E], [B], False),
    ("a U b", [], [A], False),           # b never holds
    ("a W b", [], [A], True),            # ... but the weak until holds
    ("b R a", [], [A], True),
    ("b R a", [A, E], [AB], False),
    ("b M a", [A], [AB], True),
    ("b M a", [], [A], False),
    ("X a", [E], [A], True),
    ("X a", [], [E, A], True),
    ("X X X a", [], [A, E], False),      # position 3 is the cycle's second letter again
    ("X X X a", [E], [A, E], True),
    ("G(a -> X b)", [], [A, B], True),
    ("G(a -> X b)", [], [A, A], False),
    ("a xor b", [], [A], True),
    ("a <-> b", [], [AB], True),
    ("!a | b", [], [A], False),
    ("true", [], [E], True),
    ("false", [], [AB], False),
])
def test_hand_computed_examples(text, prefix, cycle, expected):
    assert evaluate_lasso(text, prefix, cycle) is expected


def test_truth_at_every_position_and_integer_letters():
    # u = {} {a}, v = ({b} {})^omega; positions 0..3, position 3 loops back to 2.
    assert holds_at("F b", [E, A], [B, E]) == [True, True, True, True]
    assert holds_at("X a", [E, A], [B, E]) == [True, False, False, False]
    assert holds_at("b", [0, 1], [2, 0], ap=("a", "b")) == [False, False, True, False]
    with pytest.raises(ValueError):
        holds_at("a", [1], [1])


def test_empty_cycle_is_a_user_error():
    with pytest.raises(UserError):
        evaluate_lasso("a", [A], [])


def _naive(f, letters, loop, i, depth=0):
    """Textbook semantics on the infinite word, by the definitions (positions repeat after n steps)."""
    n = len(letters)

    def pos(k):
        return k if k < n else loop + (k - loop) % (n - loop)

    def sat(g, k):
        return _naive(g, letters, loop, pos(k), depth + 1)

    kind, args = f.kind, f.args
    horizon = range(i, i + 2 * n + 1)
    if kind == TT:
        return True
    if kind == FF:
        return False
    if kind == AP:
        return f.name in letters[i]
    if kind == NOT:
        return not sat(args[0], i)
    if kind == AND:
        return all(sat(g, i) for g in args)
    if kind == OR:
        return any(sat(g, i) for g in args)
    if kind == IMPLIES:
        return (not sat(args[0], i)) or sat(args[1], i)
    if kind == EQUIV:
        return sat(args[0], i) == sat(args[1], i)
    if kind == XOR:
        return sat(args[0], i) != sat(args[1], i)
    if kind == NEXT:
        return sat(args[0], i + 1)
    if kind == EVENTUALLY:
        return any(sat(args[0], k) for k in horizon)
    if kind == ALWAYS:
        return all(sat(args[0], k) for k in horizon)
    x, y = args
    if kind in (UNTIL, WEAK_UNTIL):
        for k in horizon:
            if sat(y, k):
                return True
            if not sat(x, k):
                return False
        return kind == WEAK_UNTIL  # x held over a whole period: forever
    # a R b: b holds up to and including the first a (forever if no a); a M b additionally needs that a
    for k in horizon:
        if not sat(y, k):
            return False
        if sat(x, k):
            return True
    return kind == RELEASE


@settings(max_examples=300, deadline=None)
@given(formulas(max_depth=4), lassos())
def test_evaluator_agrees_with_textbook_semantics(f, word):
    prefix, cycle = word
    letters = list(prefix) + list(cycle)
    assert evaluate_lasso(f, prefix, cycle) == _naive(f, letters, len(prefix), 0)
