"""Guarantee tests for the continuous layer (paper Sec. III-A) on simulated transitions of case study I.

Every simulated transition must: reach the target region (the entity's ball inside it, nearly at rest)
within the time bound T; keep a positive clearance to every obstacle, wall, other entity and other
region along the whole trajectory — computed from the simulated states with shapely on the raw scenario
geometry, never from the controller's map; keep m̂, α̂ bounded; produce no NaN.

The time bound T and the checks are in :mod:`tests.helpers.transitions`.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pydrake.common.value import AbstractValue
from pydrake.systems.analysis import Simulator
from shapely.geometry import Point, box

from mrodrake.control.adaptive import AdaptiveGains, NavigationTask
from mrodrake.control.freespace import Disk
from mrodrake.control.local import local_task
from mrodrake.control.pointworld import PointWorldMap
from mrodrake.errors import UserError
from mrodrake.execution.commands import TaskCommand
from mrodrake.scenario import DESIGN_MASS_RATIO, load_scenario
from mrodrake.systems.controllers import MissionControllers, NavigationController, TransportController
from mrodrake.systems.transition import simulate_transition
from mrodrake.viz.figures import figure_signals, figure_trajectory
from tests.helpers.transitions import CASE1, SCEN, check_guarantees
from tests.helpers.transitions import transition_property as _property


# ---------------------------------------------------------------------------------------------- transitions
@pytest.mark.parametrize("robot,src,dst", [("r1", "p1", "p3"), ("r3", "p4", "p2")])
def test_robot_navigation(robot, src, dst):
    r = simulate_transition(CASE1, "navigate", robot, src_region=src, dst_region=dst, t_max=5000.0)
    check_guarantees(r)
    assert {d.name for d in r.others} == {"r1", "r2", "r3", "o1", "o2"} - {robot}


@pytest.mark.slow
@pytest.mark.parametrize("src,dst", list(itertools.permutations(range(4), 2)))
def test_robot_navigation_every_ordered_pair(src, dst):
    r = simulate_transition(CASE1, "navigate", "r1", src_region=src, dst_region=dst, t_max=5000.0)
    check_guarantees(r)


WAREHOUSE = load_scenario(SCEN / "maps" / "warehouse.yaml")


def _in_aisle(r, y0: float, y1: float) -> bool:
    """Some of the entity's path runs between two shelf rows (x in [12, 48], y in [y0, y1])."""
    P = r.positions
    return bool(np.any((P[:, 0] > 14.0) & (P[:, 0] < 46.0) & (P[:, 1] > y0) & (P[:, 1] < y1)))


@pytest.mark.parametrize("kind,entity,team,src,dst,aisle", [
    ("navigate", "r1", [], "p5", "p6", (22.0, 36.0)),
    ("transport", "o1", ["r1", "r2"], "p1", "p4", (14.0, 20.0)),
])
def test_warehouse_aisles_are_travelled(kind, entity, team, src, dst, aisle):
    """On the warehouse map (6 m aisles between 2 m shelf rows) a robot and a robots-object
    team travel along the aisles (the point-world map resolves the passage; no degenerate map)."""
    r = simulate_transition(WAREHOUSE, kind, entity, team=team, src_region=src, dst_region=dst, t_max=8000.0)
    check_guarantees(r)
    assert _in_aisle(r, *aisle)


