"""LTL -> state-based Büchi automaton, after Gastin & Oddoux, "Fast LTL to Büchi automata translation",
CAV 2001, LNCS 2102, pp. 53-65, plus the usual reductions:

1. formula simplification (:func:`mrodrake.logic.simplify`);
2. very weak alternating automaton (:mod:`.vwaa`, Gastin & Oddoux Sec. 3);
3. generalized Büchi automaton (:mod:`.gba`, Sec. 4), quotiented by bisimulation (:mod:`.reduce`);
4. counter-based degeneralization (:mod:`.degen`, Sec. 5), trying several orders of the acceptance sets;
5. trimming and direct-simulation reductions (:mod:`.reduce`);
6. for obligation properties (recognised syntactically, or checked against the automaton of the
   negation, as Spot does) the minimal weak deterministic Büchi automaton (:mod:`.wdba`) when smaller.

Guards are BDDs (:mod:`mrodrake.logic.bdd`) until the export to an :class:`~mrodrake.logic.nba.NBA`.
"""

from __future__ import annotations

import itertools

from mrodrake.errors import UserError
from mrodrake.logic.bdd import BDD
from mrodrake.logic.formula import Formula, Not, atoms
from mrodrake.logic.nba import NBA, empty_nba
from mrodrake.logic.parse import parse
from mrodrake.logic.simplify import simplify
from mrodrake.logic.spot_backend import translate_spot
from mrodrake.logic.translate.ba import BA, intersection_empty
from mrodrake.logic.translate.degen import degeneralize
from mrodrake.logic.translate.gba import build_gba
from mrodrake.logic.translate.reduce import merge_bisimilar_gba, reduce_ba
from mrodrake.logic.translate.wdba import minimal_wdba, syntactic_class

__all__ = ["translate"]


def translate(f: Formula | str, backend: str = "builtin") -> NBA:
    """LTL -> state-based NBA.  ``backend="builtin"`` (the pipeline of the module docstring) or ``"spot"``
    (``spot.translate(f, "BA", "sbacc")``; needs the optional ``spottl`` package).

    ``ap`` of the result is the sorted tuple of the formula's propositions.
    """
    if isinstance(f, str):
        f = parse(f)
    if backend == "spot":
        return translate_spot(f)
    if backend != "builtin":
        raise UserError(f"translator: unknown backend '{backend}' (expected 'builtin' or 'spot')")
    ap = tuple(sorted(atoms(f)))
    ap_index = {a: i for i, a in enumerate(ap)}
    g = simplify(f)
    bdd = BDD()
    ba = _translate_core(g, ap_index, bdd)
    if ba is None:
        return empty_nba(ap)
    if ba.n > 1:
        wd = _try_wdba(g, ba, ap_index)
        if wd is not None and wd.size() < ba.size():
            ba = wd
    return ba.to_nba(ap)


def _translate_core(g: Formula, ap_index: dict[str, int], bdd: BDD) -> BA | None:
    """Simplified NNF formula -> reduced state-based BA (None if the language is empty)."""
    built = build_gba(g, ap_index, bdd)
    if built is None:
        return None
    trans, nacc = built
    trans = merge_bisimilar_gba(trans, bdd)
    # The degeneralized size depends on the order of the acceptance sets and on SCC-awareness: for small
    # GBAs try every order of up to three sets (identity and reverse otherwise), with and without
    # SCC-aware levels, and keep the smallest reduced automaton.
    if len(trans) * (nacc + 1) > 64:
        variants = [(tuple(range(nacc)), True)]  # large: one good variant only
    else:
        if nacc <= 3:
            orders = list(itertools.permutations(range(nacc)))
        else:
            orders = [tuple(range(nacc)), tuple(reversed(range(nacc)))]
        variants = [(order, scc) for order in orders for scc in (False, True)]
    best = None
    for order, scc_aware in variants:
        deg = degeneralize(trans, nacc, order, bdd, scc_aware)
        for trivial_accepting in ((False, True) if deg.trivial_states() else (False,)):
            ba = reduce_ba(deg.copy(), trivial_accepting)
            if ba is None:
                return None
            if best is None or ba.size() < best.size():
                best = ba
    return best


def _try_wdba(g: Formula, ba: BA, ap_index: dict[str, int]) -> BA | None:
    """The minimal WDBA of ``g`` if its language is an obligation: syntactically (Černá & Pelánek), or
    checked semantically against ``ba`` and the automaton of ``!g`` (as Spot does); None otherwise."""
    res = minimal_wdba(ba, limit=max(32, 4 * ba.n))
    if res is None:
        return None
    wd, comp = res
    if not syntactic_class(g, {})[2]:
        if not intersection_empty(ba, comp):
            return None
        neg = _translate_core(simplify(Not(g)), ap_index, ba.bdd)
        if neg is not None and not intersection_empty(wd, neg):
            return None
    return wd.prune(False)
