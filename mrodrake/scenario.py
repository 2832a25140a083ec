"""Scenario files: typed, validated description of a multi-robot-object problem (paper Sec. II).

A scenario YAML is loaded into frozen *pydantic dataclasses*.  We chose pydantic over Drake's
``yaml_load_typed`` because user-facing validation must name the offending field: pydantic reports the
exact location (``robots[1].mass``) of unknown, missing and wrongly typed fields and of range violations,
whereas ``yaml_load_typed`` reports neither the path nor missing keys (they silently keep defaults).
Every location is mapped back to a line of the YAML file, so messages read
``case.yaml:23: robots[1].mass: must be > 0``.  Semantic checks (geometry, packing, names, formula)
follow the type checks; every failure raises :class:`~mrodrake.errors.UserError` with one line.

Masses and frictions are the *true* values used by the simulated plants only; planners and controllers
never read them.
"""

from __future__ import annotations

import math
import re
from dataclasses import field as dc_field
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import yaml
from pydantic import ConfigDict, Field, TypeAdapter, ValidationError
from pydantic.dataclasses import dataclass

from mrodrake.errors import UserError
from mrodrake.geometry import CONTROL_MARGIN, DOCK_TOL
from mrodrake.logic import atoms, parse
from mrodrake.logic.formula import AP
from mrodrake.packing import place

_CFG = ConfigDict(extra="forbid")

Num = Annotated[float, Field(strict=True, allow_inf_nan=False)]
PosNum = Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)]
NonNegNum = Annotated[float, Field(strict=True, ge=0, allow_inf_nan=False)]
Str = Annotated[str, Field(strict=True)]
Point = tuple[Num, Num]

#: Robot, object and region names: letters and digits only, so ``<entity>_<region>`` is unambiguous.
ENTITY_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9]*$")
#: Obstacle and macro names: identifiers.
IDENTIFIER = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")

#: Design range of the adaptive controllers (the guarantee tests sample it).  Friction: α ≤ ᾱ per body
#: (Assumption 1's constant, ``Friction.alpha_bound``; ᾱ = ``control.alpha_max``, default twice the paper's
#: α = 2 × 1.25, i.e. the paper's model with scale ≤ 2.5); the controllers start α̂ at the entity's bound
#: (mrodrake.control.adaptive).  Mass: m̂_0 / DESIGN_MASS_RATIO ≤ m ≤ DESIGN_MASS_RATIO · m̂_0 per body (0.1 to
#: 2.5 kg with the default m̂_0 = 0.5).  ``mrodrake validate`` warns about true parameters outside the range.
DESIGN_ALPHA_MAX = 5.0
#: The smallest ``control.margin`` per metre of workspace diameter inside the design range: the largest crossing
#: of a wall by the panel map's boundary error measured, 0.28 m on the 304 m case-study office, scaled to the
#: floor (the map's panels are fractions of its diameter, so the error scales with it).
MARGIN_PER_DIAMETER = 1e-3
#: Robot radii (m) the control layer's absolute lengths (approach disks, receding windows, departure steps,
#: docking tolerance) are chosen for.
DESIGN_ROBOT_RADIUS = (0.25, 1.0)
DESIGN_MASS_RATIO = 5.0


@dataclass(frozen=True, config=_CFG)
class Obstacle:
    """A free-standing obstacle (desk, pillar, cabinet): a simple polygon inside the workspace."""

    name: Str
    polygon: list[Point]


@dataclass(frozen=True, config=_CFG)
class Workspace:
    """Outer boundary (one simple polygon; walls attached to it are notches) and free obstacles."""

    boundary: list[Point]
    obstacles: list[Obstacle] = dc_field(default_factory=list)


@dataclass(frozen=True, config=_CFG)
class Region:
    """Region of interest π_k = closed ball B̄(center, radius) inside the free space."""

    name: Str
    center: Point
    radius: PosNum