def test_transport_by_two_robots(tmp_path):
    r = simulate_transition(CASE1, "transport", "o1", team=["r1", "r2"], src_region="p2", dst_region="p4",
                            t_max=8000.0)
    check_guarantees(r)
    assert {d.name for d in r.others} == {"r3", "o2"}
    u = r.inputs
    np.testing.assert_allclose(r.member_input("r1") + r.member_input("r2"), u, atol=1e-12)
    for name in r.team:  # the robots follow rigidly at their grasp offsets
        off = r.member_positions(name) - r.positions
        np.testing.assert_allclose(np.linalg.norm(off, axis=1), 0.2 + 0.75 + CASE1.layout.grasp_gap)
    fig4 = figure_trajectory(r, tmp_path / "fig4.png")  # paper Figs. 4 and 5 for this transport
    fig5 = figure_signals(r, tmp_path / "fig5.png", member="r2")
    assert len(fig4.axes) == 2 and len(fig5.axes) == 2
    assert (tmp_path / "fig4.png").stat().st_size > 10_000 and (tmp_path / "fig5.png").stat().st_size > 10_000
    np.testing.assert_allclose(fig4.axes[1].lines[1].get_xydata(), r.point_world())


def test_transport_by_three_robots():
    r = simulate_transition(CASE1, "transport", "o2", team=["r1", "r2", "r3"], src_region="p1", dst_region="p3",
                            t_max=8000.0, cf=[0.5, 0.3, 0.2])
    check_guarantees(r)
    np.testing.assert_allclose(r.member_input("r2"), 0.3 * r.inputs)


@pytest.mark.slow
@pytest.mark.parametrize("obj,team,src,dst", [("o1", ["r1", "r3"], "p2", "p1"), ("o2", ["r2", "r3"], "p1", "p4"),
                                               ("o1", ["r2", "r3"], "p2", "p3"),
                                               ("o2", ["r3", "r1", "r2"], "p1", "p2")])
def test_more_transports(obj, team, src, dst):
    check_guarantees(simulate_transition(CASE1, "transport", obj, team=team, src_region=src, dst_region=dst,
                                         t_max=8000.0))


_RANDOMIZED_BODIES = {"o2": {"mass": 0.430, "scale": 2.338, "frequency": 0.784},
                   "r1": {"mass": 1.455, "scale": 2.282, "frequency": 0.853},
                   "r3": {"mass": 0.561, "scale": 1.824, "frequency": 0.886}}


def _randomized_transport(scenario):
    others = [Disk("r2", (202.025, -129.012), 0.75), Disk("o1", (250.406, -282.977), 0.2)]
    return simulate_transition(scenario, "transport", "o2", team=["r1", "r3"], src_region="p2", dst_region="p3",
                               others=others, start=(100.029, -160.088), goal=(198.878, -130.547),
                               true_params_override=_RANDOMIZED_BODIES, t_max=60.0, accuracy=1e-3)


def test_randomized_transport_stays_damped():
    """A transport of a randomized case-I mission (step 21) that diverged with the paper's initial estimate:
    o2 (0.43 kg, scale 2.34) carried by r1 (1.46 kg, 2.28) and r3 (0.56 kg, 1.82) from p2 to p3, α_A = 12.9,
    mission integration settings (RK3, accuracy 1e-3).  With the paper's α̂(0) = 0 the damping k_v + 3/2 α̂ stays
    near 1.5 while the anti-damping part of f reaches 4.7: e_v grows like exp(1.2 t) and the team leaves its
    free space within the first minute (asserted below).  With α̂(0) at the design bound (3 bodies x 5) the
    velocity loop is contracting and speeds stay below the 3 v_max the bound implies (control/adaptive.py)."""
    r = _randomized_transport(CASE1)
    assert "failed" not in r.status, r.status
    assert r.t_final == pytest.approx(60.0)
    assert r.log["alpha_hat"].iloc[0] == pytest.approx(3 * CASE1.control.alpha_max)
    speed = np.hypot(r.log["vx"], r.log["vy"])
    assert speed.max() < 3.0 * r.task.v_max, f"max speed {speed.max():.2f} m/s"
    assert np.all(np.isfinite(r.log.to_numpy()))

    paper = _randomized_transport(dataclasses.replace(CASE1, control=dataclasses.replace(CASE1.control, alpha_max=0.0)))
    fast = np.hypot(paper.log["vx"], paper.log["vy"]).max()
    assert "failed" in paper.status or fast > 3.0 * paper.task.v_max, (paper.status, fast)


