"""Tests of the Meshcat HTML replay (mrodrake.viz.replay), including a headless-Chromium browser test."""

from __future__ import annotations

import base64
import math
import re
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrodrake.errors import UserError
from mrodrake.scenario import load_scenario
from mrodrake.viz.replay import (
    _keyframes,
    choose_speedup,
    scene_only,
    synthetic_mission,
    view_bounds,
    write_replay,
)
from tests.helpers.browser import CHROMIUM, CHROMIUM_FLAGS, require_chromium

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "case_study_1.yaml"
DURATION = 200.0
FPS = 30
# Meshcat's viewer (JavaScript, inline) is 2.23 MB on pydrake 1.51; our scene and 100 s of animation for
# 5 entities add about 0.35 MB.  Both bounds leave room for another Drake version's viewer.
VIEWER_MB = (1.5, 3.2)
SCENE_BUDGET_MB = 1.0
# http(s) URLs inside Meshcat's viewer that load nothing while the replay plays: the WebXR controller
# profiles (fetched only in VR mode), an XML namespace and links in messages and comments.
ALLOWED_URL_PREFIXES = (
    "https://cdn.jsdelivr.net/npm/@webxr-input-profiles/",
    "http://www.w3.org/",
    "https://developer.mozilla.org/",
    "https://immersiveweb.dev/",
    "https://beej.us/",
)


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(SCENARIO)


@pytest.fixture(scope="module")
def mission(scenario):
    traj, grasps = synthetic_mission(scenario, DURATION, speed=4.0, seed=1)
    assert len(grasps) >= 1, "the synthetic mission must contain a grasp"
    return traj, grasps


@pytest.fixture(scope="module")
def replay(scenario, mission, tmp_path_factory):
    traj, grasps = mission
    path = tmp_path_factory.mktemp("replay") / "replay.html"
    start = time.perf_counter()
    out = write_replay(scenario, traj, path, grasps=grasps, fps=FPS)
    return out, time.perf_counter() - start


def _expected(traj: pd.DataFrame, name: str, t: float) -> np.ndarray:
    g = traj[traj["entity"] == name].sort_values("t")
    return np.array([np.interp(t, g["t"], g["x"]), np.interp(t, g["t"], g["y"])])


def _blobs(html: str) -> list[bytes]:
    """The msgpack commands Meshcat embeds as base64 data URLs."""
    return [base64.b64decode(b) for b in re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]*)", html)]


# --------------------------------------------------------------------------------------------------
# Pure functions
# --------------------------------------------------------------------------------------------------


@given(st.floats(min_value=0.0, max_value=1e7, allow_nan=False))
def test_choose_speedup_gives_60_to_120_s(duration):
    s = choose_speedup(duration)
    mantissa = s / 10.0 ** math.floor(math.log10(s) + 1e-12)
    assert any(abs(mantissa - n) < 1e-9 for n in (1, 2, 3, 5))
    if duration <= 120.0:
        assert s == 1.0
    else:
        assert 60.0 < duration / s <= 120.0 + 1e-9
        # Minimal: the next smaller candidate would exceed 120 s.
        smaller = [n * 10.0 ** k for k in range(0, 8) for n in (1, 2, 3, 5) if n * 10.0 ** k < s]
        assert all(duration / c > 120.0 for c in smaller)


@settings(max_examples=60)
@given(
    st.lists(st.tuples(st.integers(1, 40), st.floats(-5, 5), st.floats(-5, 5), st.booleans()), min_size=1,
             max_size=12),
    st.floats(1e-3, 0.5),
)
def test_keyframes_reproduce_samples_within_tolerance(segments, tol):
    # Piecewise motions: constant-velocity runs, pauses (still=True) and wiggles.
    pts = [np.zeros(2)]
    rng = np.random.default_rng(len(segments))
    for n, vx, vy, still in segments:
        for _ in range(n):
            step = np.zeros(2) if still else np.array([vx, vy]) + rng.normal(0.0, 0.3, 2) * (n % 3 == 0)
            pts.append(pts[-1] + 0.1 * step)
    samples = np.array(pts)
    kept = _keyframes(samples, tol)
    assert kept[0] == 0 and kept[-1] == len(samples) - 1 and np.all(np.diff(kept) > 0)
    idx = np.arange(len(samples))
    rebuilt = np.column_stack([np.interp(idx, kept, samples[kept, c]) for c in range(2)])
    assert np.max(np.linalg.norm(rebuilt - samples, axis=1)) <= tol * (1 + 1e-9)


def test_keyframes_of_still_and_straight_motions_are_the_endpoints():
    assert list(_keyframes(np.zeros((500, 2)), 1e-6)) == [0, 499]
    line = np.outer(np.arange(300), [0.3, -0.1])
    assert list(_keyframes(line, 1e-9)) == [0, 299]


# --------------------------------------------------------------------------------------------------
# The HTML file
# --------------------------------------------------------------------------------------------------


