"""Plan-wide placement: every goal, grasp and back-off point of the executed run, fixed before simulating.

The paper leaves the continuous goals of a transition to P_s (Sec. III-A: the desired goal "will be provided
by the procedure P_s"), a goal point in the target region given the entities there.  Chosen one arrival at a
time during execution, such goals can leave no room for what the plan brings later (a team needs its covering
disk free around its object, a later arrival its slot).  :func:`place_run` walks the whole executed run (prefix
and suffix cycles) once, in the order the sequencer will execute it, and fixes for every primitive where its
entity ends:

* a release: the back-off spot of the robot (clear of its object's reserved team disk);
* a grasp: the docking point on the team layout around the object (the layout of the object's next
  transport team, rotated so that every slot and the team's covering disk are free; robots already docked
  fix the rotation);
* a navigation or a transport: the spot of the robot, or of the object with its team's covering radius;
* *room* moves: when a grasp layout or an arrival finds no room, the parked free robots of that region are
  placed again together with it (clear of the robots that dock next), and move inside the region first.

Every spot is a P_s placement (:func:`mrodrake.packing.place`) in the region with the layout spacing to the other
entities and the rim; ungrasped objects with a later transport occupy their future team's covering disk
(reserved; the members that start beside it stand on their slots inside it; an object whose disk a team that
forms later cannot keep at the start stands where that team can form and set off); an arrival also leaves room
for the largest set of entities the plan brings into that region while it stays (foresight, dropped in the order
of the smallest first when it does not fit).  A robot that stays docked to an object moves only with it, so an
arriving team keeps such robots (its own members' slots included) out of the covering disk of every team that
stands or forms around another object while they stay docked; when no spot does, an earlier arrival learns to
keep the object in the way off it.  A robot arriving, or backing off after a release, where a team stands keeps
out of that team's covering disk if the team leaves before the robot acts again (in execution order), and parked
spots are first sought where the region's later trips keep a way out (a spot beside a door can cut it off for a
team).  Spots keep ``radius + control.margin`` to walls, obstacles and other regions (sampled boundary points are
fixed disks), so that the point-world free space of a departure or an arrival contains them.  Every local motion
(back-off, docking, room move) is checked for a straight-leg path inside its region
(:func:`mrodrake.geometry.local_path`); a docking slot also keeps the goal tolerances of the executor from the
entities parked beside it (they stop up to that far off their spots).  A geometry that cannot be realised (also a
navigation or transport whose start is not in its free space) raises :class:`PlacementError` naming the step and
the region, before any simulation.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np
import shapely
from shapely.geometry import Point
from shapely.ops import unary_union

from mrodrake.errors import UserError
from mrodrake.geometry import DOCK_TOL, GOAL_TOL, grasp_layout, local_path, polygon
from mrodrake.packing import can_place, place
from mrodrake.planning.steps import StepSpec, expand_steps
from mrodrake.ts import Grasp, Navigate, Release, TransitionSystem, Transport

#: Spacing (m) of the boundary points that keep spots off walls, obstacles and other regions.
BOUNDARY_SAMPLE = 0.2
#: Seeds tried per placement before giving up (each a different P_s start).
SEEDS = 6
_ANGLES = 72


class OpKind(Enum):
    """Kinds of the primitives the sequencer executes."""

    ROOM = "room"
    RELEASE = "release"
    GRASP = "grasp"
    NAVIGATE = "navigate"
    TRANSPORT = "transport"


@dataclass(frozen=True)
class PlacedOp:
    """One primitive with its planned end point: ``entity`` is the moving robot (room, release, grasp,
    navigate) or the transported object (entity index N + j); ``goal`` is where it ends (the object's centre
    for a transport); ``rotation`` is the team layout's angle (grasp, transport); ``action`` the TS action
    (None for a room move)."""

    kind: OpKind
    action: object
    entity: int
    region: int
    goal: tuple[float, float]
    rotation: float = 0.0
    team: tuple[int, ...] = ()


@dataclass(frozen=True)
class StepPlacement:
    """The placed primitives of one executed step, in execution order, and the planned positions of every
    entity at its end."""

    step: StepSpec
    ops: tuple[PlacedOp, ...]
    positions: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class Placement:
    """Initial positions and the placed steps of a whole executed run."""

    initial: tuple[tuple[float, float], ...]
    steps: tuple[StepPlacement, ...]


class PlacementError(UserError):
    """The executed run needs room a region does not have (one line naming the step and the region);
    ``step`` is the executed step that failed, or for an initial layout that cannot keep the room a later step
    needs, that step (None: an initial layout that fails by itself), and ``region`` its region; ``swap``: the
    object whose change of team failed because a member that stays docked is off its new slot (else −1)."""

    def __init__(self, message: str, step: StepSpec | None = None, region: int = -1, swap: int = -1):
        super().__init__(message)
        self.step, self.region, self.swap = step, region, swap


class _Retry(Exception):
    """A step found no room because of where an earlier arrival put an object; a hint now moves it."""


def layout_slots(ts: TransitionSystem, j: int, team: Sequence[int], center, rotation: float) -> np.ndarray:
    """Grasp points of ``team`` (in team order) around object j at ``center``, the layout rotated."""
    lay = grasp_layout(ts.object_radius[j], [ts.robot_radius[i] for i in team], ts.grasp_gap)
    c, s = math.cos(rotation), math.sin(rotation)
    rot = np.array([[c, -s], [s, c]])
    return np.asarray(center, dtype=float) + lay.offsets @ rot.T


class _World:
    """Positions, grasps and team rotations while the run is walked."""

    def __init__(self, ts: TransitionSystem, state: tuple, positions: np.ndarray):
        self.ts = ts
        N, M = ts.N, ts.M
        self.pos = np.array(positions, dtype=float).reshape(N + M, 2)
        self.where = [int(k) for k in state[: N + M]]
        self.grasp = [int(g) for g in state[N + M:]]
        self.rotation: dict[int, float] = {}
        self.placed = [-1] * (N + M)  # executed step whose arrival put each entity where it is (-1: start)
        self.preset: dict[int, float] = {}  # layout rotations of members on their slots from the start

    def team_of(self, j: int) -> tuple[int, ...]:
        return tuple(i for i in range(self.ts.N) if self.grasp[i] == j)


class _Placer:
    def __init__(self, ts: TransitionSystem, steps: Sequence[StepSpec], seed: int):
        self.ts, self.steps, self.seed = ts, list(steps), int(seed)
        self.deferred: set[tuple[int, int]] = set()  # (step, robot): grasps after the step's departures
        self.departures: list[list[tuple[int, Transport]]] = [[] for _ in range(ts.K)]  # per source region
        for n, spec in enumerate(self.steps):
            for a in spec.actions:
                if isinstance(a, Transport):
                    self.departures[a.src].append((n, a))
        sc = ts.scenario
        self.N, self.M, self.K = ts.N, ts.M, ts.K
        self.spacing = sc.layout.spacing
        self.centers = np.array([g.center for g in sc.regions], dtype=float)
        self.R = np.array([g.radius for g in sc.regions], dtype=float)
        self.radii = np.array(ts.robot_radius + ts.object_radius, dtype=float)
        self._samples: dict[int, np.ndarray] = {}
        self._next: dict[tuple[int, int], Transport | None] = {}
        self._fits: dict[tuple, bool] = {}  # answers of the ``future`` check of spot (a pure function)
        self.variant = 0
        self.rng = np.random.default_rng(self.seed)
        #: the (object, team) pairs with a team plant: only they can carry their object inside a region
        self.couplings = {(a.obj, tuple(a.team)) for spec in self.steps for a in spec.actions
                          if isinstance(a, Transport)}
        #: learned (centre, distance) to keep from, per (entity, executed step of its arrival; -1: start)
        self.hints: dict[tuple[int, int], list[tuple[np.ndarray, float]]] = {}
        #: the executed step whose need taught the hints of an (entity, arrival) pair first
        self.taught_by: dict[tuple[int, int], StepSpec] = {}
        self.current: StepSpec | None = None
        #: team layout rotation of an object whose members stand on their slots from the start (first grasp)
        self.preset: dict[int, float] = {}

    def restart(self, variant: int) -> None:
        """Another attempt at the whole run: variant 0 places every spot as far out as it goes, with the
        most clearance; the others take rings and points in a random order drawn from (seed, variant)."""
        self.variant = int(variant)
        self.rng = np.random.default_rng([self.seed, self.variant])
        self.hints = {}
        self.taught_by = {}
        self.preset = {}

    # ------------------------------------------------------------------------------------ geometry
    def samples(self, k: int) -> np.ndarray:
        """Boundary points near region k (walls, obstacles, other regions) that spots must keep clear of."""
        out = self._samples.get(k)
        if out is None:
            sc = self.ts.scenario
            reach = self.R[k] + self.ts.margin + 2.0 * float(self.radii.max(initial=0.0)) + 2.0
            near = Point(*self.centers[k]).buffer(reach)
            lines = [polygon(sc.workspace.boundary).exterior] + [polygon(o.polygon).exterior
                                                                  for o in sc.workspace.obstacles]
            lines += [Point(*g.center).buffer(g.radius, quad_segs=32).exterior for m, g in enumerate(sc.regions)
                      if m != k]
            pts = []
            for ln in lines:
                part = ln.intersection(near)
                if part.is_empty:
                    continue
                for seg in getattr(part, "geoms", [part]):
                    if seg.geom_type != "LineString":
                        pts.append(shapely.get_coordinates(seg))
                        continue
                    n = max(2, int(math.ceil(seg.length / BOUNDARY_SAMPLE)) + 1)
                    pts.append(shapely.get_coordinates(shapely.line_interpolate_point(
                        seg, np.linspace(0.0, 1.0, n), normalized=True)))
            out = np.vstack(pts) if pts else np.zeros((0, 2))
            self._samples[k] = out
        return out

    def next_carry(self, j: int, step: int) -> Transport | None:
        """The first transport of object j at or after executed step ``step`` (0-based), or None."""
        key = (j, step)
        if key not in self._next:
            self._next[key] = next((a for spec in self.steps[step:] for a in spec.actions
                                    if isinstance(a, Transport) and a.obj == j), None)
        return self._next[key]

    def next_team(self, j: int, step: int) -> tuple[int, ...] | None:
        """Team of the first transport of object j at or after executed step ``step`` (0-based)."""
        a = self.next_carry(j, step)
        return None if a is None else tuple(a.team)

    def first_grasp(self, j: int, step: int) -> float:
        """Executed step (0-based) at or after ``step`` at which object j's next team starts forming."""
        for n in range(step, len(self.steps)):
            if any(isinstance(a, Grasp) and a.obj == j for a in self.steps[n].actions):
                return n
        return math.inf

    def occupied_until(self, e: int, step: int) -> float:
        """Last executed step through which entity e, arriving at ``step``, keeps its disk: up to the next
        step in which it (a robot) acts again; for a carried object, until the last member of its team has
        released it or the team carries it on (the covering disk of a partial team is as large)."""
        N = self.N
        team = set()
        if e >= N:
            arriving = [a for a in self.steps[step].actions if isinstance(a, Transport) and a.obj == e - N]
            team = set(arriving[0].team) if arriving else set()
        for n in range(step + 1, len(self.steps)):
            for a in self.steps[n].actions:
                if e < N and getattr(a, "robot", None) == e:
                    return n
                if e >= N and getattr(a, "obj", None) == e - N:
                    if isinstance(a, Transport):
                        return n
                    if isinstance(a, Release):
                        team.discard(a.robot)
                        if not team:
                            return n
                    elif isinstance(a, Grasp):
                        team.add(a.robot)
        return math.inf

    def units(self, w: _World, k: int, step: int, exclude: set[int],
              until: float = math.inf) -> tuple[list[np.ndarray], list[float], list[int]]:
        """(centres, radii, entity) of the bodies in region k: every robot (free or docked at its slot) and
        every object with its own radius; entities in ``exclude`` left out.  (A moving team is a disk of its
        covering radius in the controllers' free space; standing teams are their bodies, so the covering
        disks of two teams may interleave.)  ``until`` is kept for the callers' reservations."""
        cs, rs, es = [], [], []
        for e in range(self.N + self.M):
            if w.where[e] == k and e not in exclude:
                cs.append(w.pos[e])
                rs.append(float(self.radii[e]))
                es.append(e)
        return cs, rs, es

    def place_in(self, k: int, new: Sequence[float], cs: Sequence[np.ndarray], rs: Sequence[float],
                 attempt: int = 0) -> np.ndarray | None:
        """P_s centres (absolute) for disks ``new`` in region k next to the fixed disks and off the
        boundary samples, or None."""
        c = self.centers[k]
        S = self.samples(k)
        fc = np.vstack([np.array(cs, dtype=float).reshape(-1, 2) - c, S - c]) if len(S) else \
            np.array(cs, dtype=float).reshape(-1, 2) - c
        fr = list(rs) + [self.ts.margin] * len(S)
        sol = place(self.R[k], fc, fr, [float(r) for r in new], seed=self.seed + 7919 * attempt,
                    margin=self.spacing)
        return None if sol is None else c + sol

    def spot(self, k: int, r: float, cs: Sequence[np.ndarray], rs: Sequence[float],
             keep_clear: Sequence[tuple[np.ndarray, float]] = (), future: Sequence[float] = (),
             near: np.ndarray | None = None, rim_extra: float = 0.0, accept=None) -> np.ndarray | None:
        """One disk of radius r in region k, as far out as it goes (rings from the rim inwards, every
        0.25 m; the centre stays free for what comes later), clear of the fixed disks, the boundary samples
        and ``keep_clear`` (centre, distance) by the spacing; on a ring, the most clearance first (or the
        point nearest to ``near``).  With ``future`` radii, the disk must leave a P_s placement for them
        (two candidates per ring are tried); ``rim_extra`` keeps that much more room to the rim; ``accept``
        (a predicate of the spot, :meth:`_passages`) filters the candidates."""
        c, R, sp = self.centers[k], float(self.R[k]), self.spacing
        S = self.samples(k)
        cs_xy = np.array(cs, dtype=float).reshape(-1, 2)
        fc = np.vstack([cs_xy, S]) if len(S) else cs_xy
        fr = np.concatenate([np.asarray(rs, dtype=float), np.full(len(S), self.ts.margin)])
        top = R - r - 0.5 * sp - rim_extra - 1e-6
        if top < 0.0:
            return None
        rings = np.concatenate([np.arange(top, 0.0, -0.25), [0.0]])
        if self.variant:
            rings = rings[self.rng.permutation(len(rings))]
        # with ``future``: first every ring with the greedy P_s check alone, then with its relaxations
        for restarts in ((0, None) if future else (None,)):
            p = self._spot_pass(k, r, c, rings, fc, fr, keep_clear, future, near, restarts, accept)
            if p is not None:
                return p
        return None

    def _spot_pass(self, k, r, c, rings, fc, fr, keep_clear, future, near, restarts,
                   accept=None) -> np.ndarray | None:
        """One pass of :meth:`spot` over ``rings``; ``restarts``: relaxations of the ``future`` check (None:
        as many as :func:`place` tries)."""
        sp, R = self.spacing, float(self.R[k])
        for rho in rings:
            n = 1 if rho == 0.0 else int(min(180, max(12, math.ceil(2.0 * math.pi * rho / 0.1))))
            ang = np.arange(n) * (2.0 * math.pi / n)
            pts = c + rho * np.column_stack([np.cos(ang), np.sin(ang)])
            clear = np.full(n, np.inf)
            if len(fc):
                d = np.linalg.norm(pts[:, None, :] - fc[None, :, :], axis=-1) - fr[None, :] - r
                clear = d.min(axis=1)
            ok = clear >= sp
            for kc, dist in keep_clear:
                ok &= np.linalg.norm(pts - kc, axis=1) >= dist
            idx = np.flatnonzero(ok)
            if len(idx) == 0:
                continue
            if near is not None:
                idx = idx[np.argsort(np.linalg.norm(pts[idx] - near, axis=1), kind="stable")]
            elif self.variant:
                idx = idx[self.rng.permutation(len(idx))]
            else:
                idx = idx[np.argsort(-clear[idx], kind="stable")]
            cands = idx if accept is None else (i for i in idx if accept(pts[i]))
            for i in itertools.islice(cands, 2 if future else 1):
                p = pts[i]
                if not future:
                    return p
                if self._leaves_room(R, np.vstack([fc, p]) - c, [*fr, r], list(future), restarts):
                    return p
        return None

    def _leaves_room(self, R: float, fc: np.ndarray, fr: list, future: list, restarts: int | None) -> bool:
        """can_place of the ``future`` radii next to the fixed disks (fc, fr), remembered per exact input."""
        key = (R, fc.tobytes(), tuple(map(float, fr)), tuple(map(float, future)), restarts)
        if key not in self._fits:
            kw = {} if restarts is None else {"restarts": restarts}
            self._fits[key] = can_place(R, fc, fr, future, seed=self.seed, margin=self.spacing, **kw)
        return self._fits[key]

    def drift(self, w: _World, m: int) -> float:
        """How far entity m may stand from its planned spot when executed: a navigation or transport ends within
        GOAL_TOL of it (a back-off or room move within DOCK_TOL), and a docked robot sits within DOCK_TOL of its
        slot next to an object within GOAL_TOL of its own."""
        return GOAL_TOL + DOCK_TOL if m < self.N and w.grasp[m] >= 0 else GOAL_TOL

    def path_ok(self, w: _World, e: int, k: int, goal, ignore: set[int], anchor: int | None = None) -> bool:
        """Straight-leg path inside region k for robot e from its position to ``goal`` around every other
        entity's disk (team members as themselves, objects at their own radius).  With ``anchor`` (object j),
        ``goal`` is a docking slot, which the sequencer neither moves nor checks against the planned spots: it
        keeps the drift of both j (the slot moves with it) and each other entity (:meth:`drift`) beyond the
        radii from everything but j and the robots docked to j (their slots move with it too)."""
        others = [m for m in range(self.N + self.M) if m != e and m not in ignore and w.where[m] == k]
        centers = w.pos[others].reshape(-1, 2)
        radii = self.radii[others] + self.radii[e]
        if anchor is not None:
            tied = {self.N + anchor, *w.team_of(anchor)}
            slack = [0.0 if m in tied else self.drift(w, m) + GOAL_TOL for m in others]
            if np.any(np.linalg.norm(centers - np.asarray(goal, dtype=float), axis=1) < radii + np.array(slack)):
                return False
        try:
            local_path(w.pos[e], np.asarray(goal, dtype=float), centers, radii, self.centers[k],
                       float(self.R[k] - self.radii[e]))
        except ValueError:
            return False
        return True

    def future_units(self, w: _World, step: int, k: int, stay: int) -> list[float]:
        """Radii of the largest (by area) set of units the plan brings into region k later while entity
        ``stay`` remains there (not counting what is there now)."""
        nm = self.N + self.M
        present = {e for e in range(nm) if w.where[e] == k}
        best, best_area = [], 0.0
        for spec in self.steps[step + 1:]:
            regions, grasps = spec.dst[:nm], spec.dst[nm:]
            if regions[stay] != k:
                break
            teams: dict[int, list[int]] = {}
            for i in range(self.N):
                if grasps[i] >= 0:
                    teams.setdefault(int(grasps[i]), []).append(i)
            units = []
            for e in range(nm):
                if regions[e] != k or e in present or e == stay or (e < self.N and grasps[e] >= 0):
                    continue
                j = e - self.N
                units.append(self.ts.covering_radius(j, tuple(teams[j])) if j in teams else float(self.radii[e]))
            area = sum(u * u for u in units)
            if area > best_area:
                best, best_area = units, area
        return sorted(best, reverse=True)

    def where_msg(self, spec: StepSpec, k: int) -> str:
        return f"step {spec.index} (plan step {spec.plan_step}): region '{self.ts.region_names[k]}'"

    # ------------------------------------------------------------------------------------ room moves
    def make_room(self, w: _World, spec: StepSpec, step: int, k: int, new: Sequence[float],
                  keep_out: Sequence[tuple[np.ndarray, float]],
                  protect: set[int]) -> tuple[np.ndarray, list[PlacedOp]] | None:
        """Place the parked free robots of region k again together with ``new`` disks (and clear of
        ``keep_out`` disks); returns (centres of the new disks, room ops) with every move's path checked."""
        free = [i for i in range(self.N) if w.where[i] == k and w.grasp[i] < 0 and i not in protect]
        if not free:
            return None
        cs, rs, _ = self.units(w, k, step, set(free))
        cs = list(cs) + [c for c, _ in keep_out]
        rs = list(rs) + [r for _, r in keep_out]
        for attempt in range(SEEDS):
            sol = self.place_in(k, list(new) + [float(self.radii[i]) for i in free], cs, rs, attempt)
            if sol is None:
                continue
            spots = sol[len(new):]
            trial = _World.__new__(_World)
            trial.ts, trial.pos, trial.where, trial.grasp = self.ts, w.pos.copy(), list(w.where), list(w.grasp)
            trial.rotation = dict(w.rotation)
            ops = []
            ok = True
            for i, p in zip(free, spots):
                if math.hypot(*(p - trial.pos[i])) < 1e-9:
                    continue
                if not self.path_ok(trial, i, k, p, set()):
                    ok = False
                    break
                trial.pos[i] = p
                ops.append(PlacedOp(OpKind.ROOM, None, i, k, (float(p[0]), float(p[1]))))
            if ok:
                w.pos[:] = trial.pos
                return sol[: len(new)], ops
        return None

    # ------------------------------------------------------------------------------------ primitives
    def release(self, w: _World, spec: StepSpec, step: int, robots: list[int], j: int) -> list[PlacedOp]:
        """Back-off spots for the robots releasing object j, one after the other, as near their grasp
        points as the rings allow, each reachable by a straight-leg path; if a robot is boxed in between
        its team and the rim, the team first moves inwards inside the region (a room move of the team)."""
        k = w.where[self.N + j]
        acts = {a.robot: a for a in spec.actions if isinstance(a, Release)}
        ops: list[PlacedOp] = []
        for attempt in range(2):
            found = self._backoffs(w, step, k, robots)
            if found is not None:
                for i, p in found:
                    w.pos[i] = p
                    w.grasp[i] = -1
                return ops + [PlacedOp(OpKind.RELEASE, acts[i], i, k, (float(p[0]), float(p[1]))) for i, p in found]
            if attempt == 0:
                move = self._team_inwards(w, step, k, j)
                if move is None:
                    break
                ops.append(move)
        raise PlacementError(f"{self.where_msg(spec, k)}: no room to back off for "
                             f"{', '.join(self.ts.robot_names[i] for i in robots)} after releasing "
                             f"{self.ts.object_names[j]}", spec, k)

    def _backoffs(self, w: _World, step: int, k: int, robots: list[int]) -> list | None:
        """Back-off spots of ``robots`` (None: no room); each keeps out of the covering disk of every team that
        carries an object out of region k while the robot stands there (:meth:`_departures`)."""
        saved_pos, saved_grasp = w.pos.copy(), list(w.grasp)
        out = []
        for i in robots:
            w.grasp[i] = -1
            ri = float(self.radii[i])
            cs, rs, _ = self.units(w, k, step, {i})
            keep = self._departures(w, k, step, i, -1)
            accept = self._passages(w, k, step, i, {i}, ri)
            p = None if accept is None else self.spot(k, ri, cs, rs, keep_clear=keep, near=w.pos[i], accept=accept)
            if p is None or not self.path_ok(w, i, k, p, set()):
                p = self.spot(k, ri, cs, rs, keep_clear=keep, near=w.pos[i])
            if p is None or not self.path_ok(w, i, k, p, set()):
                # the covering disks of the teams that leave while i stands there, as fixed disks of P_s
                cs_k = list(cs) + [c for c, _ in keep]
                rs_k = list(rs) + [d - ri - self.spacing for _, d in keep]
                sol = next((x for x in (self.place_in(k, [ri], cs_k, rs_k, n) for n in range(SEEDS))
                            if x is not None and self.path_ok(w, i, k, x[0], set())), None)
                if sol is None:
                    w.pos[:], w.grasp[:] = saved_pos, saved_grasp
                    return None
                p = sol[0]
            w.pos[i] = p
            out.append((i, p))
        w.pos[:], w.grasp[:] = saved_pos, saved_grasp
        return out

    def _move_teams(self, w: _World, step: int, k: int, movers: set[int], r: float, cs, keep_clear):
        """Room for an arrival of radius r by moving one team of region k inside it (a team carries its
        object to a spot as far out as it goes); returns (arrival spot, [room op]) or None."""
        for j in range(self.M):
            e = self.N + j
            team = w.team_of(j)
            if w.where[e] != k or not team or e in movers or (j, team) not in self.couplings:
                continue
            cover = self.ts.covering_radius(j, team)
            others_c, others_r, _ = self.units(w, k, step, movers | {e, *team}, self.occupied_until(e, step))
            new = self.spot(k, cover, others_c, others_r)
            if new is None:
                continue
            arrival = self.spot(k, r, list(others_c) + [new], list(others_r) + [cover],
                                [(c if not np.allclose(c, w.pos[e]) else new, d) for c, d in keep_clear])
            if arrival is None:
                continue
            try:
                local_path(w.pos[e], new, np.array(others_c, dtype=float).reshape(-1, 2),
                           np.asarray(others_r, dtype=float) + cover, self.centers[k], float(self.R[k] - cover))
            except ValueError:
                continue
            w.pos[[e, *team]] += new - w.pos[e]
            return arrival, [PlacedOp(OpKind.ROOM, None, e, k, (float(new[0]), float(new[1])),
                                      w.rotation.get(j, 0.0), team)]
        return None

    def _team_inwards(self, w: _World, step: int, k: int, j: int) -> PlacedOp | None:
        """Move the team of object j inside region k to the innermost free spot (its members then have
        room around it); None if there is none or no straight-leg path for the team."""
        e, team = self.N + j, w.team_of(j)
        if (j, team) not in self.couplings:
            return None
        cover = self.ts.covering_radius(j, team)
        cs, rs, es = self.units(w, k, step, {e, *team})
        best = None
        for rho in np.arange(0.0, self.R[k] - cover, 0.25):
            n = 1 if rho == 0.0 else int(min(180, max(12, math.ceil(2.0 * math.pi * rho / 0.1))))
            ang = np.arange(n) * (2.0 * math.pi / n)
            pts = self.centers[k] + rho * np.column_stack([np.cos(ang), np.sin(ang)])
            for p in pts[np.argsort(np.linalg.norm(pts - w.pos[e], axis=1), kind="stable")]:
                if all(math.hypot(*(p - np.asarray(c))) >= cover + r + self.spacing for c, r in zip(cs, rs)):
                    best = p
                    break
            if best is not None:
                break
        if best is None:
            return None
        centers = np.array(cs, dtype=float).reshape(-1, 2)
        try:
            local_path(w.pos[e], best, centers, np.asarray(rs, dtype=float) + cover, self.centers[k],
                       float(self.R[k] - cover))
        except ValueError:
            return None
        shift = best - w.pos[e]
        w.pos[[e, *team]] += shift
        return PlacedOp(OpKind.ROOM, None, e, k, (float(best[0]), float(best[1])), w.rotation.get(j, 0.0), team)

    def grasp(self, w: _World, spec: StepSpec, step: int, robots: list[int], j: int) -> list[PlacedOp]:
        ts, N = self.ts, self.N
        e = N + j
        k = w.where[e]
        team = self.next_team(j, step) or tuple(sorted(robots))
        if not set(robots) <= set(team):
            team = tuple(sorted(set(team) | set(robots)))
        docked = [i for i in w.team_of(j)]
        lay = grasp_layout(ts.object_radius[j], [ts.robot_radius[i] for i in team], ts.grasp_gap)
        cover = lay.covering_radius
        xo = w.pos[e]
        if docked and j in w.rotation:
            angles = [w.rotation[j]]
            stay = [i for i in docked if i in team and i not in robots]
            slots = layout_slots(ts, j, team, xo, angles[0])
            if stay and math.hypot(*(w.pos[stay[0]] - slots[team.index(stay[0])])) > DOCK_TOL:
                # the team changed: turn the new layout so that the first member that stays docked is on its slot
                q, d = slots[team.index(stay[0])] - xo, w.pos[stay[0]] - xo
                angles = [angles[0] + math.atan2(d[1], d[0]) - math.atan2(q[1], q[0])]
                slots = layout_slots(ts, j, team, xo, angles[0])
            for i in stay:  # a member that stays docked keeps its place: it must be the new layout's slot
                off = math.hypot(*(w.pos[i] - slots[team.index(i)]))
                if off > DOCK_TOL:
                    raise PlacementError(
                        f"{self.where_msg(spec, k)}: {ts.robot_names[i]} stays docked to {ts.object_names[j]} "
                        f"{off:.2f} m from its slot in the grasp layout of "
                        f"{'+'.join(ts.robot_names[m] for m in team)} (the executed team would be wider than the "
                        f"TS's)", spec, k, swap=j)
        else:  # no slot tucked against the rim; those of teammates that dock later face the region's centre
            angles = list(np.linspace(0.0, 2.0 * math.pi, _ANGLES, endpoint=False))
            later = [team.index(i) for i in team if i not in robots]

            def outer(rot):
                d = [math.hypot(*(q - self.centers[k])) for q in layout_slots(ts, j, team, xo, rot)]
                return (max(d[m] for m in later) if later else 0.0, max(d))
            angles.sort(key=outer)
            if j in w.preset:  # members standing on their slots from the start keep them
                angles.insert(0, w.preset.pop(j))
        members = set(team) | set(docked)
        ops: list[PlacedOp] = []
        acts = {a.robot: a for a in spec.actions if isinstance(a, Grasp)}
        for round_ in range(3):
            for rot in angles:
                slots = layout_slots(ts, j, team, xo, rot)
                if not self._slots_free(w, k, step, j, team, robots, slots, cover):
                    continue
                trial, trial_grasp = w.pos.copy(), list(w.grasp)
                for order in itertools.permutations(robots):  # docking order: whoever is boxed in goes first
                    ok = True
                    for i in order:
                        slot = slots[team.index(i)]
                        if not self.path_ok(w, i, k, slot, set(), anchor=j):
                            ok = False
                            break
                        w.pos[i], w.grasp[i] = slot, j
                    if ok:
                        w.rotation[j] = float(rot)
                        # a slot inside the covering disk of a team that leaves in this step: that robot, and
                        # whoever docks after it, docks once the team has left (grasps change no label)
                        late = [n for n, i in enumerate(order) if self._intruded(
                            w, k, step, j, slots[team.index(i)], float(self.radii[i]), step + 1)]
                        if late:
                            self.deferred.update((step, i) for i in order[late[0]:])
                        return ops + [PlacedOp(OpKind.GRASP, acts[i], i, k, tuple(map(float, w.pos[i])), float(rot),
                                               team) for i in order]
                    w.pos[:], w.grasp[:] = trial, trial_grasp
            if round_ == 0:  # free robots in the way move inside the region
                found = self.make_room(w, spec, step, k, [], [(xo, cover)], members)
                if found is not None:
                    ops += found[1]
            elif round_ == 1:  # another team in the way carries its object elsewhere inside the region
                moved = self._clear_disk_by_team(w, step, k, xo, cover, members | {e})
                if moved is None:
                    break
                ops.append(moved)
        for x in range(self.M):  # an ungrasped object in the way: the later of the two arrivals avoids the other
            ex = N + x
            if x == j or w.where[ex] != k or w.team_of(x):
                continue
            nxt = self.next_team(x, step)
            rx = ts.covering_radius(x, nxt) if nxt and self.first_grasp(x, step) <= self._next_transport(j, step) \
                else float(self.radii[ex])
            need = cover + rx + self.spacing
            if math.hypot(*(w.pos[ex] - xo)) < need:
                later, other = (ex, e) if w.placed[ex] >= w.placed[e] else (e, ex)
                self._hint(w, later, [(w.pos[other], need)])
        raise PlacementError(f"{self.where_msg(spec, k)}: no free grasp layout for "
                             f"{'+'.join(ts.robot_names[i] for i in team)} around {ts.object_names[j]}", spec, k)

    def _clear_disk_by_team(self, w: _World, step: int, k: int, center, radius: float,
                            keep: set[int]) -> PlacedOp | None:
        """Move one team of region k (not in ``keep``) inside it to a spot clear of the disk (center,
        radius) and of everything else, along a straight-leg path; None if no team can."""
        for j2 in range(self.M):
            e2, team2 = self.N + j2, w.team_of(j2)
            if w.where[e2] != k or not team2 or e2 in keep or (j2, team2) not in self.couplings:
                continue
            cover2 = self.ts.covering_radius(j2, team2)
            if math.hypot(*(w.pos[e2] - center)) >= cover2 + radius + self.spacing:
                continue
            cs, rs, _ = self.units(w, k, step, {e2, *team2})
            new = self.spot(k, cover2, list(cs) + [np.asarray(center)], list(rs) + [radius])
            if new is None:
                continue
            try:
                local_path(w.pos[e2], new, np.array(cs, dtype=float).reshape(-1, 2),
                           np.asarray(rs, dtype=float) + cover2, self.centers[k], float(self.R[k] - cover2))
            except ValueError:
                continue
            w.pos[[e2, *team2]] += new - w.pos[e2]
            return PlacedOp(OpKind.ROOM, None, e2, k, (float(new[0]), float(new[1])), w.rotation.get(j2, 0.0), team2)
        return None

    def _slots_free(self, w: _World, k: int, step: int, j: int, team, docking, slots: np.ndarray,
                    cover: float) -> bool:
        """Every slot inside the region; the team's covering disk clear of every entity outside the team
        (objects with their team disks, or the team disks reserved for teams that form before this one
        leaves); the slots of the robots docking now clear of every other robot."""
        sp, N = self.spacing, self.N
        xo = w.pos[N + j]
        for m, i in enumerate(team):
            if math.hypot(*(slots[m] - self.centers[k])) + float(self.radii[i]) + 0.5 * sp > self.R[k]:
                return False
        depart = self._next_transport(j, step)
        cs, rs, es = self.units(w, k, step, set(team) | {N + j})
        for c, r, b in zip(cs, rs, es):
            if self._leaves_by(b, step, depart):
                continue  # gone before the team sets off
            if math.hypot(*(np.asarray(c) - xo)) < cover + r + sp:
                return False
        for i in docking:
            q = slots[team.index(i)]
            for o in range(N):
                if o != i and o not in docking and w.where[o] == k:
                    if math.hypot(*(w.pos[o] - q)) < float(self.radii[o] + self.radii[i]) + sp:
                        return False
            if any(n > step for n in self._intruded(w, k, step, j, q, float(self.radii[i]), depart)):
                return False
        return True

    def _intruded(self, w: _World, k: int, step: int, j: int, q, r: float, until: float) -> list[int]:
        """Steps (from ``step`` up to ``until``, exclusive) at which a team carries another object out of
        region k while a robot of radius r docked at q (to object j) would be inside its covering disk: the
        team's start would lie outside its free space."""
        out = []
        for n, a in self.departures[k]:
            if step <= n < until and a.obj != j and w.where[self.N + a.obj] == k:
                need = self.ts.covering_radius(a.obj, a.team) + r + self.spacing
                if math.hypot(*(w.pos[self.N + a.obj] - np.asarray(q))) < need:
                    out.append(n)
        return out

    def arrive(self, w: _World, spec: StepSpec, step: int, a) -> list[PlacedOp]:
        ts, N = self.ts, self.N
        if isinstance(a, Navigate):
            e, movers, r, kind = a.robot, {a.robot}, float(self.radii[a.robot]), OpKind.NAVIGATE
        else:
            e, movers = N + a.obj, {N + a.obj, *a.team}
            r, kind = ts.covering_radius(a.obj, a.team), OpKind.TRANSPORT
        k = a.dst
        for m in movers:
            w.where[m] = -1  # departed
        cs, rs, es = self.units(w, k, step, movers, self.occupied_until(e, step))
        keep_clear = (self._separations(w, k, step, a) if isinstance(a, Transport)
                      else self._departures(w, k, step, e, spec.actions.index(a)))
        keep_clear += self.hints.get((e, step), [])
        future = self.future_units(w, step, k, e)
        docked = self._docked_separations(w, k, step, a) if isinstance(a, Transport) else []
        spot, ops = None, []
        accept = self._passages(w, k, step, e, movers, r)
        if accept is not None:  # first where the region's later trips keep their way out, with all the foresight
            spot = self.spot(k, r, cs, rs, keep_clear + [(c, d) for _, c, d in docked], future, accept=accept)
        for extra in (([(c, d) for _, c, d in docked], []) if docked else ([],)) if spot is None else ():
            for fut in ((future, future[:1], ()) if future else ((),)):
                spot = self.spot(k, r, cs, rs, keep_clear + extra, fut)
                if spot is not None:
                    break
            if spot is not None:
                break
            if extra:  # a docked robot would be in a later team's way: learn where earlier arrivals go
                self._learn_from_arrival(w, k, r, cs, rs, es, keep_clear, docked)
        if spot is None:
            found = self._move_teams(w, step, k, movers, r, cs, keep_clear)
            if found is not None:
                spot, ops = found
        if spot is None:
            found = self.make_room(w, spec, step, k, [r], [], movers)
            if found is None or not self._object_clear(a, found[0][0], keep_clear):
                self._learn_from_arrival(w, k, r, cs, rs, es, keep_clear)
                entity_names = ts.robot_names + ts.object_names
                nearby = ", ".join(entity_names[x] for x in self.units(w, k, step, movers)[2]) or "nothing"
                raise PlacementError(f"{self.where_msg(spec, k)}: no room for "
                                     f"{ts.format_action(a, 'names')} (radius {r:.2f} m) next to {nearby}", spec, k)
            spot, ops = found[0][0], found[1]
        rot = 0.0
        if isinstance(a, Transport):  # the members move rigidly with the object
            rot = w.rotation.get(a.obj, 0.0)
            offsets = w.pos[list(a.team)] - w.pos[e]
            w.pos[list(a.team)] = spot + offsets
        w.pos[e] = spot
        w.placed[e] = step
        for m in movers:
            w.where[m] = k
        return ops + [PlacedOp(kind, a, e, k, (float(spot[0]), float(spot[1])), rot, tuple(getattr(a, "team", ())))]

    def _hint(self, w: _World, x: int, items: Sequence[tuple[np.ndarray, float]]) -> None:
        """Learn (centre, distance) pairs for the arrival that put entity x where it is; raises _Retry when
        one of them is new (at most 8 per arrival)."""
        known = self.hints.setdefault((x, w.placed[x]), [])
        if self.current is not None:
            self.taught_by.setdefault((x, w.placed[x]), self.current)
        new = False
        for center, dist in items:
            if any(np.allclose(c, center) and d >= dist for c, d in known) or len(known) >= 8:
                continue
            known.append((np.array(center, dtype=float), float(dist)))
            new = True
        if new:
            raise _Retry()

    def _learn_from_arrival(self, w: _World, k: int, r: float, cs, rs, es, keep_clear,
                            docked: Sequence[tuple[int, np.ndarray, float]] = ()) -> None:
        """An arrival found no room (with the ``docked`` constraints of :meth:`_docked_separations`): if it
        would fit without one ungrasped object that an earlier arrival put there, that arrival must keep the
        object off the spot found and off the docked robots' slots there (hints), and the run is placed again
        (raises _Retry); otherwise nothing is learned."""
        for x in es:
            if x < self.N or w.team_of(x - self.N):
                continue
            keep = [(c, d) for c, d in keep_clear if not np.allclose(c, w.pos[x])]
            keep += [(c, d) for y, c, d in docked if y != x]
            rest = [(c, q) for c, q, y in zip(cs, rs, es) if y != x]
            p = self.spot(k, r, [c for c, _ in rest], [q for _, q in rest], keep)
            if p is None:
                continue
            need = max([d for c, d in keep_clear if np.allclose(c, w.pos[x])] +
                       [r + float(rs[es.index(x)]) + self.spacing])
            self._hint(w, x, [(p, need)] + [(p + w.pos[x] - c, d) for y, c, d in docked if y == x])

    def _leaves_by(self, e: int, step: int, last: float) -> bool:
        """Does entity e leave its region in a step from ``step`` up to ``last`` (exclusive)?"""
        n = step
        while n < min(last, len(self.steps)):
            for a in self.steps[n].actions:
                if isinstance(a, Navigate) and a.robot == e:
                    return True
                if isinstance(a, Transport) and (a.obj == e - self.N or e in a.team):
                    return True
            n += 1
        return False

    def _next_transport(self, j: int, step: int) -> float:
        """First executed step after ``step`` that carries object j on (inf: none)."""
        for n in range(step + 1, len(self.steps)):
            if any(isinstance(b, Transport) and b.obj == j for b in self.steps[n].actions):
                return n
        return math.inf

    def _separations(self, w: _World, k: int, step: int, a: Transport) -> list[tuple[np.ndarray, float]]:
        """(centre, distance) the arriving object must keep from every other object X in region k, since
        neither moves between its transports: the covering disk of a team of X (its team now, or its next
        one, formed while the arriving object is there) must keep out the arriving object's body, and the
        arriving object's next team must keep out X's body."""
        sp, N = self.spacing, self.N
        leave_a = self._next_transport(a.obj, step)
        ra = float(self.radii[N + a.obj])
        nxt_a, g_a = self.next_team(a.obj, step + 1), self.first_grasp(a.obj, step + 1)
        out = []
        for j in range(self.M):
            e = N + j
            if j == a.obj or w.where[e] != k:
                continue
            leave_x = self._next_transport(j, step)
            need = 0.0
            team = w.team_of(j)
            if team:
                need = max(need, self.ts.covering_radius(j, team) + ra + sp)
            nxt, g = self.next_team(j, step), self.first_grasp(j, step)
            if nxt and g <= leave_a:
                need = max(need, self.ts.covering_radius(j, nxt) + ra + sp)
            if nxt_a and g_a <= leave_x:
                need = max(need, self.ts.covering_radius(a.obj, nxt_a) + float(self.radii[e]) + sp)
            if need > 0.0:
                out.append((w.pos[e], need))
        return out

    def _passages(self, w: _World, k: int, step: int, e: int, movers: set[int], r: float):
        """A predicate of a spot for entity e (radius r) parked in region k from executed step ``step`` until
        it acts again: every trip from or to region k meanwhile (entity radius R) still connects its start
        (where it stands, for a departure; region k's seat, for an arrival) with the seat of its other region
        in the static travel space minus the disks of the entities in region k grown by R.  A spot beside a
        door may cut the door off for a team (corridor map: a robot parked 2.4 m inside the door of room S1
        left the team that formed in the room no way out).  None when no trip needs the check."""
        N, M, sp = self.N, self.M, self.spacing
        until = self._acts_at(e, step)[0] if e < N else self._next_transport(e - N, step)
        trips = []
        for n in range(max(step, 0), int(min(until, len(self.steps) - 1)) + 1):
            for a in self.steps[n].actions:
                if isinstance(a, Navigate):
                    body, R, x = {a.robot}, float(self.radii[a.robot]), a.robot
                elif isinstance(a, Transport):
                    body, R, x = {N + a.obj, *a.team}, self.ts.covering_radius(a.obj, a.team), N + a.obj
                else:
                    continue
                if body & (movers | {e}) or k not in (a.src, a.dst):
                    continue
                other = a.dst if a.src == k else a.src
                space = self.ts.region_graph.travel_space(R, k, other)
                if space is None:
                    continue
                seats = [Point(*self.centers[g]).buffer(max(float(self.R[g]) - R, 1e-3)) for g in (k, other)]
                src = Point(*w.pos[x]).buffer(1e-3) if a.src == k and w.where[x] == k else seats[0]
                stay = [(w.pos[y].copy(), float(self.radii[y])) for y in range(N + M)
                        if w.where[y] == k and y not in body and y not in movers and y != e]
                trips.append((R, space, src, seats[1], stay))
        if not trips:
            return None

        def ok(p) -> bool:
            for R, space, src, dst, stay in trips:
                if space.boundary.distance(Point(*p)) > r + R + sp:
                    continue  # a disk that does not reach the boundary cannot cut the space
                rest = space.difference(unary_union([Point(*c).buffer(rr + R) for c, rr in [*stay, (p, r)]]))
                if not any(q.intersects(src) and q.intersects(dst) for q in getattr(rest, "geoms", [rest])):
                    return False
            return True
        return ok

    def _acts_at(self, i: int, step: int) -> tuple[float, int]:
        """(executed step, position) of robot i's next action after ``step``; a grasp or release counts as
        position −1, since within a step they run before the region-changing actions ((inf, 0): none)."""
        for n in range(step + 1, len(self.steps)):
            for pos, b in enumerate(self.steps[n].actions):
                if isinstance(b, (Grasp, Release)) and b.robot == i:
                    return n, -1
                if (isinstance(b, Navigate) and b.robot == i) or (isinstance(b, Transport) and i in b.team):
                    return n, pos
        return math.inf, 0

    def _departures(self, w: _World, k: int, step: int, i: int, after: int) -> list[tuple[np.ndarray, float]]:
        """(centre, distance) robot i arriving in region k (action ``after`` of executed step ``step``) must keep
        from every object there whose team carries it out of k while i still stands at its arrival spot
        (before i's next action, in execution order): that transport starts as a disk of the team's covering
        radius in the controllers' free space, which must be clear of i's body (gen_n4_m2_k3_s2: r2 parked
        1.93 m from o2, inside the 1.92 m covering disk of r1's team, which then could not leave before r2)."""
        sp, N = self.spacing, self.N
        until = self._acts_at(i, step)
        out = []
        for j in range(self.M):
            if w.where[N + j] != k:
                continue
            leave = next(((n, pos, b) for n in range(step, len(self.steps))
                          for pos, b in enumerate(self.steps[n].actions)
                          if isinstance(b, Transport) and b.obj == j and (n > step or pos > after)), None)
            if leave is not None and i not in leave[2].team and leave[:2] < until:
                cover = self.ts.covering_radius(j, tuple(leave[2].team))
                out.append((w.pos[N + j], cover + float(self.radii[i]) + sp))
        return out

    def _undocked(self, i: int, j: int, step: int) -> float:
        """First executed step after ``step`` at which robot i, docked to object j, leaves its slot: its
        release of j or j's next transport (inf: never)."""
        for n in range(step + 1, len(self.steps)):
            for b in self.steps[n].actions:
                if isinstance(b, (Release, Transport)) and b.obj == j and getattr(b, "robot", i) == i:
                    return n
        return math.inf

    def _team_forms(self, j: int, step: int) -> tuple[tuple[int, ...] | None, float]:
        """(team, step) of object j's next transport after executed step ``step``: its team and the executed
        step from which its covering disk stands (its first grasp after ``step``, or ``step`` when no robot
        joins before it leaves); (None, inf) if j is not carried on."""
        team, leave = self.next_team(j, step + 1), self._next_transport(j, step)
        if team is None:
            return None, math.inf
        g = self.first_grasp(j, step + 1)
        return team, (g if g <= leave else step)

    def _docked_separations(self, w: _World, k: int, step: int,
                            a: Transport) -> list[tuple[int, np.ndarray, float]]:
        """(entity, centre, distance) the arriving object must keep for robots that stay docked in region k,
        which move only with their object: the covering disk of a team of another object X (standing now, or
        forming while the robot is still docked) must keep out the body of a docked robot not in that team.
        For a member of the arriving team the constraint is on its slot, the object's spot plus the member's
        rigid offset, so its centre is shifted by that offset; ``entity`` is X for these, the docked robot for
        the arriving object's own next team."""
        sp, N = self.spacing, self.N
        out = []
        for i in a.team:
            until, ri = self._undocked(i, a.obj, step), float(self.radii[i])
            offset = w.pos[i] - w.pos[N + a.obj]
            for j in range(self.M):
                if j == a.obj or w.where[N + j] != k:
                    continue
                covers = []
                team = w.team_of(j)
                if team and i not in team:
                    covers.append(self.ts.covering_radius(j, team))
                nxt, forms = self._team_forms(j, step)
                if nxt and i not in nxt and forms < until:
                    covers.append(self.ts.covering_radius(j, nxt))
                if covers:
                    out.append((N + j, w.pos[N + j] - offset, max(covers) + ri + sp))
        nxt, forms = self._team_forms(a.obj, step)
        if nxt:
            cover = self.ts.covering_radius(a.obj, nxt)
            for i in range(N):
                j = w.grasp[i]
                if j < 0 or j == a.obj or w.where[i] != k or i in nxt or self._undocked(i, j, step) <= forms:
                    continue
                out.append((i, w.pos[i], cover + float(self.radii[i]) + sp))
        return out

    def _object_clear(self, a, spot: np.ndarray, keep_clear: list[tuple[np.ndarray, float]]) -> bool:
        return all(math.hypot(*(spot - c)) >= d for c, d in keep_clear)

    # ------------------------------------------------------------------------------------ the run
    def seated(self, state: tuple, k: int) -> dict[int, int]:
        """Robots of region k at the start that take a slot of an object's reserved team disk there:
        robot -> object, for every free robot in the next transport team of an ungrasped object in region k
        (the object whose grasp by it comes first).  The disk covers its members' slots, so a member standing
        on its slot takes no room beyond the disk (P_s counts a formed team as its covering disk alone)."""
        N, M = self.N, self.M
        first: dict[tuple[int, int], int] = {}
        for n, spec in enumerate(self.steps):
            for a in spec.actions:
                if isinstance(a, Grasp):
                    first.setdefault((a.robot, a.obj), n)
        grasped = {int(g) for g in state[N + M:] if g >= 0}
        out = {}
        for i in range(N):
            if state[i] != k or state[N + M + i] >= 0:
                continue
            objs = [j for j in range(M) if state[N + j] == k and j not in grasped
                    and i in (self.next_team(j, 0) or ())]
            if objs:
                out[i] = min(objs, key=lambda j: (first.get((i, j), math.inf), j))
        return out

    def seat(self, pos: np.ndarray, k: int, j: int, seated: dict[int, int]) -> None:
        """Put the seated robots of object j on the slots of its next team's layout around its position,
        rotated so that the slots of the members that come later face the region's centre (most room to
        dock), and keep the rotation for its first grasp."""
        team = self.next_team(j, 0)
        xo = pos[self.N + j]
        here = [i for i in team if seated.get(i) == j]
        if not here:
            return
        later = [team.index(i) for i in team if i not in here]

        def outer(rot):
            d = [math.hypot(*(q - self.centers[k])) for q in layout_slots(self.ts, j, team, xo, rot)]
            return (max(d[m] for m in later) if later else 0.0, max(d))

        rot = min(np.linspace(0.0, 2.0 * math.pi, _ANGLES, endpoint=False), key=outer)
        slots = layout_slots(self.ts, j, team, xo, rot)
        for i in here:
            pos[i] = slots[team.index(i)]
        self.preset[j] = float(rot)

    def initial(self, state: tuple) -> np.ndarray:
        """P_s layout of the initial state, every ungrasped object with its future team's disk (the members
        in the region on their slots, :meth:`seated`), leaving room (foresight) for what the plan brings into
        the region while its objects are still there.  (The reserved disk is where the object's transport
        starts, so its free space needs it clear of walls, obstacles and other regions.)"""
        N, M = self.N, self.M
        pos = np.zeros((N + M, 2))
        self.preset = {}
        w = _World(self.ts, state, pos)
        for k in range(self.K):
            everyone = [e for e in range(N + M) if state[e] == k]
            if not everyone:
                continue
            seated = self.seated(state, k)
            while True:  # a robot of an object whose team disk is dropped is placed on its own, not seated
                ents = [e for e in everyone if e not in seated]
                radii = []
                for e in ents:
                    nxt = self.next_team(e - N, 0) if e >= N else None
                    radii.append(self.ts.covering_radius(e - N, nxt) if nxt else float(self.radii[e]))
                future = max((self.future_units(w, -1, k, e) for e in ents if e >= N), default=[],
                             key=lambda u: sum(x * x for x in u))
                if any((e, -1) in self.hints for e in everyone):  # learned: one entity after the other, hints kept
                    order = sorted(range(len(ents)), key=lambda n: -radii[n])
                    cs, rs = [], []
                    for n in order:
                        p = self.spot(k, radii[n], cs, rs, self.hints.get((ents[n], -1), []))
                        if p is None:
                            need = self.taught_by.get((ents[n], -1))
                            later = "later steps need" if need is None else f"step {need.index} needs"
                            raise PlacementError(f"initial state: region '{self.ts.region_names[k]}': no layout "
                                                 f"keeps the room {later}", need, k)
                        pos[ents[n]] = p
                        cs.append(p)
                        rs.append(radii[n])
                    for j in sorted(set(seated.values())):
                        self.seat(pos, k, j, seated)
                    sol = None
                    break
                sol = None
                for n in range(len(future), -1, -1):
                    for attempt in range(SEEDS if n == 0 else 2):
                        sol = self.place_in(k, radii + future[:n], [], [], attempt)
                        if sol is not None:
                            sol = sol[: len(radii)]
                            break
                    if sol is not None:
                        break
                # teams that form one after another need not all fit at once: reserve the disks of the objects
                # grasped first only (each later grasp checks its disk when it forms)
                later = sorted((n for n, e in enumerate(ents) if e >= N and radii[n] > self.radii[e]),
                               key=lambda n: (-self.first_grasp(ents[n] - N, 0), ents[n]))
                dropped: list[int] = []
                for drop in range(1, len(later) + 1):
                    if sol is not None:
                        break
                    fewer = list(radii)
                    dropped = later[:drop]
                    for n in dropped:
                        fewer[n] = float(self.radii[ents[n]])
                    for attempt in range(SEEDS):
                        sol = self.place_in(k, fewer, [], [], attempt)
                        if sol is not None:
                            break
                if sol is not None and dropped:
                    sol = self._formable_layout(k, ents, radii, dropped, sol)
                if sol is None:
                    who = ", ".join((self.ts.robot_names + self.ts.object_names)[e] for e in everyone)
                    raise PlacementError(f"initial state: region '{self.ts.region_names[k]}': the entities {who} "
                                         "with the team disks of their objects do not fit", None, k)
                lone = {i for i, j in seated.items() if any(ents[n] == N + j for n in dropped)}
                if not lone:
                    break
                seated = {i: j for i, j in seated.items() if i not in lone}
            if sol is None:
                continue  # placed one entity after the other (hints)
            pos[ents] = sol
            for j in sorted(set(seated.values())):
                self.seat(pos, k, j, seated)
        return pos

    def formable(self, k: int, j: int, xo) -> bool:
        """Whether the next team of object j can form around it at ``xo`` in region k and set off from there:
        its transport's start lies in its free space (:func:`starts_clear`), and some rotation of its layout
        (the angles a grasp tries) puts every slot inside the region with half the spacing to the rim."""
        carry = self.next_carry(j, 0)
        if carry is None:
            return True
        if not starts_clear(self.ts, carry, xo):
            return False
        team = tuple(carry.team)
        reach = np.array([self.R[k] - float(self.radii[i]) - 0.5 * self.spacing for i in team])
        for rot in np.linspace(0.0, 2.0 * math.pi, _ANGLES, endpoint=False):
            slots = layout_slots(self.ts, j, team, xo, rot)
            if np.all(np.linalg.norm(slots - self.centers[k], axis=1) <= reach):
                return True
        return False

    def _formable_layout(self, k: int, ents: list[int], radii: list[float], dropped: list[int],
                         sol: np.ndarray) -> np.ndarray:
        """The initial layout ``sol`` of region k, or, when an object whose team disk was dropped (its team
        forms after others) stands where that team cannot form or set off (:meth:`formable`), one that first
        puts every object with its kept disk, then each dropped object where its team can, clear of those
        disks, then the rest (when that fails too, ``sol`` is returned: the grasp, or the start check of
        :func:`unreachable_arrival`, reports the failure)."""
        N = self.N
        if all(self.formable(k, ents[n] - N, sol[n]) for n in dropped):
            return sol
        kept = sorted((n for n, e in enumerate(ents) if e >= N and n not in dropped), key=lambda n: -radii[n])
        out, cs, rs = np.zeros((len(ents), 2)), [], []
        for n in kept + dropped:  # each as far out as it goes, the dropped ones where their teams can form
            j = ents[n] - N
            r = radii[n] if n in kept else float(self.radii[ents[n]])
            p = self.spot(k, r, cs, rs, accept=None if n in kept else lambda q, j=j: self.formable(k, j, q))
            if p is None:
                return sol
            out[n] = p
            cs.append(p)
            rs.append(r)
        rest = [n for n in range(len(ents)) if n not in kept and n not in dropped]
        for attempt in range(SEEDS if rest else 0):
            part = self.place_in(k, [radii[n] for n in rest], cs, rs, attempt)
            if part is not None:
                out[rest] = part
                return out
        return out if not rest else sol

    def run(self, initial: np.ndarray) -> Placement:
        w = _World(self.ts, self.steps[0].src if self.steps else self.ts.initial, initial)
        w.preset = dict(self.preset)
        self.deferred = set()
        out = []
        for step, spec in enumerate(self.steps):
            self.current = spec
            ops: list[PlacedOp] = []
            releases: dict[int, list[int]] = {}
            grasps: dict[int, list[int]] = {}
            for a in spec.actions:
                if isinstance(a, Release):
                    releases.setdefault(a.obj, []).append(a.robot)
                elif isinstance(a, Grasp):
                    grasps.setdefault(a.obj, []).append(a.robot)
            for j, robots in releases.items():
                ops += self.release(w, spec, step, robots, j)
            late: list[PlacedOp] = []
            for j, robots in grasps.items():
                for op in self.grasp(w, spec, step, robots, j):
                    (late if op.kind is OpKind.GRASP and (step, op.entity) in self.deferred else ops).append(op)
            for a in spec.actions:
                if isinstance(a, (Navigate, Transport)):
                    ops += self.arrive(w, spec, step, a)
            ops += late
            out.append(StepPlacement(spec, tuple(ops), tuple(map(tuple, w.pos.tolist()))))
        return Placement(tuple(map(tuple, initial.tolist())), tuple(out))


