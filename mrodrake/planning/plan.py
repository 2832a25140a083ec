"""Plans in prefix-suffix form (paper Sec. III-B, Table I): the contract between planning and execution.

A :class:`Plan` is the TS run ``prefix (suffix)^ω`` together with the NBA run that accepts its trace.
The run is ``prefix + suffix + suffix + ...``: its first state is the TS's initial state (with the NBA's
initial state), every state is reached from the one before it by one TS transition, the last prefix
state steps to the first suffix state and the last suffix state steps back to the first suffix state;
Step ``k`` (1-based) goes from run state ``k`` to run state ``k + 1``; the prefix has ``len(prefix)`` steps
(the last one enters the suffix) and the suffix ``len(suffix)`` steps (the last one closes the cycle).  Costs
are Σχ over those steps.  The NBA run is a run on the *executed word* (:mod:`mrodrake.planning.semantics`):
each step's actions are stored in execution order (releases, grasps, then the region-changing actions in an
order that reaches the step's NBA state for every crossing interleaving).

JSON schema (``Plan.to_json``), version 2 (version 1 plans read labels only and are refused)::

    {
      "format": "mrodrake.plan", "version": 2,
      "scenario": "case_study_1",              # scenario name
      "formula": "...",                         # the task formula as planned (macros expanded)
      "planner": "stylus" | "exact",
      "seed": 0 | null,                         # seed of the planner's random generator
      "costs": {"prefix": 4554.5, "suffix": 2338.1, "total": 6892.6},
      "prefix": [STATE, ...],                   # run states before the suffix (may be empty)
      "suffix": [STATE, ...],                   # the repeated cycle (non-empty)
      "actions": [                              # one entry per step, prefix steps first
        {"step": 1, "part": "prefix",           # part of the step's source state
         "from": 1, "to": 2,                    # 1-based run-state indices (the last step's "to" is
                                                #   the index of the first suffix state)
         "cost": 240.3,                         # χ of the step
         "actions": [ACTION, ...]}              # in execution order; empty for the all-idle self-loop
      ],
      "stats": {...}                            # planner statistics (sizes, timings), informative
    }
    STATE  = {"robots": {"r1": "p1", ...}, "objects": {"o1": "p2", ...},
              "grasps": {"r1": "o1" | null, ...}, "nba": NBA}
    NBA    = <NBA state id>                   # planning product: one state reached on every interleaving
           | {"members": [[[S0 ids], [S1 ids]], ...], "accepting": bool}   # word-family product
    ACTION = {"type": "navigate", "robot": "r1", "from": "p1", "to": "p3", ...}
           | {"type": "grasp", "robot": "r1", "object": "o1", ...}
           | {"type": "release", "robot": "r1", "object": "o1", ...}
           | {"type": "transport", "object": "o1", "team": ["r1", "r3"], "from": "p1", "to": "p4", ...}
             each ACTION also has "text" (e.g. "transport o1 by r1+r3 p1->p4") and "paper"
             (Table I notation, e.g. "π1 →T_{1,3},1 π4").

NBA state ids refer to ``mrodrake.logic.translate.translate(formula)`` re-indexed onto the TS propositions.
"""

from __future__ import annotations

import json
import math
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from threadpoolctl import threadpool_limits

from mrodrake.errors import NoPlanFound, UserError
from mrodrake.logic.formula import Formula, atoms
from mrodrake.logic.nba import NBA
from mrodrake.logic.parse import parse
from mrodrake.logic.translate import translate
from mrodrake.planning.bans import Bans, LocalBan, SwapBan
from mrodrake.planning.decide import EXACT_BOUND, decide
from mrodrake.planning.exact import check_power, solve_exact, solve_exact_graph
from mrodrake.planning.graph import GraphTS, load_graph_ts
from mrodrake.planning.graph_stylus import GraphStrategy
from mrodrake.planning.placement import PlacementError, place_plan
from mrodrake.planning.product import planning_nba
from mrodrake.planning.semantics import ExecutedWords, SourceWords, relevant_mask, words_for
from mrodrake.planning.stylus import Stylus
from mrodrake.planning.universal import Family, FamilyResult, FamilyWords
from mrodrake.scenario import Scenario, load_scenario
from mrodrake.ts import Action, Grasp, Navigate, Release, State, TransitionSystem, Transport

