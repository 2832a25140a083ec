"""``mrodrake campaign SPEC.yaml``: many plan + execute missions, on a local process pool or on Ray.

A campaign spec (YAML, validated like scenario files: one line ``file:line: field.path: problem``) lists
scenario files and generated scenarios (:func:`mrodrake.planning.generate.generate_scenario` sizes and a
seed range), the plan and layout seeds, the number of parameter draws, the planner, the suffix cycles and
the ranges from which every mission draws its *true* plant parameters (mass and friction factors, and
optionally a random P_s initial layout).  The draws are a pure function of (``randomize.seed``, mission
id), so every engine produces the same rows.  Only the plants see the drawn values: they are written into
a copy of the scenario's robots and objects, which planners and controllers never read.

Every mission runs in its own worker process (local engine: one forked process per mission, at most
``--workers`` at a time; Ray: one task per mission).  A mission that raises, exceeds its time limit (soft:
the simulator's monitor stops it; hard: the engine kills the worker ``time_limit`` + grace later) or kills
its worker becomes a failure row; the campaign goes on.  Each finished mission is appended to
``journal.jsonl`` in the output directory, so re-running the same command skips it; at the end (and after
Ctrl-C) ``results.csv`` (+ ``results.parquet`` when pyarrow is installed), ``summary.md`` and ``figures/``
are written from the journal.

Failure kinds come from one table (:data:`FAILURE_PATTERNS`): a structured ``failure_kind`` attribute of the
mission log wins when present, else the first pattern found in the message.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import importlib.util
import json
import math
import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import field as dc_field
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import ConfigDict, Field, TypeAdapter
from pydantic.dataclasses import dataclass

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

#: Environment of every worker process: single-threaded BLAS.  A mission's outcome depends on the last bits
#: of its linear solves, and multi-threaded OpenBLAS sums in a thread-count dependent order, so without this
#: the rows would depend on the engine (Ray sets OMP_NUM_THREADS=1 itself) and the machine's core count;
#: one thread per mission is also what a pool of one mission per core wants.
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
#: Modules a local worker process needs, imported once by the fork server instead of once per mission.
WORKER_MODULES = ["mrodrake.campaign", "mrodrake.systems.mission", "mrodrake.planning.plan",
                  "mrodrake.planning.stylus", "mrodrake.planning.exact", "pandas", "shapely"]


# ------------------------------------------------------------------------------------------ spec
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
                "suffix_cycles": self.suffix_cycles,
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


def draw_parameters(spec: CampaignSpec, scenario: Scenario, mission_id: str) -> tuple[dict, int | None]:
    """True parameters of every body (mass, friction scale and frequency, with their factors) and the
    drawn layout seed (``None`` unless ``randomize.initial_positions``): a pure function of
    (``randomize.seed``, ``mission_id``), drawn in a fixed order (robots, then objects)."""
    r = spec.randomize
    digest = hashlib.sha256(mission_id.encode()).digest()
    rng = np.random.default_rng([r.seed] + [int.from_bytes(digest[i:i + 4], "little") for i in range(0, 16, 4)])
    params = {}
    bodies = [(b, r.robot_mass) for b in scenario.robots] + [(b, r.object_mass) for b in scenario.objects]
    for body, mass_range in bodies:
        fm = float(rng.uniform(*mass_range))
        fs = float(rng.uniform(*r.friction_scale))
        ff = float(rng.uniform(*r.friction_frequency))
        params[body.name] = {"mass": body.mass * fm, "friction_scale": body.friction.scale * fs,
                             "friction_frequency": body.friction.frequency * ff,
                             "factors": [fm, fs, ff]}
    layout = int(rng.integers(0, 2**31 - 1)) if r.initial_positions else None
    return params, layout


def randomized_scenario(scenario: Scenario, params: dict) -> Scenario:
    """A copy of ``scenario`` whose robots and objects have the true parameters ``params``."""

    def body(b):
        p = params[b.name]
        friction = dataclasses.replace(b.friction, scale=p["friction_scale"], frequency=p["friction_frequency"])
        return dataclasses.replace(b, mass=p["mass"], friction=friction)

    return dataclasses.replace(scenario, robots=[body(b) for b in scenario.robots],
                               objects=[body(b) for b in scenario.objects])


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
    tasks = []
    for inst, seeds in _instances(spec, where, path.resolve().parent):
        for ps in seeds.plan.values():
            for ls in seeds.layout.values():
                for d in range(seeds.draws):
                    mid = f"{inst.key}-p{ps}-l{ls}-d{d}"
                    params, drawn = draw_parameters(spec, inst.scenario, mid)
                    tasks.append(MissionTask(len(tasks), mid, inst, ps, ls if drawn is None else drawn, d, params,
                                             spec.planner, spec.iterations, spec.plan_time_limit,
                                             spec.suffix_cycles, float(spec.time_limit), None))
    for idx, mode in spec.inject.items():
        if idx >= len(tasks):
            raise UserError(f"{where(('inject', idx))}: mission index {idx} out of range (the campaign has "
                            f"{len(tasks)} missions, 0..{len(tasks) - 1})")
        tasks[idx] = dataclasses.replace(tasks[idx], inject=mode)
    return Campaign(spec, path, tasks)


# ------------------------------------------------------------------------------------------ failure kinds
#: Failure kinds by message: (stage, kind, substrings); the first row whose stage matches (``*``: any)
#: and whose substring occurs in the message wins.  Stages: ``plan`` (UserError from planning) and
#: ``mission`` (a failed mission log or an exception raised while building or simulating the mission).
FAILURE_PATTERNS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("plan", "plan_not_found", ("no plan found",)),  # it may end "... no relaxation proves ... unsatisfiable"
    ("plan", "plan_unsat", ("unsatisfiable",)),
    ("mission", "no_order", ("no order of the concurrent actions",)),
    ("mission", "nba_run", ("monitored NBA run",)),
    ("mission", "state_mismatch", ("differs from the plan",)),
    ("mission", "integrator", ("integrator", "step smaller than minimum", "minimum step")),
    ("mission", "primitive_time_limit", ("time limit",)),
    ("mission", "goal_unreachable", ("goal unreachable",)),
    ("mission", "no_grasp_point", ("no reachable grasp point",)),
    ("mission", "no_room", ("no room for an entity", "do not fit")),
    ("mission", "placement", ("no free grasp layout", "no layout keeps the room", "no room to back off",
                              "no room for")),
    ("mission", "outside_free_space", ("not in the free space",)),
    ("mission", "degenerate_map", ("degenerate",)),
    ("mission", "non_finite", ("non-finite", "not finite")),
    ("mission", "controller_fault", ("controller fault",)),
    ("mission", "exception", ("inside the simulation",)),
)
#: Kind when no pattern matches: per stage, and for an exception or a failed mission log.
DEFAULT_KINDS = {"plan": "plan_error", "exception": "exception", "log": "mission_failed"}


def classify(stage: str, message: str, default: str) -> str:
    """The failure kind of ``message`` raised or reported in ``stage`` (``plan`` or ``mission``)."""
    low = message.lower()
    for st, kind, needles in FAILURE_PATTERNS:
        if st in (stage, "*") and any(n.lower() in low for n in needles):
            return kind
    return default


def _first_line(text: str, limit: int = 300) -> str:
    line = (str(text).strip().splitlines() or [""])[0]
    return line if len(line) <= limit else line[: limit - 3] + "..."


# ------------------------------------------------------------------------------------------ metrics
def trajectory_metrics(scenario: Scenario, trajectory) -> dict:
    """Safety metrics recomputed from a logged trajectory (t, entity, x, y, vx, vy).

    ``min_clearance``: smallest signed distance from any entity disk to the walls and obstacles (shapely
    distance of the centre to the free-space boundary, negative outside it, minus the radius);
    ``min_gap``: smallest distance between two entity disks (centre distance minus both radii) at a common
    sample time; ``max_speed``; ``nan_seen``: a non-finite value anywhere.
    """
    import shapely

    from mrodrake import geometry as geo

    out = {"min_clearance": None, "min_clearance_entity": "", "min_gap": None, "min_gap_pair": "",
           "max_speed": None, "max_speed_entity": "", "nan_seen": False}
    if trajectory is None or len(trajectory) == 0:
        return out
    radius = {b.name: float(b.radius) for b in list(scenario.robots) + list(scenario.objects)}
    names = [n for n in radius if n in set(trajectory["entity"].unique())]
    wide = trajectory.pivot_table(index="t", columns="entity", values=["x", "y", "vx", "vy"], aggfunc="first",
                                  dropna=False)
    X = wide["x"][names].to_numpy(float)
    Y = wide["y"][names].to_numpy(float)
    VX = wide["vx"][names].to_numpy(float)
    VY = wide["vy"][names].to_numpy(float)
    out["nan_seen"] = bool(not (np.isfinite(X).all() and np.isfinite(Y).all() and np.isfinite(VX).all()
                                and np.isfinite(VY).all()))
    R = np.array([radius[n] for n in names])
    with np.errstate(invalid="ignore"):
        speed = np.hypot(VX, VY)
    if np.isfinite(speed).any():
        k = int(np.nanargmax(speed))
        out["max_speed"], out["max_speed_entity"] = float(speed.flat[k]), names[k % len(names)]
    free = geo.workspace_free_space(geo.polygon(scenario.workspace.boundary),
                                    [geo.polygon(o.polygon) for o in scenario.workspace.obstacles])
    walls = free.boundary
    shapely.prepare(free)
    shapely.prepare(walls)
    best = (math.inf, "")
    for e, name in enumerate(names):
        xy = np.column_stack([X[:, e], Y[:, e]])
        xy = xy[np.isfinite(xy).all(axis=1)]
        if not len(xy):
            continue
        xy = np.unique(xy, axis=0)
        pts = shapely.points(xy)
        d = shapely.distance(walls, pts)
        signed = np.where(shapely.covers(free, pts), d, -d) - R[e]
        if signed.min() < best[0]:
            best = (float(signed.min()), name)
    if best[1]:
        out["min_clearance"], out["min_clearance_entity"] = best
    if len(names) > 1:
        i, j = np.triu_indices(len(names), k=1)
        with np.errstate(invalid="ignore"):
            gap = np.hypot(X[:, i] - X[:, j], Y[:, i] - Y[:, j]) - (R[i] + R[j])
        if np.isfinite(gap).any():
            k = int(np.nanargmin(gap))
            p = k % len(i)
            out["min_gap"], out["min_gap_pair"] = float(gap.flat[k]), f"{names[i[p]]}-{names[j[p]]}"
    return out


def primitive_records(scenario: Scenario, log) -> list[dict]:
    """One record per executed primitive of a mission log: step, kind, entities, duration against the motion's
    time bound, and for navigations and transports the final estimates m̂, α̂ of its controller against the
    true mass and friction bound of the moving entity (a transport: object plus members, the bounds of
    Assumption 1 adding up)."""
    bodies = {b.name: b for b in list(scenario.robots) + list(scenario.objects)}
    ev = log.events
    if ev is None or not len(ev):
        return []
    sig = log.signals
    out = []
    for _, e in ev[ev["kind"].isin(["primitive", "room"])].iterrows():
        names = str(e["entities"]).split()
        kind = "room" if e["kind"] == "room" else str(e["action"]).split()[0]
        t0, t1 = float(e["t_start"]), float(e["t_end"])
        limit = _finite(e.get("time_limit"))
        rec = {"step": int(e["step"]), "kind": kind, "action": str(e["action"]), "entities": " ".join(names),
               "ok": bool(e["ok"]), "seconds": t1 - t0, "time_limit": limit,
               "m_true": None, "m_hat": None, "alpha_true": None, "alpha_hat": None}
        if kind in ("navigate", "transport") and names:
            s = sig[(sig["entity"] == names[0]) & (sig["t"] >= t0) & (sig["t"] <= t1)]
            if len(s):
                last = s.iloc[-1]
                rec.update(m_true=float(sum(bodies[n].mass for n in names)),
                           alpha_true=float(sum(bodies[n].friction.alpha_bound for n in names)),
                           m_hat=float(last["m_hat"]), alpha_hat=float(last["alpha_hat"]))
        out.append(rec)
    return out


def _finite(value) -> float | None:
    """A finite float, or None for empty / NaN cells."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