#: Half the narrowest gap (m) beside a parked entity that a moving entity's centre is given (at most half the
#: mover's radius): the executor finds its way around parked entities on grids of 0.25 m
#: (``control/windows.py``), and a thinner gap between a parked robot and a wall (two robots parked across a
#: corridor end, 0.22 m left for the third) passes the bare geometry but leaves the motion nowhere to go.
#: Passages between walls, obstacles and regions alone keep the control margin instead, as in the TS.
GAP_HALF_WIDTH = 0.25


def _passes(space, disks, start, goal, mover_radius: float) -> bool:
    """Does ``space`` minus the ``disks`` (centre, radius) join ``start`` and ``goal`` where the gaps beside the
    disks are at least twice the half width h = min(:data:`GAP_HALF_WIDTH`, mover radius / 2) wide?  The set
    kept is the morphological opening of the rest by h (thin parts removed) together with the rest farther
    than 2 h from every disk (passages of the static space alone stay as the TS has them); an end joins a
    part of it within h (an end keeps only the layout spacing from its neighbours)."""
    h = min(GAP_HALF_WIDTH, 0.5 * mover_radius)
    if not disks:
        rest = space
    else:
        near = unary_union([Point(*c).buffer(r + 2.0 * h) for c, r in disks])
        rest = space.difference(unary_union([Point(*c).buffer(r) for c, r in disks]))
        rest = rest.buffer(-h).buffer(h).union(rest.difference(near))
    reach = h + 1e-6
    p0, p1 = Point(*start), Point(*goal)
    return any(q.distance(p0) <= reach and q.distance(p1) <= reach for q in getattr(rest, "geoms", [rest])
               if not q.is_empty)


