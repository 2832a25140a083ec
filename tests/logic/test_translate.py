"""LTL -> NBA translation: language agreement with the lasso evaluator, the Dwyer patterns, the paper's
case-study formulas, symbolic guards and the NBA API."""

import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrodrake.errors import UserError
from mrodrake.logic.data import load_case_study_formulas, load_dwyer_patterns
from mrodrake.logic.formula import atoms
from mrodrake.logic.lasso import evaluate_lasso
from mrodrake.logic.nba import NBA, TRUE_GUARD, guard_implies, simplify_guard
from mrodrake.logic.parse import parse
from mrodrake.logic.translate import translate

from .strategies import formulas_3_or_4_props, lassos


def _random_lassos(rng: np.random.Generator, props, count: int, max_len: int = 4):
    """Random lasso words with letters as sets of true propositions."""
    out = []
    for _ in range(count):
        pre = [frozenset(p for p in props if rng.random() < 0.5) for _ in range(rng.integers(0, max_len + 1))]
        cyc = [frozenset(p for p in props if rng.random() < 0.5) for _ in range(rng.integers(1, max_len + 1))]
        out.append((pre, cyc))
    return out


def _check_agreement(f, words):
    nba = translate(f)
    for prefix, cycle in words:
        assert nba.accepts_lasso(prefix, cycle) == evaluate_lasso(f, prefix, cycle), (str(f), prefix, cycle)


@settings(max_examples=150, deadline=None)
@given(formulas_3_or_4_props(), st.lists(lassos(), min_size=1, max_size=12))
def test_nba_accepts_iff_formula_holds(f, words):
    _check_agreement(f, words)


@pytest.mark.slow
@settings(max_examples=3000, deadline=None)
@given(formulas_3_or_4_props(), st.lists(lassos(max_prefix=6, max_cycle=6), min_size=1, max_size=20))
def test_nba_accepts_iff_formula_holds_many(f, words):
    _check_agreement(f, words)


def test_dwyer_patterns_agree_with_the_evaluator():
    patterns = load_dwyer_patterns()
    assert len(patterns) == 55
    rng = np.random.default_rng(3)
    total = 0
    for text in patterns:
        f = parse(text)
        props = sorted(atoms(f))
        _check_agreement(f, _random_lassos(rng, props, 40))
        total += translate(f).num_states
    # Spot 2.13 (translate(f, "BA", "sbacc")) needs 214 states in total; the bound is 1.5x that.
    assert total <= 1.5 * 214


PSI_I = {1: "r1_p1 r2_p1 r3_p1 o1_p1 o2_p4", 2: "r1_p1 r2_p3 r3_p1 o1_p1 o2_p3",
         3: "r1_p3 r2_p3 r3_p3 o1_p4 o2_p3", 4: "r1_p2 r2_p4 r3_p1 o1_p4 o2_p2",
         5: "r1_p4 r2_p4 r3_p2 o1_p3 o2_p4"}


def _letter(*indices):
    return frozenset(x for i in indices for x in PSI_I[i].split())


def test_case_study_I_translates_small_and_correct():
    f = parse(load_case_study_formulas()[0])
    nba = translate(f)
    assert len(atoms(f)) == 16
    assert nba.num_states <= 6 and nba.num_edges <= 18  # the paper's NBA has 6 states and 18 transitions
    good = ([_letter(5), _letter(4)], [_letter(1), _letter(2), _letter(3)])
    assert nba.accepts_lasso(*good) and evaluate_lasso(f, *good)
    for prefix, cycle in [([_letter(4), _letter(5)], [_letter(1), _letter(2), _letter(3)]),  # psi4 before psi5
                          ([_letter(5)], [_letter(1), _letter(2), _letter(3)]),             # psi4 never
                          ([_letter(5), _letter(4)], [_letter(1), _letter(2)])]:            # psi3 not infinitely often
        assert not nba.accepts_lasso(prefix, cycle)
        assert not evaluate_lasso(f, prefix, cycle)
    rng = np.random.default_rng(11)
    letters = [_letter(i) for i in range(1, 6)] + [frozenset()]
    words = [([letters[j] for j in rng.integers(0, 6, rng.integers(0, 4))],
              [letters[j] for j in rng.integers(0, 6, rng.integers(1, 5))]) for _ in range(200)]
    _check_agreement(f, words)