# ------------------------------------------------------------------------------------------ one mission
#: Row columns that measure time on the machine (they differ between runs and engines).
TIMING_COLUMNS = ("plan_wall_seconds", "sim_wall_seconds", "wall_seconds", "cpu_seconds", "real_time_factor")


def base_row(task: MissionTask) -> dict:
    """The row's identification and drawn-parameter columns, outcome columns empty."""
    s = task.instance.scenario
    factors = np.array([p["factors"] for p in task.params.values()]).reshape(-1, 3)
    return {
        "index": task.index, "mission_id": task.mission_id, "family": task.instance.family,
        "scenario": task.instance.key, "source": task.instance.source, "robots": len(s.robots),
        "objects": len(s.objects), "regions": len(s.regions), "planner": task.planner,
        "plan_seed": task.plan_seed, "layout_seed": task.layout_seed, "draw": task.draw,
        "suffix_cycles": task.suffix_cycles,
        "mass_factor_min": float(factors[:, 0].min()), "mass_factor_max": float(factors[:, 0].max()),
        "friction_factor_min": float(factors[:, 1].min()), "friction_factor_max": float(factors[:, 1].max()),
        "frequency_factor_min": float(factors[:, 2].min()), "frequency_factor_max": float(factors[:, 2].max()),
        "params": json.dumps({n: [p["mass"], p["friction_scale"], p["friction_frequency"]]
                              for n, p in task.params.items()}),
        "ok": False, "failure_kind": "", "failure_message": "", "steps_done": None, "steps_total": None,
        "sim_seconds": None, "plan_wall_seconds": None, "sim_wall_seconds": None, "wall_seconds": None,
        "cpu_seconds": None, "real_time_factor": None, "min_clearance": None, "min_clearance_entity": "",
        "min_gap": None,
        "min_gap_pair": "", "max_speed": None, "max_speed_entity": "", "nan_seen": False,
    }