@dataclass(frozen=True, config=_CFG)
class Friction:
    """True friction-like term f(x, ẋ) (paper Assumption 1); read only by the simulated plants.

    ``paper``: f = scale · sin(frequency (x₁ + x₂)) · diag(exp(−|ẋ_k|) + 1) ẋ (paper Sec. IV);
    ``viscous``: f = scale · ẋ.  Both satisfy ‖f‖ ≤ α‖ẋ‖ with α = 2·scale resp. scale.
    """

    model: Literal["paper", "viscous"] = "paper"
    scale: NonNegNum = 1.25
    frequency: NonNegNum = 0.5

    @property
    def alpha_bound(self) -> float:
        """The constant α of Assumption 1 for this model."""
        return 2.0 * self.scale if self.model == "paper" else self.scale


@dataclass(frozen=True, config=_CFG)
class Robot:
    """Robot i: true mass m_i, radius r_i, power ζ_i, friction f_i, initial region π_init(i)."""

    name: Str
    mass: PosNum
    radius: PosNum
    power: PosNum
    initial_region: Str
    friction: Friction = dc_field(default_factory=Friction)


@dataclass(frozen=True, config=_CFG)
class Object:
    """Object j: true mass m^o_j, radius r^o_j, required transport power, friction, initial region."""

    name: Str
    mass: PosNum
    radius: PosNum
    required_power: PosNum
    initial_region: Str
    friction: Friction = dc_field(default_factory=Friction)


@dataclass(frozen=True, config=_CFG)
class Task:
    """LTL task in Spot syntax over ``<robot>_<region>`` / ``<object>_<region>`` and named macros."""

    formula: Str
    propositions: dict[Str, Str] = dc_field(default_factory=dict)


@dataclass(frozen=True, config=_CFG)
class Layout:
    """Geometry choices of the abstraction.

    ``grasp_gap``: gap between a grasping robot's rim and the object's rim (sets the grasp offsets d^o_ij
    and the covering radius r_A,j of a team); ``spacing``: minimum gap kept between entities in one
    region and between an entity and the region's rim (P_s packs radii inflated by spacing/2).
    """

    grasp_gap: NonNegNum = 0.1
    spacing: NonNegNum = 0.1


@dataclass(frozen=True, config=_CFG)
class ControlGains:
    """Controller gains (paper Sec. III-A; defaults: Sec. IV).

    k1, k2: navigation function weights; k_phi: gradient gain (needs k_phi > α/2); k_v: velocity-error
    gain (not given in the paper); k_m, k_alpha: adaptation gains; r_bar, tau: caps for the separation
    constant r̄ and the barrier's region of influence τ (Prop. 1: τ < min(r̄², r̄_d)); m_hat0, alpha_hat0:
    initial estimates; k1_local, k_v_local: k1 and k_v of the local (identity-map) law that docks at grasp
    points and backs off inside a region (mrodrake.control.local; not in the paper, whose grasps are
    abstract).  k_v_local exceeds the friction bound α = 2.5 of the paper's f_i (Sec. IV), so that the
    anti-damping part of f_i cannot sustain a limit cycle around the grasp point while α̂ is still small;
    it is per body: a robots-object team (friction bounds add up) uses k_v_local × (1 + members).
    margin: the clearance (m) beyond its radius that a moving entity keeps from walls, workspace obstacles and
    other regions (the map's numerical error, :mod:`mrodrake.control.freespace`; it scales with the floor, so a
    small floor can take a smaller one, see :func:`design_range_warnings`).
    alpha_max: the design friction bound ᾱ per body (:data:`DESIGN_ALPHA_MAX`); every controller starts its
    friction estimate at the bound of its entity, α̂(0) = max(alpha_hat0, n ᾱ) for n bodies (a robot: 1, a
    robots-object team: 1 + members), which keeps the velocity loop damped against any friction with α ≤ ᾱ per
    body (mrodrake.control.adaptive); 0 gives the paper's α̂(0) = alpha_hat0.
    """

    k1: PosNum = 0.01
    k2: PosNum = 5.0
    k_phi: PosNum = 1.0
    k_v: PosNum = 1.0
    k_m: PosNum = 0.01
    k_alpha: PosNum = 0.01
    r_bar: PosNum = 0.1
    tau: PosNum = 0.01
    m_hat0: PosNum = 0.5
    alpha_hat0: NonNegNum = 0.0
    k1_local: PosNum = 0.25
    k_v_local: PosNum = 4.0
    alpha_max: NonNegNum = DESIGN_ALPHA_MAX
    margin: PosNum = CONTROL_MARGIN


