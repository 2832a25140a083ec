"""What the sequencer sends the simulated systems (plain values; the Drake systems read them from ports)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrodrake.control.adaptive import NavigationTask


@dataclass(frozen=True)
class SyncCommand:
    """Command to one plant: when ``version`` changes the plant copies [x, v] into its state; ``frozen``
    parks it (zero dynamics); ``offsets`` are the grasp offsets x_i − x^o of a team plant's members."""

    version: int = 0
    x: tuple = (0.0, 0.0)
    v: tuple = (0.0, 0.0)
    frozen: bool = True
    offsets: tuple = ()

    def __deepcopy__(self, memo):
        return self


@dataclass(frozen=True)
class TaskCommand:
    """A controller's task and the episode it belongs to: the estimates restart from the task's m̂(0), α̂(0)
    when the episode changes and carry over when only the task changes within an episode (a primitive
    switching from the point-world law to the local law near its goal, or to its next leg): the paper
    adapts through the whole transition."""

    task: NavigationTask
    episode: int

    def __deepcopy__(self, memo):
        return self


@dataclass(frozen=True)
class PrimitiveRecord:
    """What the figures need of one executed motion: entity, team, kind, regions, times, F and the task;
    ``spans``: every free space its point-world law ran on, as (time it started on it, free space), in order
    (windows, corridors drawn again), of which ``free`` is the last."""

    kind: str
    entity: str
    team: tuple
    src: int
    dst: int
    radius: float
    start: np.ndarray
    goal: np.ndarray
    others: tuple
    free: object
    task: object
    controller: str
    offsets: np.ndarray
    t_start: float
    t_end: float
    spans: tuple = ()
