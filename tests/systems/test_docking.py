"""Grasp points in a crowded region (case study II, region p1): a robot docking next to one object must not
sit inside the covering disk of a team that leaves the region later in the same step, else that team's start
is not in its free space.  The supervisor takes such points last and defers the grasp instead."""

import math
from pathlib import Path

import numpy as np
import pytest

from mrodrake.planning.plan import plan_scenario, task_words
from mrodrake.scenario import load_scenario
from mrodrake.systems.supervisor import Op, StepSpec, SupState, Supervisor, _Defer
from mrodrake.ts import Grasp, Transport

ROOT = Path(__file__).resolve().parents[2]
R1, R2, R3, R4, O1, O2 = 0, 1, 2, 3, 4, 5


@pytest.fixture(scope="module")
def setup():
    scn = load_scenario(ROOT / "scenarios" / "case_study_2.yaml")
    plan = plan_scenario(scn, "stylus", seed=0)
    _, _, words = task_words(scn, plan.ts)
    couplings = [(0, (R1, R2)), (1, (R3, R4))]
    sup = Supervisor(scn, plan.ts, words, plan, couplings=couplings)
    return scn, sup


def _state(sup, X, docked, with_transport: bool):
    """Step 27 of the case-II plan: o1 (teamed by r1, r2) leaves p1 while r4 docks at o2 next to r3."""
    step = StepSpec(27, 27, 0, (), 0, (), 0, (Transport(0, (R1, R2), 0, 1), Grasp(R4, 1)))
    st = SupState()
    st.step_idx = next(i for i, s in enumerate(sup.steps) if any(isinstance(a, Transport) and a.obj == 0
                                                                  and a.team == (R1, R2) and a.src == 0
                                                                  for a in s.actions))
    st.docked = dict(docked)
    st.ops = (Op("transport", Transport(0, (R1, R2), 0, 1), step),) if with_transport else ()
    return st


def _layout(sup, o1, o2, r3_angle, team_angle=0.0):
    c = sup.centers[0]
    X = np.zeros((7, 4))
    X[O1, :2] = c + o1
    X[O2, :2] = c + o2
    X[R1, :2] = X[O1, :2] + 1.05 * np.array([math.cos(team_angle), math.sin(team_angle)])
    X[R2, :2] = 2.0 * X[O1, :2] - X[R1, :2]
    X[R3, :2] = X[O2, :2] + 1.05 * np.array([math.cos(r3_angle), math.sin(r3_angle)])
    X[R4, :2] = c + (0.0, -3.0)
    X[6, :2] = sup.centers[2]  # o3 elsewhere
    return X


def _cover(sup):
    return sup._team_cover(0, (R1, R2))


def test_dock_point_stays_out_of_the_departing_team(setup):
    scn, sup = setup
    X = _layout(sup, np.array([1.9, 0.3]), np.array([-0.4, -0.3]), r3_angle=math.radians(120))
    st = _state(sup, X, {R1: 0, R2: 0, R3: 1}, with_transport=True)
    q, legs, _ = sup._dock_point(st, X, R4, 1, defer=True)
    need = _cover(sup) + sup.radii[R4] + scn.layout.spacing
    assert math.hypot(*(q - X[O1, :2])) >= need - 1e-9
    assert math.hypot(*(q - X[O2, :2])) == pytest.approx(1.05, abs=1e-6)


def test_grasp_deferred_when_every_point_blocks_the_departing_team(setup):
    scn, sup = setup
    # o2 right next to o1's covering disk, r3 on o2's far side: every free grasp point is inside the disk
    X = _layout(sup, np.array([1.5, 0.0]), np.array([-0.8, 0.0]), r3_angle=math.pi, team_angle=math.pi / 2)
    need = _cover(sup) + sup.radii[R4] + scn.layout.spacing
    st = _state(sup, X, {R1: 0, R2: 0, R3: 1}, with_transport=True)
    with pytest.raises(_Defer):
        sup._dock_point(st, X, R4, 1, defer=True)
    # once the team has left (no transport pending) the same grasp takes a point of the last tier
    st = _state(sup, X, {R1: 0, R2: 0, R3: 1}, with_transport=False)
    q, _, _ = sup._dock_point(st, X, R4, 1, defer=True)
    assert math.hypot(*(q - X[O1, :2])) < need