FORMAT = "mrodrake.plan"
VERSION = 2


class PlanVerificationError(AssertionError):
    """A plan failed its independent check: this is a bug in a planner, never a user error."""


@dataclass
class Plan:
    """A verified prefix-suffix plan; ``prefix``/``suffix`` are lists of (TS state, NBA state)."""

    scenario: str
    formula: str
    planner: str
    seed: int | None
    prefix: list[tuple[State, int]]
    suffix: list[tuple[State, int]]
    actions: list[tuple[Action, ...]]
    step_costs: list[float]
    ts: TransitionSystem | None = field(default=None, repr=False, compare=False)
    stats: dict = field(default_factory=dict, compare=False)
    #: The placement that accepted the plan (:func:`~mrodrake.planning.placement.place_plan`), when planned here.
    placement: object = field(default=None, repr=False, compare=False)

    # ------------------------------------------------------------------------------------ construction
    @staticmethod
    def from_runs(ts: TransitionSystem, scenario: str, formula: str, planner: str, seed: int | None,
                  prefix: Sequence[tuple[State, int]], suffix: Sequence[tuple[State, int]], words: ExecutedWords,
                  stats: dict | None = None) -> Plan:
        """A plan whose step costs come from the TS and whose actions are in an execution order that takes
        the NBA run of the product nodes for every crossing interleaving (``words``)."""
        run = list(prefix) + list(suffix)
        if not suffix:
            raise PlanVerificationError("a plan needs a non-empty suffix")
        nxt = run[1:] + [suffix[0]]
        actions = []
        for k, (a, b) in enumerate(zip(run, nxt)):
            order = words.order(a[0], int(a[1]), b[0], int(b[1]))
            if order is None:
                raise PlanVerificationError(f"step {k + 1}: no execution order reaches NBA state {b[1]}")
            actions.append(order)
        costs = [ts.cost(a[0], b[0]) for a, b in zip(run, nxt)]
        return Plan(scenario, formula, planner, seed, [(tuple(s), int(q)) for s, q in prefix],
                    [(tuple(s), int(q)) for s, q in suffix], actions, costs, ts, dict(stats or {}))

    @staticmethod
    def from_families(ts: TransitionSystem, scenario: str, formula: str, planner: str, seed: int | None,
                      res: FamilyResult, stats: dict | None = None) -> Plan:
        """A plan of the word-family product (:mod:`mrodrake.planning.universal`): its nodes carry families."""
        run = list(res.prefix) + list(res.suffix)
        nxt = run[1:] + [res.suffix[0]]
        costs = [ts.cost(a[0], b[0]) for a, b in zip(run, nxt)]
        return Plan(scenario, formula, planner, seed, [(tuple(x), F) for x, F in res.prefix],
                    [(tuple(x), F) for x, F in res.suffix], list(res.orders), costs, ts, dict(stats or {}))

    @property
    def families(self) -> bool:
        """Are the NBA sides of the run families (word-family product) rather than single states?"""
        return any(isinstance(q, Family) for _, q in self.prefix + self.suffix)

    # ------------------------------------------------------------------------------------ properties
    @property
    def run(self) -> list[tuple[State, int]]:
        return self.prefix + self.suffix

    @property
    def prefix_cost(self) -> float:
        return float(sum(self.step_costs[: len(self.prefix)]))

    @property
    def suffix_cost(self) -> float:
        return float(sum(self.step_costs[len(self.prefix):]))

    @property
    def total_cost(self) -> float:
        return self.prefix_cost + self.suffix_cost

    def steps(self):
        """(step, part, from index, to index, source, target, actions, cost), 1-based indices."""
        run = self.run
        P, n = len(self.prefix), len(run)
        for k in range(n):
            to = k + 2 if k + 1 < n else P + 1
            target = run[k + 1] if k + 1 < n else self.suffix[0]
            yield (k + 1, "prefix" if k < P else "suffix", k + 1, to, run[k], target, self.actions[k],
                   self.step_costs[k])

    # ------------------------------------------------------------------------------------ verification
    def verify(self, ts: TransitionSystem, nba: NBA, formula) -> None:
        """Check the plan independently of the planner that made it (raises PlanVerificationError).

        Every step is re-derived from the TS rules (``ts.check_transition``) and holds the TS's actions, the
        NBA state of every step is reached from the previous one by the step's executed words in its stored
        order for every crossing interleaving (:class:`~mrodrake.planning.semantics.ExecutedWords`), the
        suffix visits an accepting state, the stored costs match χ, the NBA accepts the lasso of source
        labels, and every word that executing the lasso can produce satisfies ``formula`` (model-checked
        against a fresh NBA of ¬φ, :func:`~mrodrake.planning.semantics.check_plan_words`).
        """
        if tuple(nba.ap) != tuple(ts.propositions):
            raise ValueError("verify needs the NBA over the TS propositions")
        if isinstance(formula, str):
            formula = parse(formula)
        if not self.suffix:
            raise PlanVerificationError("empty suffix")
        run = self.run
        if run[0][0] != ts.initial:
            raise PlanVerificationError("the run does not start in the TS's initial state")
        family = self.families
        start = Family.of_state(nba.initial) if family else nba.initial
        if run[0][1] != start:
            raise PlanVerificationError("the NBA run does not start in the NBA's initial state")
        if len(self.actions) != len(run) or len(self.step_costs) != len(run):
            raise PlanVerificationError("actions/costs do not have one entry per step")
        for k, (s, q) in enumerate(run):
            if not ts.is_valid(s):
                raise PlanVerificationError(f"run state {k + 1} is not a valid TS state")
            if family and not isinstance(q, Family):
                raise PlanVerificationError(f"run state {k + 1}: a family plan needs a family at every state")
            if not family and not 0 <= q < nba.num_states:
                raise PlanVerificationError(f"run state {k + 1}: NBA state {q} out of range")
        relevant = relevant_mask(ts, formula)
        words = words_for(ts, nba, relevant)
        fam = FamilyWords(ExecutedWords(ts, planning_nba(nba, ts), relevant)) if family else None
        for step, part, _i, _j, a, b, acts, cost in self.steps():
            why = ts.check_transition(a[0], b[0])
            if why is not None:
                raise PlanVerificationError(f"step {step} ({part}) is not a TS transition: {why}")
            if Counter(acts) != Counter(ts.actions(a[0], b[0])):
                raise PlanVerificationError(f"step {step} ({part}): stored actions differ from the TS's")
            if _phase_rank(acts) != sorted(_phase_rank(acts)):
                raise PlanVerificationError(f"step {step} ({part}): releases and grasps must come before the "
                                            "region-changing actions")
            if family:
                if fam.execute(a[1], a[0], b[0], acts) != b[1]:
                    raise PlanVerificationError(f"step {step} ({part}): executed in its order, the step does not "
                                                "lead to the stored word family")
            elif not words.reached(1 << a[1], a[0], b[0], acts) >> b[1] & 1:
                raise PlanVerificationError(f"step {step} ({part}): executed in its order, some crossing "
                                            f"interleaving does not take the NBA from {a[1]} to {b[1]}")
            if not math.isclose(cost, ts.cost(a[0], b[0]), rel_tol=1e-9, abs_tol=1e-9):
                raise PlanVerificationError(f"step {step} ({part}): stored cost differs from χ")
        if not any(q.accepting if family else q in nba.accepting for _, q in self.suffix):
            raise PlanVerificationError("the suffix visits no accepting NBA state" + (" (no breakpoint)" if family
                                                                                      else ""))
        steps = [(a[0], b[0], acts) for _, _, _, _, a, b, acts, _ in self.steps()]
        if not words.check_plan(formula, steps, len(self.prefix)):
            raise PlanVerificationError("some word that executing the plan can produce violates the formula")

    # ------------------------------------------------------------------------------------ JSON
    def _ts(self) -> TransitionSystem:
        if self.ts is None:
            raise ValueError("this plan has no transition system attached")
        return self.ts

    def _action_dict(self, a: Action) -> dict:
        ts = self._ts()
        rn, on, gn = ts.robot_names, ts.object_names, ts.region_names
        if isinstance(a, Navigate):
            d = {"type": "navigate", "robot": rn[a.robot], "from": gn[a.src], "to": gn[a.dst]}
        elif isinstance(a, Grasp):
            d = {"type": "grasp", "robot": rn[a.robot], "object": on[a.obj]}
        elif isinstance(a, Release):
            d = {"type": "release", "robot": rn[a.robot], "object": on[a.obj]}
        else:
            d = {"type": "transport", "object": on[a.obj], "team": [rn[i] for i in a.team],
                 "from": gn[a.src], "to": gn[a.dst]}
        d["text"] = ts.format_action(a, "names")
        d["paper"] = ts.format_action(a, "text")
        return d

    def to_dict(self) -> dict:
        ts = self._ts()

        def state(node):
            q = node[1]
            return {**ts.state_dict(node[0]), "nba": q.to_dict() if isinstance(q, Family) else int(q)}

        steps = []
        for step, part, i, j, _a, _b, acts, cost in self.steps():
            steps.append({"step": step, "part": part, "from": i, "to": j, "cost": cost,
                          "actions": [self._action_dict(x) for x in acts]})
        return {
            "format": FORMAT, "version": VERSION,
            "scenario": self.scenario, "formula": self.formula, "planner": self.planner, "seed": self.seed,
            "costs": {"prefix": self.prefix_cost, "suffix": self.suffix_cost, "total": self.total_cost},
            "prefix": [state(x) for x in self.prefix],
            "suffix": [state(x) for x in self.suffix],
            "actions": steps,
            "stats": _jsonable(self.stats),
        }

    def to_json(self, indent: int | None = 1) -> str:
        return json.dumps(self.to_dict(), indent=indent, ensure_ascii=False)

    def write(self, path: str | Path) -> None:
        Path(path).write_text(self.to_json() + "\n", encoding="utf-8")

    @staticmethod
    def from_json(data: str | dict, ts: TransitionSystem, source: str = "plan") -> Plan:
        """Read a plan (JSON text or the parsed mapping) for the scenario of ``ts``; UserError on
        malformed input.  The result is not verified: call :meth:`verify`."""
        if isinstance(data, str):
            try:
                data = json.loads(data)
            except json.JSONDecodeError as e:
                raise UserError(f"{source}:{e.lineno}:{e.colno}: malformed JSON: {e.msg}") from None
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise UserError(f"{source}: not an mrodrake plan (expected \"format\": \"{FORMAT}\")")
        if data.get("version") != VERSION:
            hint = " (version 1 plans read source labels only: plan again)" if data.get("version") == 1 else ""
            raise UserError(f"{source}: version: unsupported plan version {data.get('version')!r}{hint}")
        for key in ("scenario", "formula", "planner", "prefix", "suffix", "actions"):
            if key not in data:
                raise UserError(f"{source}: {key}: missing required field")
        if data["scenario"] != ts.scenario.name:
            raise UserError(f"{source}: scenario: plan is for '{data['scenario']}', not '{ts.scenario.name}'")

        def node(d, where):
            try:
                q = d["nba"]
                return ts.state_from_dict(d), Family.from_dict(q) if isinstance(q, dict) else int(q)
            except (KeyError, TypeError, ValueError) as e:
                raise UserError(f"{source}: {where}: malformed state ({type(e).__name__}: {e})") from None

        prefix = [node(d, f"prefix[{k}]") for k, d in enumerate(data["prefix"])]
        suffix = [node(d, f"suffix[{k}]") for k, d in enumerate(data["suffix"])]
        steps = data["actions"]
        if not isinstance(steps, list) or len(steps) != len(prefix) + len(suffix):
            raise UserError(f"{source}: actions: expected one entry per step ({len(prefix) + len(suffix)})")
        actions, costs = [], []
        for k, st in enumerate(steps):
            try:
                actions.append(tuple(_action_from_dict(ts, a) for a in st["actions"]))
                costs.append(float(st["cost"]))
            except (KeyError, TypeError, ValueError) as e:
                raise UserError(f"{source}: actions[{k}]: malformed step ({type(e).__name__}: {e})") from None
        seed = data.get("seed")
        return Plan(data["scenario"], data["formula"], data["planner"], seed if seed is None else int(seed),
                    prefix, suffix, actions, costs, ts, dict(data.get("stats") or {}))

    # ------------------------------------------------------------------------------------ table
    def table(self):
        """The plan as the paper's Table I: one row per step (pandas DataFrame)."""
        import pandas as pd

        ts = self._ts()
        rows = []
        for step, part, i, j, _a, _b, acts, cost in self.steps():
            rows.append({
                "step": step,
                "part": part,
                "from": i,
                "to": j,
                "actions": ", ".join(ts.format_action(x, "text") for x in acts) or "−",
                "actions_names": "; ".join(ts.format_action(x, "names") for x in acts) or "idle",
                "cost": cost,
            })
        return pd.DataFrame(rows, columns=["step", "part", "from", "to", "actions", "actions_names", "cost"])

    def summary(self) -> str:
        return (f"{self.planner}: cost {self.total_cost:.1f} (prefix {self.prefix_cost:.1f} over "
                f"{len(self.prefix)} steps, suffix {self.suffix_cost:.1f} over {len(self.suffix)} steps)")