@dataclass(frozen=True, config=_CFG)
class Planning:
    """Planner and cost parameters (cost χ: region-centre distances + grasp_cost per grasp/release)."""

    grasp_cost: NonNegNum = 1.0
    seed: Annotated[int, Field(strict=True, ge=0)] = 0
    iterations: Annotated[int, Field(strict=True, gt=0)] = 2000
    p_rand: Annotated[float, Field(strict=True, gt=0, le=1)] = 0.9
    p_new: Annotated[float, Field(strict=True, gt=0, le=1)] = 0.8


@dataclass(frozen=True, config=_CFG)
class Scenario:
    """A whole problem: workspace, regions, robots, objects, task, gains, planner parameters."""

    name: Str
    workspace: Workspace
    regions: list[Region]
    robots: list[Robot]
    objects: list[Object]
    task: Task
    description: Str = ""
    layout: Layout = dc_field(default_factory=Layout)
    control: ControlGains = dc_field(default_factory=ControlGains)
    planning: Planning = dc_field(default_factory=Planning)

    @property
    def robot_names(self) -> list[str]:
        return [r.name for r in self.robots]

    @property
    def object_names(self) -> list[str]:
        return [o.name for o in self.objects]

    @property
    def region_names(self) -> list[str]:
        return [g.name for g in self.regions]

    def propositions(self) -> list[str]:
        """All atomic propositions ``<entity>_<region>``: robots first, then objects, region-major."""
        ents = self.robot_names + self.object_names
        return [f"{e}_{g}" for e in ents for g in self.region_names]


_ADAPTER = TypeAdapter(Scenario)


