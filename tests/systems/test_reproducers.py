"""Whole missions that used to stop early on generated tasks (issue 13's reproducers): a false alarm of the
label monitor (3, 1, 3, 11), no consistent order of concurrent actions (3, 2, 4, 15) and a mission that went
numerically unstable (4, 2, 4, 21).  Each now plans on the executed-word semantics, places the whole run and
executes to the end.  Several minutes each on the office map: slow set (``--runslow``).  A campaign mission on
the corridor map whose goal maps beyond the circle barrier runs in the default set (~20 s)."""

from __future__ import annotations

import pytest

from mrodrake.planning.generate import generate_scenario
from mrodrake.run import run_mission
from tests.helpers.campaign import campaign_mission


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
    """Campaign mission gen_corridor_n2_m1_k3_s1-p0-l0-d0 (randomized, its layout seed): step 4 carries o1
    by r1 to p6 at the dead end of the corridor, whose goal maps beyond the whole map's circle barrier
    ("transport of o1: point ... is not inside the circle barrier"); it now runs on windows there."""
    task, sc, plan = campaign_mission(tmp_path, CORRIDOR_N2_M1_K3_S1, "gen_corridor_n2_m1_k3_s1-p0-l0-d0")
    log = run_mission(sc, plan=plan, seed=task.layout_seed)
    assert log.ok, log.message
    assert log.steps_done == log.steps_total
    prims = log.events[log.events["kind"] == "primitive"]
    assert "transport o1 by r1 p3->p6" in set(prims["action"])


def test_a_robot_parked_by_a_door_leaves_the_team_a_way_out(tmp_path):
    """Campaign mission gen_corridor_n3_m1_k3_s1-p0-l0-d0: r1 parked in p4 2.4 m inside the 6 m door of room
    S1, and the team r2 + o1 (covering radius 1.91 m) that formed in p4 afterwards had no way out ("transport
    of o1: goal unreachable"); spots now keep the region's later trips connected."""
    task, sc, plan = campaign_mission(tmp_path, CORRIDOR_N2_M1_K3_S1.replace("robots: [2]", "robots: [3]"),
                                      "gen_corridor_n3_m1_k3_s1-p0-l0-d0")
    log = run_mission(sc, plan=plan, seed=task.layout_seed)
    assert log.ok, log.message
    assert log.steps_done == log.steps_total
