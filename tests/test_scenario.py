"""Scenario schema and validation: every rejection names the field, one line, exit status 2."""

from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from mrodrake.errors import UserError
from mrodrake.scenario import load_scenario, parse_scenario

ROOT = Path(__file__).resolve().parents[1]
SCEN = ROOT / "scenarios"
TINY = yaml.safe_load((SCEN / "tiny.yaml").read_text())


def _load(data) -> None:
    parse_scenario(yaml.safe_dump(data, sort_keys=False), source="t.yaml")


def _reject(mutate, *fragments: str) -> str:
    data = copy.deepcopy(TINY)
    mutate(data)
    with pytest.raises(UserError) as exc:
        _load(data)
    msg = str(exc.value)
    assert "\n" not in msg
    for frag in fragments:
        assert frag in msg, msg
    return msg


@pytest.mark.parametrize("name", ["case_study_1", "case_study_2", "tiny"])
def test_shipped_scenarios_load(name):
    s = load_scenario(SCEN / f"{name}.yaml")
    assert s.name == name
    assert len(s.workspace.obstacles) >= (8 if name.startswith("case") else 1)


def test_case_study_numbers_match_paper():
    s1 = load_scenario(SCEN / "case_study_1.yaml")
    assert [r.power for r in s1.robots] == [2, 3, 4]
    assert [o.required_power for o in s1.objects] == [5, 6]
    assert [r.initial_region for r in s1.robots] == ["p1", "p3", "p4"]
    assert [o.initial_region for o in s1.objects] == ["p2", "p1"]
    assert [tuple(g.center) for g in s1.regions] == [(88, -280), (100, -160), (200, -130), (250, -285)]
    s2 = load_scenario(SCEN / "case_study_2.yaml")
    assert [r.power for r in s2.robots] == [2, 3, 4, 4]
    assert [o.required_power for o in s2.objects] == [5, 8, 10.5]
    assert [r.initial_region for r in s2.robots] == ["p1", "p3", "p2", "p2"]
    assert [o.initial_region for o in s2.objects] == ["p2", "p1", "p3"]
    assert len(s2.regions) == 3
    for s in (s1, s2):
        assert all(r.mass == 1.0 and r.radius == 0.75 for r in s.robots)
        assert all(o.mass == 0.25 and o.radius == 0.2 for o in s.objects)
        c = s.control
        assert (c.k1, c.k2, c.k_phi, c.k_m, c.k_alpha, c.r_bar) == (0.01, 5, 1, 0.01, 0.01, 0.1)
        assert c.tau == pytest.approx(c.r_bar**2)


def test_line_numbers_in_messages():
    text = (SCEN / "tiny.yaml").read_text().replace("mass: 1.2", "mass: -1.2")
    with pytest.raises(UserError) as exc:
        parse_scenario(text, source="tiny.yaml")
    line = next(i + 1 for i, l in enumerate(text.splitlines()) if "mass: -1.2" in l)
    assert str(exc.value).startswith(f"tiny.yaml:{line}: robots[1].mass: must be > 0")


def test_a_cyclic_macro_is_reported_at_its_line():
    text = (SCEN / "tiny.yaml").read_text().replace('home: "r1_p1 & r2_p1"', 'home: "away"\n    away: "home"')
    with pytest.raises(UserError) as exc:
        parse_scenario(text, source="tiny.yaml")
    msg = str(exc.value)
    name = msg.split("task.propositions.", 1)[1].split(":", 1)[0]
    line = next(i + 1 for i, l in enumerate(text.splitlines()) if l.strip().startswith(f"{name}:"))
    assert msg.startswith(f"tiny.yaml:{line}: task.propositions.{name}: cyclic macro definition: ")
    assert {name, "home", "away"} == {"home", "away"}


@pytest.mark.parametrize(
    "mutate, fragments",
    [
        (lambda d: d["robots"][0].update(colour="red"), ["robots[0].colour", "unknown field"]),
        (lambda d: d.update(extra=1), ["extra", "unknown field"]),
        (lambda d: d["robots"][1].pop("power"), ["robots[1].power", "missing"]),
        (lambda d: d.pop("task"), ["task", "missing"]),
        (lambda d: d["robots"][0].update(mass="heavy"), ["robots[0].mass", "number"]),
        (lambda d: d["robots"][0].update(mass=True), ["robots[0].mass", "number"]),
        (lambda d: d["robots"][0].update(name=3), ["robots[0].name", "string"]),
        (lambda d: d["regions"][0].update(center=[1.0]), ["regions[0].center"]),
        (lambda d: d["robots"][0].update(mass=0), ["robots[0].mass", "> 0"]),
        (lambda d: d["robots"][0].update(radius=-1), ["robots[0].radius", "> 0"]),
        (lambda d: d["robots"][0].update(power=0), ["robots[0].power", "> 0"]),
        (lambda d: d["objects"][0].update(mass=-0.1), ["objects[0].mass", "> 0"]),
        (lambda d: d["objects"][0].update(required_power=0), ["objects[0].required_power", "> 0"]),
        (lambda d: d["regions"][1].update(radius=0), ["regions[1].radius", "> 0"]),
        (lambda d: d["objects"][0]["friction"].update(model="coulomb"), ["objects[0].friction.model"]),
        (lambda d: d["objects"][0]["friction"].update(scale=-1), ["objects[0].friction.scale", ">= 0"]),
        (lambda d: d.update(planning={"p_rand": 1.5}), ["planning.p_rand", "<= 1"]),
    ],
)
def test_schema_rejections(mutate, fragments):
    _reject(mutate, *fragments)