def _phase_rank(actions: Sequence[Action]) -> list[int]:
    """0 for releases and grasps, 1 for region-changing actions (execution phases of a step)."""
    return [0 if isinstance(a, (Grasp, Release)) else 1 for a in actions]


def _action_from_dict(ts: TransitionSystem, d: dict) -> Action:
    rob = {n: i for i, n in enumerate(ts.robot_names)}
    obj = {n: j for j, n in enumerate(ts.object_names)}
    reg = {n: k for k, n in enumerate(ts.region_names)}
    kind = d["type"]
    if kind == "navigate":
        return Navigate(rob[d["robot"]], reg[d["from"]], reg[d["to"]])
    if kind == "grasp":
        return Grasp(rob[d["robot"]], obj[d["object"]])
    if kind == "release":
        return Release(rob[d["robot"]], obj[d["object"]])
    if kind == "transport":
        return Transport(obj[d["object"]], tuple(rob[r] for r in d["team"]), reg[d["from"]], reg[d["to"]])
    raise ValueError(f"unknown action type {kind!r}")


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if hasattr(x, "item"):
        return x.item()
    return x


# ---------------------------------------------------------------------------------------- high level
def task_nba(scenario, ts: TransitionSystem):
    """(formula, NBA over ts.propositions) of the scenario's task."""
    f = parse(scenario.task.formula, macros=dict(scenario.task.propositions), source="task.formula",
              macro_prefix="task.propositions.")
    return f, translate(f).with_ap(ts.propositions)


