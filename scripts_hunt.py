"""Failure hunt for issue 13: generated missions on the shipped maps and the office, one at a time.

    python3 scripts_hunt.py list                      # the missions (id, map, n, m, k, seed)
    python3 scripts_hunt.py run [--out DIR] [ID ...]  # run missions without a result yet, each in a subprocess
                                                      # under `timeout 900 nice -n 10` (15 min wall cap)
    python3 scripts_hunt.py one ID [--out DIR]        # plan + execute one mission (what `run` calls)
    python3 scripts_hunt.py scenario ID               # print the mission's scenario YAML
    python3 scripts_hunt.py decide [--out DIR] [ID ...]  # exact planner on the missions STyLuS* found no plan for
    python3 scripts_hunt.py table [--out DIR]         # the markdown table and counts of notes13_failures.md

``one`` writes DIR/ID/scenario.yaml (the generated scenario, as ``scenario`` prints it: ``python3 -m mrodrake
run DIR/ID/scenario.yaml --seed SEED`` reproduces the mission), plans with ``plan_scenario(sc, "stylus", seed=SEED)``, executes with
``Mission(sc, plan, seed=SEED)`` (as ``run_mission`` and ``mrodrake run`` do, but keeping the log of a mission
that raises), writes the usual outputs (events.csv, trajectory.csv, ...) and DIR/ID/result.json.
Not part of the package.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import time
import traceback
from pathlib import Path

import yaml

HERE = Path(__file__).resolve().parent
DEFAULT_OUT = Path("/tmp/hunt13")
TIMEOUT = 900
MAPS = ("lab", "narrow", "warehouse", "corridor")

#: (map, n, m, k, seed); "office" is the case-study office (generate_scenario without map);
#: n = 0 marks the map file's own default task.  Small maps first; seeds are fresh (not used by the tests).
MISSIONS = [
    *[(name, 0, 0, 0, 0) for name in MAPS],
    ("lab", 2, 1, 3, 1301), ("lab", 3, 1, 4, 1302), ("lab", 2, 2, 4, 1303), ("lab", 3, 2, 5, 1304),
    ("lab", 4, 1, 5, 1305), ("lab", 3, 3, 5, 1306), ("lab", 5, 2, 5, 1307),
    ("narrow", 2, 1, 3, 1311), ("narrow", 3, 1, 4, 1312), ("narrow", 2, 2, 4, 1313), ("narrow", 3, 2, 5, 1314),
    ("narrow", 4, 2, 5, 1315),
    ("warehouse", 2, 1, 3, 1321), ("warehouse", 3, 1, 4, 1322), ("warehouse", 3, 2, 5, 1323),
    ("warehouse", 4, 2, 4, 1324), ("warehouse", 5, 3, 5, 1325),
    ("corridor", 2, 1, 3, 1331), ("corridor", 3, 2, 4, 1332), ("corridor", 4, 2, 5, 1333),
    ("office", 2, 1, 3, 1341), ("office", 3, 1, 4, 1342), ("office", 3, 2, 4, 1343), ("office", 4, 2, 5, 1344),
    ("office", 5, 3, 5, 1345),
    # second batch (a third of the first batch's tasks were unsatisfiable)
    ("lab", 2, 1, 4, 1308), ("lab", 3, 2, 4, 1309), ("lab", 4, 2, 5, 1310),
    ("narrow", 2, 1, 4, 1316), ("narrow", 3, 1, 5, 1317),
    ("warehouse", 2, 1, 4, 1326), ("warehouse", 3, 1, 5, 1327), ("warehouse", 4, 1, 5, 1328),
    ("corridor", 2, 1, 4, 1334), ("corridor", 3, 1, 5, 1335), ("corridor", 5, 2, 5, 1336),
    ("office", 2, 2, 4, 1346), ("office", 4, 1, 4, 1347), ("office", 5, 2, 5, 1348),
    # third batch: more office missions (the map), a few more on the others
    ("office", 2, 1, 4, 1401), ("office", 3, 1, 3, 1402), ("office", 3, 2, 5, 1403), ("office", 4, 3, 5, 1404),
    ("office", 5, 1, 4, 1405), ("office", 2, 2, 3, 1406),
    ("lab", 2, 1, 5, 1407), ("lab", 3, 1, 3, 1408), ("narrow", 2, 1, 5, 1409),
    ("warehouse", 2, 2, 5, 1410), ("warehouse", 3, 3, 5, 1411), ("corridor", 3, 1, 3, 1412),
]

#: (class, pattern) in the order they are tried on the failure message (issue 13's classes).
CLASSES = [
    (1, r"does not contain the plan's NBA state"),
    (2, r"no order of the concurrent actions"),
    (3, r"goal unreachable"),
    (4, r"step smaller than minimum|minimum allowed"),
    (5, r"point-world map degenerate|det J_H|circle barrier"),
    (6, r"monitored NBA run died"),
    (7, r"no reachable grasp point|P_s found no placement|no room for|make room|not in the free space"),
]


def mission_id(spec) -> str:
    name, n, m, k, seed = spec
    return f"{name}-default" if n == 0 else f"{name}-n{n}m{m}k{k}-s{seed}"


def specs_by_id() -> dict:
    return {mission_id(s): s for s in MISSIONS}


def scenario_data(spec) -> dict:
    """The scenario mapping of a mission (a map file's own task, or a generated one)."""
    from mrodrake.planning.generate import MAPS as MAP_DIR
    from mrodrake.planning.generate import generate_scenario_data

    name, n, m, k, seed = spec
    if n == 0:
        return yaml.safe_load((MAP_DIR / f"{name}.yaml").read_text(encoding="utf-8"))
    return generate_scenario_data(n, m, k, seed, map=None if name == "office" else name)


def classify(message: str) -> int:
    """Issue 13's failure class of a one-line failure message (8: anything else)."""
    for cls, pattern in CLASSES:
        if re.search(pattern, message):
            return cls
    return 8


def run_one(spec, out: Path) -> dict:
    """Plan and execute one mission; write its outputs and result.json to ``out``."""
    from mrodrake.errors import UserError
    from mrodrake.planning.plan import plan_scenario
    from mrodrake.scenario import load_scenario
    from mrodrake.systems.mission import Mission

    out.mkdir(parents=True, exist_ok=True)
    seed = spec[4]
    path = out / "scenario.yaml"
    path.write_text(yaml.safe_dump(scenario_data(spec), sort_keys=False), encoding="utf-8")
    sc = load_scenario(path)
    res = {"id": mission_id(spec), "map": spec[0], "n": len(sc.robots), "m": len(sc.objects),
           "k": len(sc.regions), "seed": seed, "formula": sc.task.formula, "propositions": dict(sc.task.propositions)}
    t0 = time.perf_counter()
    try:
        plan = plan_scenario(sc, "stylus", seed=seed)
    except UserError as exc:
        msg = str(exc)
        res.update(plan="unsat" if "unsatisfiable" in msg else "no plan", plan_message=msg,
                   plan_wall=time.perf_counter() - t0)
        return _write(out, res)
    res.update(plan="ok", plan_wall=time.perf_counter() - t0, plan_steps=len(plan.step_costs), plan_cost=plan.total_cost)
    mission, log, tb = None, None, ""
    t1 = time.perf_counter()
    try:
        mission = Mission(sc, plan, seed=seed)
        log = mission.run()
    except Exception as exc:  # record the traceback's last line, keep what was simulated
        tb = traceback.format_exc()
        res["exception"] = f"{type(exc).__name__}: {str(exc).strip().splitlines()[-1] if str(exc).strip() else ''}"
        if mission is not None:
            log = mission.log()
    res["wall"] = time.perf_counter() - t1
    if tb:
        (out / "traceback.txt").write_text(tb, encoding="utf-8")
    if log is None:
        res.update(ok=False, message=res["exception"], cls=8)
        return _write(out, res)
    log.write(out)
    message = res.get("exception") or ("" if log.ok else log.message)
    res.update(ok=bool(log.ok and not tb), message=message, sim=log.sim_seconds,
               steps_done=log.steps_done, steps_total=log.steps_total)
    if not res["ok"]:
        res["cls"] = classify(message)
        res["where"] = _running_op(mission) if tb else _failing_event(log.events, message)
    return _write(out, res)


def _running_op(mission) -> str:
    """'step s (plan step p): action @ t' of the primitive running when the simulation raised."""
    st = mission.supervisor_state()
    if st.op is None:
        return ""
    return (f"step {st.op.step.index} (plan step {st.op.step.plan_step}): "
            f"{mission.ts.format_action(st.op.action, 'names')} @ t={float(st.op_t0):.1f}")


def decide(mid: str, out: Path) -> None:
    """Run the exact planner (in a subprocess, 15 min cap) on a mission whose STyLuS* run found no plan;
    store its verdict as ``exact`` in result.json."""
    path = out / mid / "result.json"
    res = json.loads(path.read_text(encoding="utf-8"))
    if res.get("plan") != "no plan" or "exact" in res:
        return
    code = ("import sys; from mrodrake.errors import UserError; from mrodrake.planning.plan import plan_scenario\n"
            "try:\n    p = plan_scenario(sys.argv[1], 'exact')\n    print('plan exists: cost %.1f' % p.total_cost)\n"
            "except UserError as e:\n    print(str(e))")
    t0 = time.perf_counter()
    proc = subprocess.run(["timeout", str(TIMEOUT), "nice", "-n", "10", sys.executable, "-c", code,
                           str(out / mid / "scenario.yaml")], cwd=HERE, capture_output=True, text=True)
    verdict = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else (
        f"undecided (wall-time cap {TIMEOUT} s)" if proc.returncode == 124 else f"exit {proc.returncode}")
    res["exact"], res["exact_wall"] = verdict, time.perf_counter() - t0
    if verdict.startswith("task is unsatisfiable"):
        res["plan"] = "unsat"
    _write(out / mid, res)
    print(f"{mid}: {verdict} ({res['exact_wall']:.0f} s)", flush=True)


def _failing_event(events, message: str) -> str:
    """'step s (plan step p): action @ t' of the failed primitive, else of the last event (the step named
    by the message when there is no event)."""
    if events.empty:
        named = re.match(r"step \d+ \(plan step \d+\)", message)
        return named.group(0) if named else ""
    bad = events[events["ok"] == False]  # noqa: E712 (pandas mask)
    row = (bad if len(bad) else events).iloc[-1]
    return f"step {row['step']} (plan step {row['plan_step']}): {row['action']} @ t={float(row['t_start']):.1f}"


def _write(out: Path, res: dict) -> dict:
    (out / "result.json").write_text(json.dumps(res, indent=1, default=str), encoding="utf-8")
    return res


def run_all(ids, out: Path) -> None:
    """Run each mission without a result.json in its own subprocess (15 min wall cap)."""
    for mid in ids:
        target = out / mid
        if (target / "result.json").is_file():
            continue
        print(f"[{time.strftime('%H:%M:%S')}] {mid}", flush=True)
        t0 = time.perf_counter()
        cmd = ["timeout", str(TIMEOUT), "nice", "-n", "10", sys.executable, str(HERE / "scripts_hunt.py"), "one", mid,
               "--out", str(out)]
        proc = subprocess.run(cmd, cwd=HERE, capture_output=True, text=True)
        target.mkdir(parents=True, exist_ok=True)
        (target / "stderr.txt").write_text(proc.stderr, encoding="utf-8")
        if not (target / "result.json").is_file():
            spec = specs_by_id()[mid]
            last = proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else ""
            msg = f"wall-time cap {TIMEOUT} s reached" if proc.returncode == 124 else f"exit {proc.returncode}: {last}"
            _write(target, {"id": mid, "map": spec[0], "n": spec[1], "m": spec[2], "k": spec[3], "seed": spec[4],
                            "plan": "?", "ok": False, "message": msg, "cls": 8,
                            "wall": time.perf_counter() - t0})
        res = json.loads((target / "result.json").read_text(encoding="utf-8"))
        print(f"    -> {_outcome(res)} ({time.perf_counter() - t0:.0f} s)", flush=True)


def _outcome(res: dict) -> str:
    if res.get("plan") not in ("ok", "?"):
        return res["plan"]
    return "ok" if res.get("ok") else f"class {res.get('cls')}: {res.get('message', '')}"


def table(out: Path) -> str:
    """Markdown table of all results plus counts per class and per map."""
    rows, results = [], []
    for spec in MISSIONS:
        path = out / mission_id(spec) / "result.json"
        if not path.is_file():
            continue
        r = json.loads(path.read_text(encoding="utf-8"))
        if r.get("plan") == "ok" and not r.get("ok"):
            r["cls"] = classify(r.get("message", ""))
        results.append(r)
        outcome = "ok" if r.get("ok") else ("—" if r.get("plan") != "ok" else f"**{r.get('cls')}**")
        msg = r.get("plan_message", "") if r.get("plan") not in ("ok", "?") else r.get("message", "")
        if "exact" in r:
            msg = f"STyLuS*: no plan; exact: {r['exact']}"
        msg = msg if len(msg) <= 160 else msg[:157] + "..."
        steps = f"{r['steps_done']}/{r['steps_total']}" if "steps_total" in r else ""
        sim = f"{r['sim']:.0f}" if "sim" in r else ""
        wall = f"{r['wall']:.0f}" if "wall" in r else ""
        rows.append(f"| {r['id']} | {r['map']} | {r['n']},{r['m']},{r['k']} | {r['seed']} | {r.get('plan')} | "
                    f"{outcome} | {steps} | {r.get('where', '')} | {sim} | {wall} | {msg.replace('|', '/')} |")
    head = ["| id | map | n,m,k | seed | plan | mission (class) | steps | failing step / primitive | sim s | wall s | "
            "message |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    planned = [r for r in results if r.get("plan") in ("ok", "?")]
    failed = [r for r in planned if not r.get("ok")]
    counts = ["", f"missions: {len(results)}; planned: {len(planned)}; ok: {len(planned) - len(failed)}; "
              f"failed: {len(failed)}; unsat / no plan: {len(results) - len(planned)}", "",
              "| class | " + " | ".join(MAPS + ("office",)) + " | total |",
              "|---|" + "---|" * (len(MAPS) + 2)]
    for cls in range(1, 9):
        per = [sum(1 for r in failed if r["map"] == name and r.get("cls") == cls) for name in MAPS + ("office",)]
        counts.append(f"| {cls} | " + " | ".join(map(str, per)) + f" | {sum(per)} |")
    per_ok = [sum(1 for r in planned if r["map"] == name and r.get("ok")) for name in MAPS + ("office",)]
    counts.append("| ok | " + " | ".join(map(str, per_ok)) + f" | {sum(per_ok)} |")
    return "\n".join(head + rows + counts)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("command", choices=["list", "run", "one", "scenario", "decide", "table"])
    p.add_argument("ids", nargs="*", help="mission ids (default: all)")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = p.parse_args(argv)
    ids = args.ids or [mission_id(s) for s in MISSIONS]
    unknown = [i for i in ids if i not in specs_by_id()]
    if unknown:
        p.error(f"unknown mission id(s): {', '.join(unknown)}")
    if args.command == "list":
        for mid in ids:
            print(mid, *specs_by_id()[mid])
    elif args.command == "run":
        run_all(ids, args.out)
    elif args.command == "one":
        for mid in ids:
            res = run_one(specs_by_id()[mid], args.out / mid)
            print(f"{mid}: {_outcome(res)}")
    elif args.command == "scenario":
        for mid in ids:
            print(yaml.safe_dump(scenario_data(specs_by_id()[mid]), sort_keys=False), end="")
    elif args.command == "decide":
        for mid in ids:
            if (args.out / mid / "result.json").is_file():
                decide(mid, args.out)
    else:
        print(table(args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
