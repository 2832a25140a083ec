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


def campaign_mission(tmp_path, generate: str, mission_id: str):
    """(task, randomized scenario, plan) of the first mission of a campaign of the one ``generate`` entry
    (YAML flow mapping) with that campaign's randomization; the mission must be ``mission_id``."""
    spec = tmp_path / "spec.yaml"
    spec.write_text(f"name: regression\nscenarios:\n  - generate: {generate}\n{RANDOMIZE}")
    task = load_campaign(spec).tasks[0]
    assert task.mission_id == mission_id
    sc = randomized_scenario(task.instance.scenario, task.params)
    with threadpool_limits(limits=1, user_api="blas"):
        plan = plan_scenario(sc, seed=task.plan_seed, suffix_cycles=task.suffix_cycles,
                             layout_seed=task.layout_seed)
    return task, sc, plan
