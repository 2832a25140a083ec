"""Concurrent execution of a placed run: the job dependency graph and the corridors of concurrent motions
(pure Python, no Drake; beyond the paper, whose Sec. III-A moves one entity at a time).

Every placed primitive of the whole executed run is a :class:`Job`.  A job may start once its predecessors
are done; the predecessors of job j are the earlier jobs (in the sequential order) that

* share a body with it (robot, object, team member: one controller per body, and a grasp docks at the
  object's actual position);
* share a region with it (source, destination, or the region of a release, grasp or room move: the spots
  of the placement were chosen one primitive after another, each seeing the earlier ones where they end),
  unless both are navigations or transports whose spots in every region they share keep the layout spacing
  (:func:`motion_spots`: where each starts in its source and ends in its destination), so that each spot is
  free whichever runs first;
* or are *visible* to the task (a region-changing action some crossing of which AP_φ sees) and precede it
  in the chain of visible jobs.  Consecutive visible actions of one TS step form one *group* when every
  interleaving of all their crossings still reaches the plan's NBA state
  (:meth:`~mrodrake.planning.semantics.ExecutedWords.concurrent_reach`); groups run one after another in
  the sequential order.  Jobs AP_φ cannot see change no letter, so the executed word of any concurrent run
  is a word of the sequential semantics, read with the same monitor.

Corridors keep the paper's proof (Theorem 1 is for one mover among static obstacles).  The motions
(navigations, transports) that are ready at one tick ask together (:func:`assign_corridors`).  One motion
and nothing else moving: it runs on its whole free space F, and no other motion starts until it ends.
Otherwise the floor not held by running motions is split into the Voronoi cells of the askers' grid routes
and spot disks; each motion gets its cell shrunk by its covering radius r, the margin and :data:`GAP` (its
centre positions), if that still connects its start to its goal and holds each of its two regions (with or
without its approach ring) or, in a region it shares with another motion, the disk of radius
:data:`SPOT_LEG` around its start (goal), in which its exit (settle) legs then run.  Its point-world map is
built on F ∩ corridor, a static free space: Theorem 1 applies to it alone, its bodies stay inside the cell
(the map's margin covers the map's numerical error, as for walls), and cells are disjoint, so no two
concurrent bodies meet.  Motions that get no corridor ask again when a job ends or after a while; then the
corridors of the running motions on the point-world law may be drawn again together with theirs
(:func:`redraw_corridors`), each running motion's route starting where it is, so the floor it has left behind
(a door it has passed) goes to the others: its law restarts there on F ∩ its new corridor, a static free space
that holds its bodies, so Theorem 1 applies again from there.  A motion settling in its destination on local
legs holds only the disk of their rim.  Releases, grasps and room moves stay inside their region, which no
other running job touches, and every motion's F keeps r + margin off the regions other than its own two.  Two
motions that share a region run in it inside their own cells: the point-world law on F ∩ corridor, the local
legs in their spot disks, which the cells hold.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np
import shapely
from shapely.errors import GEOSException
from shapely.geometry import LineString, Point, Polygon

from mrodrake.control.windows import grid_path
from mrodrake.geometry import DISK_QUAD_SEGS
from mrodrake.planning.placement import OpKind, PlacedOp, Placement, layout_slots
from mrodrake.planning.semantics import bodies
from mrodrake.planning.steps import StepSpec
from mrodrake.ts import TransitionSystem

#: Grid steps (m) tried in turn for a concurrent motion's route.
ROUTE_STEPS = (1.0, 0.5)
#: Spacing (m) of the route points whose Voronoi cells split the floor between concurrent motions.
ROUTE_SAMPLE = 1.0
#: Extra gap (m) between the bodies' corridors of concurrent motions (polygon rounding).
GAP = 0.05
#: Radius (m) of the disk of centre positions around its start (its goal) in which a navigation or transport
#: runs its exit (settle) legs when its corridor holds that disk but not its source (destination) region.
SPOT_LEG = 1.0
#: Width (m) on each side of a motion's route within which a corridor drawn again must leave the motion's free
#: space whole (:func:`squeezes`).
ROUTE_SIDE = 2.0
#: Area (m²) of the free space near its route a corridor may cut off (polygon rounding).
SQUEEZE_AREA = 0.01
#: Most bodies whose crossings one task group may interleave (bounds the crossing lattice, 3^bodies nodes).
GROUP_BODIES = 8


class Execution(Enum):
    """How the sequencer runs a placed run: one primitive at a time (the paper), or every job as soon as its
    predecessors are done."""

    SEQUENTIAL = "sequential"
    CONCURRENT = "concurrent"


@dataclass(frozen=True)
class Job:
    """One placed primitive of the run: ``uid`` (position in the sequential order), ``step`` (index of its
    executed step), the bodies and regions it uses, its task group (−1: AP_φ cannot see it) and the uids of
    its predecessors."""

    uid: int
    step: int
    op: PlacedOp
    bodies: frozenset
    regions: frozenset
    group: int
    preds: tuple[int, ...]

    @property
    def visible(self) -> bool:
        return self.group >= 0

    @property
    def moves_between_regions(self) -> bool:
        return self.op.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT)


@dataclass(frozen=True)
class Corridor:
    """Where a concurrent motion may go: ``confine`` holds its centre positions (intersected with its free
    space; None: all of it, for a motion that runs alone), ``body`` everything its bodies may cover
    (``confine`` grown by the covering radius and the margin, and the approach disks it uses; the whole
    floor for a motion alone); ``rings``: whether it may use the approach ring of its source and of its
    destination (else its local legs stay inside the region); ``spots``: whether its local legs in its source
    (destination) stay in the disk of radius :data:`SPOT_LEG` around its start (goal) instead, the corridor
    holding that disk but not the region (a region shared with another motion running at the same time)."""

    confine: Polygon | None
    body: Polygon
    rings: tuple[bool, bool] = (True, True)
    spots: tuple[bool, bool] = (False, False)


def op_bodies(ts: TransitionSystem, op: PlacedOp) -> frozenset:
    """Entities (robots 0..N−1, objects N..) a primitive moves or holds."""
    a = op.action
    if op.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT):
        return frozenset(bodies(ts, a))
    if op.kind in (OpKind.GRASP, OpKind.RELEASE):
        return frozenset((a.robot, ts.N + a.obj))
    return frozenset((op.entity, *op.team))


def op_regions(op: PlacedOp) -> frozenset:
    if op.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT):
        return frozenset((op.action.src, op.action.dst))
    return frozenset((op.region,))


def task_groups(words, spec: StepSpec, actions: Sequence) -> list[list[int]]:
    """Indices (into ``actions``, the step's visible actions in execution order) grouped greedily: the next
    action joins the current group while every interleaving of every group's crossings still reaches the
    step's planned NBA state from its source state.  Steps between word families (universal planner) keep
    one action per group."""
    if not actions:
        return []
    if not isinstance(spec.src_q, int) or not isinstance(spec.dst_q, int):
        return [[i] for i in range(len(actions))]
    groups: list[list[int]] = [[0]]
    for i in range(1, len(actions)):
        trial = [g[:] for g in groups]
        trial[-1].append(i)
        if _fits(words, trial[-1], actions) and _reaches(words, spec, spec, [[actions[k] for k in g] for g in trial]):
            groups = trial
        else:
            groups.append([i])
    return groups


def _fits(words, group, actions) -> bool:
    return sum(len(words.crossings(actions[k])) for k in group) <= GROUP_BODIES


def _reaches(words, first: StepSpec, last: StepSpec, groups) -> bool:
    F = words.concurrent_reach(first.src_q, first.src, groups)
    return all(S >> last.dst_q & 1 for S in F)


@dataclass(frozen=True)
class TaskOrder:
    """The order the task needs: the group of every visible op (``group[(step, op index)]``, numbered along
    the run) and the last step of every step's *block* (consecutive steps whose visible actions all AP_φ sees
    interleave across their boundaries; the monitor checks the plan's NBA state at block ends)."""

    group: dict
    block_end: tuple[int, ...]


def task_order(words, placement: Placement) -> TaskOrder:
    """Groups within each step (:func:`task_groups`); then the last group of a block and the first group of
    the next step merge, extending the block, while every interleaving of the block's groups reaches the
    next step's planned NBA state from the block's source state, both steps have visible actions (no step
    reads a label of its own) and belong to the same cycle (prefix or one suffix cycle: the lasso repeats
    whole blocks), and the block does not end at an accepting NBA state (so that an accepting planned state
    stays a checked state of the run)."""
    accepting = set(words.nba.accepting)
    steps = placement.steps
    vis = [[k for k, op in enumerate(sp.ops)
            if op.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT) and words.crossings(op.action)] for sp in steps]
    block_end = list(range(len(steps)))
    # a block: (first step, groups as lists of (step, op index))
    blocks: list[tuple[int, list[list[tuple[int, int]]]]] = []
    for s, sp in enumerate(steps):
        acts = [sp.ops[k].action for k in vis[s]]
        own = [[(s, vis[s][i]) for i in g] for g in task_groups(words, sp.step, acts)]
        if blocks and own and _joins(words, steps, blocks[-1], s, own, accepting):
            first, groups = blocks[-1]
            blocks[-1] = (first, groups[:-1] + [groups[-1] + own[0]] + own[1:])
        else:
            blocks.append((s, own))
    group: dict = {}
    n = 0
    for first, groups in blocks:
        last = max((st for g in groups for st, _ in g), default=first)
        for t in range(first, last + 1):
            block_end[t] = last
        for g in groups:
            for key in g:
                group[key] = n
            n += 1
    return TaskOrder(group, tuple(block_end))