def test_polygon_rejections():
    _reject(lambda d: d["workspace"].update(boundary=[[0, 0], [40, 30], [40, 0], [0, 30]]),
            "workspace.boundary", "not simple")
    _reject(lambda d: d["workspace"].update(boundary=[[0, 0], [40, 0]]), "workspace.boundary", "at least 3")
    _reject(lambda d: d["workspace"]["obstacles"][1].update(polygon=[[26, 4], [30, 9], [30, 4], [26, 9]]),
            "workspace.obstacles[1].polygon", "not simple")
    _reject(lambda d: d["workspace"]["obstacles"][0].update(polygon=[[35, 10], [45, 10], [45, 20], [35, 20]]),
            "workspace.obstacles[0].polygon", "not inside")
    _reject(lambda d: d["workspace"]["obstacles"][0].update(polygon=[[30, 10], [40, 10], [40, 20], [30, 20]]),
            "workspace.obstacles[0].polygon", "touches workspace.boundary")
    _reject(lambda d: d["workspace"]["obstacles"][1].update(polygon=[[17, 12], [22, 12], [22, 16], [17, 16]]),
            "workspace.obstacles[1].polygon", "overlaps obstacle 'desk_1'")


def test_region_rejections():
    _reject(lambda d: d["regions"][2].update(center=[38.0, 22.0]), "regions[2]", "not inside the free space")
    _reject(lambda d: d["regions"][2].update(center=[16.0, 15.0]), "regions[2]", "not inside the free space")
    _reject(lambda d: d["regions"][1].update(center=[8.0, 10.0]), "regions[1]", "overlaps region 'p1'")


def test_fit_rejection():
    def crowd(d):
        d["robots"][1]["initial_region"] = "p1"
        d["regions"][0]["radius"] = 1.6
    _reject(crowd, "regions[0].radius", "do not fit", "r1, r2, o1")


def test_name_rejections():
    _reject(lambda d: d["robots"][1].update(name="r1"), "robots[1].name", "duplicate name 'r1'")
    _reject(lambda d: d["objects"][0].update(name="p2"), "regions[1].name", "duplicate name 'p2'")
    _reject(lambda d: d["robots"][0].update(name="r_1"), "robots[0].name", "letters and digits")
    _reject(lambda d: d["workspace"]["obstacles"][1].update(name="desk_1"), "workspace.obstacles[1].name",
            "duplicate")
    _reject(lambda d: d["robots"][0].update(initial_region="p9"), "robots[0].initial_region",
            "unknown region 'p9'")


@pytest.mark.parametrize("group, index, name", [("robots", 1, "G"), ("objects", 0, "Fo"), ("robots", 1, "XGr2")])
def test_an_entity_name_that_reads_as_ltl_operators_is_rejected(group, index, name):
    """'G_p1' parses as G(_p1) and 'Fo_p1' as F(o_p1) (operators glued to a name, as in Spot): such a name
    would silently change what the task says about the entity."""
    _reject(lambda d: d[group][index].update(name=name), f"{group}[{index}].name", "read as LTL operators")


@pytest.mark.parametrize("name", ["F", "GFx", "xor"])
def test_a_macro_name_that_reads_as_ltl_operators_is_rejected(name):
    _reject(lambda d: d["task"]["propositions"].update({name: "r1_p1"}), f"task.propositions.{name}",
            "reads as LTL operators")


def test_task_rejections():
    msg = _reject(lambda d: d["task"].update(formula="F G o1_p3 & G F (home"), "task.formula")
    assert "task.formula:17: unclosed" in msg  # column of the unmatched parenthesis
    _reject(lambda d: d["task"].update(formula="F r3_p1"), "task.formula", "unknown robot or object 'r3'")
    _reject(lambda d: d["task"].update(formula="F r1_p7"), "task.formula", "unknown region 'p7'")
    _reject(lambda d: d["task"].update(formula="F psi9"), "task.formula", "'psi9'", "not a macro")
    _reject(lambda d: d["task"]["propositions"].update(home="r1_p1 & o2_p1"), "task.propositions.home",
            "'o2'")
    _reject(lambda d: d["task"]["propositions"].update(r1_p1="true"), "task.propositions.r1_p1", "clashes")