def task_words(scenario, ts: TransitionSystem) -> tuple[Formula, NBA, ExecutedWords]:
    """(formula, NBA over ts.propositions, executed-word semantics) of the scenario's task."""
    f, nba = task_nba(scenario, ts)
    return f, nba, ExecutedWords(ts, nba, relevant_mask(ts, f))


def _check_budget(planner: str, iterations: int | None, time_limit: float | None, seed: int | None = None) -> None:
    """One-line UserErrors for an unknown planner, a budget that is not positive or a negative seed."""
    if seed is not None and seed < 0:
        raise UserError(f"--seed: must be >= 0, got {seed}")
    if planner not in ("stylus", "exact"):
        raise UserError(f"--planner: unknown planner '{planner}' (expected 'stylus' or 'exact')")
    if iterations is not None and iterations <= 0:
        raise UserError(f"--iterations: must be > 0, got {iterations}")
    if time_limit is not None and not time_limit > 0:
        raise UserError(f"--time-limit: must be > 0, got {time_limit}")


#: Candidate plans the placement may reject before planning gives up (each rejection bans its TS transition and,
#: for STyLuS*'s first search, every transition with the same local situation: :mod:`mrodrake.planning.bans`).
MAX_REFINEMENTS = 16
#: Without a plan after ``iterations`` and without a verdict, STyLuS* samples up to this many times as long.
EXTEND_FACTOR = 10


