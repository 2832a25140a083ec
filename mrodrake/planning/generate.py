"""Random scenarios on the case-study office or on any map, for tests, benchmarks and failure hunts.

:func:`generate_scenario` builds a validated scenario with N robots, M objects and K regions.  On the
office (``map=None``, ``mrodrake bench plan``) it reuses the boundary and obstacles of
``scenarios/case_study_1.yaml`` and places the K region disks at fixed candidate centres inside its rooms
and corridor.  On a map (``map=`` a scenario file, a shipped map name such as ``"lab"`` from
``scenarios/maps/``, or a :class:`~mrodrake.scenario.Scenario`) it takes the map's workspace, layout and
control settings (a small floor's ``control.margin``), and K of the map's own regions (centres, radii and
names), chosen by the seed.

It then draws N robots and M objects with powers and required powers such that a team of at most three
robots can move every object, puts them in random regions where they fit (P_s), and writes a random task
of the paper's shape (Sec. IV): ``G F ψ_a & G F ψ_b & F ψ_c & (!ψ_d U ψ_e) & G !ψ_f`` over macros ψ
that are conjunctions of ``<entity>_<region>`` propositions.

Entity sizes: robots of radius 0.75 m and objects of radius 0.2-0.4 m on the office.  On a map both are
scaled by ``s = r / 0.75``, r the largest robot radius of the map file (1 on the office-sized maps; the
small lab's robots have r = 0.5, so its objects are 0.13-0.27 m).  Masses stay 1 kg and 0.25 kg.
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache
from pathlib import Path

import numpy as np
import yaml

from mrodrake.packing import entities_fit
from mrodrake.scenario import ControlGains, Scenario, load_scenario, scenario_from_dict

ROOT = Path(__file__).resolve().parents[2] / "scenarios"
OFFICE = ROOT / "case_study_1.yaml"
MAPS = ROOT / "maps"

#: Candidate region centres inside the office (rooms A, B, C, D, E, F and the corridor), chosen at least
#: 8 m from walls and obstacles; the case-study regions p1..p4 come first.
CENTRES = [
    (88.0, -280.0), (100.0, -160.0), (200.0, -130.0), (250.0, -285.0), (165.0, -245.0),
    (155.0, -180.0), (232.0, -192.0), (78.0, -190.0), (215.0, -285.0), (140.0, -216.0),
    (118.0, -238.0), (203.0, -216.0),
]
MAX_K = len(CENTRES)
#: Robot radius (m) of the office scenarios; map entity sizes are scaled by (map robot radius) / this.
ROBOT_RADIUS = 0.75


@lru_cache(maxsize=1)
def _office_workspace() -> dict:
    data = yaml.safe_load(OFFICE.read_text(encoding="utf-8"))
    return data["workspace"]


def shipped_maps() -> list[str]:
    """Names of the maps in ``scenarios/maps/`` (usable as ``map=`` of :func:`generate_scenario`)."""
    return sorted(p.stem for p in MAPS.glob("*.yaml"))


def load_map(map) -> Scenario:
    """The map scenario for ``map``: a Scenario, a shipped map name (``"lab"``) or a scenario file path."""
    if isinstance(map, Scenario):
        return map
    shipped = MAPS / f"{map}.yaml"
    path = shipped if not Path(map).exists() and shipped.is_file() else Path(map)
    return _load_map_file(str(path.resolve()))


@lru_cache(maxsize=16)
def _load_map_file(path: str) -> Scenario:
    return load_scenario(path)


def _workspace_dict(sc: Scenario) -> dict:
    ws = sc.workspace
    return {"boundary": [list(p) for p in ws.boundary],
            "obstacles": [{"name": o.name, "polygon": [list(p) for p in o.polygon]} for o in ws.obstacles]}


def generate_scenario(n: int, m: int, k: int, seed: int, region_radius: float | None = None,
                      full: bool = False, map=None) -> Scenario:
    """A validated random scenario with ``n`` robots, ``m`` objects and ``k`` regions (see
    :func:`generate_scenario_data`, whose mapping it validates)."""
    data = generate_scenario_data(n, m, k, seed, region_radius=region_radius, full=full, map=map)
    return scenario_from_dict(data, source=f"generate_scenario({n}, {m}, {k}, {seed})" if map is None
                              else data["name"])


def generate_scenario_data(n: int, m: int, k: int, seed: int, region_radius: float | None = None,
                           full: bool = False, map=None) -> dict:
    """The scenario mapping (YAML-ready) of :func:`generate_scenario`.

    ``k`` ≤ 12 on the office, ≤ the map's region count on a map.  ``region_radius`` overrides the region
    radii (office default: 4 m, 5 m beyond eight entities; maps: their own radii).  ``full=True`` makes ψa,
    ψb, ψc complete configurations (every robot and object placed), like the case studies' macros;
    otherwise each macro constrains a random subset of up to half the entities."""
    sc_map = None if map is None else load_map(map)
    max_k = MAX_K if sc_map is None else len(sc_map.regions)
    if not 1 <= n or not 0 <= m or not 1 <= k <= max_k:
        raise ValueError(f"need n >= 1, m >= 0, 1 <= k <= {max_k}")
    rng = np.random.default_rng(seed)
    if sc_map is None:
        R = region_radius if region_radius is not None else (4.0 if n + m <= 8 else 5.0)
        regions = [{"name": f"p{i + 1}", "center": list(CENTRES[i]), "radius": R} for i in range(k)]
        name, site, workspace, layout, control = "gen", "the case-study office", _office_workspace(), None, {}
        robot_radius = ROBOT_RADIUS
    else:
        chosen = sorted(int(i) for i in rng.choice(max_k, size=k, replace=False))
        regions = [{"name": sc_map.regions[i].name, "center": list(sc_map.regions[i].center),
                    "radius": float(sc_map.regions[i].radius if region_radius is None else region_radius)}
                   for i in chosen]
        name, site, workspace = f"gen_{sc_map.name}", f"map {sc_map.name}", _workspace_dict(sc_map)
        layout = {"grasp_gap": sc_map.layout.grasp_gap, "spacing": sc_map.layout.spacing}
        default = dataclasses.asdict(ControlGains())
        control = {key: v for key, v in dataclasses.asdict(sc_map.control).items() if v != default[key]}
        robot_radius = max(r.radius for r in sc_map.robots)
    radii = [float(g["radius"]) for g in regions]
    names = [g["name"] for g in regions]
    spacing = 0.1 if layout is None else layout["spacing"]
    scale = robot_radius / ROBOT_RADIUS
    power = [int(rng.integers(2, 5)) for _ in range(n)]
    robots = []
    objects = []
    occupants: list[list[float]] = [[] for _ in range(k)]

    def place(radius: float) -> str:
        order = rng.permutation(k)
        for r in order:
            if entities_fit(radii[r], occupants[r] + [radius], spacing):
                occupants[r].append(radius)
                return names[r]
        raise ValueError("generated entities do not fit in the regions; use fewer entities or more regions")

    for i in range(n):
        robots.append({"name": f"r{i + 1}", "mass": 1.0, "radius": robot_radius, "power": power[i],
                       "initial_region": place(robot_radius)})
    for j in range(m):
        size = int(rng.integers(1, min(3, n) + 1))
        team = rng.choice(n, size=size, replace=False)
        need = float(sum(power[t] for t in team)) - 0.5
        radius = float(np.round(rng.uniform(0.2, 0.4) * scale, 2))
        objects.append({"name": f"o{j + 1}", "mass": 0.25, "radius": radius, "required_power": max(need, 0.5),
                        "initial_region": place(radius)})
    initial = {e["name"]: names.index(e["initial_region"]) for e in robots + objects}
    props, formula = _random_task(rng, [r["name"] for r in robots], [o["name"] for o in objects], names, initial,
                                  full, radii, spacing, robot_radius, 0.4 * scale)
    data = {
        "name": f"{name}_n{n}_m{m}_k{k}_s{seed}",
        "description": f"generated: {n} robots, {m} objects, {k} regions on {site} (seed {seed})",
        "workspace": workspace,
        "regions": regions,
        "robots": robots,
        "objects": objects,
        "task": {"propositions": props, "formula": formula},
    }
    if layout is not None:
        data["layout"] = layout
    if control:
        data["control"] = control
    data["planning"] = {"seed": int(seed)}
    return data


def _random_task(rng: np.random.Generator, robots: list[str], objects: list[str], names: list[str],
                 initial: dict[str, int], full: bool, radii: list[float], spacing: float,
                 robot_radius: float, object_radius: float):
    """Macros ψa..ψf and the formula ``G F ψa & G F ψb & F ψc & (!ψd U ψe) & G !ψf`` over the regions
    ``names`` (radii ``radii``); ψd and ψf are false in the initial state (else the task would be violated
    at once).  Complete configurations are packed with robots of ``robot_radius`` and objects of the
    largest ``object_radius``."""
    entities = robots + objects
    k = len(names)
    used: set[tuple[str, int]] = set()
    hi = max(2, min(len(entities), (len(entities) + 1) // 2))

    def conj(size: int, false_initially: bool = False) -> str:
        chosen = sorted(rng.choice(len(entities), size=min(size, len(entities)), replace=False))
        regions = [int(rng.integers(k)) for _ in chosen]
        if false_initially and k > 1 and all(initial[entities[e]] == r for e, r in zip(chosen, regions)):
            e0 = chosen[0]
            regions[0] = (initial[entities[e0]] + 1 + int(rng.integers(k - 1))) % k
        for e, r in zip(chosen, regions):
            used.add((entities[e], r))
        return " & ".join(f"{entities[e]}_{names[r]}" for e, r in zip(chosen, regions))

    def configuration() -> str:
        """Every entity placed, regions drawn until the robots and objects fit (P_s)."""
        for _ in range(1000):
            regions = [int(rng.integers(k)) for _ in entities]
            per: list[list[float]] = [[] for _ in range(k)]
            for e, r in zip(entities, regions):
                per[r].append(robot_radius if e in robots else object_radius)
            if all(entities_fit(radii[r], rs, spacing) for r, rs in enumerate(per) if rs):
                break
        else:
            raise ValueError("no configuration of all entities fits in the regions; use more regions")
        for e, r in zip(entities, regions):
            used.add((e, r))
        return " & ".join(f"{e}_{names[r]}" for e, r in zip(entities, regions))

    props = {}
    for name in ("psia", "psib", "psic", "psid", "psie"):
        if full and name in ("psia", "psib", "psic"):
            props[name] = configuration()
        else:
            props[name] = conj(int(rng.integers(1, hi + 1)), false_initially=(name == "psid"))
    # ψf: a robot in a region where it does not start and that no other macro mentions
    free = [(r, p) for r in robots for p in range(k) if (r, p) not in used and initial[r] != p]
    if free:
        r, p = free[int(rng.integers(len(free)))]
        props["psif"] = f"{r}_{names[p]}"
        formula = "G F psia & G F psib & F psic & (!psid U psie) & G !psif"
    else:
        formula = "G F psia & G F psib & F psic & (!psid U psie)"
    return props, formula
