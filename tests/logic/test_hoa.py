"""HOA v1 output and input (state- and transition-based Büchi, label forms, errors)."""

import numpy as np
import pytest
from hypothesis import given, settings

from mrodrake.errors import UserError
from mrodrake.logic.hoa import read_hoa
from mrodrake.logic.lasso import evaluate_lasso
from mrodrake.logic.parse import parse
from mrodrake.logic.translate import translate

from .strategies import formulas_3_or_4_props


def _words(props, count=200, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        pre = [frozenset(p for p in props if rng.random() < 0.5) for _ in range(rng.integers(0, 4))]
        cyc = [frozenset(p for p in props if rng.random() < 0.5) for _ in range(rng.integers(1, 4))]
        out.append((pre, cyc))
    return out


def test_hoa_output_format():
    text = translate("a U b").to_hoa(name='a U b "quoted"')
    lines = text.splitlines()
    assert lines[:9] == [
        "HOA: v1",
        'name: "a U b \\"quoted\\""',
        "States: 2",
        "Start: 0",
        'AP: 2 "a" "b"',
        "acc-name: Buchi",
        "Acceptance: 1 Inf(0)",
        "properties: trans-labels explicit-labels state-acc",
        "--BODY--",
    ]
    assert lines[-1] == "--END--"
    assert "State: 1 {0}" in lines and "[0&!1] 0" in lines and "[1] 1" in lines and "[t] 1" in lines


@settings(max_examples=60, deadline=None)
@given(formulas_3_or_4_props(max_depth=4))
def test_hoa_round_trip(f):
    nba = translate(f)
    assert read_hoa(nba.to_hoa(name=str(f))) == nba


def test_transition_based_buchi_is_converted_to_state_based():
    # G F a with the acceptance mark on the a-edge (transition-based).
    hoa = """HOA: v1
States: 1
Start: 0
AP: 1 "a"
acc-name: Buchi
Acceptance: 1 Inf(0)
properties: trans-labels explicit-labels trans-acc
--BODY--
State: 0
[0] 0 {0}
[!0] 0
--END--
"""
    nba = read_hoa(hoa)
    assert nba.ap == ("a",) and nba.num_states == 2 and len(nba.accepting) == 1
    f = parse("G F a")
    for prefix, cycle in _words(("a",)):
        assert nba.accepts_lasso(prefix, cycle) == evaluate_lasso(f, prefix, cycle)


def test_hoa_explicit_labels_aliases_and_state_labels():
    # F G (a & !b) written two ways; comments and aliases are allowed.
    explicit = """HOA: v1 /* comment */
States: 2 Start: 0 AP: 2 "a" "b"
Alias: @ok 0 & !1
Acceptance: 1 Inf(0)
--BODY--
State: 0 "wait"
[t] 0
[@ok] 1
State: 1 {0}
[!(!0 | 1)] 1
--END--"""
    state_labels = """HOA: v1
States: 3
Start: 0
AP: 2 "a" "b"
Acceptance: 1 Inf(0)
--BODY--
State: [t] 0
0 2
State: [0&!1] 2
1
State: [0&!1] 1 {0}
1
--END--"""
    f = parse("F G (a & !b)")
    nba = read_hoa(explicit)
    for prefix, cycle in _words(("a", "b")):
        assert nba.accepts_lasso(prefix, cycle) == evaluate_lasso(f, prefix, cycle)
    with_state_labels = read_hoa(state_labels)
    for prefix, cycle in _words(("a", "b"), seed=1):
        assert with_state_labels.accepts_lasso(prefix, cycle) == evaluate_lasso(f, prefix, cycle)


def test_hoa_implicit_labels():
    hoa = """HOA: v1
States: 2
Start: 0
AP: 2 "a" "b"
Acceptance: 1 Inf(0)
--BODY--
State: 0
0 1 0 0
State: 1 {0}
1 1 1 1
--END--"""
    nba = read_hoa(hoa)  # letter 1 (a & !b) leads to the accepting sink: F(a & !b)
    f = parse("F(a & !b)")
    for prefix, cycle in _words(("a", "b"), seed=2):
        assert nba.accepts_lasso(prefix, cycle) == evaluate_lasso(f, prefix, cycle)


def test_several_start_states_and_all_accepting():
    hoa = """HOA: v1
States: 2
Start: 0
Start: 1
AP: 1 "a"
Acceptance: 0 t
--BODY--
State: 0
[0] 0
State: 1
[!0] 1
--END--"""
    nba = read_hoa(hoa)  # G a | G !a
    f = parse("G a | G !a")
    for prefix, cycle in _words(("a",), seed=3):
        assert nba.accepts_lasso(prefix, cycle) == evaluate_lasso(f, prefix, cycle)


@pytest.mark.parametrize("text, what", [
    ("garbage", "HOA v1"),
    ("HOA: v1\nStates: 1\nStart: 0\nAP: 0\nAcceptance: 1 Fin(0)\n--BODY--\nState: 0\n[t] 0\n--END--",
     "only Büchi"),
    ("HOA: v1\nStates: 1\nStart: 0&1\nAP: 0\nAcceptance: 1 Inf(0)\n--BODY--\n--END--", "alternating"),
    ("HOA: v1\nStates: 1\nStart: 0\nAP: 1 \"a\"\nAcceptance: 1 Inf(0)\n--BODY--\nState: 0\n[1] 0\n--END--",
     "out of range"),
    ("HOA: v1\nStates: 1\nStart: 0\nAP: 0\nAcceptance: 1 Inf(0)\n--BODY--\nState: 0\n[t] 3\n--END--",
     "out of range"),
    ("HOA: v1\nStates: 1\nStart: 0\nAP: 0\nAcceptance: 1 Inf(0)\n--BODY--\nState: 0\n[t] 0\n", "--END--"),
    ("HOA: v1\nStates: 1\nStart: 0\nAP: 2 \"a\"\nAcceptance: 1 Inf(0)\n--BODY--\n--END--", "declares 2"),
    ("HOA: v1\nStates: 1\nStart: 0\nAP: 1 \"a\"\nAcceptance: 1 Inf(0)\n--BODY--\nState: 0\n0\n[0] 0\n--END--",
     "mixes labelled"),
    ("HOA: v1\nStates: 1\nStart: 0\nAP: 1 \"a\"\nAcceptance: 1 Inf(0)\n--BODY--\nState: 0\n0 0 0\n--END--",
     "expected 2"),
    ("HOA: v1\nStates: 2\nStart: 0\nAP: 0\nAcceptance: 1 Inf(0)\n--BODY--\nState: 0\n[t] 0\nState: 0\n--END--",
     "defined twice"),
])
def test_hoa_errors_are_user_errors_with_a_line(text, what):
    with pytest.raises(UserError) as ei:
        read_hoa(text, source="aut.hoa")
    assert str(ei.value).startswith("aut.hoa:")
    assert what in str(ei.value)
