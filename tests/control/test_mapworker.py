"""The map worker builds the very map the mission would have built itself, reports a failed build as an error
of that request only, a forked process gets a worker of its own, and an idle worker ends."""

from __future__ import annotations

import multiprocessing
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import Polygon
from threadpoolctl import threadpool_limits

from mrodrake.control.freespace import Disk, entity_free_space
from mrodrake.control.mapworker import map_worker
from mrodrake.control.pointworld import PointWorldMap
from mrodrake.control.tasks import MAP_OPTIONS
from mrodrake.scenario import load_scenario

SCEN = Path(__file__).resolve().parents[2] / "scenarios"
_FIELDS = ("panel_start", "panel_end", "panel_ring", "sigma", "hole_points", "_const")


@pytest.fixture(scope="module")
def free():
    sc = load_scenario(SCEN / "tiny.yaml")  # desks and the region p3 are holes, the robot r2 another
    c0, c1 = (np.asarray(sc.regions[k].center, dtype=float) for k in (0, 1))
    others = [Disk(sc.robots[1].name, (20.0, 15.0), sc.robots[1].radius)]
    return entity_free_space(sc, sc.robots[0].radius, c0, c1, 0, 1, others).polygon


def test_the_worker_builds_the_map_the_process_builds(free):
    with threadpool_limits(limits=1, user_api="blas"):  # as a mission builds its maps
        here = PointWorldMap.build(free, **MAP_OPTIONS)
    there = map_worker().submit(free, MAP_OPTIONS).result(timeout=600)
    assert isinstance(there, PointWorldMap)
    for name in _FIELDS:  # the same code on the same machine: the same bits, not just close
        assert np.array_equal(getattr(here, name), getattr(there, name)), name
    pts = np.array(free.representative_point().coords)
    assert np.array_equal(here(pts), there(pts))


def test_a_failed_build_fails_its_request_only(free):
    worker = map_worker()
    bad = worker.submit(Polygon([(0, 0), (1, 1), (1, 0), (0, 1)]), MAP_OPTIONS)  # self-intersecting
    good = worker.submit(free, MAP_OPTIONS)
    with pytest.raises(RuntimeError):
        bad.result(timeout=600)
    assert good.result(timeout=600).n_panels > 0


def _build_in_child(polygon, queue):
    queue.put(map_worker().submit(polygon, MAP_OPTIONS).result(timeout=600).n_panels)


def test_a_forked_process_gets_a_worker_of_its_own(free):
    parent = map_worker()
    parent.submit(free, MAP_OPTIONS).result(timeout=600)
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_build_in_child, args=(free, queue))
    child.start()
    n = queue.get(timeout=600)
    child.join(timeout=60)
    assert child.exitcode == 0 and n > 0
    assert map_worker() is parent and parent.submit(free, MAP_OPTIONS).result(timeout=600).n_panels == n


def test_an_idle_worker_ends_and_the_next_request_starts_another(free, monkeypatch):
    import mrodrake.control.mapworker as mw

    idle = mw.MapWorker(idle_exit=0.2)
    assert idle.submit(free, MAP_OPTIONS).result(timeout=600).n_panels > 0  # a request resets the idle clock
    assert idle._proc.wait(timeout=120) == 0  # then, with none for 0.2 s, it ends on its own
    assert not idle.alive
    late = idle.submit(free, MAP_OPTIONS)  # a request that meets an ended worker fails (the mission builds it)
    with pytest.raises(RuntimeError):
        late.result(timeout=600)
    monkeypatch.setattr(mw, "_WORKER", idle)
    fresh = mw.map_worker()
    assert fresh is not idle and fresh.alive
    assert fresh.submit(free, MAP_OPTIONS).result(timeout=600).n_panels > 0
