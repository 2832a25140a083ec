"""``mrodrake campaign SPEC.yaml``: many plan + execute missions, on a local process pool or on Ray.

A campaign spec (YAML, validated like scenario files: one line ``file:line: field.path: problem``) lists
scenario files and generated scenarios (:func:`mrodrake.planning.generate.generate_scenario` sizes and a
seed range), the plan and layout seeds, the number of parameter draws, the planner, the suffix cycles and
the ranges from which every mission draws its *true* plant parameters (mass and friction factors, and
optionally a random P_s initial layout).  The draws are a pure function of (``randomize.seed``, mission
id), so every engine produces the same rows.  Only the plants see the drawn values: they are written into
a copy of the scenario's robots and objects, which planners and controllers never read.

Every mission runs in its own worker process (local engine: one forked process per mission, at most
``--workers`` at a time; Ray: one task per mission).  A mission that raises, exceeds its time limit (soft:
the simulator's monitor stops it; hard: the engine kills the worker ``time_limit`` + grace later) or kills
its worker becomes a failure row; the campaign goes on.  Each finished mission is appended to
``journal.jsonl`` in the output directory, so re-running the same command skips it; at the end (and after
Ctrl-C) ``results.csv`` (+ ``results.parquet`` when pyarrow is installed), ``summary.md`` and ``figures/``
are written from the journal.

Failure kinds come from one table (:data:`FAILURE_PATTERNS`): a structured ``failure_kind`` attribute of the
mission log wins when present, else the first pattern found in the message.

Modules, one concern each: :mod:`~mrodrake.campaign.spec` (the spec file and its missions),
:mod:`~mrodrake.campaign.draws` (true plant parameters), :mod:`~mrodrake.campaign.mission` (one mission to
one row), :mod:`~mrodrake.campaign.failures` (failure kinds), :mod:`~mrodrake.campaign.metrics` (safety
metrics of a trajectory), :mod:`~mrodrake.campaign.local_engine` and :mod:`~mrodrake.campaign.ray_engine`,
:mod:`~mrodrake.campaign.journal` (resume), :mod:`~mrodrake.campaign.results`,
:mod:`~mrodrake.campaign.summary` and :mod:`~mrodrake.campaign.figures` (outputs),
:mod:`~mrodrake.campaign.run` (:func:`run_campaign`) and :mod:`~mrodrake.campaign.cli`.
"""

from mrodrake.campaign.cli import add_subparser
from mrodrake.campaign.draws import draw_parameters, randomized_scenario
from mrodrake.campaign.failures import DEFAULT_KINDS, FAILURE_PATTERNS, classify
from mrodrake.campaign.metrics import primitive_records, trajectory_metrics
from mrodrake.campaign.mission import TIMING_COLUMNS, execute
from mrodrake.campaign.run import CampaignResult, run_campaign
from mrodrake.campaign.spec import Campaign, CampaignSpec, MissionTask, ScenarioInstance, load_campaign

__all__ = [
    "run_campaign", "CampaignResult", "load_campaign", "Campaign", "CampaignSpec", "MissionTask",
    "ScenarioInstance", "draw_parameters", "randomized_scenario", "execute", "classify", "FAILURE_PATTERNS",
    "DEFAULT_KINDS", "trajectory_metrics", "primitive_records", "TIMING_COLUMNS", "add_subparser",
]
