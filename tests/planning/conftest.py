"""Fixtures shared by the planning tests: the shipped scenarios, their TS and task NBAs."""

from __future__ import annotations

from pathlib import Path

import pytest

from mrodrake.planning.plan import task_nba
from mrodrake.planning.semantics import ExecutedWords, relevant_mask
from mrodrake.scenario import load_scenario
from mrodrake.ts import TransitionSystem

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "scenarios"


class Case:
    """A scenario with its TS, formula, NBA (over the TS propositions) and executed-word semantics."""

    def __init__(self, name: str):
        self.path = SCENARIOS / f"{name}.yaml"
        self.scenario = load_scenario(self.path)
        self.ts = TransitionSystem(self.scenario)
        self.formula, self.nba = task_nba(self.scenario, self.ts)
        self.relevant = relevant_mask(self.ts, self.formula)
        self.words = ExecutedWords(self.ts, self.nba, self.relevant)


@pytest.fixture(scope="session")
def tiny() -> Case:
    return Case("tiny")


@pytest.fixture(scope="session")
def case1() -> Case:
    return Case("case_study_1")


@pytest.fixture(scope="session")
def case2() -> Case:
    return Case("case_study_2")