def failure_row(task: MissionTask, kind: str, message: str, wall: float) -> dict:
    """The row of a mission that produced no result of its own (killed, crashed worker)."""
    row = base_row(task)
    row.update(failure_kind=kind, failure_message=_first_line(message), wall_seconds=float(wall))
    return row


def _record_log(row: dict, task: MissionTask, scenario: Scenario, log, stopped: bool) -> None:
    """Fill ``row`` from a mission log: progress, timings, the outcome (unless an exception already set
    the failure), the trajectory metrics; write the mission's outputs with ``--keep-runs``."""
    row.update(steps_done=int(log.steps_done), steps_total=int(log.steps_total), sim_seconds=float(log.sim_seconds),
               sim_wall_seconds=float(log.wall_seconds),
               real_time_factor=float(log.sim_seconds / log.wall_seconds) if log.wall_seconds > 0 else None)
    if not row["failure_kind"]:
        row["ok"] = bool(log.ok)
        if stopped and not log.ok:
            row.update(failure_kind="timeout", failure_message=(
                f"time limit {task.time_limit:g} s reached after {log.steps_done}/{log.steps_total} plan steps "
                f"(simulated {log.sim_seconds:.0f} s)"))
        elif not log.ok:
            msg = _first_line(log.message)
            kind = getattr(log, "failure_kind", None) or classify("mission", msg, DEFAULT_KINDS["log"])
            row.update(failure_kind=str(kind), failure_message=msg)
    row.update(trajectory_metrics(scenario, log.trajectory))
    row["primitives"] = primitive_records(scenario, log)
    if task.run_dir is not None:
        from mrodrake.viz.outputs import write_mission

        write_mission(log, task.run_dir)