def test_formula_error_has_caret():
    data = copy.deepcopy(TINY)
    data["task"]["formula"] = "F G o1_p3 & & G F home"
    with pytest.raises(UserError) as exc:
        _load(data)
    assert "^" in exc.value.detail


def test_yaml_errors():
    with pytest.raises(UserError, match=r"t.yaml:3:1: malformed YAML: .*flow sequence at line 2"):
        parse_scenario("name: x\nworkspace: [1, 2\n", source="t.yaml")
    with pytest.raises(UserError, match=r"^t.yaml:2: name: duplicate key"):
        parse_scenario("name: x\nname: y\n", source="t.yaml")
    with pytest.raises(UserError, match="expected a mapping"):
        parse_scenario("- 1\n- 2\n", source="t.yaml")
    with pytest.raises(UserError, match="no such file"):
        load_scenario("/nonexistent/scenario.yaml")


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mrodrake.cli", *args], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)


def test_cli_validate_ok_and_errors(tmp_path):
    ok = _cli("validate", str(SCEN / "tiny.yaml"))
    assert ok.returncode == 0 and "ok" in ok.stdout
    bad = tmp_path / "bad.yaml"
    bad.write_text((SCEN / "tiny.yaml").read_text().replace("power: 3", "power: -3"))
    res = _cli("validate", str(bad))
    assert res.returncode == 2
    assert "Traceback" not in res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "robots[1].power" in lines[0] and lines[0].startswith("error: ")


def test_deeply_nested_task_formulas():
    """3,000 parentheses load; a tree deeper than the LTL limit is rejected at its operator, one line."""
    data = copy.deepcopy(TINY)
    data["task"]["formula"] = "(" * 3000 + "F G o1_p3 & G F home" + ")" * 3000
    _load(data)
    _reject(lambda d: d["task"].update(formula="X " * 300 + "home"), "task.formula:203:", "nested deeper than 200")


def test_cli_validate_warns_outside_the_design_range(tmp_path):
    """True masses / frictions outside the controllers' design range (scenario.DESIGN_MASS_RATIO, control.alpha_max)
    are warnings on stderr, not errors: the file validates and the exit status stays 0."""
    from mrodrake.scenario import design_range_warnings

    assert design_range_warnings(load_scenario(SCEN / "case_study_1.yaml")) == []
    text = (SCEN / "tiny.yaml").read_text()
    text = text.replace("{name: r2, mass: 1.2,", "{name: r2, mass: 3.0,")
    text = text.replace("friction: {model: viscous, scale: 0.5}", "friction: {model: paper, scale: 2.6}")
    path = tmp_path / "wide.yaml"
    path.write_text(text)
    res = _cli("validate", str(path))
    assert res.returncode == 0 and "ok" in res.stdout
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 2 and all(line.startswith(f"warning: {path}:") for line in lines), res.stderr
    assert "robots[1].mass: 3 kg outside the design range [0.1, 2.5] kg" in lines[0]
    assert "objects[0].friction.scale: friction bound α = 5.2" in lines[1] and "outside the design range" in lines[1]
    # a scenario that declares a wider friction design bound (its controllers start α̂ there) gets no warning
    path.write_text(text + "control: {alpha_max: 6.0}\n")
    res = _cli("validate", str(path))
    assert res.returncode == 0 and "friction" not in res.stderr and "robots[1].mass" in res.stderr


def test_centimetre_robots_and_a_spacing_below_the_docking_tolerance_are_warned_about():
    """Robots outside radius 0.25-1 m (the control layer's absolute lengths) and, with objects to carry, a layout
    spacing below twice the docking tolerance (a team goal spacing/2 from a rim, members docked up to
    DOCK_TOL off their slots) are warnings naming the field; the shipped case study gets none."""
    from mrodrake.geometry import DOCK_TOL
    from mrodrake.scenario import design_range_warnings, scenario_from_dict

    data = copy.deepcopy(TINY)
    data["robots"][1]["radius"] = 0.1
    data["layout"] = dict(data.get("layout", {}), spacing=2.0 * DOCK_TOL - 0.01)
    warnings = design_range_warnings(scenario_from_dict(data))
    assert len(warnings) == 2
    assert "robots[1].radius: 0.1 m outside the design range [0.25, 1] m" in warnings[0]
    assert "layout.spacing" in warnings[1] and "below twice the docking tolerance" in warnings[1]
    data["layout"]["spacing"] = 2.0 * DOCK_TOL
    assert len(design_range_warnings(scenario_from_dict(data))) == 1