def test_replay_is_self_contained_and_small(replay, scenario, mission):
    path, _ = replay
    html = path.read_text(encoding="utf-8")
    size_mb = path.stat().st_size / 1e6
    assert VIEWER_MB[0] < size_mb < VIEWER_MB[1] + SCENE_BUDGET_MB
    urls = set(re.findall(r"https?://[^\s\"'`()<>\\]+", html))
    unexpected = sorted(u for u in urls if not u.startswith(ALLOWED_URL_PREFIXES))
    assert not unexpected, f"external URLs in the replay: {unexpected}"
    # Nothing is loaded from the network: no src, url(), fetch() or import() of an http(s) address (the
    # viewer's only href to one is the "WEBXR NOT AVAILABLE" hyperlink).  The browser test checks requests.
    assert not re.search(r"""src\s*=\s*["']https?:|url\(\s*["']?https?:|(fetch|import)\(\s*["'`]https?:""", html)
    # The scene and the animation are embedded: every entity, region label and the grasp link.
    blob = b"".join(_blobs(html))
    for name in scenario.robot_names + scenario.object_names:
        assert f"/mrodrake/entities/{name}".encode() in blob
    assert b"/mrodrake/scene/regions/labels" in blob and b"set_animation" in blob
    _, grasps = mission
    g = grasps.iloc[0]
    assert f"/mrodrake/grasps/0_{g.robot}_{g.object}".encode() in blob


def test_long_mission_uses_a_speedup_and_stays_small(scenario, tmp_path):
    traj, grasps = synthetic_mission(scenario, 3000.0, seed=2)
    path = write_replay(scenario, traj, tmp_path / "long.html", grasps=grasps)
    html = path.read_text(encoding="utf-8")
    anim = next(b for b in _blobs(html) if b"set_animation" in b[:40])
    # choose_speedup(3000) = 30: 100 s of replay at 30 fps, so the last keyframe is frame 3000.
    assert choose_speedup(3000.0) == 30.0
    assert re.search(rb"\xa4time\xcd\x0b\xb8", anim), "no keyframe at frame 3000"
    assert not re.search(rb"\xa4time\xcd\x0b\xb9", anim)
    assert path.stat().st_size / 1e6 < VIEWER_MB[1] + 2.0 * SCENE_BUDGET_MB


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda t, g: (t.drop(columns=["vy"]), g), "trajectory: missing column(s) vy"),
        (lambda t, g: (t.assign(entity=t["entity"].replace("o2", "o9")), g), "unknown entity 'o9'"),
        (lambda t, g: (t[t["entity"] != "r2"], g), "no rows for entity 'r2'"),
        (lambda t, g: (t.assign(x=t["x"].where(t.index != 7, np.nan)), g), "non-finite t, x or y in row 7"),
        (lambda t, g: (t, g.assign(robot="o1")), "grasps[0].robot: unknown robot 'o1'"),
        (lambda t, g: (t, g.assign(t_end=g["t_start"] - 1.0)), "grasps[0]: need finite t_start <= t_end"),
        (lambda t, g: (t, g.drop(columns=["object"])), "grasps: missing column(s) object"),
    ],
)
def test_bad_logs_raise_user_errors(scenario, mission, tmp_path, change, message):
    traj, grasps = change(*mission)
    with pytest.raises(UserError) as err:
        write_replay(scenario, traj, tmp_path / "bad.html", grasps=grasps)
    assert message in str(err.value)
    assert "\n" not in str(err.value)
    assert not (tmp_path / "bad.html").exists()


@pytest.mark.parametrize(("kw", "message"), [({"fps": 0}, "fps: must be a positive number"),
                                             ({"speedup": -2.0}, "speedup: must be a positive number")])
def test_bad_options_raise_user_errors(scenario, mission, tmp_path, kw, message):
    traj, grasps = mission
    with pytest.raises(UserError, match=re.escape(message)):
        write_replay(scenario, traj, tmp_path / "bad.html", grasps=grasps, **kw)


def test_scene_only_draws_the_static_scene_and_entities(scenario):
    from pydrake.geometry import Meshcat

    meshcat = Meshcat()
    scene_only(scenario, meshcat)
    for path in ["/mrodrake/scene/floor", "/mrodrake/scene/walls", "/mrodrake/scene/obstacles/fill",
                 "/mrodrake/scene/regions/labels", "/mrodrake/legend/names"]:
        assert meshcat.HasPath(path), path
    for reg in scenario.regions:
        assert meshcat.HasPath(f"/mrodrake/scene/regions/{reg.name}/disk")
    for name in scenario.robot_names + scenario.object_names:
        assert meshcat.HasPath(f"/mrodrake/entities/{name}/disk")


# --------------------------------------------------------------------------------------------------
# Browser test
# --------------------------------------------------------------------------------------------------


def _shot(page) -> np.ndarray:
    import io

    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(float) / 255.0


def _seek(page, t_replay: float) -> None:
    page.evaluate(f"viewer.animator.seek({t_replay!r}); viewer.set_dirty()")
    page.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")