def plan_scenario(scenario, planner: str = "stylus", seed: int | None = None, iterations: int | None = None,
                  time_limit: float | None = None, progress: Callable[[dict], None] | None = None,
                  replan: bool = True, suffix_cycles: int = 1, layout_seed: int | None = None,
                  place: bool = True) -> Plan:
    """Plan a scenario (a :class:`~mrodrake.scenario.Scenario` or a YAML path) and return the verified plan.

    ``planner="stylus"``: STyLuS* with ``seed`` (default ``planning.seed``) for ``iterations`` (default
    ``planning.iterations``) or ``time_limit`` seconds; ``"exact"``: optimal plan on the explicit product.
    Both plan on the executed-word semantics. STyLuS* searches first the sub-TS in which every object, in its
    initial region too, lies where its smallest team fits around it
    (:meth:`~mrodrake.ts.TransitionSystem.bound_at_home`: its runs leave room to grasp each object wherever it lies,
    so placement rejects fewer of them), and the whole TS once that search finds nothing. A plan is returned only
    when its executed run (the prefix and ``suffix_cycles`` suffix cycles) places
    (:func:`~mrodrake.planning.placement.place_plan` with ``layout_seed``, default the planner's seed or 0: what
    ``Mission(seed=...)`` uses); a plan placement rejects bans the step that failed, and for STyLuS*'s first
    search every step with the same local situation in the failed region (for every search, a team change whose
    staying member is off its new slot: :mod:`mrodrake.planning.bans`), and the planner searches again
    (``place=False``: no placement).
    When STyLuS* finds no plan within ``iterations``, :func:`~mrodrake.planning.decide.decide` tries to prove
    the task unsatisfiable (relaxations; the exact search when the product is small, whose plan is used), and
    otherwise STyLuS* samples up to :data:`EXTEND_FACTOR` times as long.  Unsatisfiable tasks raise a
    one-line UserError; a budget that runs out undecided raises NoPlanFound (a UserError, exit status 3).
    ``replan=False``: STyLuS* without the exact re-planning of its best lassos.  BLAS runs single-threaded
    meanwhile (as in :meth:`~mrodrake.systems.mission.Mission.run`): the plan does not depend on the core count.
    """
    with threadpool_limits(limits=1, user_api="blas"):
        return _plan_scenario(scenario, planner, seed, iterations, time_limit, progress, replan, suffix_cycles,
                              layout_seed, place)


