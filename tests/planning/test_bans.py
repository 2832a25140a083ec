"""Bans after placement rejections: the rejected transition and every one with its local situation."""

from __future__ import annotations

from mrodrake.planning import plan as plan_module
from mrodrake.planning.bans import Bans, LocalBan, SwapBan
from mrodrake.planning.placement import PlacementError
from mrodrake.planning.plan import plan_scenario
from mrodrake.planning.steps import expand_steps
from mrodrake.ts import Transport


def _state(ts, robots, objects, grasps):
    return ts.make_state(robots, objects, grasps)


def test_local_ban_ignores_what_happens_in_other_regions(tiny):
    ts = tiny.ts  # r1 and o1 in p1, r2 in p2
    s = _state(ts, [0, 1], [0], [-1, -1])
    ban = LocalBan.of(ts, s, _state(ts, [2, 1], [0], [-1, -1]), 2)  # r1 p1 -> p3, rejected in p3
    assert ban.regions == frozenset({0, 2})
    bans = Bans(ts, (), [ban])
    assert bans.banned(s, _state(ts, [2, 1], [0], [-1, -1]))
    assert not bans.banned(s, _state(ts, [2, 0], [0], [-1, -1]))  # r2 enters p1 as well
    assert not bans.banned(_state(ts, [0, 1], [0], [0, -1]), _state(ts, [0, 1], [0], [-1, -1]))
    kept = Bans(ts, (), [LocalBan.of(ts, s, _state(ts, [2, 1], [0], [-1, -1]), 1)])  # rejected in p2: r2 stays
    assert kept.banned(s, _state(ts, [0, 1], [0], [0, -1]))  # whatever r1 does in p1
    assert kept.banned(_state(ts, [2, 1], [0], [-1, -1]), s)  # both directions
    assert not kept.banned(s, _state(ts, [0, 2], [0], [-1, -1]))  # r2 leaves p2
    assert s in kept and _state(ts, [2, 1], [0], [-1, -1]) in kept.get(s)


def test_a_swap_ban_bans_every_change_to_the_team_that_keeps_the_staying_member(tiny):
    """r1 stays docked to o1 while r2 joins (team {r1} -> {r1, r2}) was rejected: any change to {r1, r2} from
    a team holding r1 is banned, in either direction and wherever the entities are; forming {r1, r2} around a
    free object, or a change to another team, is not."""
    ts = tiny.ts
    ban = SwapBan.of(ts, _state(ts, [0, 0], [0], [0, -1]), _state(ts, [0, 0], [0], [0, 0]), 0)
    assert ban == SwapBan(0, frozenset({0}), frozenset({0, 1}))
    bans = Bans(ts, (), [ban])
    assert bans.banned(_state(ts, [2, 2], [2], [0, -1]), _state(ts, [2, 2], [2], [0, 0]))  # elsewhere
    assert bans.banned(_state(ts, [2, 2], [2], [0, 0]), _state(ts, [2, 2], [2], [0, -1]))  # and back
    assert not bans.banned(_state(ts, [0, 0], [0], [-1, -1]), _state(ts, [0, 0], [0], [0, 0]))  # a free object
    assert not bans.banned(_state(ts, [0, 0], [0], [0, 0]), _state(ts, [0, 0], [0], [-1, 0]))  # r2 stays instead
    assert _state(ts, [2, 2], [2], [0, -1]) in bans and _state(ts, [0, 0], [0], [-1, -1]) not in bans


def test_rejected_pairs_are_banned_both_ways(tiny):
    ts = tiny.ts
    a, b = _state(ts, [0, 1], [0], [-1, -1]), _state(ts, [1, 1], [0], [-1, -1])
    bans = Bans(ts, [(a, b)])
    assert bans.banned(a, b) and bans.banned(b, a) and a in bans and b in bans[a]
    assert not bans.banned(a, _state(ts, [2, 1], [0], [-1, -1]))


def test_replanning_avoids_the_local_situation_of_a_rejected_step(tiny, monkeypatch):
    """The first plan's transport into p3 is rejected there: the next plan has no step with that situation in
    p3 and the regions its travels connect, whatever the other robot does meanwhile."""
    real = plan_module.place_plan
    seen = []

    def place(plan, cycles, seed=0):
        if not seen:
            for spec in expand_steps(plan, cycles):
                moved = [a for a in spec.actions if isinstance(a, Transport) and a.dst == 2]
                if moved:
                    seen.append(LocalBan.of(plan.ts, spec.src, spec.dst, 2))
                    raise PlacementError("step: region 'p3': no room", spec, 2)
        return real(plan, cycles, seed=seed)

    monkeypatch.setattr(plan_module, "place_plan", place)
    plan = plan_scenario(tiny.scenario, iterations=300)
    assert seen and plan.stats["placement"]["rejected"] == ["step: region 'p3': no room"]
    n = plan.ts.N + plan.ts.M
    assert not any(seen[0].matches(a[0], b[0], n) for *_x, a, b, _acts, _c in plan.steps())