def _joins(words, steps, block, s: int, own, accepting) -> bool:
    first, groups = block
    prev = steps[s - 1].step
    if not groups or max(st for g in groups for st, _ in g) != s - 1:
        return False
    specs = [steps[t].step for t in range(first, s + 1)]
    if any(not isinstance(x.src_q, int) or not isinstance(x.dst_q, int) for x in specs):
        return False
    if prev.dst_q in accepting or prev.cycle != steps[s].step.cycle:
        return False
    merged = groups[:-1] + [groups[-1] + own[0]] + own[1:]
    if sum(len(words.crossings(steps[st].ops[k].action)) for st, k in merged[-len(own)]) > GROUP_BODIES:
        return False
    acts = [[steps[st].ops[k].action for st, k in g] for g in merged]
    return _reaches(words, specs[0], specs[-1], acts)


def motion_spots(ts: TransitionSystem, placement: Placement) -> list[dict[int, tuple[np.ndarray, float]]]:
    """Per placed primitive of the run, in order: for a navigation or transport the disk (centre, radius) its
    bodies cover in its source region where it starts and in its destination region where it ends (a
    robot's disk, or a team's covering disk around its object: the members on their slots), as planned; {}
    for the others."""
    N = ts.N
    pos = np.asarray(placement.initial, dtype=float).reshape(-1, 2).copy()
    out: list[dict[int, tuple[np.ndarray, float]]] = []
    for sp in placement.steps:
        for op in sp.ops:
            goal = np.asarray(op.goal, dtype=float)
            if op.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT):
                a = op.action
                r = (ts.robot_radius[a.robot] if op.kind is OpKind.NAVIGATE
                     else ts.covering_radius(a.obj, tuple(a.team)))
                out.append({a.src: (pos[op.entity].copy(), float(r)), a.dst: (goal, float(r))})
            else:
                out.append({})
            pos[op.entity] = goal
            if op.entity >= N and op.team:
                pos[list(op.team)] = layout_slots(ts, op.entity - N, op.team, goal, op.rotation)
    return out


