"""The executed run of a plan: its prefix steps followed by suffix cycles (pure Python)."""

from __future__ import annotations

from dataclasses import dataclass

from mrodrake.planning.universal import Family
from mrodrake.ts import Action


@dataclass(frozen=True)
class StepSpec:
    """One executed TS step: number in the executed run (1-based), plan step, cycle (0 = prefix), source and
    target TS states with their NBA states, and the actions in execution order."""

    index: int
    plan_step: int
    cycle: int
    src: tuple
    src_q: int | Family
    dst: tuple
    dst_q: int | Family
    actions: tuple[Action, ...]


def expand_steps(plan, suffix_cycles: int) -> list[StepSpec]:
    """The plan's prefix steps followed by ``suffix_cycles`` copies of its suffix steps."""
    steps = list(plan.steps())
    P = len(plan.prefix)
    out: list[StepSpec] = []
    for step, _part, _i, _j, a, b, acts, _cost in steps[:P]:
        out.append(StepSpec(len(out) + 1, step, 0, a[0], a[1], b[0], b[1], tuple(acts)))
    for c in range(suffix_cycles):
        for step, _part, _i, _j, a, b, acts, _cost in steps[P:]:
            out.append(StepSpec(len(out) + 1, step, c + 1, a[0], a[1], b[0], b[1], tuple(acts)))
    return out
