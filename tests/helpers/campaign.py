"""One randomized campaign mission, as a campaign worker plans it (single-threaded BLAS, its plan seed)."""

from __future__ import annotations

from threadpoolctl import threadpool_limits

from mrodrake.campaign import load_campaign, randomized_scenario
from mrodrake.planning.plan import plan_scenario


def campaign_mission(tmp_path, spec_text: str, mission_id: str):
    """(task, randomized scenario, plan) of the first mission of the spec ``spec_text``, which must be
    ``mission_id``."""
    spec = tmp_path / "spec.yaml"
    spec.write_text(spec_text)
    task = load_campaign(spec).tasks[0]
    assert task.mission_id == mission_id
    sc = randomized_scenario(task.instance.scenario, task.params)
    with threadpool_limits(limits=1, user_api="blas"):
        plan = plan_scenario(sc, seed=task.plan_seed, time_limit=60)
    return task, sc, plan