def _apart(a: dict, b: dict, shared: frozenset, spacing: float) -> bool:
    """The spots of two motions in every region they share keep the layout spacing."""
    return all(float(np.hypot(*(a[k][0] - b[k][0]))) >= a[k][1] + b[k][1] + spacing - 1e-9 for k in shared)


def dependency_graph(ts: TransitionSystem, words, placement: Placement,
                     order: TaskOrder | None = None) -> tuple[Job, ...]:
    """The jobs of ``placement`` with their predecessors (module docstring)."""
    order = task_order(words, placement) if order is None else order
    spots = motion_spots(ts, placement)
    jobs: list[Job] = []
    members: dict[int, list[int]] = {}
    for s, sp in enumerate(placement.steps):
        for k, op in enumerate(sp.ops):
            uid = len(jobs)
            b, r, g = op_bodies(ts, op), op_regions(op), order.group.get((s, k), -1)
            preds = [j.uid for j in jobs if j.bodies & b or (j.regions & r and not (
                spots[uid] and spots[j.uid] and _apart(spots[uid], spots[j.uid], j.regions & r, ts.spacing)))]
            if g > 0:
                preds.extend(members.get(g - 1, ()))
            if g >= 0:
                members.setdefault(g, []).append(uid)
            jobs.append(Job(uid, s, op, b, r, g, tuple(sorted(set(preds)))))
    return tuple(jobs)


def critical_path(preds: Sequence[Sequence[int]], durations: Sequence[float]) -> float:
    """Makespan (s) of the schedule that starts every job the moment its predecessors ``preds[uid]`` (earlier
    uids) are done, job uid lasting ``durations[uid]``: the shortest time concurrent execution can take on
    that graph, motions never waiting for a corridor."""
    finish: list[float] = []
    for uid, d in enumerate(durations):
        finish.append(max((finish[p] for p in preds[uid]), default=0.0) + float(d))
    return max(finish, default=0.0)


