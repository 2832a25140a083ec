"""Whole missions on tasks that stress execution: generated tasks whose label monitor, action order and
integration are delicate ((3, 1, 3, 11), (3, 2, 4, 15), (4, 2, 4, 21), each several minutes on the office map:
slow set, ``--runslow``); campaign missions on the corridor map (a dead-end goal, a door, boxed-in starts);
and an until-task on tiny whose satisfaction depends on which crossing interleavings the geometry allows."""

from __future__ import annotations

import pytest
import yaml

from mrodrake.planning.generate import generate_scenario
from mrodrake.planning.placement import unreachable_arrival
from mrodrake.planning.plan import plan_scenario
from mrodrake.run import run_mission
from mrodrake.scenario import scenario_from_dict
from tests.helpers.campaign import RANDOMIZE, campaign_mission
from tests.planning.conftest import SCENARIOS


@pytest.mark.slow
@pytest.mark.parametrize("n, m, k, seed", [(3, 1, 3, 11), (3, 2, 4, 15), (4, 2, 4, 21)])
def test_generated_reproducer_runs_to_completion(n, m, k, seed):
    sc = generate_scenario(n, m, k, seed)
    log = run_mission(sc, seed=seed)
    assert log.ok, log.message
    assert log.steps_done == log.steps_total
    labels = log.events[log.events["kind"] == "label"]
    assert labels["ok"].all()


CORRIDOR_N2_M1_K3_S1 = "{robots: [2], objects: [1], regions: [3], seeds: {start: 1, count: 1}, map: corridor}"


def test_a_transport_to_the_end_of_a_narrow_corridor_runs_to_completion(tmp_path):
    """Campaign mission gen_corridor_n2_m1_k3_s1-p0-l0-d0 (randomized, its layout seed): r1 carries o1 to p6
    at the dead end of the corridor, whose goal maps beyond the whole map's circle barrier ("transport of o1:
    point ... is not inside the circle barrier"); it runs on windows there."""
    task, sc, plan = campaign_mission(tmp_path, CORRIDOR_N2_M1_K3_S1, "gen_corridor_n2_m1_k3_s1-p0-l0-d0")
    log = run_mission(sc, plan=plan, seed=task.layout_seed)
    assert log.ok, log.message
    assert log.steps_done == log.steps_total
    prims = log.events[log.events["kind"] == "primitive"]
    assert any(a.startswith("transport o1 by r1 ") and a.endswith("->p6") for a in prims["action"])


def test_a_robot_parked_by_a_door_leaves_the_team_a_way_out(tmp_path):
    """Campaign mission gen_corridor_n3_m1_k3_s1-p0-l0-d0: r1 parked in p4 2.4 m inside the 6 m door of room
    S1, and the team r2 + o1 (covering radius 1.91 m) that formed in p4 afterwards had no way out ("transport
    of o1: goal unreachable"); spots now keep the region's later trips connected."""
    task, sc, plan = campaign_mission(tmp_path, CORRIDOR_N2_M1_K3_S1.replace("robots: [2]", "robots: [3]"),
                                      "gen_corridor_n3_m1_k3_s1-p0-l0-d0")
    log = run_mission(sc, plan=plan, seed=task.layout_seed)
    assert log.ok, log.message
    assert log.steps_done == log.steps_total


def test_a_robot_boxed_in_at_the_corridor_end_gets_a_layout_it_can_leave(tmp_path):
    """Campaign mission gen_corridor_n3_m1_k4_s1100-p0-l0-d0: the three robots start in p6 at the corridor's
    west end, r2 east of r1 with 0.22 m left between its grown disk and the grown walls on either side; the
    bare geometry connected r1 to p2, but no grid path or window found the gap ("navigate of r1: point ... is
    not inside the circle barrier" at t = 3 s).  Placement now closes gaps narrower than
    0.5 m beside parked entities."""
    randomize = RANDOMIZE.replace("seed: 13", "seed: 1100")
    task, sc, plan = campaign_mission(tmp_path, CORRIDOR_N2_M1_K3_S1.replace("robots: [2]", "robots: [3]")
                                      .replace("regions: [3]", "regions: [4]").replace("start: 1,", "start: 1100,"),
                                      "gen_corridor_n3_m1_k4_s1100-p0-l0-d0", randomize=randomize, iterations=3000)
    assert unreachable_arrival(plan.ts, plan.placement) is None
    log = run_mission(sc, plan=plan, seed=task.layout_seed)
    assert log.ok, log.message
    assert log.steps_done == log.steps_total


def test_a_concurrent_motion_boxed_in_by_a_parked_robot_waits_for_it_to_leave(tmp_path):
    """Campaign mission gen_corridor_n3_m2_k4_s1100-p0-l0-d0, concurrent: r1 and r3 leave p6 at the corridor's
    west end in the same step, and r3's way out runs past r1's spot.  r3 asked first, found no free space and,
    since nothing was moving, was started to report "goal unreachable" although r1 was ready to clear the way;
    a motion without a free space now waits while another job can move."""
    task, sc, plan = campaign_mission(tmp_path, CORRIDOR_N2_M1_K3_S1.replace("robots: [2]", "robots: [3]")
                                      .replace("objects: [1]", "objects: [2]").replace("regions: [3]", "regions: [4]")
                                      .replace("start: 1,", "start: 1100,"), "gen_corridor_n3_m2_k4_s1100-p0-l0-d0",
                                      randomize=RANDOMIZE.replace("seed: 13", "seed: 1100"), iterations=3000)
    log = run_mission(sc, plan=plan, seed=task.layout_seed, execution="concurrent", prefetch=False)
    assert log.ok, log.message
    assert log.steps_done == log.steps_total


def test_an_until_task_whose_transport_crosses_far_apart_regions_runs():
    """tiny with ``!r1_p2 U (o1_p3 & r1_p1)``: r2 comes to p1, r1 and r2 carry o1 to p3 (25 m away, so every
    body leaves p1 before any enters p3) and r1 returns to p1 without entering p2.  The word where o1 enters p3
    before r1 leaves p1 is geometrically impossible, so the task is satisfiable and the mission keeps it."""
    data = yaml.safe_load((SCENARIOS / "tiny.yaml").read_text())
    data["task"] = {"formula": "(!r1_p2 U (o1_p3 & r1_p1))", "propositions": {}}
    sc = scenario_from_dict(data)
    plan = plan_scenario(sc, seed=0)
    log = run_mission(sc, plan=plan, seed=0)
    assert log.ok, log.message
    assert log.steps_done == log.steps_total
    labels = log.events[log.events["kind"] == "label"]
    assert len(labels) and labels["ok"].all()
    assert not any("r1_p2" in str(x).split() for x in labels["propositions"])