def _plan_scenario(scenario, planner, seed, iterations, time_limit, progress, replan, suffix_cycles,
                   layout_seed, place) -> Plan:
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    _check_budget(planner, iterations, time_limit, seed)
    if layout_seed is not None and layout_seed < 0:
        raise UserError(f"--seed: must be >= 0, got {layout_seed}")
    if suffix_cycles < 0:
        raise UserError(f"suffix_cycles: must be >= 0, got {suffix_cycles}")
    t0 = time.perf_counter()
    ts = TransitionSystem(scenario)
    strict = ts.bound_at_home() if planner == "stylus" and ts.M else None
    formula, nba, words = task_words(scenario, ts)
    check_power(ts, nba)
    used_seed = None if planner == "exact" else (scenario.planning.seed if seed is None else int(seed))
    its = scenario.planning.iterations if iterations is None else int(iterations)
    lay_seed = int(layout_seed) if layout_seed is not None else (used_seed or 0)
    report = (lambda msg: progress({"message": msg})) if progress else None
    banned: list[tuple[State, State]] = []
    local_bans: list[LocalBan | SwapBan] = []
    rejected: list[str] = []
    decision = None
    while True:
        name, s_seed = planner, used_seed
        if planner == "exact":
            res = solve_exact(ts, nba, words.relevant, progress=report, banned=tuple(banned))
        else:
            try:
                bans = Bans(ts, banned, local_bans)
                res = Stylus(strict or ts, nba, words.relevant, seed=used_seed, replan=replan, banned=bans).run(
                    its, time_limit=time_limit, progress=progress)
            except NoPlanFound as first:
                strict = None
                if report:
                    report("deciding satisfiability")
                if decision is None or decision.exact is not None and banned:
                    decision = decide(ts, nba, words.relevant, banned=tuple(banned))
                if decision.exact is not None:
                    res, name, s_seed = decision.exact, "exact", None
                    res.stats["stylus"] = f"{first}; the exact planner found this plan"
                else:
                    try:
                        swaps = [b for b in local_bans if isinstance(b, SwapBan)]
                        res = Stylus(ts, nba, words.relevant, seed=used_seed, replan=replan,
                                     banned=Bans(ts, banned, swaps)).run(
                            its, time_limit=time_limit, progress=progress, extend_iterations=EXTEND_FACTOR * its)
                    except NoPlanFound as e:
                        raise NoPlanFound(f"{e}; {decision.undecided}" + _rejections(rejected)) from None
        plan = _make_plan(ts, scenario, formula, nba, words, name, s_seed, res, decision, t0)
        if not place:
            return plan
        try:
            placement = place_plan(plan, suffix_cycles, seed=lay_seed)
        except PlacementError as e:
            edge = _rejected_step(plan, e)
            rejected.append(str(e))
            if edge is None or edge in banned or len(rejected) > MAX_REFINEMENTS:
                raise NoPlanFound(f"no plan found whose executed run places: placement rejected {len(rejected)} "
                                  f"plans (last: {e}); satisfiability unknown") from None
            banned.append(edge)
            if e.step is not None and e.swap >= 0:
                local_bans.append(SwapBan.of(ts, tuple(e.step.src), tuple(e.step.dst), e.swap))
            elif e.step is not None and e.region >= 0:
                local_bans.append(LocalBan.of(ts, tuple(e.step.src), tuple(e.step.dst), e.region))
            if report:
                report(f"placement rejected a plan ({e}); planning again without that step")
            continue
        plan.placement = placement
        plan.stats["placement"] = {"seed": lay_seed, "suffix_cycles": suffix_cycles, "rejected": rejected}
        plan.stats["total_seconds"] = time.perf_counter() - t0
        return plan