# --------------------------------------------------------------------------------------------------
# YAML reading with line numbers
# --------------------------------------------------------------------------------------------------


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that rejects duplicate mapping keys (PyYAML keeps the last one silently)."""


class _DuplicateKey(Exception):
    def __init__(self, line: int, key):
        super().__init__(line, key)
        self.line, self.key = line, key


def _construct_mapping(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False):
    seen = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if key in seen:
            raise _DuplicateKey(key_node.start_mark.line + 1, key)
        seen[key] = True
    return loader.construct_mapping(node, deep=deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def format_path(loc: tuple) -> str:
    """('robots', 1, 'mass') -> 'robots[1].mass'."""
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "<top level>"


def _node_line(root: yaml.Node | None, loc: tuple) -> int | None:
    """1-based line of the YAML node at ``loc`` (deepest existing ancestor)."""
    node, line = root, None
    if node is not None:
        line = node.start_mark.line + 1
    for part in loc:
        nxt = None
        if isinstance(node, yaml.MappingNode):
            for k, v in node.value:
                if k.value == str(part):
                    nxt = v
                    line = k.start_mark.line + 1
                    break
        elif isinstance(node, yaml.SequenceNode) and isinstance(part, int) and 0 <= part < len(node.value):
            nxt = node.value[part]
            line = nxt.start_mark.line + 1
        if nxt is None:
            break
        node = nxt
    return line


class Where:
    """Formats locations of a loaded file: ``file:line: path``."""

    def __init__(self, source: str, root: yaml.Node | None):
        self.source, self.root = source, root

    def __call__(self, loc: tuple) -> str:
        line = _node_line(self.root, loc)
        prefix = f"{self.source}:{line}" if line else self.source
        return f"{prefix}: {format_path(loc)}"


_PYDANTIC_MESSAGES = {
    "missing": "missing required field",
    "unexpected_keyword_argument": "unknown field",
    "extra_forbidden": "unknown field",
    "float_type": "expected a number",
    "int_type": "expected an integer",
    "string_type": "expected a string",
    "bool_type": "expected true or false",
    "list_type": "expected a list",
    "tuple_type": "expected a list [x, y]",
    "dict_type": "expected a mapping",
    "dataclass_type": "expected a mapping",
    "literal_error": None,
    "too_short": "expected [x, y] (2 numbers)",
    "too_long": "expected [x, y] (2 numbers)",
    "finite_number": "must be a finite number",
}


def _bound(value) -> str:
    return format(value, "g") if isinstance(value, (int, float)) else str(value)


def _pydantic_message(err: dict) -> str:
    kind = err["type"]
    msg = _PYDANTIC_MESSAGES.get(kind)
    if msg is None:
        ctx = err.get("ctx") or {}
        if kind == "greater_than":
            return f"must be > {_bound(ctx.get('gt'))}"
        if kind == "greater_than_equal":
            return f"must be >= {_bound(ctx.get('ge'))}"
        if kind == "less_than_equal":
            return f"must be <= {_bound(ctx.get('le'))}"
        if kind == "less_than":
            return f"must be < {_bound(ctx.get('lt'))}"
        msg = err["msg"]
    return msg


def _yaml_error(source: str, exc: yaml.YAMLError) -> UserError:
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    context, cmark = getattr(exc, "context", None), getattr(exc, "context_mark", None)
    where = f" ({context} at line {cmark.line + 1})" if context and cmark is not None else ""
    if mark is not None:
        return UserError(f"{source}:{mark.line + 1}:{mark.column + 1}: malformed YAML: {problem}{where}")
    return UserError(f"{source}: malformed YAML: {problem}")


def parse_typed(text: str, source: str, adapter: TypeAdapter, top_level: str) -> tuple[Any, Where]:
    """Parse YAML ``text`` into ``adapter``'s type; return (value, where) for the semantic checks.

    Malformed YAML, duplicate keys, a top level that is not a mapping (``top_level`` lists the expected
    fields) and the first pydantic error raise a one-line UserError ``source:line: field.path: problem``.
    Shared by scenario files and campaign specs.
    """
    try:
        root = yaml.compose(text, Loader=_UniqueKeyLoader)
        data = yaml.load(text, Loader=_UniqueKeyLoader)
    except _DuplicateKey as e:
        raise UserError(f"{source}:{e.line}: {e.key}: duplicate key (also given above)") from None
    except yaml.YAMLError as e:
        raise _yaml_error(source, e) from None
    where = Where(source, root)
    if not isinstance(data, dict):
        raise UserError(f"{source}: expected a mapping at the top level ({top_level})")
    try:
        value = adapter.validate_python(data)
    except ValidationError as e:
        err = e.errors()[0]
        loc = tuple(p for p in err["loc"] if p != "__root__")
        raise UserError(f"{where(loc)}: {_pydantic_message(err)}") from None
    return value, where


def parse_scenario(text: str, source: str = "<scenario>", warnings: list[str] | None = None) -> Scenario:
    """Parse and fully validate scenario YAML text; raise UserError naming the file line and field.
    ``warnings``: a list to append design-range warnings to (:func:`design_range_warnings`)."""
    scenario, where = parse_typed(text, source, _ADAPTER, "name, workspace, regions, ...")
    check_scenario(scenario, where)
    if warnings is not None:
        warnings.extend(design_range_warnings(scenario, where))
    return scenario


def read_text(path: str | Path) -> str:
    """A UTF-8 text file's contents; a missing or unreadable file is a one-line UserError."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise UserError(f"{path}: cannot read: {e}") from None


