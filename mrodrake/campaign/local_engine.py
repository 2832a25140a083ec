"""The local engine: one process per mission, forked from a fork server, at most ``workers`` at a time."""

from __future__ import annotations

import dataclasses
import os
import signal
import time
from collections import deque
from collections.abc import Callable, Iterable
from pathlib import Path

from mrodrake.campaign.mission import WORKER_ENV, execute, failure_row
from mrodrake.campaign.spec import MissionTask

#: Modules a local worker process needs, imported once by the fork server instead of once per mission.
WORKER_MODULES = ["mrodrake.campaign.mission", "mrodrake.systems.mission", "mrodrake.planning.plan",
                  "mrodrake.planning.stylus", "mrodrake.planning.exact", "pandas", "shapely"]


def _exit_text(code: int | None) -> str:
    """How a worker process ended, for the failure message."""
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