def trip_space(ts: TransitionSystem, a: Navigate | Transport):
    """(radius, static travel space) of a navigation (the robot's radius) or a transport (its team's travel
    radius): the component of the travel space between its regions (paper Sec. III-A: walls, obstacles and the
    other regions grown by radius + ``control.margin``), None when there is none."""
    R = float(ts.robot_radius[a.robot]) if isinstance(a, Navigate) else ts.travel_radius(a.obj, tuple(a.team))
    return R, ts.region_graph.travel_space(R, a.src, a.dst)


def starts_clear(ts: TransitionSystem, a: Navigate | Transport, start) -> bool:
    """Whether navigation or transport ``a`` can set off from ``start``: its static travel space
    (:func:`trip_space`) contains it, as the controllers' free space must contain the start (a team's disk
    there keeps its travel radius + ``control.margin`` from walls, obstacles and other regions)."""
    space = trip_space(ts, a)[1]
    return space is not None and bool(space.contains(Point(*np.asarray(start, dtype=float))))


def unreachable_arrival(ts: TransitionSystem, placement: Placement) -> PlacementError | None:
    """The first navigation or transport of the placed run whose start is not in the free space of the moving
    entity (:func:`starts_clear`) or whose goal that free space does not connect with its start (the
    sequencer's test, paper Sec. III-A: walls, obstacles and the other regions grown by radius +
    ``control.margin``, the other entities' bodies by the radius), as a PlacementError naming the step; None
    when every arrival is reachable."""
    N = ts.N
    radii = np.array(list(ts.robot_radius) + list(ts.object_radius), dtype=float)
    X = np.array(placement.initial, dtype=float)
    for sp_ in placement.steps:
        end = np.array(sp_.positions, dtype=float)
        for op in sp_.ops:
            if op.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT):
                a = op.action
                movers = {a.robot} if isinstance(a, Navigate) else {N + a.obj, *a.team}
                R, space = trip_space(ts, a)
                start, goal = X[op.entity], np.asarray(op.goal, dtype=float)
                disks = [(X[e], radii[e] + R) for e in range(len(X)) if e not in movers]
                who = ts.format_action(a, "names")
                if space is not None and not space.contains(Point(*start)):
                    return PlacementError(
                        f"step {sp_.step.index} (plan step {sp_.step.plan_step}): region "
                        f"'{ts.region_names[a.src]}': the start ({start[0]:.3f}, {start[1]:.3f}) of {who} is "
                        f"not in its free space (radius {R:.2f} m + {ts.margin:g} m margin to walls, obstacles "
                        f"and other regions)", sp_.step, a.src)
                if space is None or not _passes(space, disks, start, goal, R):
                    return PlacementError(
                        f"step {sp_.step.index} (plan step {sp_.step.plan_step}): region "
                        f"'{ts.region_names[a.dst]}': the goal ({goal[0]:.3f}, {goal[1]:.3f}) of {who} is "
                        f"separated from its start by the entities in the way (radius {R:.2f} m; gaps beside them "
                        f"narrower than {2 * min(GAP_HALF_WIDTH, 0.5 * R):.2f} m closed)", sp_.step, a.dst)
                for e in movers:
                    X[e] = end[e]
            else:
                X[op.entity] = op.goal
        X = end
    return None


