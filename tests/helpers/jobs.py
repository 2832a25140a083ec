"""The job graph of a small generated task's placed plan (None when the planner finds no plan)."""

from __future__ import annotations

from mrodrake.errors import NoPlanFound, UserError
from mrodrake.execution.schedule import dependency_graph
from mrodrake.planning.generate import generate_scenario_data
from mrodrake.planning.plan import plan_scenario, task_words
from mrodrake.scenario import scenario_from_dict


def generated_jobs(n: int, m: int, k: int, seed: int, iterations: int = 300):
    """(plan, jobs) of generated task (n robots, m objects, k regions, ``seed``) planned with ``seed``."""
    sc = scenario_from_dict(generate_scenario_data(n, m, k, seed))
    try:
        plan = plan_scenario(sc, iterations=iterations, seed=seed, layout_seed=seed)
    except (NoPlanFound, UserError):
        return None
    _f, _nba, words = task_words(sc, plan.ts)
    return plan, dependency_graph(plan.ts, words, plan.placement)