def load_scenario(path: str | Path, warnings: list[str] | None = None) -> Scenario:
    """Read a scenario YAML file and validate it (see :func:`parse_scenario`; ``warnings`` likewise)."""
    return parse_scenario(read_text(path), source=str(path), warnings=warnings)


def scenario_from_dict(data: dict[str, Any], source: str = "<dict>") -> Scenario:
    """Validate a scenario given as a Python mapping (used by tests and generators)."""
    return parse_scenario(yaml.safe_dump(data, sort_keys=False), source=source)


# --------------------------------------------------------------------------------------------------
# Semantic validation
# --------------------------------------------------------------------------------------------------


def _reads_as_atom(name: str) -> bool:
    """Does ``name`` parse as the atomic proposition ``name`` (not as operators glued to a name, 'Fa' = F a)?"""
    try:
        f = parse(name)
    except UserError:
        return False
    return f.kind == AP and atoms(f) == {name}


def _reading(name: str) -> str:
    try:
        return f"'{parse(name)}'"
    except UserError:
        return "an operator"


def _check_names(s: Scenario, where: Where) -> None:
    seen: dict[str, tuple] = {}
    for group in ("robots", "objects", "regions"):
        for i, item in enumerate(getattr(s, group)):
            loc = (group, i, "name")
            if not ENTITY_NAME.match(item.name):
                raise UserError(f"{where(loc)}: name '{item.name}' must be letters and digits only "
                                "(starting with a letter), so that '<entity>_<region>' is unambiguous")
            if item.name in seen:
                raise UserError(f"{where(loc)}: duplicate name '{item.name}' (also {format_path(seen[item.name])})")
            prop = f"{item.name}_{s.regions[0].name if s.regions else 'p'}"
            if group != "regions" and not _reads_as_atom(prop):
                raise UserError(f"{where(loc)}: name '{item.name}' makes its propositions read as LTL operators "
                                f"('{prop}' parses as {_reading(prop)}): a robot or object name must not start "
                                "with F, G or X followed by a letter or an underscore")
            seen[item.name] = loc
    obstacle_names: dict[str, tuple] = {}
    for i, obs in enumerate(s.workspace.obstacles):
        loc = ("workspace", "obstacles", i, "name")
        if not IDENTIFIER.match(obs.name):
            raise UserError(f"{where(loc)}: name '{obs.name}' must be an identifier")
        if obs.name in obstacle_names:
            raise UserError(f"{where(loc)}: duplicate obstacle name '{obs.name}'")
        obstacle_names[obs.name] = loc
    props = set(s.propositions())
    for name in s.task.propositions:
        loc = ("task", "propositions", name)
        if not IDENTIFIER.match(name):
            raise UserError(f"{where(loc)}: macro name '{name}' must be an identifier")
        if not _reads_as_atom(name):
            raise UserError(f"{where(loc)}: macro name '{name}' reads as LTL operators in a formula "
                            f"({_reading(name)})")
        if name in props or name in seen:
            raise UserError(f"{where(loc)}: macro name '{name}' clashes with a robot, object, region or "
                            "atomic proposition")
    if not s.robots:
        raise UserError(f"{where(('robots',))}: at least one robot is required")
    if not s.regions:
        raise UserError(f"{where(('regions',))}: at least one region is required")


