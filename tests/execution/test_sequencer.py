"""The sequencer's phase machine without Drake: a kinematic stand-in for the plants puts every commanded
entity at its goal, so each primitive must run through its phases in the plan's order, couple and uncouple
teams, keep the monitored run consistent and end the mission done."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mrodrake.control.windows import WINDOW_MARGIN, WINDOW_RADIUS
from mrodrake.execution.sequencer import Phase, Sequencer, Status, couplings_of
from mrodrake.planning.placement import OpKind, place_run
from mrodrake.planning.plan import plan_scenario, task_words
from mrodrake.planning.steps import expand_steps
from mrodrake.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def tiny():
    sc = load_scenario(ROOT / "scenarios" / "tiny.yaml")
    plan = plan_scenario(sc, "stylus", seed=0)
    _, _, words = task_words(sc, plan.ts)
    placement = place_run(plan.ts, expand_steps(plan, 1), seed=0)
    return sc, plan, words, placement


def _kinematic(seq: Sequencer, st, X: np.ndarray) -> np.ndarray:
    """Where the plants would be once the active motion has done its current leg: its entity (and team)
    at the leg's end (the goal of a point-world motion), at rest."""
    X = X.copy()
    X[:, 2:] = 0.0
    a = st.active
    if a is None or a.motion is None:
        return X
    m = a.motion
    goal = np.asarray(m.legs[m.leg] if m.legs is not None else m.goal)
    shift = goal - X[m.entity, :2]
    X[m.entity, :2] = goal
    for i in m.team:
        X[i, :2] += shift
    return X


def test_every_primitive_runs_through_its_phases_in_plan_order(tiny):
    sc, plan, words, placement = tiny
    seq = Sequencer(sc, plan.ts, words, placement, couplings_of(plan))
    st = seq.initial_state()
    X = np.zeros((len(seq.entities), 4))
    X[:, :2] = np.asarray(placement.initial)
    seen_phases: dict[OpKind, set] = {}
    t = 0.0
    for _ in range(2000):
        st = seq.tick(st, t, X)
        if st.status is not Status.RUNNING:
            break
        if st.active is not None:
            seen_phases.setdefault(st.active.op.kind, set()).add(st.active.phase)
        X = _kinematic(seq, st, X)
        t += 0.5
    assert st.status is Status.DONE, st.message
    assert seq.steps_done(st) == len(seq.steps)
    prim = [e for e in st.events if e["kind"] == "primitive"]
    planned = [seq._op_text(op) for sp in placement.steps for op in sp.ops if op.kind is not OpKind.ROOM]
    assert [e["action"] for e in prim] == planned and all(e["ok"] for e in prim)
    assert seen_phases[OpKind.TRANSPORT] >= {Phase.ENGAGE, Phase.MOVING}
    assert seen_phases[OpKind.RELEASE] >= {Phase.DISENGAGE, Phase.MOVING}
    assert not st.engaged and not st.coupled  # every team released at the end of the suffix cycle
    assert st.monitor.contains(seq.steps[-1].dst_q)  # the kinematic word is one the plan was verified for


def test_abort_names_the_primitive_step_and_time(tiny):
    sc, plan, words, placement = tiny
    seq = Sequencer(sc, plan.ts, words, placement, couplings_of(plan))
    st = seq.initial_state()
    X = np.zeros((len(seq.entities), 4))
    X[:, :2] = np.asarray(placement.initial)
    st = seq.tick(st, 0.0, X)
    st = seq.abort(st, 12.345, "integrator failure (test)")
    assert st.status is Status.FAILED
    op = placement.steps[0].ops[0]
    assert st.message == f"{seq._op_text(op)} (step 1, plan step 1) failed at t = 12.35 s: integrator failure (test)"
    assert st.events[-1]["kind"] == "primitive" and not st.events[-1]["ok"]
    assert all(v is None for v in st.tasks.values())


def test_time_limit_ends_a_stuck_primitive(tiny):
    sc, plan, words, placement = tiny
    seq = Sequencer(sc, plan.ts, words, placement, couplings_of(plan), time_limit=(5.0, 0.0))
    st = seq.initial_state()
    X = np.zeros((len(seq.entities), 4))
    X[:, :2] = np.asarray(placement.initial)
    for k in range(40):  # the plants never move
        st = seq.tick(st, 0.5 * k, X)
    assert st.status is Status.FAILED and "time limit 5 s exceeded" in st.message