#: Whole-run attempts of :func:`place_run` (greedy placement with different orders of candidate spots).
ATTEMPTS = 4
#: Re-placements of one attempt after a learned hint (an earlier arrival keeps off a spot a later step needs).
RETRIES = 40


def place_run(ts: TransitionSystem, steps: Sequence[StepSpec], seed: int = 0,
              initial: np.ndarray | None = None, attempts: int = ATTEMPTS) -> Placement:
    """Every goal, grasp and back-off point of the executed run ``steps`` (module docstring); ``initial``
    positions default to a P_s layout of the initial state that reserves the future team disks.  The run is
    placed greedily in execution order.  When a step finds no room because an earlier arrival (or the
    initial layout) put an ungrasped object in the way, that arrival learns to keep off the spot the step
    needs and the run is placed again (up to :data:`RETRIES` times); when nothing can be learned, the whole
    run starts over with another order of candidate spots (:meth:`_Placer.restart`), up to ``attempts``
    times.  The first failure is reported."""
    placer = _Placer(ts, steps, seed)
    state = steps[0].src if steps else ts.initial
    first: PlacementError | None = None
    for variant in range(max(1, attempts)):
        placer.restart(variant)
        for _ in range(RETRIES):
            try:
                pos = placer.initial(state) if initial is None else np.asarray(initial, dtype=float)
                placed = placer.run(pos)
                blocked = unreachable_arrival(ts, placed)
                if blocked is not None:
                    raise blocked
                return placed
            except _Retry:
                continue
            except PlacementError as exc:
                first = first or exc
                break
    raise first


def place_plan(plan, suffix_cycles: int = 1, seed: int = 0) -> Placement:
    """:func:`place_run` of the plan's executed run: the prefix and ``suffix_cycles`` suffix cycles."""
    return place_run(plan.ts, expand_steps(plan, suffix_cycles), seed=seed)