def execute(task: MissionTask) -> dict:
    """Plan and simulate one mission and return its row; never raises for a failing mission."""
    from mrodrake.planning.plan import plan_scenario
    from mrodrake.systems.mission import Mission

    t0, cpu0 = time.perf_counter(), time.process_time()
    row = base_row(task)
    if task.inject == "crash":
        os.abort()
    if task.inject == "hang":
        while True:
            time.sleep(1.0)
    scenario = randomized_scenario(task.instance.scenario, task.params)
    stage, mission, log, timer, stopped = "plan", None, None, None, threading.Event()
    try:
        seed = None if task.planner == "exact" else task.plan_seed
        limit = min(task.plan_time_limit or math.inf, task.time_limit) if task.planner == "stylus" else None
        plan = plan_scenario(scenario, task.planner, seed=seed, iterations=task.iterations, time_limit=limit)
        row["plan_wall_seconds"] = time.perf_counter() - t0
        stage = "mission"
        if task.inject == "raise":
            raise RuntimeError(f"injected failure (spec inject[{task.index}])")
        mission = Mission(scenario, plan, suffix_cycles=task.suffix_cycles, seed=task.layout_seed)

        def stop() -> None:
            stopped.set()
            mission.request_stop()

        if task.inject == "slow":  # simulated time at most 5x wall time: a mission that outlives its soft limit
            mission.simulator.set_target_realtime_rate(5.0)
        elapsed = time.perf_counter() - t0 if task.dispatched is None else time.time() - task.dispatched
        timer = threading.Timer(max(0.0, task.time_limit - elapsed), stop)
        timer.daemon = True
        timer.start()
        log = mission.run()
    except UserError as e:
        msg = _first_line(e)
        if stage == "plan" and time.perf_counter() - t0 >= task.time_limit:
            row.update(failure_kind="timeout", failure_message=f"planning: {msg}")
        else:
            kind = classify(stage, msg, DEFAULT_KINDS["plan" if stage == "plan" else "exception"])
            row.update(failure_kind=kind, failure_message=msg if stage == "plan" else f"UserError: {msg}")
    except Exception as e:  # a mission's exception is a recorded failure, never a campaign stop
        msg = f"{type(e).__name__}: {_first_line(e)}"
        row.update(failure_kind=classify(stage, msg, DEFAULT_KINDS["exception"]), failure_message=msg)
    finally:
        if timer is not None:
            timer.cancel()
    try:
        if log is None and mission is not None:
            log = mission.log()  # what was simulated before the exception
        if log is not None:
            _record_log(row, task, scenario, log, stopped.is_set())
    except Exception as e:  # the metrics or outputs of a finished mission: still a row, never a lost worker
        row.update(ok=False, failure_kind=row["failure_kind"] or "exception",
                   failure_message=row["failure_message"] or f"recording: {type(e).__name__}: {_first_line(e)}")
    row["wall_seconds"], row["cpu_seconds"] = time.perf_counter() - t0, time.process_time() - cpu0
    if task.run_dir is not None:
        Path(task.run_dir).mkdir(parents=True, exist_ok=True)
        (Path(task.run_dir) / "row.json").write_text(json.dumps(row, indent=1, default=str), encoding="utf-8")
    return row


# ------------------------------------------------------------------------------------------ engines
def _exit_text(code: int | None) -> str:
    if code is None:
        return "no exit status"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