def test_case_study_II_translates_small():
    f = parse(load_case_study_formulas()[1])
    nba = translate(f)
    assert len(atoms(f)) == 22
    assert nba.num_states <= 8 and nba.num_edges <= 27  # the paper's NBA has 8 states and 27 transitions
    assert len(nba.accepting) == 1


def test_guards_stay_symbolic_with_many_propositions():
    # 40 propositions: enumerating the 2^40 letters would never finish.
    props = [f"r{i}_p{j}" for i in range(1, 9) for j in range(1, 6)]
    conj = " & ".join(props[:20])
    text = f"G F ({conj}) & G !({' & '.join(props[20:])}) & F (r1_p1 | r2_p2)"
    nba = translate(text)
    assert len(nba.ap) == 40
    everything = 0
    for p in props[:20]:
        everything |= 1 << nba.ap.index(p)
    # the word (all of psi)^omega is accepted, the empty word is not
    assert nba.accepts_lasso([], [everything])
    assert not nba.accepts_lasso([], [0])


def test_empty_and_universal_languages():
    for text in ("false", "a & !a", "G a & F !a", "F G a & G F !a"):
        nba = translate(text)
        assert nba.is_empty() and nba.num_states == 1 and nba.num_edges == 0
    nba = translate("true")
    assert nba.num_states == 1 and nba.accepting == frozenset({0}) and nba.edges[0] == ((TRUE_GUARD, 0),)
    assert translate("G a | !a | F !a").num_states == 1  # valid formula


def test_translation_is_deterministic():
    text = "G(a -> F(b & X c)) & (d U a)"
    n1 = translate(text)
    n2 = translate(parse(text))
    assert n1 == n2 and n1.to_hoa() == n2.to_hoa()


def test_nba_api_successors_guards_and_ap_order():
    nba = translate("a U b")
    assert nba.ap == ("a", "b") and nba.initial == 0
    qa = nba.successors(0, 0b01)           # a & !b: stay
    assert qa == [0]
    q_acc = nba.successors(0, 0b10)        # b: go to the accepting sink
    assert len(q_acc) == 1 and q_acc[0] in nba.accepting
    assert nba.successors(0, 0b00) == []
    assert nba.successors(0, 0b100 | 0b01) == [0]  # bits beyond ap are ignored
    assert NBA.guard_holds(((0b01, 0b10),), 0b01) and not NBA.guard_holds(((0b01, 0b10),), 0b11)
    assert nba.num_edges == sum(len(row) for row in nba.edges)
    assert nba.accepts_lasso([{"a"}, 1], [{"b", "zzz"}])  # names and masks may be mixed; unknown names ignored


def test_with_ap_reindexes_onto_a_larger_order():
    nba = translate("G(a -> F b)")
    ts_ap = ("z", "b", "y", "a")
    wide = nba.with_ap(ts_ap)
    assert wide.ap == ts_ap and wide.num_states == nba.num_states and wide.num_edges == nba.num_edges
    rng = np.random.default_rng(5)
    for prefix, cycle in _random_lassos(rng, ts_ap, 100):
        assert wide.accepts_lasso(prefix, cycle) == nba.accepts_lasso(prefix, cycle)
    with pytest.raises(UserError, match="proposition 'a'"):
        nba.with_ap(("b", "c"))
    narrow = nba.with_ap(("b",), missing="false")  # a is always false: G(a -> F b) is valid
    assert narrow.accepts_lasso([], [frozenset()])


def test_guard_helpers():
    a, b = 0b01, 0b10
    assert simplify_guard([(a, 0), (0, a)]) == TRUE_GUARD
    assert simplify_guard([(a | b, 0), (a, b)]) == ((a, 0),)
    assert simplify_guard([(a, a)]) == ()
    assert guard_implies([(a | b, 0)], [(a, 0)]) and not guard_implies([(a, 0)], [(a | b, 0)])
    assert guard_implies([(a, 0)], [(a | b, 0), (a, b)])


def test_unknown_backend_and_missing_spot(monkeypatch):
    with pytest.raises(UserError, match="unknown backend"):
        translate("a", backend="ltl3ba")
    monkeypatch.setitem(sys.modules, "spot", None)  # makes `import spot` fail
    with pytest.raises(UserError, match="pip install"):
        translate("a", backend="spot")
