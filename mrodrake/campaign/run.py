"""``run_campaign``: load the spec, skip what the journal has, run the rest on an engine, write the outputs."""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path
from typing import Any

from mrodrake.campaign.figures import write_figures
from mrodrake.campaign.journal import append_row, read_journal
from mrodrake.campaign.local_engine import LocalEngine
from mrodrake.campaign.mission import base_row
from mrodrake.campaign.ray_engine import RayEngine
from mrodrake.campaign.results import primitives_table, write_results
from mrodrake.campaign.spec import load_campaign
from mrodrake.campaign.summary import summarize
from mrodrake.errors import UserError


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
    journal = read_journal(journal_path)
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
            append_row(jf, fingerprints[row["mission_id"]], row)
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