def _check_geometry(s: Scenario, where: Where) -> None:
    from mrodrake import geometry as geo

    problem = geo.ring_problem(s.workspace.boundary)
    if problem:
        raise UserError(f"{where(('workspace', 'boundary'))}: {problem}")
    boundary = geo.polygon(s.workspace.boundary)
    obstacles = []
    for i, obs in enumerate(s.workspace.obstacles):
        loc = ("workspace", "obstacles", i, "polygon")
        problem = geo.ring_problem(obs.polygon)
        if problem:
            raise UserError(f"{where(loc)}: {problem}")
        poly = geo.polygon(obs.polygon)
        if not boundary.contains(poly):
            raise UserError(f"{where(loc)}: obstacle '{obs.name}' is not inside workspace.boundary")
        if poly.distance(boundary.exterior) <= 0.0:
            raise UserError(f"{where(loc)}: obstacle '{obs.name}' touches workspace.boundary; walls "
                            "attached to the boundary belong in the boundary polygon")
        for k, other in enumerate(obstacles):
            if poly.distance(other) <= 0.0:
                raise UserError(f"{where(loc)}: obstacle '{obs.name}' touches or overlaps obstacle "
                                f"'{s.workspace.obstacles[k].name}'; merge them into one polygon")
        obstacles.append(poly)
    free = geo.workspace_free_space(boundary, obstacles)
    for i, reg in enumerate(s.regions):
        loc = ("regions", i)
        if not geo.disk_inside(free, reg.center, reg.radius):
            raise UserError(f"{where(loc)}: region '{reg.name}' (centre {list(reg.center)}, radius "
                            f"{reg.radius}) is not inside the free space of the workspace")
        for k in range(i):
            other = s.regions[k]
            dist = math.dist(reg.center, other.center)
            if dist <= reg.radius + other.radius:
                raise UserError(f"{where(loc)}: region '{reg.name}' overlaps region '{other.name}' "
                                f"(centres {dist:.3g} m apart, radii sum {reg.radius + other.radius:.3g} m)")


def _check_initial(s: Scenario, where: Where) -> None:
    from mrodrake.packing import entities_fit

    regions = {g.name: g for g in s.regions}
    members: dict[str, list[float]] = {g: [] for g in regions}
    for group in ("robots", "objects"):
        for i, item in enumerate(getattr(s, group)):
            if item.initial_region not in regions:
                raise UserError(f"{where((group, i, 'initial_region'))}: unknown region "
                                f"'{item.initial_region}' (regions: {', '.join(regions)})")
            members[item.initial_region].append(item.radius)
    for i, reg in enumerate(s.regions):
        if not entities_fit(reg.radius, members[reg.name], s.layout.spacing):
            who = [x.name for x in list(s.robots) + list(s.objects) if x.initial_region == reg.name]
            raise UserError(f"{where(('regions', i, 'radius'))}: the entities starting in region "
                            f"'{reg.name}' ({', '.join(who)}) do not fit in it (P_s, spacing "
                            f"{s.layout.spacing} m)")


def _check_task(s: Scenario, where: Where) -> None:
    from mrodrake.logic.formula import atoms
    from mrodrake.logic.parse import parse

    macros = dict(s.task.propositions)
    entities = set(s.robot_names) | set(s.object_names)
    regions = s.region_names
    sources = [(("task", "propositions", name), body) for name, body in macros.items()]
    sources.append((("task", "formula"), s.task.formula))
    for loc, text in sources:
        src = where(loc)
        for atom in sorted(atoms(parse(text, macros=macros, source=src,
                                       macro_source=lambda m: where(("task", "propositions", m))))):
            ent, sep, reg = atom.partition("_")
            if not sep or not ent or not reg:
                raise UserError(f"{src}: proposition '{atom}' is not of the form <robot>_<region> or "
                                "<object>_<region> and is not a macro")
            if ent not in entities:
                raise UserError(f"{src}: proposition '{atom}' names unknown robot or object '{ent}' "
                                f"(known: {', '.join(s.robot_names + s.object_names)})")
            if reg not in regions:
                raise UserError(f"{src}: proposition '{atom}' names unknown region '{reg}' "
                                f"(regions: {', '.join(regions)})")


def check_scenario(s: Scenario, where: Where | None = None) -> None:
    """Semantic validation: names, geometry, initial packing, task (raises UserError)."""
    where = where or Where("<scenario>", None)
    _check_names(s, where)
    _check_geometry(s, where)
    _check_initial(s, where)
    _check_task(s, where)