def _local_worker(conn, task: MissionTask, log_path: str | None) -> None:
    """Entry point of a local worker process: run the mission, send the row (SIGINT is the parent's)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    sink = os.open(log_path or os.devnull, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(sink, 1)
    os.dup2(sink, 2)
    conn.send(execute(task))
    conn.close()


def _forkserver_context():
    """The forkserver context, its server started with :data:`WORKER_ENV` and :data:`WORKER_MODULES`
    (every worker forked from it inherits both)."""
    import multiprocessing as mp
    from multiprocessing import forkserver

    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(WORKER_MODULES)
    saved = {k: os.environ.get(k) for k in WORKER_ENV}
    os.environ.update(WORKER_ENV)
    try:
        forkserver.ensure_running()
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return ctx


class LocalEngine:
    """At most ``workers`` missions at a time, each in its own process forked from a fork server that has
    imported Drake and mrodrake once; a process that dies or outlives ``kill_after`` is a failure row."""

    name = "local"

    def __init__(self, workers: int | None = None):
        self.workers = int(workers or os.cpu_count() or 1)
        self._ctx = None

    def open(self) -> None:
        """Start the fork server (imports Drake and mrodrake once)."""
        self._ctx = _forkserver_context()

    def close(self) -> None:
        """Nothing to release: the fork server ends with this process."""

    def run(self, tasks: Iterable[MissionTask], on_row: Callable[[dict], None], log_dir: Path | None = None) -> None:
        from multiprocessing.connection import wait

        ctx = self._ctx or _forkserver_context()
        pending = deque(tasks)
        running: dict = {}
        try:
            while pending or running:
                while pending and len(running) < self.workers:
                    task = dataclasses.replace(pending.popleft(), dispatched=time.time())
                    receive, send = ctx.Pipe(duplex=False)
                    log_path = None
                    if log_dir is not None:
                        (log_dir / task.mission_id).mkdir(parents=True, exist_ok=True)
                        log_path = str(log_dir / task.mission_id / "worker.log")
                    proc = ctx.Process(target=_local_worker, args=(send, task, log_path), daemon=True,
                                       name=f"mission-{task.index}")
                    proc.start()
                    send.close()
                    running[receive] = (task, proc, time.monotonic())
                next_kill = min(t0 + task.kill_after for task, _, t0 in running.values())
                for conn in wait(list(running), timeout=max(0.05, min(next_kill - time.monotonic(), 1.0))):
                    task, proc, t0 = running.pop(conn)
                    try:
                        row = conn.recv()
                    except Exception:  # EOF or a message cut short: the worker died before sending its row
                        row = None
                    conn.close()
                    proc.join(timeout=30.0)
                    if proc.is_alive():
                        proc.kill()
                        proc.join()
                    if row is None:
                        row = failure_row(task, "worker_crash",
                                          f"worker process died ({_exit_text(proc.exitcode)})",
                                          time.monotonic() - t0)
                    on_row(row)
                now = time.monotonic()
                for conn, (task, proc, t0) in list(running.items()):
                    if now - t0 > task.kill_after:
                        proc.kill()
                        proc.join()
                        conn.close()
                        del running[conn]
                        on_row(failure_row(task, "timeout", f"killed after {now - t0:.0f} s: time limit "
                                           f"{task.time_limit:g} s and the mission did not stop", now - t0))
        finally:
            for conn, (_, proc, _) in running.items():
                proc.kill()
                proc.join()
                conn.close()


class RayEngine:
    """One Ray task per mission (``num_cpus=1``, no retries), at most ``workers`` (default: the cluster's
    CPUs) in flight so that a task's age is its running time; a task past ``kill_after`` is cancelled
    with ``force=True`` (its worker is killed).  Starts a local Ray unless ``address`` or an initialised
    Ray is given."""

    name = "ray"

    def __init__(self, workers: int | None = None, address: str | None = None):
        self.workers, self.address = workers, address
        self._started = False

    def open(self) -> None:
        """Join ``address``, or start a local Ray with ``workers`` CPUs, unless Ray is initialised."""
        import logging

        try:
            import ray
        except ImportError:
            raise UserError("--engine ray: Ray is not installed (pip install -e \".[ray]\")") from None
        if ray.is_initialized():
            return
        kw = {"include_dashboard": False, "log_to_driver": False, "logging_level": logging.WARNING}
        if self.address:
            try:
                ray.init(address=self.address, **kw)
            except (ConnectionError, RuntimeError, ValueError) as e:
                raise UserError(f"--address: cannot join the Ray cluster at '{self.address}': "
                                f"{_first_line(e)}") from None
        else:
            ray.init(num_cpus=self.workers, **kw)
        self._started = True

    def close(self) -> None:
        """Shut down the Ray that :meth:`open` started (a joined or given one stays up)."""
        if self._started:
            import ray

            ray.shutdown()
            self._started = False

    def run(self, tasks: Iterable[MissionTask], on_row: Callable[[dict], None], log_dir: Path | None = None) -> None:
        import ray

        remote = ray.remote(num_cpus=1, max_retries=0, runtime_env={"env_vars": WORKER_ENV})(execute)
        capacity = int(self.workers or max(1, int(ray.cluster_resources().get("CPU", 1))))
        pending = deque(tasks)
        running: dict = {}
        try:
            while pending or running:
                while pending and len(running) < capacity:
                    task = dataclasses.replace(pending.popleft(), dispatched=time.time())
                    running[remote.remote(task)] = (task, time.monotonic())
                next_kill = min(t0 + task.kill_after for task, t0 in running.values())
                ready, _ = ray.wait(list(running), num_returns=1,
                                    timeout=max(0.05, min(next_kill - time.monotonic(), 1.0)))
                for ref in ready:
                    task, t0 = running.pop(ref)
                    try:
                        row = ray.get(ref)
                    except Exception as e:  # a dead or cancelled worker is a recorded failure
                        row = failure_row(task, "worker_crash", f"ray: {type(e).__name__}: {_first_line(e)}",
                                          time.monotonic() - t0)
                    on_row(row)
                now = time.monotonic()
                for ref, (task, t0) in list(running.items()):
                    if now - t0 > task.kill_after:
                        ray.cancel(ref, force=True)
                        del running[ref]
                        on_row(failure_row(task, "timeout", f"killed after {now - t0:.0f} s: time limit "
                                           f"{task.time_limit:g} s and the mission did not stop", now - t0))
        finally:
            for ref in running:
                ray.cancel(ref, force=True)


# ------------------------------------------------------------------------------------------ campaign run
@dataclasses.dataclass
class CampaignResult:
    """Rows of the spec's finished missions (index order), counts and timing of this invocation."""

    rows: Any
    total: int
    ran: int
    skipped: int
    wall_seconds: float
    interrupted: bool
    summary: str
    out: Path


def _read_journal(path: Path) -> dict[str, tuple[str, dict]]:
    found: dict[str, tuple[str, dict]] = {}
    if not path.is_file():
        return found
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            rec = json.loads(line)
            found[rec["row"]["mission_id"]] = (rec["fingerprint"], rec["row"])
        except (ValueError, KeyError, TypeError):
            continue  # a line cut short by a killed run
    return found


