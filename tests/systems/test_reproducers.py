"""Whole missions that used to stop early on generated tasks (issue 13's reproducers): a false alarm of the
label monitor (3, 1, 3, 11), no consistent order of concurrent actions (3, 2, 4, 15) and a mission that went
numerically unstable (4, 2, 4, 21).  Each now plans on the executed-word semantics, places the whole run and
executes to the end.  Several minutes each on the office map: slow set (``--runslow``)."""

from __future__ import annotations

import pytest

from mrodrake.planning.generate import generate_scenario
from mrodrake.run import run_mission


@pytest.mark.slow
@pytest.mark.parametrize("n, m, k, seed", [(3, 1, 3, 11), (3, 2, 4, 15), (4, 2, 4, 21)])
def test_generated_reproducer_runs_to_completion(n, m, k, seed):
    sc = generate_scenario(n, m, k, seed)
    log = run_mission(sc, seed=seed)
    assert log.ok, log.message
    assert log.steps_done == log.steps_total
    labels = log.events[log.events["kind"] == "label"]
    assert labels["ok"].all()
