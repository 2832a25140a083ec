"""The true plant parameters of a mission: drawn per body from the spec's ranges, seen only by the plants."""

from __future__ import annotations

import dataclasses
import hashlib
from typing import TYPE_CHECKING

import numpy as np

from mrodrake.scenario import Scenario

if TYPE_CHECKING:
    from mrodrake.campaign.spec import CampaignSpec

def draw_parameters(spec: CampaignSpec, scenario: Scenario, mission_id: str) -> tuple[dict, int | None]:
    """True parameters of every body (mass, friction scale and frequency, with their factors) and the
    drawn layout seed (``None`` unless ``randomize.initial_positions``): a pure function of
    (``randomize.seed``, ``mission_id``), drawn in a fixed order (robots, then objects)."""
    r = spec.randomize
    digest = hashlib.sha256(mission_id.encode()).digest()
    rng = np.random.default_rng([r.seed] + [int.from_bytes(digest[i:i + 4], "little") for i in range(0, 16, 4)])
    params = {}
    bodies = [(b, r.robot_mass) for b in scenario.robots] + [(b, r.object_mass) for b in scenario.objects]
    for body, mass_range in bodies:
        fm = float(rng.uniform(*mass_range))
        fs = float(rng.uniform(*r.friction_scale))
        ff = float(rng.uniform(*r.friction_frequency))
        params[body.name] = {"mass": body.mass * fm, "friction_scale": body.friction.scale * fs,
                             "friction_frequency": body.friction.frequency * ff,
                             "factors": [fm, fs, ff]}
    layout = int(rng.integers(0, 2**31 - 1)) if r.initial_positions else None
    return params, layout


def randomized_scenario(scenario: Scenario, params: dict) -> Scenario:
    """A copy of ``scenario`` whose robots and objects have the true parameters ``params``."""

    def body(b):
        p = params[b.name]
        friction = dataclasses.replace(b.friction, scale=p["friction_scale"], frequency=p["friction_frequency"])
        return dataclasses.replace(b, mass=p["mass"], friction=friction)

    return dataclasses.replace(scenario, robots=[body(b) for b in scenario.robots],
                               objects=[body(b) for b in scenario.objects])