transitions = st.sampled_from([("navigate", "r1", ()), ("navigate", "r2", ()),
                               ("transport", "o1", ("r1", "r2")), ("transport", "o2", ("r1", "r2", "r3"))])


# The design range of the controllers (mrodrake.scenario.DESIGN_MASS_RATIO, DESIGN_ALPHA_MAX) for every body:
# masses m̂_0/5 .. 5 m̂_0 = 0.1 .. 2.5 kg, the paper's friction with scale 0 .. 2.5 (α = 2 scale <= 5) and
# frequency 0.2 .. 1.0 (the campaigns' randomisation: masses x U[0.5, 2], scale 1.25 x U[0, 2], frequency U[0.2, 1]).
_LO, _HI = CASE1.control.m_hat0 / DESIGN_MASS_RATIO, CASE1.control.m_hat0 * DESIGN_MASS_RATIO
masses = st.lists(st.floats(_LO, _HI), min_size=4, max_size=4)
scales = st.lists(st.floats(0.0, CASE1.control.alpha_max / 2.0), min_size=4, max_size=4)
frequencies = st.lists(st.floats(0.2, 1.0), min_size=4, max_size=4)


# Hypothesis seeds its derandomized (CI) examples from these functions' source: they keep calling `_property`.
@settings(max_examples=1, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(transitions, masses, scales, frequencies, st.integers(0, 10_000), st.integers(0, 11))
def test_random_true_parameters_and_initial_spots(case, masses, scales, frequencies, seed, pair_index):
    """True masses, friction scales and frequencies anywhere in the design range, random start spots (one quick
    sample; 30 in the slow variant below)."""
    _property(case, masses, scales, frequencies, seed, pair_index)


@pytest.mark.slow
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(transitions, masses, scales, frequencies, st.integers(0, 10_000), st.integers(0, 11))
def test_random_true_parameters_and_initial_spots_many(case, masses, scales, frequencies, seed, pair_index):
    _property(case, masses, scales, frequencies, seed, pair_index)


# ---------------------------------------------------------------------------------------------- controllers
ROOM = box(0, 0, 20, 12).difference(Point(6, 6).buffer(1.5))


@pytest.fixture(scope="module")
def room_task():
    pw = PointWorldMap.build(ROOM)
    return NavigationTask.build(pw, [18.0, 10.0], AdaptiveGains(m_hat0=0.7, alpha_hat0=0.1), k1=1.0, k2=1.0,
                                r_bar_cap=0.1, tau_cap=0.01, start=[2.0, 2.0])


def test_navigation_controller_outputs_the_law(room_task):
    ctrl = NavigationController(room_task)
    ctx = ctrl.CreateDefaultContext()
    s = np.array([3.0, 4.0, 0.2, -0.1])
    ctrl.state_port.FixValue(ctx, s)
    np.testing.assert_allclose(ctrl.estimates_port.Eval(ctx), [0.7, 0.1])
    ev = room_task.evaluate(s[:2], s[2:], 0.7, 0.1)
    np.testing.assert_allclose(ctrl.u_port.Eval(ctx), ev.u)
    np.testing.assert_allclose(ctrl.EvalTimeDerivatives(ctx).CopyToVector(), [ev.m_hat_dot, ev.alpha_hat_dot])
    ctrl.task_port.FixValue(ctx, AbstractValue.Make(None))  # disabled: zero input, frozen estimates
    np.testing.assert_allclose(ctrl.u_port.Eval(ctx), 0.0)
    np.testing.assert_allclose(ctrl.EvalTimeDerivatives(ctx).CopyToVector(), 0.0)


def test_controller_dependencies_allow_supervisor_routing(room_task):
    """u depends on the state and task inputs; the estimates output on neither (no algebraic loops)."""
    ctrl = TransportController(["a", "b"], room_task.__class__(room_task.pw_map, room_task.nf, room_task.goal,
                                                              room_task.gains, np.array([0.25, 0.75])))
    st_i, task_i = ctrl.state_port.get_index(), ctrl.task_port.get_index()
    assert ctrl.HasDirectFeedthrough(st_i, ctrl.u_port.get_index())
    assert ctrl.HasDirectFeedthrough(task_i, ctrl.member_u_ports[0].get_index())
    assert not ctrl.HasDirectFeedthrough(st_i, ctrl.estimates_port.get_index())
    assert not ctrl.HasDirectFeedthrough(task_i, ctrl.estimates_port.get_index())
    ctx = ctrl.CreateDefaultContext()
    ctrl.state_port.FixValue(ctx, [3.0, 4.0, 0.0, 0.0])
    u = ctrl.u_port.Eval(ctx)
    np.testing.assert_allclose(ctrl.GetOutputPort("u_a").Eval(ctx), 0.25 * u)
    np.testing.assert_allclose(ctrl.GetOutputPort("u_b").Eval(ctx), 0.75 * u)
    with pytest.raises(ValueError):
        TransportController(["a", "b", "c"], ctrl._task)


def test_new_episode_resets_the_estimates_and_a_new_task_within_it_does_not(room_task):
    """A supervisor swapping tasks: within one episode (one primitive switching to the local law, or to its
    next leg) m̂, α̂ carry over; a new episode restarts them from its task's m̂(0), α̂(0) at the next step."""
    ctrl = NavigationController(room_task)
    ctx = ctrl.CreateDefaultContext()
    ctrl.state_port.FixValue(ctx, [3.0, 4.0, 1.0, 1.0])
    ctrl.task_port.FixValue(ctx, AbstractValue.Make(TaskCommand(room_task, 1)))
    sim = Simulator(ctrl, ctx)
    sim.AdvanceTo(1.0)
    moved = ctx.get_continuous_state_vector().CopyToVector()
    assert moved[1] > 0.1  # α̂ grew (‖e_v‖ > 0)
    other = NavigationTask(room_task.pw_map, room_task.nf, room_task.goal, AdaptiveGains(m_hat0=5.0, alpha_hat0=2.0),
                           room_task.cf)
    ctrl.task_port.FixValue(ctx, AbstractValue.Make(TaskCommand(other, 1)))
    sim.AdvanceTo(1.0 + 1e-9)
    np.testing.assert_allclose(ctx.get_continuous_state_vector().CopyToVector(), moved, rtol=1e-6)
    ctrl.task_port.FixValue(ctx, AbstractValue.Make(TaskCommand(other, 2)))
    sim.AdvanceTo(1.0 + 2e-9)
    np.testing.assert_allclose(ctx.get_continuous_state_vector().CopyToVector(), [5.0, 2.0], atol=1e-6)


def test_mission_controllers_compute_the_single_controllers(room_task):
    """MissionControllers gives every active controller the outputs and rates of its single controller (the
    same floating-point operations: equal to the last bit); an idle one has zero input and frozen estimates,
    and its state input is never evaluated."""
    team_task = dataclasses.replace(room_task, cf=np.array([0.25, 0.75]))
    gains = room_task.gains
    bank = MissionControllers([("nav_a", ()), ("nav_b", ()), ("ab_ctrl", ("a", "b"))], gains)
    ctx = bank.CreateDefaultContext()
    s_a, s_t = np.array([3.0, 4.0, 0.2, -0.1]), np.array([5.0, 3.0, -0.3, 0.4])
    bank.state_ports["nav_a"].FixValue(ctx, s_a)
    bank.state_ports["ab_ctrl"].FixValue(ctx, s_t)
    bank.task_ports["nav_a"].FixValue(ctx, AbstractValue.Make(TaskCommand(room_task, 0)))
    bank.task_ports["nav_b"].FixValue(ctx, AbstractValue.Make(None))
    bank.task_ports["ab_ctrl"].FixValue(ctx, AbstractValue.Make(TaskCommand(team_task, 0)))
    bank.set_estimates(ctx, "ab_ctrl", 1.5, 2.5)
    rates = bank.EvalTimeDerivatives(ctx).CopyToVector()

    nav = NavigationController(room_task)
    nc = nav.CreateDefaultContext()
    nav.state_port.FixValue(nc, s_a)
    u, forces = bank.u_port.Eval(ctx), bank.forces_port.Eval(ctx)
    assert bank.force_slots == [("nav_a", None), ("nav_b", None), ("ab_ctrl", "a"), ("ab_ctrl", "b")]
    np.testing.assert_array_equal(u[0:2], nav.u_port.Eval(nc))
    np.testing.assert_array_equal(forces[0:2], nav.u_port.Eval(nc))
    np.testing.assert_array_equal(rates[0:2], nav.EvalTimeDerivatives(nc).CopyToVector())
    np.testing.assert_array_equal(u[2:4], 0.0)
    np.testing.assert_array_equal(forces[2:4], 0.0)
    np.testing.assert_array_equal(rates[2:4], 0.0)
    team = TransportController(["a", "b"], team_task)
    tc = team.CreateDefaultContext()
    team.state_port.FixValue(tc, s_t)
    team.set_estimates(tc, 1.5, 2.5)
    np.testing.assert_array_equal(rates[4:6], team.EvalTimeDerivatives(tc).CopyToVector())
    np.testing.assert_array_equal(u[4:6], team.u_port.Eval(tc))
    for k in range(2):
        np.testing.assert_array_equal(forces[4 + 2 * k : 6 + 2 * k], team.member_u_ports[k].Eval(tc))
    np.testing.assert_array_equal(bank.estimates_port.Eval(ctx)[4:6], [1.5, 2.5])
    assert bank.fault(ctx, "nav_b") == "" and bank.fault(ctx, "nav_a") == nav.fault(nc) == ""
    assert bank.first_fault(ctx) is None
    past_pole = local_task([5.0, 0.0], [[2.5, 1.5]], [1.0], [0.0, 0.0], 8.0, gains, k1=0.25, k2=5.0, cf=2,
                           start=[0.0, 0.0])
    bank.task_ports["ab_ctrl"].FixValue(ctx, AbstractValue.Make(TaskCommand(past_pole, 0)))
    bank.state_ports["ab_ctrl"].FixValue(ctx, [2.5, 1.0, 0.3, 0.0])  # inside the other entity's disk
    name, why = bank.first_fault(ctx)
    assert name == "ab_ctrl" and why == bank.fault(ctx, "ab_ctrl") != ""
    for c in bank.names:
        assert not bank.HasDirectFeedthrough(int(bank.state_ports[c].get_index()),
                                             int(bank.estimates_port.get_index()))


def test_mission_controllers_reset_only_on_a_new_episode(room_task):
    """As a single controller: a new task within an episode keeps m̂, α̂; a new episode restarts them from its
    task's m̂(0), α̂(0) at the next step; the other controllers are untouched."""
    bank = MissionControllers([("nav_a", ()), ("nav_b", ())], room_task.gains)
    ctx = bank.CreateDefaultContext()
    bank.state_ports["nav_a"].FixValue(ctx, [3.0, 4.0, 1.0, 1.0])
    bank.task_ports["nav_a"].FixValue(ctx, AbstractValue.Make(TaskCommand(room_task, 1)))
    bank.task_ports["nav_b"].FixValue(ctx, AbstractValue.Make(None))
    bank.set_estimates(ctx, "nav_b", 3.0, 4.0)
    sim = Simulator(bank, ctx)
    sim.AdvanceTo(1.0)
    moved = bank.estimates(ctx, "nav_a")
    assert moved[1] > 0.1  # α̂ grew (‖e_v‖ > 0)
    other = NavigationTask(room_task.pw_map, room_task.nf, room_task.goal, AdaptiveGains(m_hat0=5.0, alpha_hat0=2.0),
                           room_task.cf)
    bank.task_ports["nav_a"].FixValue(ctx, AbstractValue.Make(TaskCommand(other, 1)))
    sim.AdvanceTo(1.0 + 1e-9)
    np.testing.assert_allclose(bank.estimates(ctx, "nav_a"), moved, rtol=1e-6)
    bank.task_ports["nav_a"].FixValue(ctx, AbstractValue.Make(TaskCommand(other, 2)))
    sim.AdvanceTo(1.0 + 2e-9)
    np.testing.assert_allclose(bank.estimates(ctx, "nav_a"), [5.0, 2.0], atol=1e-6)
    np.testing.assert_array_equal(bank.estimates(ctx, "nav_b"), [3.0, 4.0])
    with pytest.raises(ValueError):
        MissionControllers([("c", ()), ("c", ())], room_task.gains)


def test_bad_requests_are_user_errors():
    with pytest.raises(UserError, match="not a robot"):
        simulate_transition(CASE1, "navigate", "o1", src_region="p1", dst_region="p2")
    with pytest.raises(UserError, match="team"):
        simulate_transition(CASE1, "transport", "o1", team=[], src_region="p2", dst_region="p1")
    with pytest.raises(UserError, match="same as the source"):
        simulate_transition(CASE1, "navigate", "r1", src_region="p1", dst_region="p1")
    with pytest.raises(UserError, match="true_params_override.r9"):
        simulate_transition(CASE1, "navigate", "r1", src_region="p1", dst_region="p2",
                            true_params_override={"r9": {"mass": 1.0}})
    with pytest.raises(UserError, match="unknown keys"):
        simulate_transition(CASE1, "navigate", "r1", src_region="p1", dst_region="p2",
                            true_params_override={"r1": {"masss": 1.0}})


def test_estimates_start_at_the_entity_design_bound(room_task):
    """α̂(0) = max(α̂_0, n ᾱ) with n the entity's bodies (1 for a robot, 1 + members for a team), at construction
    and on every new task; alpha_max = 0 is the paper's α̂(0) = α̂_0."""
    import dataclasses

    g = AdaptiveGains(m_hat0=0.7, alpha_hat0=0.1, alpha_max=5.0)
    assert g.initial_estimates(1) == (0.7, 5.0) and g.initial_estimates(4) == (0.7, 20.0)
    assert AdaptiveGains(alpha_hat0=30.0, alpha_max=5.0).initial_estimates(3)[1] == 30.0
    assert AdaptiveGains(alpha_hat0=0.1).initial_estimates(3)[1] == 0.1
    with pytest.raises(ValueError):
        g.initial_estimates(0)
    task = dataclasses.replace(room_task, gains=g)
    nav = NavigationController(task)
    np.testing.assert_allclose(nav.estimates_port.Eval(nav.CreateDefaultContext()), [0.7, 5.0])
    team = TransportController(["a", "b"], dataclasses.replace(task, cf=np.array([0.5, 0.5])))
    ctx = team.CreateDefaultContext()
    np.testing.assert_allclose(team.estimates_port.Eval(ctx), [0.7, 15.0])
    team.state_port.FixValue(ctx, [3.0, 4.0, 0.0, 0.0])
    other = dataclasses.replace(task, cf=np.array([0.5, 0.5]), gains=dataclasses.replace(g, alpha_max=2.0))
    team.task_port.FixValue(ctx, AbstractValue.Make(TaskCommand(other, 1)))
    sim = Simulator(team, ctx)
    sim.AdvanceTo(1e-9)
    np.testing.assert_allclose(ctx.get_continuous_state_vector().CopyToVector(), [0.7, 6.0], atol=1e-6)