def makespan_bounds(jobs: Sequence[Job], durations: Sequence[float]) -> dict[str, float]:
    """:func:`critical_path` of the job graph (``graph``) and of two weaker graphs with the same
    ``durations``: without the shared-region rule (``bodies+task``: shared bodies and the task's group
    chain) and with shared bodies only (``bodies``); ``sequential``: the sum.  The weaker graphs are not safe
    to execute (they drop the spot and corridor argument); they bound what finer spatial resources, and
    then a weaker task order, can gain on this plan."""
    members: dict[int, list[int]] = {}
    for j in jobs:
        if j.visible:
            members.setdefault(j.group, []).append(j.uid)
    body = [[k.uid for k in jobs[: j.uid] if k.bodies & j.bodies] for j in jobs]
    chain = [b + (members.get(j.group - 1, []) if j.group > 0 else []) for b, j in zip(body, jobs)]
    return {"sequential": float(sum(durations)), "graph": critical_path([j.preds for j in jobs], durations),
            "bodies+task": critical_path(chain, durations), "bodies": critical_path(body, durations)}


def _component(geom, point: Point) -> Polygon | None:
    parts = list(geom.geoms) if hasattr(geom, "geoms") else [geom]
    return next((p for p in parts if isinstance(p, Polygon) and p.contains(point)), None)


@dataclass(frozen=True)
class Request:
    """A navigation or transport that may start now: its job, its free space F (centre positions, with
    every other entity as a hole), start, goal, covering radius and the disks of its source and
    destination regions, each with and without its approach ring (body extent), and the disks of radius
    :data:`SPOT_LEG` around its start and its goal grown by its radius (None: the regions only)."""

    uid: int
    free: Polygon
    start: np.ndarray
    goal: np.ndarray
    radius: float
    regions: tuple[tuple[Polygon, Polygon], tuple[Polygon, Polygon]]
    spots: tuple[Polygon, Polygon] | None = None


def _route(rq: Request, room: Polygon) -> np.ndarray | None:
    area = _component(room, Point(rq.start)) if not room.is_empty else None
    if area is None or not area.contains(Point(rq.goal)):
        return None
    for step in ROUTE_STEPS:
        try:
            return grid_path(area, rq.start, rq.goal, step=step)
        except ValueError:
            continue
    return None


def _line(path: np.ndarray):
    return LineString(path) if len(path) > 1 else Point(path[0])


def _sites(rq: Request, path: np.ndarray) -> np.ndarray:
    """The points whose Voronoi cells are the motion's: its route every :data:`ROUTE_SAMPLE`, and the rims of
    the disks around its start and its goal that its local legs may use (so a route of another motion that
    passes near its spot does not cut into that disk)."""
    line = _line(path)
    n = max(2, int(line.length / ROUTE_SAMPLE) + 1)
    pts = [(p.x, p.y) for p in (line.interpolate(d) for d in np.linspace(0.0, line.length, n))]
    for spot in rq.spots or ():
        pts.extend(spot.exterior.coords[:-1])
    return np.array(pts, dtype=float)


def _cells(sites: dict[int, np.ndarray], available: Polygon) -> dict[int, Polygon]:
    """The Voronoi cells of the motions' ``sites`` (points closer to one motion's sites than to every other's)
    within ``available``."""
    if len(sites) == 1:
        return {uid: available for uid in sites}
    pts, owner = [], []
    for uid, arr in sites.items():
        pts.extend(map(tuple, arr))
        owner.extend([uid] * len(arr))
    pts_arr = np.unique(np.round(np.array(pts), 6), axis=0, return_index=True)
    keep = sorted(pts_arr[1])
    pts, owner = [pts[i] for i in keep], [owner[i] for i in keep]
    cells = shapely.voronoi_polygons(shapely.MultiPoint(pts), extend_to=available, ordered=True)
    out: dict[int, list] = {uid: [] for uid in sites}
    for cell, uid in zip(cells.geoms, owner):
        out[uid].append(cell)
    return {uid: shapely.make_valid(shapely.union_all(c).intersection(available)) for uid, c in out.items()}


