"""Uncertain plants as Drake systems (paper eqs. (1), (2), (5))."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from pydrake.systems.analysis import Simulator

from mrodrake.execution.commands import SyncCommand
from mrodrake.scenario import Friction, load_scenario
from mrodrake.systems.plants import CoupledPlant, MissionPlants, ObjectPlant, RobotPlant, friction

SCEN = Path(__file__).resolve().parents[2] / "scenarios"
num = st.floats(-100, 100, allow_nan=False)


@pytest.fixture(scope="module")
def case1():
    return load_scenario(SCEN / "case_study_1.yaml")


def _xdot(system, context):
    return system.EvalTimeDerivatives(context).CopyToVector()


@given(num, num, num, num, st.floats(0, 5), st.floats(0, 3))
def test_friction_models_satisfy_assumption_1(x1, x2, v1, v2, scale, freq):
    """‖f(x, ẋ)‖ ≤ α‖ẋ‖ with α = 2·scale (paper model) and α = scale (viscous)."""
    x, v = np.array([x1, x2]), np.array([v1, v2])
    fp = friction("paper", scale, freq, x, v)
    expected = scale * math.sin(freq * (x1 + x2)) * np.array([(math.exp(-abs(v1)) + 1) * v1,
                                                              (math.exp(-abs(v2)) + 1) * v2])
    np.testing.assert_allclose(fp, expected, rtol=1e-12, atol=1e-12)
    assert np.linalg.norm(fp) <= 2 * scale * np.linalg.norm(v) * (1 + 1e-12) + 1e-300
    np.testing.assert_allclose(friction("viscous", scale, freq, x, v), scale * v)
    with pytest.raises(ValueError):
        friction("coulomb", scale, freq, x, v)


def test_robot_plant_matches_the_viscous_closed_form():
    """m ẍ + c ẋ = u: ẋ(t) = u/c (1 − e^{−ct/m}), x(t) = u/c (t − m/c (1 − e^{−ct/m}))."""
    m, c, u = 2.0, 0.5, np.array([1.0, -3.0])
    plant = RobotPlant(m, Friction(model="viscous", scale=c))
    ctx = plant.CreateDefaultContext()
    plant.u_port.FixValue(ctx, u)
    plant.set_state(ctx, [1.0, 2.0])
    sim = Simulator(plant, ctx)
    sim.get_mutable_integrator().set_target_accuracy(1e-10)
    sim.AdvanceTo(3.0)
    s = ctx.get_continuous_state_vector().CopyToVector()
    e = math.exp(-c * 3.0 / m)
    np.testing.assert_allclose(s[2:], u / c * (1 - e), rtol=1e-7)
    np.testing.assert_allclose(s[:2], [1.0, 2.0] + u / c * (3.0 - m / c * (1 - e)), rtol=1e-7)
    np.testing.assert_allclose(plant.state_port.Eval(ctx), s)


def test_robot_plant_paper_friction_and_contact_force(case1):
    plant = RobotPlant.from_scenario(case1, "r2")
    ctx = plant.CreateDefaultContext()
    x, v, u, h = np.array([3.0, -1.0]), np.array([0.4, -2.0]), np.array([1.0, 2.0]), np.array([0.3, 0.1])
    plant.set_state(ctx, x, v)
    plant.u_port.FixValue(ctx, u)
    acc = _xdot(plant, ctx)[2:]
    np.testing.assert_allclose(acc, (u - friction("paper", 1.25, 0.5, x, v)) / 1.0)  # h unconnected: zero
    plant.h_port.FixValue(ctx, h)
    np.testing.assert_allclose(_xdot(plant, ctx)[2:], (u - h - friction("paper", 1.25, 0.5, x, v)) / 1.0)
    np.testing.assert_allclose(_xdot(plant, ctx)[:2], v)


def test_true_parameters_vary_per_context(case1):
    """Two contexts of one plant with different true masses/frictions: no rebuild needed (Monte Carlo)."""
    plant = RobotPlant.from_scenario(case1, "r1")
    a, b = plant.CreateDefaultContext(), plant.CreateDefaultContext()
    for c in (a, b):
        plant.set_state(c, [1.0, 1.0], [1.0, 0.0])
        plant.u_port.FixValue(c, [2.0, 0.0])
    plant.set_body_parameters(b, 0, mass=3.0, scale=0.0)
    np.testing.assert_allclose(plant.body_parameters(b), [3.0, 0.0, 0.5])
    np.testing.assert_allclose(_xdot(plant, b)[2:], [2.0 / 3.0, 0.0])
    np.testing.assert_allclose(_xdot(plant, a)[2:], [2.0, 0.0] - friction("paper", 1.25, 0.5, [1.0, 1.0], [1.0, 0.0]))


def test_object_plant_moves_only_under_contact_force(case1):
    plant = ObjectPlant.from_scenario(case1, "o1")
    ctx = plant.CreateDefaultContext()
    plant.set_state(ctx, [5.0, 5.0])
    np.testing.assert_allclose(_xdot(plant, ctx), 0.0)
    plant.h_port.FixValue(ctx, [0.5, 0.0])
    np.testing.assert_allclose(_xdot(plant, ctx), [0, 0, 0.5 / 0.25, 0])


def test_coupled_plant_is_eq_coupled_dynamics(case1):
    """m_A ẍ = Σ u_i − f_o(x_o, ẋ) − Σ f_i(x_o + offset_i, ẋ) with m_A = m_o + Σ m_i."""
    plant = CoupledPlant.from_scenario(case1, "o2", ["r1", "r3", "r2"])
    ctx = plant.CreateDefaultContext()
    plant.set_body_parameters(ctx, 2, mass=2.5, scale=0.7)  # r3
    x, v = np.array([3.0, -2.0]), np.array([0.5, 1.5])
    plant.set_state(ctx, x, v)
    us = [np.array([1.0, 0.0]), np.array([0.0, 2.0]), np.array([-0.5, 0.5])]
    for port, u in zip(plant.u_ports, us):
        port.FixValue(ctx, u)
    off = plant.offsets
    assert [p.get_name() for p in plant.u_ports] == ["u_r1", "u_r3", "u_r2"]
    m_a = 0.25 + 1.0 + 2.5 + 1.0
    assert plant.total_mass(ctx) == pytest.approx(m_a)
    f = (friction("paper", 1.25, 0.5, x, v) + friction("paper", 1.25, 0.5, x + off[0], v)
         + friction("paper", 0.7, 0.5, x + off[1], v) + friction("paper", 1.25, 0.5, x + off[2], v))
    np.testing.assert_allclose(_xdot(plant, ctx), np.r_[v, (sum(us) - f) / m_a], rtol=1e-12)
    for k, name in enumerate(["r1", "r3", "r2"]):
        np.testing.assert_allclose(plant.GetOutputPort(f"state_{name}").Eval(ctx), np.r_[x + off[k], v])
    np.testing.assert_allclose(np.linalg.norm(off, axis=1), 0.2 + 0.75 + case1.layout.grasp_gap)


def test_plant_outputs_do_not_feed_through_inputs(case1):
    """State outputs depend on the state only, so controllers can be wired in closed loop."""
    for plant in (RobotPlant.from_scenario(case1, "r1"), CoupledPlant.from_scenario(case1, "o1", ["r1", "r2"])):
        for i in range(plant.num_input_ports()):
            for o in range(plant.num_output_ports()):
                assert not plant.HasDirectFeedthrough(i, o)


def test_invalid_plants():
    with pytest.raises(ValueError):
        RobotPlant(-1.0)
    with pytest.raises(ValueError):
        CoupledPlant(1.0, None, ["a", "a"], [1.0, 1.0], [None, None], np.zeros((2, 2)))
    with pytest.raises(ValueError):
        CoupledPlant(1.0, None, [], [], [], np.zeros((0, 2)))


def _mission_plants(case1, moving, offsets):
    """MissionPlants of case I with team o2_r1+r3 (object 1, robots 0, 2); the plants in ``moving`` unfrozen,
    every sync command at version 0 with state (x, v) = (k, −k, 0.1 k, 0.2 k) for plant k."""
    plants = MissionPlants(case1, [("o2_r1+r3", 1, (0, 2))])
    ctx = plants.CreateDefaultContext()
    for k, name in enumerate(plants.names):
        off = tuple(map(tuple, offsets)) if name == "o2_r1+r3" else ()
        cmd = SyncCommand(0, (float(k), -float(k)), (0.1 * k, 0.2 * k), name not in moving, off)
        plants.sync_ports[name].FixValue(ctx, cmd)
    return plants, ctx


def test_mission_plants_compute_the_single_plants(case1):
    """Every moving plant of MissionPlants has the dynamics of its single plant (the same floating-point
    operations: equal to the last bit); parked plants have zero dynamics."""
    offsets = np.array([[0.8, 0.3], [-0.6, -0.9]])
    plants, ctx = _mission_plants(case1, {"r2", "o1", "o2_r1+r3"}, offsets)
    names = plants.names
    assert names == ["r1", "r2", "r3", "o1", "o2", "o2_r1+r3"]
    rng = np.random.default_rng(3)
    s = rng.uniform(-5.0, 5.0, 4 * len(names))
    ctx.SetContinuousState(s)
    u_r2, u_team = np.array([1.0, -2.0]), [np.array([0.5, 0.25]), np.array([-1.5, 2.0])]
    assert plants.force_slots == [("r1", None), ("r2", None), ("r3", None), ("o2_r1+r3", "r1"), ("o2_r1+r3", "r3")]
    # the parked robots' forces are NaN: a parked plant never reads its force
    plants.forces_port.FixValue(ctx, np.concatenate([[np.nan, np.nan], u_r2, [np.nan, np.nan], *u_team]))
    xdot = plants.EvalTimeDerivatives(ctx).CopyToVector().reshape(-1, 4)
    for k in (0, 2, 4):
        np.testing.assert_array_equal(xdot[k], 0.0)

    robot = RobotPlant.from_scenario(case1, "r2")
    rc = robot.CreateDefaultContext()
    robot.set_state(rc, s[4:6], s[6:8])
    robot.u_port.FixValue(rc, u_r2)
    np.testing.assert_array_equal(xdot[1], _xdot(robot, rc))
    obj = ObjectPlant.from_scenario(case1, "o1")
    oc = obj.CreateDefaultContext()
    obj.set_state(oc, s[12:14], s[14:16])
    np.testing.assert_array_equal(xdot[3], _xdot(obj, oc))
    team = CoupledPlant.from_scenario(case1, "o2", ["r1", "r3"], offsets=offsets)
    tc = team.CreateDefaultContext()
    team.set_state(tc, s[20:22], s[22:24])
    for port, u in zip(team.u_ports, u_team):
        port.FixValue(tc, u)
    np.testing.assert_array_equal(xdot[5], _xdot(team, tc))
    for k, name in enumerate(["r1", "r3"]):
        np.testing.assert_array_equal(plants.member_ports["o2_r1+r3"][k].Eval(ctx),
                                      team.GetOutputPort(f"state_{name}").Eval(tc))
    assert plants.moving(ctx) == ["r2", "o1", "o2_r1+r3"]


def test_mission_plants_sync_on_a_new_version(case1):
    """A per-step update copies a plant's commanded [x, ẋ] when its command's version changes; a parked
    plant then stays there."""
    plants, ctx = _mission_plants(case1, set(), np.zeros((2, 2)))
    sim = Simulator(plants, ctx)
    sim.AdvanceTo(1.0)
    s = ctx.get_continuous_state_vector().CopyToVector().reshape(-1, 4)
    k = np.arange(len(plants.names), dtype=float)
    np.testing.assert_array_equal(s, np.column_stack([k, -k, 0.1 * k, 0.2 * k]))
    plants.sync_ports["r3"].FixValue(ctx, SyncCommand(1, (7.0, 8.0), (0.0, 0.0), True, ()))
    sim.AdvanceTo(2.0)
    np.testing.assert_array_equal(plants.plant_state(ctx, "r3"), [7.0, 8.0, 0.0, 0.0])
    np.testing.assert_array_equal(plants.plant_state(ctx, "r2"), [1.0, -1.0, 0.1, 0.2])


def test_mission_plant_states_do_not_feed_through_the_forces(case1):
    plants = MissionPlants(case1, [("o1_r1+r2", 0, (0, 1))])
    for o in range(plants.num_output_ports()):
        assert not plants.HasDirectFeedthrough(int(plants.forces_port.get_index()), o)
    with pytest.raises(ValueError):
        MissionPlants(case1, [("o1_r1+r1", 0, (0, 0))])