def run_campaign(spec_path: str | Path, out: str | Path | None = None, engine: str = "local",
                 workers: int | None = None, address: str | None = None, keep_runs: bool = False,
                 progress: bool = True) -> CampaignResult:
    """Run (or resume) the campaign of ``spec_path`` into ``out`` and write the results and summary.

    Raises KeyboardInterrupt after writing what finished when interrupted."""
    import pandas as pd
    from tqdm import tqdm

    if workers is not None and workers < 1:
        raise UserError(f"--workers: must be >= 1, got {workers}")
    if engine not in ("local", "ray"):
        raise UserError(f"--engine: unknown engine '{engine}' (expected 'local' or 'ray')")
    if address and engine != "ray":
        raise UserError("--address: only with --engine ray")
    camp = load_campaign(spec_path)
    out = Path(out) if out is not None else Path("out") / "campaigns" / camp.spec.name
    out.mkdir(parents=True, exist_ok=True)
    journal_path = out / "journal.jsonl"
    journal = _read_journal(journal_path)
    rows: dict[str, dict] = {}
    todo = []
    for task in camp.tasks:
        rec = journal.get(task.mission_id)
        if rec is not None and rec[0] == task.fingerprint():
            rows[task.mission_id] = rec[1]
        else:
            if keep_runs:
                task = dataclasses.replace(task, run_dir=str(out / "runs" / task.mission_id))
            todo.append(task)
    skipped = len(rows)
    runner = RayEngine(workers, address) if engine == "ray" else LocalEngine(workers)
    meta = {"spec": str(camp.path), "name": camp.spec.name, "engine": runner.name,
            "workers": getattr(runner, "workers", None), "address": address, "missions": len(camp.tasks),
            "started": time.strftime("%Y-%m-%d %H:%M:%S")}
    (out / "campaign.json").write_text(json.dumps(meta, indent=1), encoding="utf-8")
    fingerprints = {t.mission_id: t.fingerprint() for t in camp.tasks}
    if todo:
        runner.open()
    bar = tqdm(total=len(camp.tasks), initial=skipped, desc=camp.spec.name, unit="mission", file=sys.stderr,
               disable=not progress, dynamic_ncols=True)

    def postfix() -> None:
        done = len(rows)
        ok = sum(1 for r in rows.values() if r["ok"])
        bar.set_postfix_str(f"ok {ok}/{done} ({ok / done:.0%})" if done else "", refresh=False)

    postfix()
    bar.refresh()
    t0 = time.perf_counter()
    interrupted = False
    ran = 0
    with journal_path.open("a", encoding="utf-8") as jf:
        def on_row(row: dict) -> None:
            nonlocal ran
            jf.write(json.dumps({"fingerprint": fingerprints[row["mission_id"]], "row": row}) + "\n")
            jf.flush()
            os.fsync(jf.fileno())
            rows[row["mission_id"]] = row
            ran += 1
            postfix()
            bar.update(1)

        try:
            if todo:
                log_dir = out / "runs" if keep_runs else None
                if log_dir is not None:
                    log_dir.mkdir(parents=True, exist_ok=True)
                runner.run(todo, on_row, log_dir)
        except KeyboardInterrupt:
            interrupted = True
        finally:
            bar.close()
            runner.close()
    wall = time.perf_counter() - t0
    ordered = [rows[t.mission_id] for t in camp.tasks if t.mission_id in rows]
    df = pd.DataFrame(ordered, columns=list(base_row(camp.tasks[0]).keys()) if camp.tasks else None)
    write_results(df, out)
    prims = primitives_table(ordered)
    prims.to_csv(out / "primitives.csv", index=False, float_format="%.10g")
    meta.update(ran=ran, skipped=skipped, wall_seconds=wall, interrupted=interrupted)
    summary = summarize(df, meta, prims)
    (out / "summary.md").write_text(summary, encoding="utf-8")
    write_figures(df, out / "figures")
    (out / "campaign.json").write_text(json.dumps(meta, indent=1), encoding="utf-8")
    result = CampaignResult(df, len(camp.tasks), ran, skipped, wall, interrupted, summary, out)
    if interrupted:
        print(summary, file=sys.stderr)
        print(f"interrupted: {len(df)}/{len(camp.tasks)} missions finished, kept in {out}/ (run the same "
              "command again to resume)", file=sys.stderr)
        raise KeyboardInterrupt
    return result


PRIMITIVE_COLUMNS = ("mission_id", "family", "step", "kind", "action", "entities", "ok", "seconds", "time_limit",
                     "m_true", "m_hat", "alpha_true", "alpha_hat")


def primitives_table(rows: list[dict]):
    """primitives.csv: the primitive records of every finished mission, with its id and family."""
    import pandas as pd

    recs = [{"mission_id": r["mission_id"], "family": r["family"], **p}
            for r in rows for p in r.get("primitives") or ()]
    return pd.DataFrame(recs, columns=list(PRIMITIVE_COLUMNS))


def write_results(df, out: Path) -> list[Path]:
    """results.csv, and results.parquet when pyarrow is installed."""
    written = [out / "results.csv"]
    df.to_csv(out / "results.csv", index=False, float_format="%.10g")
    if importlib.util.find_spec("pyarrow") is None:
        return written
    df.to_parquet(out / "results.parquet", index=False, engine="pyarrow")
    written.append(out / "results.parquet")
    return written


# ------------------------------------------------------------------------------------------ report
def _md_table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c).replace("|", "\\|") for c in r) + " |" for r in rows]
    return "\n".join(lines)


