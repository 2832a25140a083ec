"""``mrodrake bench ltl``: size and speed of the built-in LTL -> NBA translator against Spot.

Measures the 55 Dwyer et al. specification patterns (total NBA states, ours vs Spot's
``translate(f, "BA", "sbacc")``, worst ratios, translation times) and the two case-study formulas of the
paper (states/edges; the paper reports 6/18 and 8/27), both loaded by :mod:`mrodrake.logic.data`.  Spot
is optional; without it only our numbers are printed.
"""

from __future__ import annotations

import sys
import time

from mrodrake.logic.data import load_case_study_formulas, load_dwyer_patterns
from mrodrake.logic.formula import atoms, to_str
from mrodrake.logic.nba import NBA
from mrodrake.logic.parse import parse
from mrodrake.logic.spot_backend import import_spot, spot_available
from mrodrake.logic.translate import translate

__all__ = ["run_ltl_benchmark", "TARGETS"]

TARGETS = {"dwyer_state_ratio": 1.5, "dwyer_total_time_s": 2.0, "case_study_time_s": 0.5}
PAPER_CASE_STUDIES = [("case I", 6, 18), ("case II", 8, 27)]


def _timed(fn, *args) -> tuple[NBA, float]:
    t0 = time.perf_counter()
    r = fn(*args)
    return r, time.perf_counter() - t0


def run_ltl_benchmark(stream=sys.stdout) -> dict:
    """Run the benchmark, print its table to ``stream`` and return the numbers as a dict."""
    have_spot = spot_available()
    spot = import_spot() if have_spot else None
    w = stream.write
    patterns = load_dwyer_patterns()
    rows = []
    for i, text in enumerate(patterns, start=1):
        f = parse(text, source=f"dwyer_patterns.txt:{i}")
        ours, t_ours = _timed(translate, f)
        row = {"index": i, "formula": text, "states": ours.num_states, "edges": ours.num_edges,
               "time_s": t_ours}
        if have_spot:
            aut, t_spot = _timed(lambda s: spot.translate(s, "BA", "sbacc"), text)
            row.update(spot_states=aut.num_states(), spot_edges=aut.num_edges(), spot_time_s=t_spot,
                       equivalent=bool(spot.are_equivalent(spot.automaton(ours.to_hoa()), spot.formula(text))))
            row["ratio"] = row["states"] / row["spot_states"]
        rows.append(row)

    w("LTL -> NBA benchmark: 55 Dwyer et al. patterns (states / edges; Spot: translate(f, 'BA', 'sbacc'))\n")
    w(f"{'#':>3} {'ours':>9} {'spot':>9} {'ratio':>6} {'ms':>7}  formula\n")
    for r in rows:
        spot_col = f"{r['spot_states']:>3}/{r['spot_edges']:<4}" if have_spot else f"{'-':>9}"
        ratio = f"{r['ratio']:6.2f}" if have_spot else f"{'-':>6}"
        flag = "" if not have_spot or r["equivalent"] else "  NOT EQUIVALENT"
        w(f"{r['index']:>3} {r['states']:>4}/{r['edges']:<4} {spot_col} {ratio} {1000 * r['time_s']:7.1f}  "
          f"{r['formula']}{flag}\n")
    total_ours = sum(r["states"] for r in rows)
    total_time = sum(r["time_s"] for r in rows)
    max_time = max(r["time_s"] for r in rows)
    result: dict = {"spot_available": have_spot, "dwyer": {
        "count": len(rows), "states_total": total_ours, "edges_total": sum(r["edges"] for r in rows),
        "time_total_s": total_time, "time_max_s": max_time, "patterns": rows}}
    w(f"\nDwyer total states: ours {total_ours}")
    if have_spot:
        total_spot = sum(r["spot_states"] for r in rows)
        ratio = total_ours / total_spot
        worst = sorted(rows, key=lambda r: (-r["ratio"], r["index"]))[:5]
        n_equiv = sum(r["equivalent"] for r in rows)
        result["dwyer"].update(spot_states_total=total_spot, ratio=ratio, equivalent=n_equiv,
                               spot_time_total_s=sum(r["spot_time_s"] for r in rows),
                               worst=[(r["index"], r["states"], r["spot_states"], r["ratio"]) for r in worst])
        w(f", Spot {total_spot}, ratio {ratio:.3f} (target <= {TARGETS['dwyer_state_ratio']})\n")
        w("worst ratios: " + ", ".join(f"#{r['index']} {r['states']}/{r['spot_states']}={r['ratio']:.2f}"
                                       for r in worst) + "\n")
        w(f"language-equivalent to the formula (checked with Spot): {n_equiv}/{len(rows)}\n")
    else:
        w(" (Spot not installed: no comparison)\n")
    w(f"Dwyer translation time: total {total_time:.3f} s (target <= {TARGETS['dwyer_total_time_s']} s), "
      f"max {1000 * max_time:.1f} ms\n")

    w("\nCase-study formulas (paper: case I 6 states/18 transitions, case II 8/27)\n")
    cases = []
    for (name, p_states, p_edges), text in zip(PAPER_CASE_STUDIES, load_case_study_formulas()):
        f = parse(text, source=name)
        ours, t = _timed(translate, f)
        case = {"name": name, "states": ours.num_states, "edges": ours.num_edges,
                "accepting": len(ours.accepting), "time_s": t, "paper_states": p_states, "paper_edges": p_edges,
                "propositions": len(atoms(f))}
        line = (f"{name:8s} ours {ours.num_states} states / {ours.num_edges} edges / {len(ours.accepting)} accepting, "
                f"{1000 * t:.1f} ms (target <= {1000 * TARGETS['case_study_time_s']:.0f} ms); "
                f"paper {p_states}/{p_edges}")
        if have_spot:
            aut = spot.translate(to_str(f), "BA", "sbacc")
            case.update(spot_states=aut.num_states(), spot_edges=aut.num_edges())
            line += f"; Spot {aut.num_states()}/{aut.num_edges()}"
        w(line + f"; {case['propositions']} propositions\n")
        cases.append(case)
    result["case_studies"] = cases
    targets = {"dwyer_total_time": total_time <= TARGETS["dwyer_total_time_s"],
               "case_study_time": all(c["time_s"] <= TARGETS["case_study_time_s"] for c in cases)}
    if have_spot:
        targets["dwyer_state_ratio"] = result["dwyer"]["ratio"] <= TARGETS["dwyer_state_ratio"]
        targets["dwyer_equivalent"] = result["dwyer"]["equivalent"] == len(rows)
    result["targets"] = targets
    w("\ntargets: " + ", ".join(f"{k} {'PASS' if v else 'FAIL'}" for k, v in targets.items()) + "\n")
    return result