def _rejections(rejected: list[str]) -> str:
    return f"; placement rejected {len(rejected)} plans (last: {rejected[-1]})" if rejected else ""


def _rejected_step(plan: Plan, e: PlacementError) -> tuple[State, State] | None:
    """The TS transition to ban after a placement failure: the failed step's (the first step that changes
    grasps or regions when the initial layout failed), or None for an all-idle run."""
    if e.step is not None:
        return (tuple(e.step.src), tuple(e.step.dst))
    for _step, _part, _i, _j, a, b, _acts, _cost in plan.steps():
        if a[0] != b[0]:
            return (tuple(a[0]), tuple(b[0]))
    return None


def _make_plan(ts, scenario, formula, nba, words, planner, seed, res, decision, t0) -> Plan:
    stats = dict(res.stats)
    if decision is not None:
        stats["decide"] = decision.stats
    if getattr(res, "history", None):
        stats["cost_history"] = [[round(t, 4), it, c] for t, it, c in res.history]
    stats["nba_states"] = nba.num_states
    stats["nba_edges"] = nba.num_edges
    stats["total_seconds"] = time.perf_counter() - t0
    if isinstance(res, FamilyResult):
        plan = Plan.from_families(ts, scenario.name, str(formula), planner, seed, res, stats)
    else:
        plan = Plan.from_runs(ts, scenario.name, str(formula), planner, seed, res.prefix, res.suffix, words, stats)
    plan.verify(ts, nba, formula)
    return plan


