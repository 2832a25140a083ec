"""Random scenarios on the case-study office for tests and benchmarks (``mrodrake bench plan``).

:func:`generate_scenario` reuses the office of ``scenarios/case_study_1.yaml`` (boundary and obstacles),
places K region disks at fixed candidate centres inside its rooms and corridor, draws N robots and M
objects with powers and required powers such that a team of at most three robots can move every object,
puts them in random regions where they fit (P_s), and writes a random task of the paper's shape
(Section IV): ``G F ψ_a & G F ψ_b & F ψ_c & (!ψ_d U ψ_e) & G !ψ_f`` over macros ψ that are conjunctions
of ``<entity>_<region>`` propositions.  Every scenario passes the scenario validator.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import yaml

from mrodrake.scenario import Scenario, entities_fit, scenario_from_dict

OFFICE = Path(__file__).resolve().parents[2] / "scenarios" / "case_study_1.yaml"

#: Candidate region centres inside the office (rooms A, B, C, D, E, F and the corridor), chosen at least
#: 8 m from walls and obstacles; the case-study regions p1..p4 come first.
CENTRES = [
    (88.0, -280.0), (100.0, -160.0), (200.0, -130.0), (250.0, -285.0), (165.0, -245.0),
    (155.0, -180.0), (232.0, -192.0), (78.0, -190.0), (215.0, -285.0), (140.0, -216.0),
    (118.0, -238.0), (203.0, -216.0),
]
MAX_K = len(CENTRES)


@lru_cache(maxsize=1)
def _office_workspace() -> dict:
    data = yaml.safe_load(OFFICE.read_text(encoding="utf-8"))
    return data["workspace"]


def generate_scenario(n: int, m: int, k: int, seed: int, region_radius: float | None = None,
                      full: bool = False) -> Scenario:
    """A validated random scenario with ``n`` robots, ``m`` objects and ``k`` regions (k ≤ 12).

    ``full=True`` makes ψa, ψb, ψc complete configurations (every robot and object placed), like the
    case studies' macros; otherwise each macro constrains a random subset of up to half the entities."""
    if not 1 <= n or not 0 <= m or not 1 <= k <= MAX_K:
        raise ValueError(f"need n >= 1, m >= 0, 1 <= k <= {MAX_K}")
    rng = np.random.default_rng(seed)
    R = region_radius if region_radius is not None else (4.0 if n + m <= 8 else 5.0)
    regions = [{"name": f"p{i + 1}", "center": list(CENTRES[i]), "radius": R} for i in range(k)]
    power = [int(rng.integers(2, 5)) for _ in range(n)]
    robots = []
    objects = []
    occupants: list[list[float]] = [[] for _ in range(k)]
    spacing = 0.1

    def place(radius: float) -> str:
        order = rng.permutation(k)
        for r in order:
            if entities_fit(R, occupants[r] + [radius], spacing):
                occupants[r].append(radius)
                return f"p{r + 1}"
        raise ValueError("generated entities do not fit in the regions; use fewer entities or more regions")

    for i in range(n):
        robots.append({"name": f"r{i + 1}", "mass": 1.0, "radius": 0.75, "power": power[i],
                       "initial_region": place(0.75)})
    for j in range(m):
        size = int(rng.integers(1, min(3, n) + 1))
        team = rng.choice(n, size=size, replace=False)
        need = float(sum(power[t] for t in team)) - 0.5
        radius = float(np.round(rng.uniform(0.2, 0.4), 2))
        objects.append({"name": f"o{j + 1}", "mass": 0.25, "radius": radius, "required_power": max(need, 0.5),
                        "initial_region": place(radius)})
    initial = {e["name"]: int(e["initial_region"][1:]) - 1 for e in robots + objects}
    props, formula = _random_task(rng, [r["name"] for r in robots], [o["name"] for o in objects], k, initial,
                                  full, R, spacing)
    data = {
        "name": f"gen_n{n}_m{m}_k{k}_s{seed}",
        "description": f"generated: {n} robots, {m} objects, {k} regions on the case-study office (seed {seed})",
        "workspace": _office_workspace(),
        "regions": regions,
        "robots": robots,
        "objects": objects,
        "task": {"propositions": props, "formula": formula},
        "planning": {"seed": int(seed)},
    }
    return scenario_from_dict(data, source=f"generate_scenario({n}, {m}, {k}, {seed})")


def _random_task(rng: np.random.Generator, robots: list[str], objects: list[str], k: int,
                 initial: dict[str, int], full: bool = False, R: float = 4.0, spacing: float = 0.1):
    """Macros ψa..ψf and the formula ``G F ψa & G F ψb & F ψc & (!ψd U ψe) & G !ψf``; ψd and ψf are
    false in the initial state (else the task would be violated at once)."""
    entities = robots + objects
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
        return " & ".join(f"{entities[e]}_p{r + 1}" for e, r in zip(chosen, regions))

    def configuration() -> str:
        """Every entity placed, regions drawn until the robots and objects fit (P_s)."""
        for _ in range(1000):
            regions = [int(rng.integers(k)) for _ in entities]
            per: list[list[float]] = [[] for _ in range(k)]
            for e, r in zip(entities, regions):
                per[r].append(0.75 if e in robots else 0.4)
            if all(entities_fit(R, radii, spacing) for radii in per if radii):
                break
        else:
            raise ValueError("no configuration of all entities fits in the regions; use more regions")
        for e, r in zip(entities, regions):
            used.add((e, r))
        return " & ".join(f"{e}_p{r + 1}" for e, r in zip(entities, regions))

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
        props["psif"] = f"{r}_p{p + 1}"
        formula = "G F psia & G F psib & F psic & (!psid U psie) & G !psif"
    else:
        formula = "G F psia & G F psib & F psic & (!psid U psie)"
    return props, formula
