"""Maps built ahead by the map worker are the maps the mission would have built: the same mission, primitive
for primitive, with and without prefetching, and most maps of the run come from the worker."""

from __future__ import annotations

from pathlib import Path

from mrodrake.planning.plan import plan_scenario
from mrodrake.scenario import load_scenario
from mrodrake.systems.mission import Mission

ROOT = Path(__file__).resolve().parents[2]


def test_prefetched_maps_change_nothing_but_where_they_are_built():
    sc = load_scenario(ROOT / "scenarios" / "tiny.yaml")
    plan = plan_scenario(sc, "stylus", seed=0)
    runs = []
    for prefetch in (True, False):
        mission = Mission(sc, plan, suffix_cycles=1, seed=0, prefetch=prefetch)
        log = mission.run()
        assert log.ok, log.message
        runs.append((log, mission.sequencer.map_sources, mission.simulator.get_num_steps_taken()))
    (with_log, with_maps, with_steps), (without_log, without_maps, without_steps) = runs
    assert with_steps == without_steps
    cols = ["action", "t_start", "t_end", "ok"]
    assert with_log.primitive_events[cols].equals(without_log.primitive_events[cols])
    assert without_maps["worker"] == 0 and with_maps["worker"] > with_maps["built"]
    assert with_maps["worker"] + with_maps["built"] == without_maps["built"]
