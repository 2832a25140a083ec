"""One randomized campaign mission, as a campaign worker plans it (single-threaded BLAS, its plan seed)."""

from __future__ import annotations

from threadpoolctl import threadpool_limits

from mrodrake.campaign import load_campaign, randomized_scenario
from mrodrake.planning.plan import plan_scenario

#: The randomization of scenarios/campaigns/success_across_maps.yaml.
RANDOMIZE = """
randomize:
  seed: 13
  robot_mass: [0.5, 2.0]
  object_mass: [0.5, 2.0]
  friction_scale: [0.0, 2.0]
  friction_frequency: [0.4, 2.0]
  initial_positions: true
"""


def campaign_mission(tmp_path, generate: str, mission_id: str, randomize: str = RANDOMIZE,
                     iterations: int | None = None):
    """(task, randomized scenario, plan) of the first mission of a campaign of the one ``generate`` entry
    (YAML flow mapping) with the randomization ``randomize`` (default: that campaign's) and the planner's
    ``iterations``; the mission must be ``mission_id``."""
    spec = tmp_path / "spec.yaml"
    budget = "" if iterations is None else f"iterations: {iterations}\n"
    spec.write_text(f"name: regression\nscenarios:\n  - generate: {generate}\n{budget}{randomize}")
    task = load_campaign(spec).tasks[0]
    assert task.mission_id == mission_id
    sc = randomized_scenario(task.instance.scenario, task.params)
    with threadpool_limits(limits=1, user_api="blas"):
        plan = plan_scenario(sc, seed=task.plan_seed, suffix_cycles=task.suffix_cycles,
                             layout_seed=task.layout_seed, **({} if iterations is None else {"iterations": iterations}))
    return task, sc, plan
