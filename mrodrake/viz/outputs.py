"""The outputs of a mission run: logs as CSV, the plan, the Meshcat replay and the paper's figures."""

from __future__ import annotations

from pathlib import Path

from mrodrake.errors import UserError
from mrodrake.viz.figures import figure_initial, figure_signals, figure_trajectory
from mrodrake.viz.replay import write_replay


def write_mission(log, out_dir) -> list[Path]:
    """Write a mission log's plan.json, plan.csv, trajectory.csv, signals.csv, events.csv, replay.html and
    figures/ (paper Figs. 1-5).

    Every file is attempted even if an earlier one fails; then an :class:`OutputError` names what could
    not be written and where the rest went."""
    out = Path(out_dir)
    written: list[Path] = []
    failed: list[str] = []

    def attempt(path: Path, write) -> None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            result = write(path)
            written.append(Path(result) if isinstance(result, (str, Path)) else path)
        except (OSError, ValueError) as exc:
            failed.append(f"{path.name}: {exc}")

    attempt(out / "plan.json", log.plan.write)
    attempt(out / "plan.csv", lambda p: log.plan.table().to_csv(p, index=False))
    for name, df in (("trajectory", log.trajectory), ("signals", log.signals), ("events", log.events)):
        attempt(out / f"{name}.csv", lambda p, df=df: df.to_csv(p, index=False, float_format="%.10g"))
    if len(log.trajectory):
        attempt(out / "replay.html",
                lambda p: write_replay(log.scenario, log.trajectory, p, grasps=log.grasps))
        attempt(out / "figures" / "fig1_initial.png", lambda p: figure_initial(log.scenario, log.trajectory, p))
    navs = [r for r in log.primitives if r.kind == "navigate"]
    trans = [r for r in log.primitives if r.kind == "transport"]
    for recs, f_traj, f_sig in ((navs, "fig2_navigation", "fig3_navigation_signals"),
                                (trans, "fig4_transport", "fig5_transport_signals")):
        if not recs:
            continue
        res = log.transition_result(max(recs, key=lambda r: r.t_end - r.t_start))
        if len(res.log) < 2:
            continue
        attempt(out / "figures" / f"{f_traj}_{res.entity}.png", lambda p, res=res: figure_trajectory(res, p))
        attempt(out / "figures" / f"{f_sig}_{res.entity}.png", lambda p, res=res: figure_signals(res, p))
    if failed:
        raise OutputError(f"could not write {len(failed)} output file(s) to {out}/ ({'; '.join(failed)}); "
                          f"{len(written)} written", written)
    return written


class OutputError(UserError):
    """Some output files could not be written; ``written`` lists those that were."""

    def __init__(self, message: str, written: list[Path]):
        super().__init__(message)
        self.written = written


def ensure_output_dir(path, option: str = "--out") -> Path:
    """Create ``path`` (with parents) and check that files can be written there, before any simulation."""
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / ".mrodrake-write-test"
        probe.write_text("", encoding="utf-8")
        probe.unlink()
    except OSError as exc:
        raise UserError(f"{option}: cannot write to '{out}': {exc.strerror or exc}") from None
    return out