def assign_corridors(requests: Sequence[Request], floor: Polygon, busy: Polygon | None,
                     margin: float, side: float | None = None) -> dict[int, Corridor]:
    """Corridors for the motions of ``requests`` that can start together now (module docstring); ``busy``:
    the bodies' corridors of the motions running (None: none).  One motion and nothing running: the whole
    floor, unconfined.  Otherwise the floor not held by running motions is split into the Voronoi cells of
    the requests' routes and spot disks (:func:`_sites`); a motion gets its cell shrunk by its covering
    radius, the margin and :data:`GAP` (its centre positions) if that connects its start to its goal and holds
    its regions' approach disks, its regions, or the disks of radius :data:`SPOT_LEG` around its start and
    goal; with ``side``, only if it also leaves the centre positions it could have on that floor whole within
    ``side`` of its route (:func:`squeezes`).  Motions without one are left out and the cells drawn again for
    the others; they wait."""
    alone = {requests[0].uid: Corridor(None, floor)} if busy is None else {}
    if busy is None and len(requests) == 1:
        return alone
    available = floor if busy is None else shapely.make_valid(floor.difference(busy))
    rooms, routes = {}, {}
    for rq in requests:
        rooms[rq.uid] = rq.free.intersection(available.buffer(-(rq.radius + margin + GAP)))
        path = _route(rq, rooms[rq.uid])
        if path is not None:
            routes[rq.uid] = path
    members = [rq for rq in requests if rq.uid in routes]
    while members:
        if busy is None and len(members) == 1:
            return {members[0].uid: Corridor(None, floor)}
        cells = _cells({rq.uid: _sites(rq, routes[rq.uid]) for rq in members}, available)
        out, failed = {}, []
        for rq in members:
            try:
                got = _corridor_in(rq, cells[rq.uid], margin)
                if got is not None and side is not None and squeezes(rq, got, rooms[rq.uid], routes[rq.uid], side):
                    got = None
            except GEOSException:  # a cell too degenerate to shrink: no corridor in it
                got = None
            if got is None:
                failed.append(rq.uid)
            else:
                out[rq.uid] = got
        if not failed:
            return out
        # the motions later in the run give way: drop the last one and split the floor again
        members = members[:-1] if len(members) > 1 else []
    return alone


def redraw_corridors(moving: Sequence[Request], requests: Sequence[Request], floor: Polygon, busy: Polygon | None,
                     margin: float) -> dict[int, Corridor] | None:
    """Corridors for the running motions ``moving``, each asking from where it is now, and the waiting
    ``requests``, drawn together (:func:`assign_corridors`, the running motions first, so the waiting ones give
    way) on the floor not held by ``busy`` (the running motions that keep their corridors; None: none).  A
    running motion's route starts where it is, so the floor behind it goes to the others.  Every corridor
    leaves its motion's surroundings whole within :data:`ROUTE_SIDE` of its route (:func:`squeezes`).  None
    unless every motion of ``moving`` gets a confined corridor."""
    got = assign_corridors([*moving, *requests], floor, busy, margin, side=ROUTE_SIDE)
    if any(rq.uid not in got or got[rq.uid].confine is None for rq in moving):
        return None
    return got


def squeezes(rq: Request, corridor: Corridor, room: Polygon, path: np.ndarray, side: float = ROUTE_SIDE) -> bool:
    """Whether ``corridor`` cuts ``room`` (the centre positions the motion of ``rq`` could have with no other
    motion asking) within ``side`` of its route ``path`` through ``room``.  The map of a free space flattens
    along a narrow channel, where the law crawls or runs on windows (:mod:`mrodrake.control.windows`): a motion
    on such a corridor may take several times as long."""
    near = _component(room.intersection(_line(path).buffer(side)), Point(rq.start))
    return near is None or near.difference(corridor.confine).area > SQUEEZE_AREA


def _corridor_in(rq: Request, cell: Polygon, margin: float) -> Corridor | None:
    confine = _component(rq.free.intersection(cell.buffer(-(rq.radius + margin + GAP))), Point(rq.start))
    if confine is None or not confine.contains(Point(rq.goal)):
        return None
    rings, spots, used = [], [], []
    for (ring, region), spot in zip(rq.regions, rq.spots or (None, None)):
        if cell.contains(ring):
            rings.append(True)
            used.append(ring)
        elif cell.contains(region):
            rings.append(False)
            used.append(region)
        elif spot is not None and cell.contains(spot):
            rings.append(False)
            used.append(spot)
        else:
            return None
        spots.append(used[-1] is spot)
    body = shapely.union_all([confine.buffer(rq.radius + margin, quad_segs=DISK_QUAD_SEGS), *used])
    return Corridor(confine, body, (rings[0], rings[1]), (spots[0], spots[1]))
