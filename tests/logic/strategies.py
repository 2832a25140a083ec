"""Hypothesis strategies shared by the temporal-logic tests: random LTL formulas and lasso words."""

from hypothesis import strategies as st

from mrodrake.logic.formula import FALSE, TRUE, And, Ap, Equiv, F, G, Implies, M, Not, Or, R, U, W, X, Xor

UNARY = (Not, X, F, G)
BINARY = (And, Or, Implies, Equiv, Xor, U, R, W, M)
PROPS = ("a", "b", "c", "d")


def formulas(props=PROPS, max_depth: int = 5):
    """Formulas of depth <= ``max_depth`` using every operator, over ``props`` (plus the constants)."""
    leaves = st.one_of(st.sampled_from([Ap(p) for p in props]), st.sampled_from([TRUE, FALSE]))

    def level(depth):
        if depth == 0:
            return leaves
        sub = level(depth - 1)
        return st.one_of(
            leaves,
            st.builds(lambda op, x: op(x), st.sampled_from(UNARY), sub),
            st.builds(lambda op, x, y: op(x, y), st.sampled_from(BINARY), sub, sub),
        )

    return level(max_depth)


def formulas_3_or_4_props(max_depth: int = 5):
    """Formulas over 3 or 4 propositions (drawn per example)."""
    return st.sampled_from([PROPS[:3], PROPS]).flatmap(lambda ps: formulas(ps, max_depth))


def lassos(props=PROPS, max_prefix: int = 4, max_cycle: int = 4):
    """Lasso words ``(prefix, cycle)`` with letters as frozensets of true propositions."""
    letters = st.frozensets(st.sampled_from(props))
    return st.tuples(st.lists(letters, max_size=max_prefix), st.lists(letters, min_size=1, max_size=max_cycle))
