"""LTL and Büchi automata: the formula values, the parser, NNF and simplification, the translation to NBAs.

Formulas, the parser and the rewrites are importable from here (``from mrodrake.logic import parse, simplify``);
:func:`mrodrake.logic.translate.translate` turns a formula into an NBA.
"""

from mrodrake.logic.formula import (
    FALSE,
    TRUE,
    And,
    Ap,
    Equiv,
    F,
    Formula,
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
from mrodrake.logic.nnf import is_nnf, nnf
from mrodrake.logic.parse import parse
from mrodrake.logic.simplify import simplify

__all__ = [
    "Formula", "TRUE", "FALSE", "Ap", "Not", "And", "Or", "Implies", "Equiv", "Xor",
    "X", "F", "G", "U", "R", "W", "M", "atoms", "to_str", "parse", "nnf", "is_nnf", "simplify",
]
