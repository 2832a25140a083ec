"""The monitored NBA run on the executed word (no Drake).

:class:`WordMonitor` reads the word that execution actually produces, in the way the planners assumed
(:mod:`mrodrake.planning.semantics`): it tracks in which region every body's ball lies (or none), splits
every observed change into single-body crossings (a body that both left and entered between two
observations leaves first), reads the label being left at each crossing that changes the label projected
onto the task's propositions, and at the end of a plan step reads the source label if the step had no such
crossing.  Its subset run then contains the plan's NBA state whenever the executed word is one of those the
plan was verified for; it is also right, as an observer, when the geometry does something else (a body
re-entering a region), since it reads whatever happened.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from mrodrake.planning.semantics import ExecutedWords


def entity_regions(centers: np.ndarray, radii: np.ndarray, positions: np.ndarray, region_radii: np.ndarray,
                   tol: float = 1e-9) -> np.ndarray:
    """Region index of every entity whose ball B̄(x_e, r_e) lies in a region (−1: in none; the first such region
    if several)."""
    positions = np.asarray(positions, dtype=float)
    out = np.empty(len(positions), dtype=np.int64)
    _regions(np.asarray(centers, dtype=float), np.asarray(radii, dtype=float), positions,
             np.asarray(region_radii, dtype=float), float(tol), out)
    return out


@njit(cache=True, nogil=True)
def _regions(centers, radii, positions, region_radii, tol, out):
    for e in range(positions.shape[0]):
        out[e] = -1
        for k in range(centers.shape[0]):
            if math.hypot(positions[e, 0] - centers[k, 0], positions[e, 1] - centers[k, 1]) + radii[e] \
                    <= region_radii[k] + tol:
                out[e] = k
                break


def label_of(regions: Sequence[int], K: int) -> int:
    """TS label mask of a configuration: bit e·K + k for entity e in region k (none if k = −1)."""
    m = 0
    for e, k in enumerate(regions):
        if k >= 0:
            m |= 1 << (e * K + int(k))
    return m


@dataclass(frozen=True)
class Crossing:
    """One observed body crossing: entity, region left (−1: none) and region entered (−1: none)."""

    entity: int
    left: int
    entered: int


class WordMonitor:
    """Subset run of the NBA on the executed word (module docstring); ``regions`` is the initial region
    of every entity (−1: none)."""

    def __init__(self, words: ExecutedWords, regions: Sequence[int]):
        self.words = words
        self.K = words.ts.K
        self.regions = [int(k) for k in regions]
        self.run = 1 << words.nba.initial
        self.read_in_step = False

    def copy(self) -> WordMonitor:
        other = WordMonitor.__new__(WordMonitor)
        other.words, other.K, other.regions = self.words, self.K, list(self.regions)
        other.run, other.read_in_step = self.run, self.read_in_step
        return other

    @property
    def label(self) -> int:
        """The current label projected onto the task's propositions."""
        return label_of(self.regions, self.K) & self.words.relevant

    @property
    def states(self) -> list[int]:
        """NBA states of the subset run."""
        return [q for q in range(self.words.Q) if self.run >> q & 1]

    def begin_step(self) -> None:
        self.read_in_step = False

    def observe(self, regions: Sequence[int]) -> list[Crossing]:
        """Read the change from the last observation to ``regions``; returns the crossings in reading
        order.  The run may become empty (the executed word left the task)."""
        new = [int(k) for k in regions]
        if new == self.regions:
            return []
        events = []
        for e, (a, b) in enumerate(zip(self.regions, new)):
            if a == b:
                continue
            if a >= 0:
                events.append((0, e, a, -1))
            if b >= 0:
                events.append((1, e, -1, b))
        events.sort(key=lambda x: (x[0], x[1]))  # all leaves first, then all entries
        out = []
        for _, e, left, entered in events:
            before = self.label
            self.regions[e] = entered
            if self.label != before:
                self.run = self.words.delta(self.run, before)
                self.read_in_step = True
            out.append(Crossing(e, left, entered))
        return out

    def end_step(self) -> None:
        """Close a plan step: a step without a visible crossing reads its source label once."""
        if not self.read_in_step:
            self.run = self.words.delta(self.run, self.label)
        self.read_in_step = False

    def contains(self, q: int) -> bool:
        return bool(self.run >> q & 1)

    def admits(self, q) -> bool:
        """Is the executed word one the plan was verified for at a node whose NBA side is ``q``: a state of the
        run, or a word family (:class:`~mrodrake.planning.universal.Family`) some member of which the run
        holds?"""
        return q.admits(self.run) if hasattr(q, "admits") else self.contains(q)
