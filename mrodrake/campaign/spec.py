"""Campaign specs: the YAML file's typed form, its validation, and the missions it enumerates."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import field as dc_field
from pathlib import Path
from typing import Annotated, Literal

from pydantic import ConfigDict, Field, TypeAdapter
from pydantic.dataclasses import dataclass

from mrodrake.campaign.draws import draw_parameters
from mrodrake.errors import UserError
from mrodrake.scenario import (
    NonNegNum,
    PosNum,
    Scenario,
    Str,
    Where,
    format_path,
    load_scenario,
    parse_typed,
    read_text,
)

_CFG = ConfigDict(extra="forbid")
PosInt = Annotated[int, Field(strict=True, gt=0)]
NonNegInt = Annotated[int, Field(strict=True, ge=0)]
Bool = Annotated[bool, Field(strict=True)]
InjectMode = Literal["raise", "crash", "hang", "slow"]


@dataclass(frozen=True, config=_CFG)
class SeedRange:
    """The seeds ``start, start + 1, ..., start + count - 1``."""

    start: NonNegInt = 0
    count: PosInt = 1

    def values(self) -> range:
        return range(self.start, self.start + self.count)


@dataclass(frozen=True, config=_CFG)
class Generate:
    """Generated scenarios: every (robots, objects, regions) size combination × every seed, on the case-study
    office or on ``map`` (a shipped map name such as ``warehouse``, or a scenario file relative to the spec)."""

    robots: list[PosInt]
    objects: list[NonNegInt]
    regions: list[PosInt]
    seeds: SeedRange = dc_field(default_factory=SeedRange)
    map: Str | None = None


@dataclass(frozen=True, config=_CFG)
class Seeds:
    """Planner seeds, layout seeds (P_s initial positions and goal points) and parameter draws per pair."""

    plan: SeedRange = dc_field(default_factory=SeedRange)
    layout: SeedRange = dc_field(default_factory=SeedRange)
    draws: PosInt = 1


@dataclass(frozen=True, config=_CFG)
class ScenarioEntry:
    """One entry of ``scenarios``: a scenario ``file`` (relative to the spec) or ``generate`` sizes, and
    optionally its own ``seeds`` (default: the campaign's)."""

    file: Str | None = None
    generate: Generate | None = None
    seeds: Seeds | None = None


@dataclass(frozen=True, config=_CFG)
class Randomize:
    """Ranges [min, max] of the factors applied to every robot's and object's true parameters.

    Each body draws its own factors uniformly; ``initial_positions`` draws the layout seed too (a random
    valid P_s layout in the initial regions) instead of taking it from ``seeds.layout``.
    """

    seed: NonNegInt = 0
    robot_mass: list[PosNum] = dc_field(default_factory=lambda: [1.0, 1.0])
    object_mass: list[PosNum] = dc_field(default_factory=lambda: [1.0, 1.0])
    friction_scale: list[NonNegNum] = dc_field(default_factory=lambda: [1.0, 1.0])
    friction_frequency: list[NonNegNum] = dc_field(default_factory=lambda: [1.0, 1.0])
    initial_positions: Bool = False


@dataclass(frozen=True, config=_CFG)
class CampaignSpec:
    """A campaign: scenarios × plan seeds × layout seeds × draws missions (see the README)."""

    name: Str
    scenarios: list[ScenarioEntry]
    description: Str = ""
    planner: Literal["stylus", "exact"] = "stylus"
    iterations: PosInt | None = None
    plan_time_limit: PosNum | None = None
    suffix_cycles: NonNegInt = 1
    execution: list[Literal["sequential", "concurrent"]] = dc_field(default_factory=lambda: ["sequential"])
    time_limit: PosNum = 600.0
    seeds: Seeds = dc_field(default_factory=Seeds)
    randomize: Randomize = dc_field(default_factory=Randomize)
    inject: dict[NonNegInt, InjectMode] = dc_field(default_factory=dict)


_SPEC_ADAPTER = TypeAdapter(CampaignSpec)


@dataclasses.dataclass(frozen=True)
class ScenarioInstance:
    """A concrete scenario of the campaign: ``key`` (unique, in mission ids), ``family`` (summary group)."""

    key: str
    family: str
    source: str
    scenario: Scenario


@dataclasses.dataclass(frozen=True)
class MissionTask:
    """Everything a worker needs for one mission (picklable); ``params``: true values per body."""

    index: int
    mission_id: str
    instance: ScenarioInstance
    plan_seed: int
    layout_seed: int
    draw: int
    params: dict
    planner: str
    iterations: int | None
    plan_time_limit: float | None
    suffix_cycles: int
    time_limit: float
    inject: str | None = None
    execution: str = "sequential"
    run_dir: str | None = None
    #: wall-clock time (time.time()) at which the engine dispatched the mission: the soft limit counts from
    #: it, as the engine's kill does, so a slow worker start-up (Ray) is inside both (a cluster's clocks are
    #: assumed synchronised to well within the grace period); None: from the start of :func:`execute`
    dispatched: float | None = None

    @property
    def kill_after(self) -> float:
        """Wall seconds after which the engine kills the worker (the soft limit plus a grace period)."""
        return self.time_limit + min(60.0, max(5.0, 0.1 * self.time_limit))

    def fingerprint(self) -> str:
        """Hash of every input that can change the row (a resumed mission must match it)."""
        data = {"scenario": dataclasses.asdict(self.instance.scenario), "plan_seed": self.plan_seed,
                "layout_seed": self.layout_seed, "params": self.params, "planner": self.planner,
                "iterations": self.iterations, "plan_time_limit": self.plan_time_limit,
                "suffix_cycles": self.suffix_cycles, "execution": self.execution,
                "time_limit": self.time_limit, "inject": self.inject}
        return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()[:16]


@dataclasses.dataclass(frozen=True)
class Campaign:
    """A loaded spec and its missions in index order."""

    spec: CampaignSpec
    path: Path
    tasks: list[MissionTask]


def _check_range(values: list[float], loc: tuple, where: Where) -> tuple[float, float]:
    if len(values) != 2:
        raise UserError(f"{where(loc)}: expected [min, max] (2 numbers)")
    lo, hi = float(values[0]), float(values[1])
    if lo > hi:
        raise UserError(f"{where(loc)}: min {lo:g} is larger than max {hi:g}")
    return lo, hi


def _check_seeds(spec: CampaignSpec, seeds: Seeds, loc: tuple, where: Where) -> None:
    if spec.planner == "exact" and seeds.plan.count > 1:
        raise UserError(f"{where(loc + ('plan', 'count'))}: the exact planner takes no seed; use count 1")
    if spec.randomize.initial_positions and seeds.layout.count > 1:
        raise UserError(f"{where(loc + ('layout', 'count'))}: randomize.initial_positions draws the layout "
                        "seed of every mission; use count 1")


def _instances(spec: CampaignSpec, where: Where, base: Path) -> list[tuple[ScenarioInstance, Seeds]]:
    """Every scenario of the spec with the seeds of its entry (files loaded, generated ones generated)."""
    from mrodrake.planning.generate import MAPS, MAX_K, generate_scenario, load_map

    out: list[tuple[ScenarioInstance, Seeds]] = []
    seen: dict[str, tuple] = {}

    def add(inst: ScenarioInstance, seeds: Seeds, loc: tuple) -> None:
        if inst.key in seen:
            raise UserError(f"{where(loc)}: scenario '{inst.key}' appears twice (also {format_path(seen[inst.key])})")
        seen[inst.key] = loc
        out.append((inst, seeds))

    if not spec.scenarios:
        raise UserError(f"{where(('scenarios',))}: at least one scenario entry is required")
    _check_seeds(spec, spec.seeds, ("seeds",), where)
    for i, entry in enumerate(spec.scenarios):
        loc = ("scenarios", i)
        if (entry.file is None) == (entry.generate is None):
            raise UserError(f"{where(loc)}: give exactly one of 'file' and 'generate'")
        seeds = spec.seeds if entry.seeds is None else entry.seeds
        if entry.seeds is not None:
            _check_seeds(spec, seeds, loc + ("seeds",), where)
        if entry.file is not None:
            path = Path(entry.file) if Path(entry.file).is_absolute() else base / entry.file
            if not path.is_file():
                raise UserError(f"{where(loc + ('file',))}: no such file '{entry.file}' (relative to the spec)")
            add(ScenarioInstance(path.stem, path.stem, entry.file, load_scenario(path)), seeds, loc + ("file",))
            continue
        gen = entry.generate
        for name, values in (("robots", gen.robots), ("objects", gen.objects), ("regions", gen.regions)):
            if not values:
                raise UserError(f"{where(loc + ('generate', name))}: expected a non-empty list of sizes")
        map_scenario, max_k, tag = None, MAX_K, ""
        if gen.map is not None:
            path = Path(gen.map) if Path(gen.map).is_absolute() else base / gen.map
            shipped = sorted(p.stem for p in MAPS.glob("*.yaml"))
            if not path.is_file() and gen.map not in shipped:
                raise UserError(f"{where(loc + ('generate', 'map'))}: unknown map '{gen.map}' (a shipped map: "
                                f"{', '.join(shipped)}; or a scenario file relative to the spec)")
            try:
                map_scenario = load_map(str(path) if path.is_file() else gen.map)
            except UserError as e:
                raise UserError(f"{where(loc + ('generate', 'map'))}: {e}") from None
            max_k, tag = len(map_scenario.regions), f"_{map_scenario.name}"
        for j, k in enumerate(gen.regions):
            if k > max_k:
                raise UserError(f"{where(loc + ('generate', 'regions', j))}: at most {max_k} regions, got {k}")
        for n in gen.robots:
            for m in gen.objects:
                for k in gen.regions:
                    for seed in gen.seeds.values():
                        where_map = "" if gen.map is None else f", map={gen.map!r}"
                        text = f"generate_scenario({n}, {m}, {k}, {seed}{where_map})"
                        try:
                            scenario = generate_scenario(n, m, k, seed, map=map_scenario)
                        except (ValueError, UserError) as e:
                            raise UserError(f"{where(loc + ('generate',))}: {text}: {e}") from None
                        add(ScenarioInstance(scenario.name, f"gen{tag}_n{n}_m{m}_k{k}", text, scenario), seeds,
                            loc + ("generate",))
    return out


def load_campaign(path: str | Path) -> Campaign:
    """Read and validate a campaign spec and enumerate its missions (UserError naming the field)."""
    path = Path(path)
    spec, where = parse_typed(read_text(path), str(path), _SPEC_ADAPTER,
                              "name, scenarios, seeds, randomize, ...")
    r = spec.randomize
    for name in ("robot_mass", "object_mass", "friction_scale", "friction_frequency"):
        _check_range(getattr(r, name), ("randomize", name), where)
    for name in ("iterations", "plan_time_limit"):
        if spec.planner == "exact" and getattr(spec, name) is not None:
            raise UserError(f"{where((name,))}: only for the stylus planner")
    modes = list(dict.fromkeys(spec.execution))
    if not modes:
        raise UserError(f"{where(('execution',))}: give at least one of sequential, concurrent")
    tasks = []
    for inst, seeds in _instances(spec, where, path.resolve().parent):
        for ps in seeds.plan.values():
            for ls in seeds.layout.values():
                for d in range(seeds.draws):
                    mid = f"{inst.key}-p{ps}-l{ls}-d{d}"
                    params, drawn = draw_parameters(spec, inst.scenario, mid)
                    for mode in modes:
                        tasks.append(MissionTask(len(tasks), mid if mode == "sequential" else f"{mid}-{mode}", inst,
                                                 ps, ls if drawn is None else drawn, d, params, spec.planner,
                                                 spec.iterations, spec.plan_time_limit, spec.suffix_cycles,
                                                 float(spec.time_limit), None, execution=mode))
    for idx, mode in spec.inject.items():
        if idx >= len(tasks):
            raise UserError(f"{where(('inject', idx))}: mission index {idx} out of range (the campaign has "
                            f"{len(tasks)} missions, 0..{len(tasks) - 1})")
        tasks[idx] = dataclasses.replace(tasks[idx], inject=mode)
    return Campaign(spec, path, tasks)
