"""Adaptation through a whole primitive: m̂, α̂ carry over when a navigation or transport switches from the
point-world law to the local law near its goal (paper Sec. III-A adapts through the whole transition)."""

from pathlib import Path

import numpy as np

from mrodrake.run import run_mission
from mrodrake.scenario import load_scenario

TINY = Path(__file__).resolve().parents[2] / "scenarios" / "tiny.yaml"


def test_alpha_hat_never_falls_within_a_primitive():
    """dα̂/dt = k_α‖e_v‖² ≥ 0, so within one primitive α̂ can only grow; a restart from α̂(0) at the switch to
    the local law (what a new task used to do) would make it fall."""
    scn = load_scenario(TINY)
    log = run_mission(scn, seed=0)
    assert log.ok, log.message
    sig = log.signals
    checked = 0
    for rec in log.primitives:
        if rec.kind not in ("navigate", "transport"):
            continue
        rows = sig[(sig["controller"] == rec.controller) & (sig["entity"] == rec.entity)
                   & (sig["t"] >= rec.t_start) & (sig["t"] <= rec.t_end)].sort_values("t")
        assert len(rows) > 10
        a = rows["alpha_hat"].to_numpy()
        assert np.all(np.diff(a) >= -1e-12), (rec.kind, rec.entity, a.min(), a.max())
        assert a[-1] > a[0] > -1.0  # it adapted
        checked += 1
    assert checked >= 2