def _num(x, fmt: str = ".3g") -> str:
    return "" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(float(x), fmt)


def summarize(df, meta: dict, prims=None) -> str:
    """The campaign summary (Markdown): totals, success per family and size, failures by kind with one
    example each, clearance / gap / speed / wall-time distributions; with ``prims`` (primitives.csv) the
    per-primitive durations against their time bounds and the final estimates against the true values."""
    import pandas as pd

    n, total = len(df), meta["missions"]
    ok = int(df["ok"].sum()) if n else 0
    rate = f"{ok / n:.1%}" if n else "n/a"
    wall = meta["wall_seconds"]
    per_min = meta["ran"] / wall * 60.0 if wall > 0 and meta["ran"] else 0.0
    parts = [f"# Campaign {meta['name']}", "",
             f"spec `{meta['spec']}`, engine {meta['engine']}"
             + (f" ({meta['workers']} workers)" if meta.get("workers") else "")
             + (f", address {meta['address']}" if meta.get("address") else ""), "",
             f"- missions: {n}/{total} finished{' (interrupted)' if meta.get('interrupted') else ''}; "
             f"{meta['ran']} ran now, {meta['skipped']} resumed from the journal",
             f"- success: {ok}/{n} ({rate})",
             f"- wall time of this run: {wall:.1f} s ({per_min:.2f} missions/min)", ""]
    if not n:
        return "\n".join(parts) + "\n"
    parts += ["## Success by scenario family", ""]
    fam = []
    for name, g in df.groupby("family", sort=False):
        fam.append([name, len(g), int(g["ok"].sum()), f"{g['ok'].mean():.0%}",
                    _num(pd.to_numeric(g["wall_seconds"]).median(), ".1f")])
    parts += [_md_table(["family", "missions", "ok", "success", "median wall s"], fam), ""]
    size = []
    for (r, o, k), g in df.groupby(["robots", "objects", "regions"]):
        size.append([f"{r}/{o}/{k}", len(g), int(g["ok"].sum()), f"{g['ok'].mean():.0%}"])
    parts += ["## Success by size (robots/objects/regions)", "",
              _md_table(["size", "missions", "ok", "success"], size), ""]
    failed = df[~df["ok"].astype(bool)]
    parts += ["## Failures by kind", ""]
    if len(failed):
        kinds = []
        for kind, g in failed.groupby("failure_kind"):
            ex = g.iloc[0]
            kinds.append([kind or "(none)", len(g), f"`{ex['mission_id']}`", ex["failure_message"]])
        kinds.sort(key=lambda r: -r[1])
        parts += [_md_table(["kind", "count", "example", "message"], kinds), ""]
    else:
        parts += ["none", ""]
    qs = [0.0, 0.05, 0.5, 0.95, 1.0]
    dist = []
    for col, label in (("min_clearance", "min clearance to walls/obstacles [m]"),
                       ("min_gap", "min gap between entity disks [m]"), ("max_speed", "max speed [m/s]"),
                       ("wall_seconds", "mission wall time [s]"), ("sim_seconds", "simulated time [s]"),
                       ("real_time_factor", "real-time factor")):
        v = pd.to_numeric(df[col], errors="coerce").dropna()
        if len(v):
            dist.append([label, len(v)] + [_num(v.quantile(q)) for q in qs])
    parts += ["## Distributions", "", _md_table(["quantity", "n", "min", "5%", "median", "95%", "max"], dist), ""]
    nan = int(df["nan_seen"].astype(bool).sum())
    neg = int((pd.to_numeric(df["min_clearance"], errors="coerce") < 0).sum())
    overlap = int((pd.to_numeric(df["min_gap"], errors="coerce") < 0).sum())
    parts += [f"- missions with NaN in the trajectory: {nan}; with a wall/obstacle contact (clearance < 0): {neg}; "
              f"with overlapping entity disks (gap < 0): {overlap}",
              "- figures: figures/success_by_size.png, figures/hist_wall.png, figures/hist_clearance.png", ""]
    if prims is not None and len(prims):
        parts += _primitive_sections(prims)
    return "\n".join(parts)


def _primitive_sections(prims) -> list[str]:
    """Summary sections of primitives.csv: durations by kind; final m̂/m and α̂/α by kind."""
    import pandas as pd

    rows = []
    for kind, g in prims.groupby("kind", sort=True):
        sec = pd.to_numeric(g["seconds"], errors="coerce")
        lim = pd.to_numeric(g["time_limit"], errors="coerce")
        frac = (sec / lim).dropna()
        rows.append([kind, len(g), int(g["ok"].astype(bool).sum()), _num(sec.median(), ".1f"),
                     _num(sec.quantile(0.95), ".1f"), _num(sec.max(), ".1f"),
                     _num(frac.max(), ".3f") if len(frac) else "", int((frac > 1).sum())])
    parts = ["## Primitives", "",
             _md_table(["kind", "n", "ok", "median s", "95% s", "max s", "max s / bound", "over bound"], rows), ""]
    est = prims.dropna(subset=["m_hat", "m_true", "alpha_hat", "alpha_true"])
    if not len(est):
        return parts
    rows = []
    for kind, g in est.groupby("kind", sort=True):
        m = pd.to_numeric(g["m_hat"]) / pd.to_numeric(g["m_true"])
        at = pd.to_numeric(g["alpha_true"])
        a = (pd.to_numeric(g["alpha_hat"]) / at.where(at > 0)).dropna()
        cover = int((pd.to_numeric(g["alpha_hat"]) >= at).sum())
        rows.append([kind, len(g)] + [_num(m.quantile(q)) for q in (0.05, 0.5, 0.95)]
                    + [_num(a.quantile(q)) if len(a) else "" for q in (0.05, 0.5, 0.95)] + [f"{cover}/{len(g)}"])
    parts += ["## Final estimates against the true values (navigations and transports)", "",
              _md_table(["kind", "n", "m̂/m 5%", "m̂/m median", "m̂/m 95%", "α̂/α 5%", "α̂/α median", "α̂/α 95%",
                         "α̂ ≥ α"], rows), "",
              "- m: true mass of the moving entity (a transport: object + members); α: its friction bound of "
              "Assumption 1 (summed over the bodies); m̂, α̂: the controller's estimates at the primitive's end", ""]
    return parts