def test_replay_plays_in_headless_chromium(replay, scenario, mission, tmp_path):
    require_chromium()
    from playwright.sync_api import sync_playwright

    path, _ = replay
    traj, grasps = mission
    xmin, xmax, ymin, ymax = view_bounds(scenario)
    height = 900
    px_per_m = height / (ymax - ymin)
    width = int(math.ceil((xmax - xmin) * px_per_m)) + 40
    speedup = choose_speedup(DURATION)
    n_frames = int(math.ceil(DURATION / speedup * FPS - 1e-9)) + 1

    def to_px(xy):
        return (xy[0] - xmin) * px_per_m, (ymax - xy[1]) * px_per_m

    errors, requests = [], []
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_FLAGS)
        try:
            page = browser.new_page(viewport={"width": width, "height": height}, device_scale_factor=1)
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))

            def route(r):
                if r.request.url.startswith(("file:", "data:", "blob:")):
                    r.continue_()
                else:
                    requests.append(r.request.url)
                    r.abort()

            page.route("**/*", route)
            page.goto(path.as_uri())
            page.wait_for_function("typeof viewer !== 'undefined' && viewer.animator.duration > 0", timeout=60000)
            assert page.evaluate("viewer.animator.duration") == pytest.approx((n_frames - 1) / FPS, abs=1e-6)

            # The animation plays by itself and advances.
            t_a = page.evaluate("viewer.animator.time")
            shot_a = _shot(page)
            time.sleep(1.5)
            t_b = page.evaluate("viewer.animator.time")
            shot_b = _shot(page)
            assert page.evaluate("viewer.animator.playing")
            assert t_b - t_a > 0.5, (t_a, t_b)
            assert np.abs(shot_a - shot_b).max() > 0.2, "two frames 1.5 s apart look the same"
            # The WebGL canvas is not blank: many colours, light floor and dark walls.
            colours = np.unique((shot_b * 255).astype(np.uint8).reshape(-1, 3), axis=0)
            assert len(colours) > 50 and shot_b.std() > 0.05
            lum = shot_b.mean(axis=2)
            assert (lum > 0.8).mean() > 0.3 and (lum < 0.45).mean() > 0.01

            # Seek to mid-grasp: the link is visible, entities are where the log says, seen from the top.
            page.evaluate("viewer.animator.pause()")
            g = grasps.iloc[0]
            t_sim = 0.5 * (g.t_start + g.t_end)
            frame = round(t_sim / speedup * FPS)
            t_sim = frame * speedup / FPS
            _seek(page, frame / FPS)
            link = f"0_{g.robot}_{g.object}"
            assert page.evaluate(f"viewer.scene_tree.find(['mrodrake','grasps','{link}']).object.visible")
            tol = 0.05 * min(e.radius for e in list(scenario.robots) + list(scenario.objects)) + 1e-3
            shot = _shot(page)
            page.screenshot(path=str(tmp_path / "mid_grasp.png"))
            for name in scenario.robot_names + scenario.object_names:
                p = page.evaluate(f"(() => {{ const o = viewer.scene_tree.find(['mrodrake','entities','{name}'])"
                                  ".object.position; return [o.x, o.y]; })()")
                assert np.linalg.norm(np.array(p) - _expected(traj, name, t_sim)) <= tol, name
            swatch = {}
            for name in scenario.robot_names:
                s = page.evaluate(f"(() => {{ const o = viewer.scene_tree.find(['mrodrake','legend','swatch_{name}'])"
                                  ".object.position; return [o.x, o.y]; })()")
                u, v = to_px(s)
                swatch[name] = np.median(shot[int(v) - 1:int(v) + 2, int(u) - 1:int(u) + 2].reshape(-1, 3), axis=0)
            assert len({tuple(np.round(c, 1)) for c in swatch.values()}) == len(swatch)
            for name in scenario.robot_names:  # robots' disks are 6 px wide at this size; objects' 2 px
                u, v = to_px(_expected(traj, name, t_sim))
                seen = np.median(shot[int(v) - 1:int(v) + 2, int(u) - 1:int(u) + 2].reshape(-1, 3), axis=0)
                nearest = min(swatch, key=lambda n: np.abs(swatch[n] - seen).max())
                assert nearest == name and np.abs(swatch[name] - seen).max() < 0.1, (name, seen, swatch[name])

            # Before the grasp the link is hidden; at the start no trail piece is shown, at the end some are.
            if g.t_start > 1.0:
                _seek(page, 0.0)
                assert not page.evaluate(f"viewer.scene_tree.find(['mrodrake','grasps','{link}']).object.visible")
            count = ("(() => { let n = 0; viewer.scene_tree.find(['mrodrake','trails']).object.traverse(o => {"
                     " if (o.type === 'Line' && o.parent.visible && o.parent.parent.visible) n++; }); return n; })()")
            _seek(page, 0.0)
            shown_start = page.evaluate(count)
            _seek(page, (n_frames - 1) / FPS)
            shown_end = page.evaluate(count)
            page.screenshot(path=str(tmp_path / "end.png"))
            assert shown_end > shown_start + 10
        finally:
            browser.close()
    assert not errors, errors
    assert not requests, f"the replay tried to load {requests}"
