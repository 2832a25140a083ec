"""The Ray engine: one Ray task per mission on a local or joined cluster."""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from collections.abc import Callable, Iterable
from pathlib import Path

from mrodrake.campaign.failures import first_line
from mrodrake.campaign.mission import WORKER_ENV, execute, failure_row
from mrodrake.campaign.spec import MissionTask
from mrodrake.errors import UserError


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
                                f"{first_line(e)}") from None
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
                        row = failure_row(task, "worker_crash", f"ray: {type(e).__name__}: {first_line(e)}",
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