def test_make_room_moves_a_free_robot_for_an_arriving_team(setup):
    """Case II, step 29 (seen in a run): o1's team arrives in p3 where o3 sits near the centre, o2 with r4 docked
    on one side and the free robot r3 on the other; no spot is left for the team's covering disk unless r3
    moves inside p3."""
    scn, sup = setup
    from mrodrake.systems.supervisor import _Failure

    c3 = sup.centers[2]
    X = np.zeros((7, 4))
    X[R1, :2], X[R2, :2], X[O1, :2] = (99.9, -159.1), (99.0, -160.6), (100.0, -160.2)
    for e, rel in ((R3, (0.501, 2.666)), (R4, (-2.647, 0.279)), (O2, (-1.593, 0.33)), (6, (0.395, -0.469))):
        X[e, :2] = c3 + np.array(rel)
    st = SupState()
    st.step_idx = 28
    st.docked = {R4: 1}
    movers = {O1, R1, R2}
    radius = 1.80148
    with pytest.raises(_Failure):
        sup._goal(st, X, 2, radius, movers)
    goal, moves = sup._room_moves(st, X, 2, movers, radius)
    assert [m[0] for m in moves] == [R3]
    Y = X.copy()
    for robot, spot, legs in moves:
        assert np.allclose(legs[-1], spot)
        Y[robot, :2] = spot
    gap = scn.layout.spacing
    for e in (R3, R4, O2, 6):
        assert math.hypot(*(Y[e, :2] - goal)) >= radius + sup.radii[e] + gap - 1e-6
        assert math.hypot(*(Y[e, :2] - c3)) + sup.radii[e] <= sup.region_radii[2] + 1e-9
    assert math.hypot(*(goal - c3)) + radius <= sup.region_radii[2] - gap + 1e-6


def test_make_room_clears_the_disk_of_a_team_being_formed(setup):
    """Case II with the seed-1 plan, step 8 (seen in a run): r2 must dock at o3 in p3, but r1 (docked at o1)
    and r3 (just arrived, not docked yet) leave no free grasp point; r3 is moved out of the covering disk of
    o3's team r2+r3+r4, after which r2 finds a grasp point."""
    scn, sup = setup
    from mrodrake.systems.supervisor import _Failure

    c3 = sup.centers[2]
    X = np.zeros((7, 4))
    for e, rel in ((R1, (-0.04, -1.45)), (R2, (-1.22, 2.0)), (R3, (2.12, -1.43)), (O1, (-1.11, -1.44)),
                   (6, (1.05, -1.42))):
        X[e, :2] = c3 + np.array(rel)
    X[R4, :2], X[O2, :2] = sup.centers[0] + (2.17, 0.74), sup.centers[0] + (-1.22, 1.49)
    st = SupState()
    st.step_idx = 0
    st.docked = {R1: 0}
    with pytest.raises(_Failure):
        sup._dock_point(st, X, R2, 2)
    cover = sup._team_cover(2, (R2, R3, R4))
    goal, moves = sup._room_moves(st, X, 2, {R2, 6}, keep_out=(X[6, :2], cover))
    assert goal is None and [m[0] for m in moves] == [R3]
    Y = X.copy()
    Y[R3, :2] = moves[0][1]
    assert math.hypot(*(Y[R3, :2] - X[6, :2])) >= cover + sup.radii[R3] + scn.layout.spacing - 1e-6
    q, legs, _ = sup._dock_point(st, Y, R2, 2)
    assert math.hypot(*(q - X[6, :2])) == pytest.approx(1.05, abs=1e-6)