def write_figures(df, folder: Path) -> list[Path]:
    """success_by_size.png, hist_wall.png, hist_clearance.png (matplotlib, no display)."""
    import pandas as pd
    from matplotlib.figure import Figure

    folder.mkdir(parents=True, exist_ok=True)
    written = []
    if not len(df):
        return written
    fig = Figure(figsize=(7, 3.5))
    ax = fig.subplots()
    groups = list(df.groupby(["robots", "objects", "regions"]))
    labels = [f"{r}/{o}/{k}" for (r, o, k), _ in groups]
    rates = [g["ok"].astype(bool).mean() * 100 for _, g in groups]
    bars = ax.bar(labels, rates, color="#2a9d3a")
    for b, (_, g) in zip(bars, groups):
        ax.annotate(f"{int(g['ok'].sum())}/{len(g)}", (b.get_x() + b.get_width() / 2, b.get_height()),
                    ha="center", va="bottom", fontsize=8)
    ax.set_ylim(0, 110)
    ax.set_xlabel("robots/objects/regions")
    ax.set_ylabel("success [%]")
    ax.set_title("success by scenario size", fontsize=10)
    fig.savefig(folder / "success_by_size.png", dpi=120, bbox_inches="tight")
    written.append(folder / "success_by_size.png")

    ok = df["ok"].astype(bool)
    fig = Figure(figsize=(6, 3.5))
    ax = fig.subplots()
    wall = pd.to_numeric(df["wall_seconds"], errors="coerce")
    ax.hist([wall[ok].dropna(), wall[~ok].dropna()], bins=20, stacked=True, label=["ok", "failed"],
            color=["#2a9d3a", "#d62728"])
    ax.set_xlabel("mission wall time [s]")
    ax.set_ylabel("missions")
    ax.legend()
    fig.savefig(folder / "hist_wall.png", dpi=120, bbox_inches="tight")
    written.append(folder / "hist_wall.png")

    fig = Figure(figsize=(9, 3.5))
    axes = fig.subplots(1, 2)
    for ax, col, label in zip(axes, ("min_clearance", "min_gap"),
                              ("min clearance to walls/obstacles [m]", "min gap between entity disks [m]")):
        v = pd.to_numeric(df[col], errors="coerce")
        ax.hist([v[ok].dropna(), v[~ok].dropna()], bins=20, stacked=True, label=["ok", "failed"],
                color=["#2a9d3a", "#d62728"])
        ax.set_xlabel(label)
        ax.set_ylabel("missions")
        ax.legend()
    fig.savefig(folder / "hist_clearance.png", dpi=120, bbox_inches="tight")
    written.append(folder / "hist_clearance.png")
    return written


# ------------------------------------------------------------------------------------------ CLI
def add_subparser(subparsers) -> argparse.ArgumentParser:
    """Register ``campaign`` on the top-level CLI's subparsers."""
    p = subparsers.add_parser(
        "campaign", help="run many plan + execute missions (randomized plants), summarize the failures",
        description="Run every mission of a campaign spec (scenarios x plan seeds x layout seeds x parameter "
        "draws) in isolated workers, append each row to DIR/journal.jsonl (a rerun resumes), and write "
        "results.csv (+ results.parquet with pyarrow), summary.md and figures/.")
    p.add_argument("spec", metavar="SPEC.yaml", help="campaign spec file")
    p.add_argument("--out", metavar="DIR", default=None, help="output directory (default: out/campaigns/<name>)")
    p.add_argument("--engine", choices=["local", "ray"], default="local",
                   help="local process pool (default) or Ray tasks")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="missions at a time (default: the core count; with Ray: the cluster's CPUs)")
    p.add_argument("--address", metavar="ADDR", default=None,
                   help="with --engine ray: join this cluster (auto or HOST:PORT) instead of starting Ray")
    p.add_argument("--keep-runs", action="store_true",
                   help="also write every mission's own outputs (logs, replay, figures) to DIR/runs/<mission>/")
    p.set_defaults(func=_cmd_campaign)
    return p


def _cmd_campaign(args: argparse.Namespace) -> int:
    res = run_campaign(args.spec, out=args.out, engine=args.engine, workers=args.workers, address=args.address,
                       keep_runs=args.keep_runs, progress=True)
    print(res.summary)
    print(f"results: {res.out}/results.csv, summary: {res.out}/summary.md, figures: {res.out}/figures/")
    return 0
