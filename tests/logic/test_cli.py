"""``mrodrake ltl2nba``: HOA per formula, formula files, translator choice, errors with exit status 2."""

import argparse
import io

import pytest

from mrodrake.cli import main
from mrodrake.errors import UserError
from mrodrake.logic import cli as logic_cli
from mrodrake.logic.hoa import read_hoa
from mrodrake.logic.translate import translate


def _parser():
    parser = argparse.ArgumentParser(prog="mrodrake")
    logic_cli.add_subparser(parser.add_subparsers(dest="command"))
    return parser


def _run(argv):
    args = _parser().parse_args(argv)
    out = io.StringIO()
    code = args.func(args, out=out)
    return code, out.getvalue()


def _split_hoa(text):
    return [block + "--END--\n" for block in text.split("--END--\n") if block.strip()]


def test_prints_one_hoa_automaton_per_formula_in_order():
    code, out = _run(["ltl2nba", "G F a", "a U b", "false"])
    assert code == 0
    blocks = _split_hoa(out)
    assert len(blocks) == 3
    assert [b.splitlines()[1] for b in blocks] == ['name: "G F a"', 'name: "a U b"', 'name: "false"']
    for block, text in zip(blocks, ["G F a", "a U b", "false"]):
        assert "Acceptance: 1 Inf(0)" in block and "acc-name: Buchi" in block and "state-acc" in block
        assert read_hoa(block) == translate(text)


def test_formula_file(tmp_path):
    path = tmp_path / "formulas.txt"
    path.write_text("# comment\nG(a -> F b)\n\n  F G c  \n", encoding="utf-8")
    code, out = _run(["ltl2nba", "X a", "-f", str(path)])
    assert code == 0
    names = [b.splitlines()[1] for b in _split_hoa(out)]
    assert names == ['name: "X a"', 'name: "G(a -> F b)"', 'name: "F G c"']


def test_syntax_error_in_file_names_file_line_and_column(tmp_path):
    path = tmp_path / "bad.ltl"
    path.write_text("G a\nF (b | c\n", encoding="utf-8")
    with pytest.raises(UserError) as ei:
        _run(["ltl2nba", "-f", str(path)])
    assert str(ei.value) == f"{path}:2:3: unclosed '('"
    assert ei.value.detail.splitlines()[1] == "  ^"


def test_errors_without_formulas_and_missing_file(tmp_path):
    with pytest.raises(UserError, match="no formula"):
        _run(["ltl2nba"])
    with pytest.raises(UserError, match="cannot read"):
        _run(["ltl2nba", "-f", str(tmp_path / "missing.txt")])


def test_help_lists_the_options(capsys):
    with pytest.raises(SystemExit) as ei:
        _parser().parse_args(["ltl2nba", "--help"])
    assert ei.value.code == 0
    text = capsys.readouterr().out
    assert "--translator {builtin,spot}" in text and "-f FILE" in text and "FORMULA" in text


def test_top_level_cli_exit_status(capsys):
    assert main(["ltl2nba", "G (a"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: formula 1:") and "^" in err
    assert main(["ltl2nba", "a U b"]) == 0
    assert "HOA: v1" in capsys.readouterr().out


def test_spot_translator_option():
    pytest.importorskip("spot")
    code, out = _run(["ltl2nba", "--translator", "spot", "G F a"])
    assert code == 0 and "HOA: v1" in out


def test_deeply_nested_formulas_exit_cleanly(capsys):
    assert main(["ltl2nba", "(" * 3000 + "a" + ")" * 3000]) == 0
    assert "HOA: v1" in capsys.readouterr().out
    assert main(["ltl2nba", "X " * 3000 + "a"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: formula 1:5601: formula nested deeper than 200") and "Traceback" not in err