def design_range_warnings(s: Scenario, where: Where | None = None) -> list[str]:
    """One line ``<file>:<line>: <field path>: ... outside the design range ...`` per true parameter outside the
    design range of the controllers (:data:`DESIGN_ALPHA_MAX`, :data:`DESIGN_MASS_RATIO`,
    :data:`MARGIN_PER_DIAMETER`, :data:`DESIGN_ROBOT_RADIUS`, the layout spacing against the docking tolerance):
    not an error, the plants simulate any positive mass and friction, but the
    controllers' guarantees assume the range."""
    where = where or Where("<scenario>", None)
    c = s.control
    lo, hi = c.m_hat0 / DESIGN_MASS_RATIO, c.m_hat0 * DESIGN_MASS_RATIO
    out = []
    for group in ("robots", "objects"):
        for i, b in enumerate(getattr(s, group)):
            if not lo <= b.mass <= hi:
                out.append(f"{where((group, i, 'mass'))}: {b.mass:g} kg outside the design range [{lo:g}, {hi:g}] kg "
                           f"of the controllers (m̂_0/{DESIGN_MASS_RATIO:g} to {DESIGN_MASS_RATIO:g} m̂_0, "
                           f"m̂_0 = control.m_hat0 = {c.m_hat0:g} kg)")
            alpha = b.friction.alpha_bound
            if alpha > c.alpha_max:
                out.append(f"{where((group, i, 'friction', 'scale'))}: friction bound α = {alpha:g} "
                           f"({b.friction.model} "
                           f"model, scale {b.friction.scale:g}) outside the design range α ≤ {c.alpha_max:g} per body "
                           f"of the controllers (control.alpha_max)")
    lo_r, hi_r = DESIGN_ROBOT_RADIUS
    for i, r in enumerate(s.robots):
        if not lo_r <= r.radius <= hi_r:
            out.append(f"{where(('robots', i, 'radius'))}: {r.radius:g} m outside the design range [{lo_r:g}, "
                       f"{hi_r:g}] m of the control layer's absolute lengths (windows, departure steps, docking "
                       f"tolerance {DOCK_TOL:g} m)")
    if s.objects and s.layout.spacing < 2.0 * DOCK_TOL:
        out.append(f"{where(('layout', 'spacing'))}: {s.layout.spacing:g} m below twice the docking tolerance "
                   f"({2.0 * DOCK_TOL:g} m): a team whose goal keeps spacing/2 to a region's rim may sit partly "
                   f"outside it with its members docked up to {DOCK_TOL:g} m off their slots, and the transport "
                   f"does not complete")
    diameter = _diameter(s.workspace.boundary)
    if c.margin < MARGIN_PER_DIAMETER * diameter:
        out.append(f"{where(('control', 'margin'))}: {c.margin:g} m outside the design range ≥ "
                   f"{MARGIN_PER_DIAMETER:g} × the workspace diameter ({MARGIN_PER_DIAMETER * diameter:.3g} m for "
                   f"{diameter:.3g} m): the map's boundary error may cross it")
    return out


def _diameter(boundary) -> float:
    xy = np.asarray(boundary, dtype=float)
    return float(np.hypot(*(xy.max(axis=0) - xy.min(axis=0))))


def initial_layout(scenario: Scenario) -> dict[str, np.ndarray]:
    """A position for every robot and object in its initial region, from P_s (:func:`mrodrake.packing.place`
    with the planning seed)."""
    out = {}
    for reg in scenario.regions:
        ents = [e for e in list(scenario.robots) + list(scenario.objects) if e.initial_region == reg.name]
        if not ents:
            continue
        centres = place(reg.radius, np.zeros((0, 2)), [], [e.radius for e in ents],
                        seed=scenario.planning.seed, margin=scenario.layout.spacing)
        if centres is None:
            raise UserError(f"regions: the entities starting in region '{reg.name}' do not fit in it")
        for e, c in zip(ents, centres):
            out[e.name] = np.asarray(reg.center, dtype=float) + c
    return out