def test_an_arrival_needs_the_whole_ball_inside_the_target_region(tiny):
    """An entity at rest within goal_tol of a goal near the rim of its target region, but protruding from
    the region, has not arrived (the executed state would not be the planned one: the campaign's
    state_mismatch of gen_n4_m2_k4_s1, a team member 6 mm outside); at the goal itself it has."""
    sc, plan, words, placement = tiny
    seq = Sequencer(sc, plan.ts, words, placement, couplings_of(plan))
    st, _, _ = _first_tick(seq, placement, lambda st: st.active is not None
                           and st.active.op.kind is OpKind.NAVIGATE and st.active.motion is not None)
    m = st.active.motion
    c, R = np.asarray(sc.regions[m.dst].center, dtype=float), float(sc.regions[m.dst].radius)
    u = np.asarray(m.goal) - c
    u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-9 else np.array([1.0, 0.0])
    m = replace(m, legs=None, goal=tuple(c + (R - m.radius - 0.02) * u))  # a goal 2 cm inside the rim
    out = np.zeros((len(seq.entities), 4))
    out[m.entity, :2] = c + (R - m.radius + 0.02) * u  # 4 cm from it (< goal_tol), 2 cm outside the region
    assert np.linalg.norm(out[m.entity, :2] - np.asarray(m.goal)) < seq.goal_tol
    assert not seq._arrived(out, m)
    out[m.entity, :2] = m.goal
    assert seq._arrived(out, m)


def test_point_world_motions_start_clear_of_other_entities(tiny):
    """A navigation or transport that starts nearer than the margin (control.margin) to another entity first
    leaves on exit legs of the local law in its source region's approach disk (same episode), so every
    point-world law starts the margin clear of every other entity (the kinematic plants end each leg at its
    waypoint)."""
    sc, plan, words, placement = tiny
    seq = Sequencer(sc, plan.ts, words, placement, couplings_of(plan))
    st = seq.initial_state()
    X = np.zeros((len(seq.entities), 4))
    X[:, :2] = np.asarray(placement.initial)
    starts, exits, t = {}, set(), 0.0
    for _ in range(2000):
        st = seq.tick(st, t, X)
        if st.status is not Status.RUNNING:
            break
        m = st.active.motion if st.active is not None else None
        if m is not None and m.kind in (OpKind.NAVIGATE, OpKind.TRANSPORT):
            if m.exiting:
                exits.add(m.episode)
                assert st.tasks[m.controller].episode == m.episode
            elif m.legs is None and m.episode not in starts:
                starts[m.episode] = min((np.hypot(*(np.asarray(d.center) - m.free.start)) - d.radius - m.radius
                                         for d in m.others), default=np.inf)
        X = _kinematic(seq, st, X)
        t += 0.5
    assert st.status is Status.DONE, st.message
    assert exits and exits <= set(starts)
    assert min(starts.values()) >= sc.control.margin - 1e-9


def test_the_planned_track_ends_every_step_at_its_planned_positions(tiny):
    """The positions the sequencer expects before each primitive (its map's plan data) walk the placement:
    after the last primitive of every step, every entity is at the step's planned position."""
    sc, plan, words, placement = tiny
    seq = Sequencer(sc, plan.ts, words, placement, couplings_of(plan), prefetch=False)
    end = 0
    for sp in placement.steps:
        end += len(sp.ops)
        assert np.allclose(seq._planned[end], np.asarray(sp.positions), atol=1e-9)


def test_a_tick_that_changes_nothing_returns_the_state_itself(tiny):
    """While a motion is under way and nothing happens, the tick returns its input state (the supervisor then
    leaves the Drake context untouched); the tick at which it reaches the end of its leg does not."""
    sc, plan, words, placement = tiny
    seq = Sequencer(sc, plan.ts, words, placement, couplings_of(plan), prefetch=False)
    st = seq.initial_state()
    X = np.zeros((len(seq.entities), 4))
    X[:, :2] = np.asarray(placement.initial)
    t = 0.0
    for _ in range(2000):
        a = st.active
        if a is not None and a.motion is not None and a.motion.kind is OpKind.NAVIGATE and a.motion.world:
            break
        st = seq.tick(st, t, X)
        X = _kinematic(seq, st, X)
        t += 0.5
    else:
        pytest.fail("no navigation on the point-world law")
    X[st.active.motion.entity, 2:] = 1.0  # under way: not at rest, so neither at a leg's end nor arrived
    st = seq.tick(st, t, X)
    assert st.active is not None and st.active.motion.kind is OpKind.NAVIGATE
    assert seq.tick(st, t + 0.5, X) is st and seq.tick(st, t + 1.0, X) is st
    moved = seq.tick(st, t + 1.5, _kinematic(seq, st, X))  # at rest at the end of its leg: the next leg or done
    assert moved is not st
    assert moved.active is not st.active or len(moved.primitives) == len(st.primitives) + 1


