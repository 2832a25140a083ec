"""TS transitions the planner must avoid after placement rejected a plan.

A rejected step names the region where the geometry failed.  What placement has to realise there is the
step's *local situation*: which entities, with which grasps, are in that region and in the regions its
travels in or out of connect it to, before and after the step.  Everything else the step does happens
elsewhere, so the same failure comes back under another transition with the same local situation.
:class:`Bans` therefore bans, besides each rejected transition, every transition with the local situation of
a rejected one (both directions, as the rejected pairs).  A grasp rejected because a member that stays docked
is off its slot in the new team's layout bans that change of team everywhere (:class:`SwapBan`).

Placement depends on where earlier steps put the entities and on what later steps bring, so a local ban may
exclude a plan that placement could realise.  Only STyLuS*'s first search honours local bans; the extended
search honours swap bans too (a team change whose staying member is off its new slot never places, wherever it
happens: without them the extended search offered one such change after another), the exact planner avoids the
rejected transitions alone, and a rejection never enters a proof of unsatisfiability.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from mrodrake.ts import Navigate, State, TransitionSystem, Transport


@dataclass(frozen=True)
class LocalBan:
    """The local situation of a rejected step: ``regions`` and, per entity, its region there or −1 (with
    robots' grasps) before and after the step."""

    regions: frozenset[int]
    before: tuple[int, ...]
    after: tuple[int, ...]

    @staticmethod
    def of(ts: TransitionSystem, s: State, t: State, region: int) -> LocalBan:
        """The local situation of step s → t in ``region``."""
        regions = {region}
        for a in ts.actions(s, t):
            if isinstance(a, (Navigate, Transport)) and region in (a.src, a.dst):
                regions.update((a.src, a.dst))
        regions = frozenset(regions)
        return LocalBan(regions, local(ts, s, regions), local(ts, t, regions))

    def matches(self, s: State, t: State, n: int) -> bool:
        """Is s → t or t → s a step with this local situation (``n`` = N + M)?"""
        ls = _local(s, self.regions, n)
        if ls == self.before:
            return _local(t, self.regions, n) == self.after
        return ls == self.after and _local(t, self.regions, n) == self.before


@dataclass(frozen=True)
class SwapBan:
    """A change of object ``obj``'s team to ``after`` in which the members ``stay`` stay docked, which placement
    rejected because a staying member's slot in the new team's grasp layout is not where it is docked (a matter
    of the members' radii, not of where it happens): every change to ``after`` from a team holding ``stay`` is
    banned, in both directions."""

    obj: int
    stay: frozenset[int]
    after: frozenset[int]

    @staticmethod
    def of(ts: TransitionSystem, s: State, t: State, obj: int) -> SwapBan:
        n = ts.N + ts.M
        before, after = _team(s, obj, ts.N, n), _team(t, obj, ts.N, n)
        return SwapBan(obj, before & after, after)

    def matches(self, s: State, t: State, n_robots: int, n: int) -> bool:
        a, b = _team(s, self.obj, n_robots, n), _team(t, self.obj, n_robots, n)
        return (b == self.after and self.stay <= a != b) or (a == self.after and self.stay <= b != a)

    def touches(self, s: State, n_robots: int, n: int) -> bool:
        team = _team(s, self.obj, n_robots, n)
        return team == self.after or self.stay <= team


def _team(s: State, obj: int, n_robots: int, n: int) -> frozenset[int]:
    return frozenset(i for i in range(n_robots) if s[n + i] == obj)


def local(ts: TransitionSystem, s: State, regions: frozenset[int]) -> tuple[int, ...]:
    """Per entity its region if in ``regions`` else −1, then each robot's grasp if it is in them."""
    return _local(s, regions, ts.N + ts.M)


def _local(s: State, regions: frozenset[int], n: int) -> tuple[int, ...]:
    where = tuple(k if k in regions else -1 for k in s[:n])
    return where + tuple(g if where[i] >= 0 else -1 for i, g in enumerate(s[n:]))


class Bans:
    """The transitions STyLuS* must not use, as a mapping state -> container of neighbour states: rejected
    pairs (both directions) and transitions with the local situation of a :class:`LocalBan`."""

    def __init__(self, ts: TransitionSystem, pairs: Iterable[tuple[State, State]] = (),
                 local_bans: Iterable[LocalBan | SwapBan] = ()):
        self.n = ts.N + getattr(ts, "M", 0)  # graph TSs have robots only
        self.n_robots = ts.N
        self.pairs: dict[State, set[State]] = {}
        for a, b in pairs:
            self.pairs.setdefault(tuple(a), set()).add(tuple(b))
            self.pairs.setdefault(tuple(b), set()).add(tuple(a))
        bans = list(dict.fromkeys(local_bans))
        self.swaps = [b for b in bans if isinstance(b, SwapBan)]
        self.local = [b for b in bans if isinstance(b, LocalBan)]
        self._sides = {(ban.regions, side) for ban in self.local for side in (ban.before, ban.after)}
        self._regions = list(dict.fromkeys(ban.regions for ban in self.local))

    def __bool__(self) -> bool:
        return bool(self.pairs or self.local or self.swaps)

    def __contains__(self, s: State) -> bool:
        return (s in self.pairs
                or any((regions, _local(s, regions, self.n)) in self._sides for regions in self._regions)
                or any(b.touches(s, self.n_robots, self.n) for b in self.swaps))

    def __getitem__(self, s: State) -> _Neighbours:
        return _Neighbours(self, s)

    def get(self, s: State, default=()) -> _Neighbours:
        return _Neighbours(self, s)

    def banned(self, s: State, t: State) -> bool:
        return (t in self.pairs.get(s, ()) or any(ban.matches(s, t, self.n) for ban in self.local)
                or any(ban.matches(s, t, self.n_robots, self.n) for ban in self.swaps))


class _Neighbours:
    """The states a banned transition joins to ``s``."""

    def __init__(self, bans: Bans, s: State):
        self.bans, self.s = bans, s

    def __contains__(self, t: State) -> bool:
        return self.bans.banned(self.s, tuple(t))
