"""``mrodrake draw``: a PNG and an HTML map of every shipped scenario and map, bad inputs, and the HTML page in
headless Chromium."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from mrodrake.cli import main
from mrodrake.scenario import load_scenario
from mrodrake.ts import TransitionSystem
from mrodrake.viz.mapview import travellers, write_map
from tests.helpers.browser import CHROMIUM, CHROMIUM_FLAGS, require_chromium

ROOT = Path(__file__).resolve().parents[2]
FILES = sorted((ROOT / "scenarios").glob("*.yaml")) + sorted((ROOT / "scenarios" / "maps").glob("*.yaml"))


def _pixels(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        assert im.format == "PNG"
        return np.asarray(im.convert("RGB")).astype(float) / 255.0


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_draw_writes_a_png_and_an_html_page(path, tmp_path, capsys):
    png, page = tmp_path / "map.png", tmp_path / "map.html"
    assert main(["draw", str(path), "-o", str(png)]) == 0
    assert main(["draw", str(path), "-o", str(page)]) == 0
    assert f"wrote {page}" in capsys.readouterr().out
    px = _pixels(png)
    assert px.shape[0] >= 300 and px.shape[1] >= 400
    assert px.std() > 0.05 and len(np.unique((px * 255).astype(np.uint8).reshape(-1, 3), axis=0)) > 20
    text = page.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>") and text.count("<svg") == 1
    assert not re.search(r"""(src|href)\s*=\s*["']https?:""", text)
    sc = load_scenario(path)
    svg = text[text.index("<svg"):text.index("</svg>")]
    for name in sc.region_names + sc.robot_names + sc.object_names:
        assert re.search(rf">\s*{name}\s*<", svg), name


def test_narrow_door_closes_for_teams_only():
    ts = TransitionSystem(load_scenario(ROOT / "scenarios" / "maps" / "narrow.yaml"))
    robots, team = travellers(ts)
    west, east = {"p1", "p2", "p3"}, {"p4", "p5", "p6"}
    assert robots.closed == () and not robots.unreachable
    names = ts.region_names
    cut = {frozenset((names[a], names[b])) for a, b in team.closed}
    assert cut and all(len(p & west) == 1 and len(p & east) == 1 for p in cut)
    assert {names[k] for k in team.unreachable["o1"]} == east


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["draw", "scenarios/tiny.yaml", "-o", "map.pdf"], "-o: expected a .png or .html file name"),
        (["draw", "nowhere.yaml"], "nowhere.yaml: no such file"),
    ],
)
def test_draw_bad_arguments_are_one_line_errors(args, message, capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    assert main(args) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_draw_bad_scenario_names_the_field(tmp_path, capsys):
    text = (ROOT / "scenarios" / "tiny.yaml").read_text(encoding="utf-8")
    bad = tmp_path / "bad.yaml"
    bad.write_text(re.sub(r"radius: ([0-9.]+)", "radius: -1", text, count=1), encoding="utf-8")
    assert main(["draw", str(bad), "-o", str(tmp_path / "m.png")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "radius: must be > 0" in err
    assert not (tmp_path / "m.png").exists()


def test_unwritable_output_is_a_user_error(tmp_path):
    from mrodrake.errors import UserError

    blocker = tmp_path / "file"
    blocker.write_text("", encoding="utf-8")
    with pytest.raises(UserError, match="-o: cannot write"):
        write_map(load_scenario(ROOT / "scenarios" / "tiny.yaml"), blocker / "map.png")


def test_map_page_renders_in_headless_chromium(tmp_path):
    require_chromium()
    from playwright.sync_api import sync_playwright

    page_path = tmp_path / "narrow.html"
    sc = load_scenario(ROOT / "scenarios" / "maps" / "narrow.yaml")
    write_map(sc, page_path)
    errors, requests = [], []
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_FLAGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900}, device_scale_factor=1)
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))

            def route(r):
                if r.request.url.startswith(("file:", "data:")):
                    r.continue_()
                else:
                    requests.append(r.request.url)
                    r.abort()

            page.route("**/*", route)
            page.goto(page_path.as_uri())
            box = page.evaluate("(() => { const b = document.querySelector('#map svg').getBoundingClientRect();"
                                " return [b.width, b.height]; })()")
            assert box[0] > 600 and box[1] > 100
            texts = page.evaluate("Array.from(document.querySelectorAll('#map svg text')).map(t => t.textContent)")
            joined = " ".join(texts)
            for name in sc.region_names:
                assert name in joined
            assert "cannot use" in page.inner_text("body")
            shot = page.screenshot(path=str(tmp_path / "narrow.png"))
            assert len(shot) > 10_000
            px = _pixels(tmp_path / "narrow.png")
            assert px.std() > 0.05
        finally:
            browser.close()
    assert not errors, errors
    assert not requests, requests
