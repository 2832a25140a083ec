"""Optional Spot backend: ``spot.translate(f, "BA", "sbacc")`` read back through HOA into our NBA class.

Spot (PyPI ``spottl``) is GPL-licensed and never required: it is imported lazily, and a clear UserError
explains how to install it when it is missing.
"""

from __future__ import annotations

from mrodrake.errors import UserError
from mrodrake.logic.formula import Formula, atoms, to_str
from mrodrake.logic.hoa import read_hoa
from mrodrake.logic.nba import NBA
from mrodrake.logic.parse import parse

__all__ = ["spot_available", "import_spot", "translate_spot"]


def import_spot():
    """The ``spot`` module, or a UserError if it is not installed."""
    try:
        import spot
    except ImportError as exc:
        raise UserError("translator 'spot' needs the optional Spot package: "
                        "pip install 'mrodrake[spot]' (or: pip install spottl)") from exc
    return spot


def spot_available() -> bool:
    """True iff ``import spot`` works."""
    try:
        import_spot()
    except UserError:
        return False
    return True


def translate_spot(f: Formula | str) -> NBA:
    """Spot's state-based Büchi automaton for ``f`` as an :class:`NBA` over the sorted propositions of
    ``f`` (the same ``ap`` order as the built-in translator)."""
    spot = import_spot()
    if isinstance(f, str):
        f = parse(f)
    aut = spot.translate(spot.formula(to_str(f)), "BA", "sbacc")
    nba = read_hoa(aut.to_str("hoa"), source="spot")
    return nba.with_ap(tuple(sorted(atoms(f))))