def graph_task_nba(ts: GraphTS, formula: str | None = None) -> tuple[Formula, NBA]:
    """(formula, NBA over ts.propositions) of a graph task; UserError for atoms that are not propositions."""
    f = parse(ts.scenario.formula if formula is None else formula, source="task")
    unknown = sorted(atoms(f) - set(ts.propositions))
    if unknown:
        raise UserError(f"task: unknown proposition '{unknown[0]}' (propositions: {', '.join(ts.propositions)})")
    return f, translate(f).with_ap(ts.propositions)


def plan_graph(ts, formula: str | None = None, planner: str = "stylus", seed: int | None = None,
               iterations: int | None = None, time_limit: float | None = None,
               progress: Callable[[dict], None] | None = None) -> Plan:
    """Plan a multi-robot graph task (a :class:`~mrodrake.planning.graph.GraphTS` or a task file) and return
    the verified plan; the NBA reads source labels.  ``planner`` and the budget as in :func:`plan_scenario`;
    the default planner first decides small products exactly (at most
    :data:`~mrodrake.planning.decide.EXACT_BOUND` joint states × NBA states) and returns that plan if
    STyLuS* finds none."""
    if not isinstance(ts, GraphTS):
        ts = load_graph_ts(ts)
    _check_budget(planner, iterations, time_limit, seed)
    t0 = time.perf_counter()
    f, nba = graph_task_nba(ts, formula)
    words = SourceWords(ts, nba, relevant_mask(ts, f))
    exact = None
    bound = math.prod(int(GraphStrategy(ts, words.relevant).reach(i).sum()) for i in range(ts.N))
    if planner == "exact":
        res, used_seed = solve_exact_graph(ts, nba, words.relevant), None
    else:
        if bound * nba.num_states <= EXACT_BOUND:
            exact = solve_exact_graph(ts, nba, words.relevant)
        used_seed = ts.scenario.planning.seed if seed is None else int(seed)
        its = ts.scenario.planning.iterations if iterations is None else int(iterations)
        try:
            res = Stylus(ts, nba, words.relevant, seed=used_seed).run(
                its, time_limit=time_limit, progress=progress, extend_iterations=EXTEND_FACTOR * its)
        except NoPlanFound as e:
            if exact is None:
                raise NoPlanFound(f"{e}; the explicit product is too large to decide (up to {bound:.1e} joint "
                                  f"states × {nba.num_states} NBA states)") from None
            res, planner, used_seed = exact, "exact", None
            res.stats["stylus"] = f"{e}; the exact planner found this plan"
    stats = dict(res.stats)
    if getattr(res, "history", None):
        stats["cost_history"] = [[round(t, 4), it, c] for t, it, c in res.history]
    stats.update(nba_states=nba.num_states, nba_edges=nba.num_edges, joint_states_bound=float(bound),
                 total_seconds=time.perf_counter() - t0)
    plan = Plan.from_runs(ts, ts.name, str(f), planner, used_seed, res.prefix, res.suffix, words, stats)
    plan.verify(ts, nba, f)
    return plan
