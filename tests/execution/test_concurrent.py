"""Concurrent execution: the job dependency graph, corridors, and the executed words it can produce.

* two robots crossing a floor on separate lanes, or side by side along one channel, move at the same time,
  each inside the corridors its law ran on (piecewise in time, corridors drawn again included), far from the
  other; two leaving one region in opposite directions move at the same time; of two whose routes cross,
  or pass one door, the second starts once the first has left the crossing (the door) behind, before the
  first arrives (the running motion's corridor drawn again from where it is);
* two jobs the graph leaves unordered share no body, and share a region only as two motions whose spots there
  keep the layout spacing (so every spot of the placement is free whichever runs first);
* a safety clause that one interleaving of two concurrent crossings would violate keeps the two in the plan's
  order;
* on random small plans, every executed word a concurrent run can produce (random linear extensions of the
  job graph's crossings, block by block) satisfies the task, evaluated on the lasso without an automaton.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrodrake.control.freespace import Disk
from mrodrake.errors import NoPlanFound, UserError
from mrodrake.execution.schedule import (
    SPOT_LEG,
    Corridor,
    Execution,
    assign_corridors,
    dependency_graph,
    motion_spots,
    redraw_corridors,
    task_order,
)
from mrodrake.execution.sequencer import Motion
from mrodrake.geometry import CONTROL_MARGIN, disk
from mrodrake.logic.lasso import evaluate_lasso
from mrodrake.planning.generate import generate_scenario_data
from mrodrake.planning.placement import OpKind
from mrodrake.planning.plan import plan_scenario, task_words
from mrodrake.planning.semantics import crossings
from mrodrake.scenario import scenario_from_dict
from mrodrake.systems.mission import Mission
from tests.helpers.jobs import generated_jobs
from tests.helpers.tasks import region_atoms


def _floor(name, boundary, obstacles, regions, formula, radius=3.0):
    return scenario_from_dict({
        "name": name, "workspace": {"boundary": boundary, "obstacles": obstacles},
        "regions": [{"name": f"p{k + 1}", "center": c, "radius": radius} for k, c in enumerate(regions)],
        "robots": [{"name": "r1", "mass": 1.0, "radius": 0.75, "power": 2, "initial_region": "p1"},
                   {"name": "r2", "mass": 1.2, "radius": 0.75, "power": 2, "initial_region": "p3"}],
        "objects": [], "task": {"formula": formula}})


def lanes(formula: str):
    """A 60 m x 30 m floor split by a wall into a north and a south lane: p1 (NW), p2 (NE), p3 (SE), p4 (SW)."""
    wall = [{"name": "wall", "polygon": [[12.0, 14.0], [48.0, 14.0], [48.0, 16.0], [12.0, 16.0]]}]
    return _floor("lanes", [[0, 0], [60, 0], [60, 30], [0, 30]], wall, [[5, 24], [55, 24], [55, 6], [5, 6]], formula)


def open_floor(formula: str):
    """An empty 40 m x 40 m floor: p1 (NW), p2 (SE), p3 (NE), p4 (SW); p1 -> p2 and p3 -> p4 cross."""
    return _floor("open", [[0, 0], [40, 0], [40, 40], [0, 40]], [], [[5, 35], [35, 5], [35, 35], [5, 5]], formula)


def door(formula: str):
    """A 60 m x 40 m floor split by a 2 m wall at x = 30 with one 4 m door (y in [17, 21]): p1 (NW) and p3 (SW)
    west of it, p2 (NE) and p4 (SE) east of it; p1 -> p2 and p3 -> p4 both pass the door."""
    boundary = [[0, 0], [29, 0], [29, 17], [31, 17], [31, 0], [60, 0], [60, 40], [31, 40], [31, 21], [29, 21],
                [29, 40], [0, 40]]
    return _floor("door", boundary, [], [[8, 32], [52, 34], [8, 8], [52, 6]], formula)


def hub(formula: str):
    """A 70 m x 30 m empty floor: p1 (radius 6 m) in the middle holds both robots, p2 west, p3 east."""
    return scenario_from_dict({
        "name": "hub", "workspace": {"boundary": [[0, 0], [70, 0], [70, 30], [0, 30]], "obstacles": []},
        "regions": [{"name": "p1", "center": [35, 15], "radius": 6.0},
                    {"name": "p2", "center": [5, 15], "radius": 3.0},
                    {"name": "p3", "center": [65, 15], "radius": 3.0}],
        "robots": [{"name": "r1", "mass": 1.0, "radius": 0.75, "power": 2, "initial_region": "p1"},
                   {"name": "r2", "mass": 1.2, "radius": 0.75, "power": 2, "initial_region": "p1"}],
        "objects": [], "task": {"formula": formula}})


def channel(formula: str):
    """A 70 m x 9 m empty channel: p1 (NW) and p3 (SW) at its west end, p2 (NE) and p4 (SE) at its east end,
    radius 2 m; p1 -> p2 and p3 -> p4 run side by side, 4.5 m apart."""
    return _floor("channel", [[0, 0], [70, 0], [70, 9], [0, 9]], [], [[5, 6.75], [65, 6.75], [5, 2.25], [65, 2.25]],
                  formula, radius=2.0)


def _mission(sc, execution):
    plan = plan_scenario(sc, iterations=300, seed=0, layout_seed=0)
    log = Mission(sc, plan, suffix_cycles=1, seed=0, execution=execution).run()
    assert log.ok, log.message
    return log


def _spans(rec):
    """(t0, t1, free) for every free space the motion of ``rec`` ran on; the first from its start."""
    times = [rec.t_start, *(t for t, _ in rec.spans[1:]), rec.t_end]
    return [(times[k], times[k + 1], free) for k, (_, free) in enumerate(rec.spans)]


def _assert_inside_disjoint_corridors(log):
    """Every motion's centre stays within the control margin of the free space its law ran on at the time,
    and the free spaces of two motions running at the same time, grown by radius and margin, are disjoint."""
    tr = log.trajectory
    spans = [(rec.entity, *span) for rec in log.primitives for span in _spans(rec)]
    assert spans
    for entity, t0, t1, free in spans:
        seg = tr[(tr.entity == entity) & (tr.t >= t0) & (tr.t <= t1)][["x", "y"]].to_numpy()
        d = shapely.distance(free.polygon, shapely.points(seg))
        assert np.max(d) <= CONTROL_MARGIN, (entity, t0, float(np.max(d)))
    for (ea, a0, a1, fa), (eb, b0, b1, fb) in itertools.combinations(spans, 2):
        if ea != eb and max(a0, b0) < min(a1, b1):
            grown = [f.polygon.buffer(0.75 + CONTROL_MARGIN) for f in (fa, fb)]
            assert not grown[0].intersects(grown[1]), (ea, eb, a0, b0)


def _intervals(log):
    ev = log.primitive_events
    return {a: (float(t0), float(t1)) for a, t0, t1 in zip(ev["action"], ev["t_start"], ev["t_end"])}


def _gap(log, a: str, b: str) -> float:
    tr = log.trajectory
    pa = tr[tr.entity == a][["x", "y"]].to_numpy()
    pb = tr[tr.entity == b][["x", "y"]].to_numpy()
    return float(np.min(np.linalg.norm(pa - pb, axis=1))) - 1.5


def test_two_robots_on_separate_lanes_move_at_the_same_time_inside_their_corridors():
    log = _mission(lanes("F (r1_p2 & r2_p4)"), "concurrent")
    iv = _intervals(log)
    (a0, a1), (b0, b1) = iv["navigate r1 p1->p2"], iv["navigate r2 p3->p4"]
    assert max(a0, b0) < min(a1, b1)  # the two motions overlap in time
    # each stays in its corridor: its centre within the margin of the confined free space its map was built
    # on (the corridor construction keeps the two grown corridors disjoint)
    _assert_inside_disjoint_corridors(log)
    assert _gap(log, "r1", "r2") > 2 * CONTROL_MARGIN
    seq = _mission(lanes("F (r1_p2 & r2_p4)"), "sequential")
    assert log.sim_seconds < seq.sim_seconds


def test_two_robots_leaving_one_region_in_opposite_directions_move_at_the_same_time():
    log = _mission(hub("F (r1_p2 & r2_p3)"), "concurrent")
    iv = _intervals(log)
    (a0, a1), (b0, b1) = iv["navigate r1 p1->p2"], iv["navigate r2 p1->p3"]
    assert max(a0, b0) < min(a1, b1)
    _assert_inside_disjoint_corridors(log)
    assert _gap(log, "r1", "r2") > 0.0


def test_two_robots_side_by_side_along_one_channel_move_at_the_same_time():
    log = _mission(channel("F (r1_p2 & r2_p4)"), "concurrent")
    iv = _intervals(log)
    (a0, a1), (b0, b1) = iv["navigate r1 p1->p2"], iv["navigate r2 p3->p4"]
    assert max(a0, b0) < min(a1, b1)
    _assert_inside_disjoint_corridors(log)
    assert _gap(log, "r1", "r2") > 2 * CONTROL_MARGIN
    # each corridor is half the 9 m channel, but it keeps its robot's route straight: no crawl
    seq = _mission(channel("F (r1_p2 & r2_p4)"), "sequential")
    assert log.sim_seconds < 0.75 * seq.sim_seconds


def test_two_motions_leaving_one_region_get_disjoint_corridors_that_hold_their_spot_disks():
    sc = hub("F (r1_p2 & r2_p3)")
    plan = plan_scenario(sc, iterations=300, seed=0, layout_seed=0)
    seq = Mission(sc, plan, execution="concurrent").sequencer
    X = np.asarray(plan.placement.initial, dtype=float)
    moves = [j for j in seq.jobs if j.moves_between_regions]
    assert not moves[0].preds and not moves[1].preds
    reqs = [seq._request(j.uid, j.op, X[j.op.entity], 0.75,
                         [Disk(f"e{e}", tuple(X[e]), 0.75) for e in range(2) if e != j.op.entity]) for j in moves]
    got = assign_corridors(reqs, seq._floor, None, seq.margin)
    assert set(got) == {j.uid for j in moves}
    a, b = (got[j.uid] for j in moves)
    assert a.spots[0] and b.spots[0]  # p1 is split: each holds the disk around its start, not the region
    assert not a.body.intersects(b.body)
    for rq in reqs:
        assert got[rq.uid].body.contains(rq.spots[0]) and got[rq.uid].confine.contains(shapely.Point(rq.start))


def test_local_legs_of_a_motion_on_a_spot_corridor_stay_in_its_spot_disk():
    sc = hub("F (r1_p2 & r2_p3)")
    plan = plan_scenario(sc, iterations=300, seed=0, layout_seed=0)
    seq = Mission(sc, plan, execution="concurrent").sequencer
    X = np.zeros((2, 4))
    X[:, :2] = plan.placement.initial
    job = next(j for j in seq.jobs if j.moves_between_regions)
    start, goal = X[job.op.entity, :2], np.asarray(job.op.goal)
    m = Motion(OpKind.NAVIGATE, job.op.entity, (), "c", "p", job.op.action.src, job.op.action.dst, 0.75,
               tuple(start), tuple(goal), 0.0, 100.0, 1, None,
               corridor=Corridor(None, shapely.Point(0, 0).buffer(1.0), (False, True), (True, False)))
    c, R, _centers, _radii = seq._motion_world(X, m, m.src, 0.0)
    assert np.allclose(c, start) and R == SPOT_LEG
    c, R, _centers, _radii = seq._motion_world(X, m, m.dst, 2.0)  # the destination keeps its region and ring
    assert np.allclose(c, seq.centers[m.dst]) and np.isclose(R, seq.region_radii[m.dst] + 2.0 - 0.75)


def _at(log, entity: str, t: float) -> np.ndarray:
    own = log.trajectory[log.trajectory.entity == entity]
    return own[["x", "y"]].to_numpy()[np.argmin(np.abs(own["t"].to_numpy() - t))]


def test_two_robots_whose_routes_cross_pass_the_crossing_one_after_the_other():
    log = _mission(open_floor("F (r1_p2 & r2_p4)"), "concurrent")
    iv = _intervals(log)
    (a0, a1), (b0, _b1) = sorted(iv.values())
    first = "r1" if iv["navigate r1 p1->p2"][0] == a0 else "r2"
    assert a0 < b0 < a1  # the second waits, not for the whole motion of the first, ...
    x = _at(log, first, b0)  # ... until the first has left the crossing (20, 20) behind, toward the south
    assert x[1] < 20.0 and np.hypot(*(x - 20.0)) > 2 * (0.75 + CONTROL_MARGIN)
    _assert_inside_disjoint_corridors(log)
    assert _gap(log, "r1", "r2") > 2 * CONTROL_MARGIN


def test_a_robot_crosses_a_door_once_the_robot_ahead_has_left_it_behind():
    log = _mission(door("F (r1_p2 & r2_p4)"), "concurrent")
    (a0, a1), (b0, b1) = sorted(_intervals(log).values())
    assert a0 < b0 < a1  # the second starts before the first has arrived, once the door is behind the first
    first = "r1" if _intervals(log)["navigate r1 p1->p2"][0] == a0 else "r2"
    assert _at(log, first, b0)[0] > 31.0 + 0.75  # the first is past the door when the second starts
    ahead = next(rec for rec in log.primitives if rec.entity == first)
    assert len(ahead.spans) >= 2 and a0 < ahead.spans[1][0] <= b0  # its corridor was drawn again to let it
    _assert_inside_disjoint_corridors(log)
    assert _gap(log, "r1", "r2") > 2 * CONTROL_MARGIN
    seq = _mission(door("F (r1_p2 & r2_p4)"), "sequential")
    assert log.sim_seconds < seq.sim_seconds


def test_corridors_drawn_again_give_a_door_to_a_waiting_robot_once_the_running_one_has_passed_it():
    sc = door("F (r1_p2 & r2_p4)")
    plan = plan_scenario(sc, iterations=300, seed=0, layout_seed=0)
    seq = Mission(sc, plan, execution="concurrent").sequencer
    X = np.asarray(plan.placement.initial, dtype=float)
    first, second = sorted((j for j in seq.jobs if j.moves_between_regions), key=lambda j: j.op.entity)

    def ask(job, at, other_at):
        return seq._request(job.uid, job.op, np.asarray(at, dtype=float), 0.75, [Disk("other", tuple(other_at), 0.75)])

    for x, passed in (((24.0, 21.0), False), ((33.5, 20.5), False), ((41.0, 26.0), True)):
        moving = ask(first, x, X[1])
        waiting = ask(second, X[1], x)
        got = redraw_corridors([moving], [waiting], seq._floor, None, seq.margin)
        assert (got is not None and second.uid in got) is passed
        if passed:
            a, b = got[first.uid], got[second.uid]
            assert a.confine.contains(shapely.Point(x))
            assert not a.body.intersects(b.body)
            assert a.confine.contains(shapely.Point(first.op.goal)) and b.confine.contains(shapely.Point(X[1]))


def test_a_motion_settling_on_local_legs_holds_only_their_rim():
    sc = hub("F (r1_p2 & r2_p3)")
    plan = plan_scenario(sc, iterations=300, seed=0, layout_seed=0)
    seq = Mission(sc, plan, execution="concurrent").sequencer
    job = next(j for j in seq.jobs if j.moves_between_regions)
    dst = job.op.action.dst
    body = shapely.box(0, 0, 70, 30)
    m = Motion(OpKind.NAVIGATE, job.op.entity, (), "c", "p", job.op.action.src, dst, 0.75, (35.0, 15.0),
               tuple(job.op.goal), 0.0, 100.0, 1, None, corridor=Corridor(shapely.box(1, 1, 69, 29), body), world=(1,))
    assert seq._held(m) is body  # on the point-world law: the whole corridor
    settling = replace(m, legs=(tuple(job.op.goal),), extra=2.0)
    rim = seq._held(settling)
    assert rim.area < 0.1 * body.area
    assert np.isclose(rim.hausdorff_distance(disk(seq.centers[dst], seq.region_radii[dst] + 2.0)), 0.0)
    spot = replace(settling, corridor=Corridor(shapely.box(1, 1, 69, 29), body, (True, False), (False, True)))
    assert np.isclose(seq._held(spot).hausdorff_distance(disk(job.op.goal, SPOT_LEG + 0.75)), 0.0)


def test_a_safety_clause_one_interleaving_would_break_keeps_the_plan_order():
    # r2 must leave p3 before r1 is in p2: entering p2 first is a word that violates the task
    sc = lanes("F (r1_p2 & r2_p4) & G !(r1_p2 & r2_p3)")
    log = _mission(sc, "concurrent")
    iv = _intervals(log)
    assert iv["navigate r2 p3->p4"][1] <= iv["navigate r1 p1->p2"][0]
    assert (log.events[log.events.kind == "label"]["ok"]).all()
    plan = plan_scenario(sc, iterations=300, seed=0, layout_seed=0)
    _f, _nba, words = task_words(sc, plan.ts)
    jobs = dependency_graph(plan.ts, words, plan.placement)
    moves = [j for j in jobs if j.moves_between_regions]
    assert moves[0].uid in moves[1].preds
    # without the safety clause the two crossings may interleave either way: one group, no order
    sc2 = lanes("F (r1_p2 & r2_p4)")
    plan2 = plan_scenario(sc2, iterations=300, seed=0, layout_seed=0)
    _f, _nba, words2 = task_words(sc2, plan2.ts)
    moves2 = [j for j in dependency_graph(plan2.ts, words2, plan2.placement) if j.moves_between_regions]
    assert moves2[0].group == moves2[1].group and moves2[0].uid not in moves2[1].preds


def test_the_mission_rejects_an_unknown_execution_mode():
    sc = lanes("F r1_p2")
    plan = plan_scenario(sc, iterations=100, seed=0, layout_seed=0)
    with pytest.raises(UserError, match="--execution"):
        Mission(sc, plan, execution="parallel")
    assert Mission(sc, plan, execution="concurrent").sequencer.execution is Execution.CONCURRENT


def _ordered(jobs) -> list[set[int]]:
    """For every job, the jobs it waits for directly or through others."""
    before: list[set[int]] = []
    for j in jobs:
        before.append(set(j.preds).union(*(before[p] for p in j.preds)))
    return before


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(2, 4), m=st.integers(0, 2), k=st.integers(3, 4), seed=st.integers(0, 10_000))
def test_jobs_left_unordered_keep_apart(n, m, k, seed):
    planned = generated_jobs(n, m, k, seed)
    if planned is None:
        return
    plan, jobs = planned
    spots = motion_spots(plan.ts, plan.placement)
    before = _ordered(jobs)
    for a, b in itertools.combinations(jobs, 2):
        if a.uid in before[b.uid]:
            continue
        assert not a.bodies & b.bodies
        for r in a.regions & b.regions:
            assert a.moves_between_regions and b.moves_between_regions
            (ca, ra), (cb, rb) = spots[a.uid][r], spots[b.uid][r]
            assert np.hypot(*(ca - cb)) >= ra + rb + plan.ts.spacing - 1e-9


# ------------------------------------------------------------------------------------------ words
@st.composite
def _tasks(draw):
    n, m, k = draw(st.integers(2, 4)), draw(st.integers(0, 2)), draw(st.integers(3, 5))
    seed = draw(st.integers(0, 10_000))
    atoms = st.sampled_from(region_atoms(n, m, k))
    lit = st.one_of(atoms, atoms.map(lambda a: f"!{a}"))
    prop = st.one_of(lit, st.builds(lambda a, b: f"({a} & {b})", lit, lit))
    # goals that make several bodies move, and clauses an interleaving of their crossings can break
    goal = st.builds(lambda a, b: f"F ({a} & {b})", atoms, atoms)
    clause = st.one_of(
        st.builds(lambda a, b: f"G !({a} & {b})", atoms, atoms),
        st.builds(lambda a, b: f"(!{a} U {b})", atoms, atoms),
        st.builds(lambda a, b: f"({a} U {b})", prop, prop),
        st.builds(lambda a: f"G F {a}", prop),
        st.builds(lambda a, b: f"G ({a} -> X {b})", lit, lit),
        st.builds(lambda a, b: f"G ({a} -> F {b})", lit, prop))
    return n, m, k, seed, " & ".join([draw(goal), *draw(st.lists(clause, min_size=1, max_size=2))])


def _block_word(ts, relevant, steps, groups, rng) -> list[int]:
    """One word of a block: its groups one after another, the crossing events of each group in a random order
    that keeps every body's leave before its entry and every entry after the leaves the geometry puts first;
    a letter (the label being left) at every event that changes the projected label; the source label once if
    there is none."""
    label = ts.label_mask(steps[0].src) & relevant
    out = []
    for acts in groups:
        cross = [c for a in acts for c in crossings(ts, relevant, a)]
        left = {c.body for c in cross if c.leave >= 0}
        todo = [("leave", c) for c in cross if c.leave >= 0] + [("enter", c) for c in cross if c.enter >= 0]
        gone: set[int] = set()
        while todo:
            ready = [i for i, (kind, c) in enumerate(todo) if kind == "leave"
                     or ((c.body not in left or c.body in gone) and all(e in gone for e in c.after))]
            kind, c = todo.pop(ready[rng.integers(len(ready))])
            new = label & ~(1 << c.leave) if kind == "leave" else label | (1 << c.enter)
            if kind == "leave":
                gone.add(c.body)
            if new != label:
                out.append(label)
                label = new
    return out or [label]


def _blocks(placement, order):
    """(steps, groups of actions) of every block of the run, in order."""
    out, s = [], 0
    while s < len(placement.steps):
        e = order.block_end[s]
        keys = sorted(((g, st_, k) for (st_, k), g in order.group.items() if s <= st_ <= e))
        groups = [[placement.steps[st_].ops[k].action for _, st_, k in grp]
                  for _, grp in itertools.groupby(keys, key=lambda x: x[0])]
        out.append(([placement.steps[t].step for t in range(s, e + 1)], groups))
        s = e + 1
    return out


def _planned(task):
    """(scenario, plan or None, seed, formula) of a drawn task: the generated scenario with the formula."""
    n, m, k, seed, formula = task
    data = generate_scenario_data(n, m, k, seed)
    data["task"] = {"formula": formula, "propositions": {}}
    sc = scenario_from_dict(data)
    try:
        return sc, plan_scenario(sc, iterations=300, seed=seed, layout_seed=seed), seed, formula
    except (NoPlanFound, UserError):
        return sc, None, seed, formula


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(task=_tasks())
def test_every_word_of_a_concurrent_run_satisfies_the_task(task):
    sc, plan, seed, formula = _planned(task)
    if plan is None:
        return
    f, _nba, words = task_words(sc, plan.ts)
    order = task_order(words, plan.placement)
    blocks = _blocks(plan.placement, order)
    assert all(len({x.cycle for x in specs}) == 1 for specs, _ in blocks)
    rng = np.random.default_rng(seed)
    ts = plan.ts
    for _ in range(12):
        u, v = [], []
        for specs, groups in blocks:
            (u if specs[0].cycle == 0 else v).extend(_block_word(ts, words.relevant, specs, groups, rng))
        assert evaluate_lasso(f, u, v, ts.propositions), (formula, u, v)