def test_a_parked_entity_is_a_hole_at_its_planned_spot_within_its_parking_tolerance(tiny):
    """A robot (docked robots sit within the docking tolerance of slots beside objects within the goal
    tolerance) counts at its planned spot grown by ROBOT_PARK_TOL while within that of it, an object by
    PARK_TOL; farther off, either is its actual disk."""
    from mrodrake.execution.sequencer import DOCK_TOL, GOAL_TOL, PARK_TOL, ROBOT_PARK_TOL

    sc, plan, words, placement = tiny
    seq = Sequencer(sc, plan.ts, words, placement, couplings_of(plan), prefetch=False)
    assert ROBOT_PARK_TOL == pytest.approx(GOAL_TOL + DOCK_TOL) and PARK_TOL == GOAL_TOL
    planned = np.asarray(placement.initial, dtype=float)
    robot, obj = 0, seq.N
    for off, robot_near, obj_near in ((0.9 * PARK_TOL, True, True), (0.5 * (PARK_TOL + ROBOT_PARK_TOL), True, False),
                                      (1.1 * ROBOT_PARK_TOL, False, False)):
        X = np.zeros((len(seq.entities), 4))
        X[:, :2] = planned + [off, 0.0]
        disks = {d.name: d for d in seq._map_disks(X, set(), planned)}
        for e, near, tol in ((robot, robot_near, ROBOT_PARK_TOL), (obj, obj_near, PARK_TOL)):
            d, r = disks[seq.entities[e]], float(seq.radii[e])
            if near:
                assert np.allclose(d.center, planned[e]) and d.radius == pytest.approx(r + tol)
                assert np.hypot(*(X[e, :2] - planned[e])) + r <= d.radius + 1e-12  # contains the actual disk
            else:
                assert np.allclose(d.center, X[e, :2]) and d.radius == pytest.approx(r)


def _first_tick(seq: Sequencer, placement, wanted):
    """The state, time and entity states (kinematic plants) at the first tick whose state satisfies ``wanted``."""
    st = seq.initial_state()
    X = np.zeros((len(seq.entities), 4))
    X[:, :2] = np.asarray(placement.initial)
    t = 0.0
    for _ in range(2000):
        st = seq.tick(st, t, X)
        if wanted(st):
            return st, t, X
        X = _kinematic(seq, st, X)
        t += 0.5
    raise AssertionError("no such tick")


def _point_world_navigation(seq: Sequencer, placement):
    """The state, time and entity states at the first tick with a navigation on the point-world law."""
    def wanted(st):
        m = st.active.motion if st.active is not None else None
        return m is not None and m.kind is OpKind.NAVIGATE and m.legs is None and bool(m.world)
    return _first_tick(seq, placement, wanted)


def test_a_navigation_that_stops_short_of_its_goal_moves_to_a_smaller_window(tiny):
    """An entity held still on the map of its whole motion stalls within two periods 1/(2 k1) and goes on in a
    window around it smaller than the default, inside its free space; the stall is logged."""
    sc, plan, words, placement = tiny
    seq = Sequencer(sc, plan.ts, words, placement, couplings_of(plan))
    st, t0, X = _point_world_navigation(seq, placement)
    m = st.active.motion
    t = t0
    while t < t0 + 2.0 * seq.stall_period:
        t += 0.5
        st = seq.tick(st, t, X)
        if st.active.motion.waypoint is not None:
            break
    assert st.status is Status.RUNNING
    w = st.active.motion
    assert w.waypoint is not None and w.window_radius < WINDOW_RADIUS and t - t0 >= seq.stall_period
    assert w.free.polygon.difference(m.world[0].polygon).area < 1e-9
    assert st.tasks[w.controller].task is w.task
    assert [e["kind"] for e in st.events].count("stall") == 1


def test_a_stalled_navigation_without_a_window_fails_with_the_reason(tiny):
    sc, plan, words, placement = tiny
    seq = Sequencer(sc, plan.ts, words, placement, couplings_of(plan))
    st, t0, X = _point_world_navigation(seq, placement)
    st = replace(st, active=replace(st.active, motion=replace(st.active.motion, window_radius=2.0 * WINDOW_MARGIN)))
    t = t0
    while st.status is Status.RUNNING and t < t0 + 3.0 * seq.stall_period:
        t += 0.5
        st = seq.tick(st, t, X)
    assert st.status is Status.FAILED
    assert "stalled at" in st.message and "no window around it leads on" in st.message


def test_a_stalled_navigation_left_on_an_unresolving_map_fails_within_two_periods(tiny):
    """A motion whose map does not resolve its position and around which no window could be built (its
    ``world`` cleared) has nothing that moves it on once it stalls: it fails with the reason within two stall
    periods instead of running to its time limit."""
    sc, plan, words, placement = tiny
    seq = Sequencer(sc, plan.ts, words, placement, couplings_of(plan))
    st, t0, X = _point_world_navigation(seq, placement)
    st = replace(st, active=replace(st.active, motion=replace(st.active.motion, world=())))
    t = t0
    while st.status is Status.RUNNING and t < t0 + 2.0 * seq.stall_period + 1.0:
        t += 0.5
        st = seq.tick(st, t, X)
    assert st.status is Status.FAILED
    assert "stalled at" in st.message and "neither its map nor a window around it resolves" in st.message
