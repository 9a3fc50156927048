"""Run one case into one results folder: logging, resolved case, dispatch, metrics, plots."""

from __future__ import annotations

import logging
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from mpi4py import MPI

from . import interrupt
from .case import Case
from .caseio import case_to_toml
from .results import DISK_FULL_ERRNOS, ResultsFolder

log = logging.getLogger(__name__)


class RunFailed(RuntimeError):
    """A run started but did not finish; what was computed so far is on disk."""


class RunInterrupted(RuntimeError):
    """SIGINT / SIGTERM stopped the run at a safe point; a checkpoint was written.

    ``signum`` is the signal's number, ``time`` the simulated time reached (s), ``out`` the folder.
    """

    def __init__(self, signum: int, time_s: float | None, out: Path) -> None:
        self.signum, self.time, self.out = signum, time_s, out
        at = "before the first step" if time_s is None else f"at t = {time_s:.6g} s"
        super().__init__(f"interrupted {at}; continue with --resume (results in {out})")


class _RunLogHandler(logging.FileHandler):
    """run.log; a failing write (full disk) is dropped silently instead of printing a traceback:
    the run reports the full disk once, where the write that matters fails."""

    def handleError(self, record: logging.LogRecord) -> None:  # noqa: N802 - logging's name
        self.failed = True


class ResumeError(ValueError):
    """``--resume`` cannot continue this folder (no checkpoint, or a different case)."""


@contextmanager
def run_log(path: Path) -> Iterator[None]:
    """Send this run's log records to ``path``: pulseform's from DEBUG, other libraries' as they come."""
    handler = _RunLogHandler(path, mode="a", encoding="utf-8")
    handler.setLevel(logging.DEBUG)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)-7s %(name)s: %(message)s"))
    own = logging.getLogger("pulseform")
    old_level = own.level
    own.setLevel(logging.DEBUG)
    logging.getLogger().addHandler(handler)
    try:
        yield
    finally:
        logging.getLogger().removeHandler(handler)
        own.setLevel(old_level)
        handler.close()


def run_case(case: Case, out: Path, *, force: bool = False, resume: bool = False,
             quiet: bool = False, comm: MPI.Comm = MPI.COMM_WORLD) -> dict[str, float]:
    """Run ``case`` and write its results folder ``out``.

    Returns
    -------
    dict
        The metrics written to ``metrics.json``.

    Raises
    ------
    ResultsExistError
        ``out`` exists and neither ``force`` nor ``resume`` is set.
    RunFailed
        The solver failed; the log, history so far and partial metrics stay in ``out``.
    """
    if resume:
        _check_resumable(case, Path(out))
    results = ResultsFolder(out, force=force, resume=resume) if comm.rank == 0 else None
    comm.Barrier()
    if results is None:
        results = ResultsFolder(out, resume=True, lock=False)
    try:
        with interrupt.signals_stop_run():
            return _run_in(case, results, resume=resume, quiet=quiet, comm=comm)
    finally:
        results.release()


def _run_in(case: Case, results: ResultsFolder, *, resume: bool, quiet: bool, comm: MPI.Comm) -> dict[str, float]:
    wall0 = time.perf_counter()
    with run_log(results.log_file) if comm.rank == 0 else _nullcontext():
        log.info("case %s -> %s", case.case.name, results.root)
        try:
            if comm.rank == 0 and not resume:
                results.write_text("case.toml", case_to_toml(case))
            run = _dispatch(case, results, quiet=quiet, resume=resume, comm=comm)
        except interrupt.RunInterrupted as exc:
            _final_metrics(results, comm, {"status": "interrupted", "status_ok": 0.0,
                                           "end_time_s": exc.time if exc.time is not None else 0.0,
                                           "wall_time_s": time.perf_counter() - wall0})
            raise RunInterrupted(exc.signum, exc.time, results.root) from None
        except KeyboardInterrupt:  # a second Ctrl-C: stop at once, the last checkpoint stays
            log.warning("stopped at once by a second interrupt; the last checkpoint stays")
            raise
        except Exception as exc:  # solver failures: keep what is on disk, report, re-raise as RunFailed
            log.debug("run failed: %s", exc, exc_info=True)  # the traceback goes to run.log only
            _final_metrics(results, comm, {"status": "failed", "status_ok": 0.0,
                                           "wall_time_s": time.perf_counter() - wall0})
            raise RunFailed(f"{case.case.name}: {_failure_text(exc, results.root)} "
                            f"(partial results and log in {results.root})") from exc
        metrics = run.metrics
        metrics["wall_time_s"] = run.wall_before_s + time.perf_counter() - wall0
        metrics["status_ok"] = 1.0
        _final_metrics(results, comm, {**metrics, "status": "ok"})
        log.info("done in %.2f s; metrics in %s", metrics["wall_time_s"], results.root / "metrics.json")
    return metrics


def _final_metrics(results: ResultsFolder, comm: MPI.Comm, metrics: dict) -> None:
    """Write metrics.json on rank 0; a full disk is logged, not raised (the run's own error wins)."""
    if comm.rank != 0:
        return
    try:
        results.write_metrics(metrics)
    except OSError as exc:
        if metrics.get("status") == "ok":
            raise
        log.error("could not write %s: %s", results.root / "metrics.json", exc.strerror)


def _failure_text(exc: BaseException, root: Path) -> str:
    """What went wrong, for the one-line error: a full disk and an out-of-memory named plainly."""
    seen = exc
    while seen is not None:
        if isinstance(seen, OSError) and seen.errno in DISK_FULL_ERRNOS:
            where = seen.filename or root
            return f"no space left to write {where} ({seen.strerror}); what was written before stays readable"
        if isinstance(seen, MemoryError):
            return "out of memory (the case's meshes or fields do not fit: coarsen the mesh or use a larger machine)"
        seen = seen.__cause__ or seen.__context__
    text = str(exc) or type(exc).__name__
    if "No space left on device" in text or "Disk quota exceeded" in text:
        return f"no space left on the device of {root}; what was written before stays readable"
    return text


def _check_resumable(case: Case, out: Path) -> None:
    stored = out / "case.toml"
    if not stored.is_file():
        raise ResumeError(f"{out}: nothing to resume (no case.toml from an earlier run)")
    if not any(out.glob("checkpoint*.npz")):
        raise ResumeError(f"{out}: nothing to resume (no checkpoint written yet)")
    if stored.read_text() != case_to_toml(case):
        raise ResumeError(f"{stored}: the case differs from the one this folder was run with; "
                          "resume needs the same case and --set overrides")


def _dispatch(case: Case, results: ResultsFolder, *, quiet: bool, resume: bool, comm: MPI.Comm):
    from .driver import run_case_loop
    from .plots import plot_em_snapshot, plot_energies, plot_probes, plot_shapes, plot_time_step

    run = run_case_loop(case, results, quiet=quiet, resume=resume, comm=comm)
    interrupt.check()  # a signal after the last step still ends with an honest status
    if case.output.plots and comm.rank == 0:
        plot_energies(run.history, results.plots)
        plot_time_step(run.history, results.plots)
        plot_probes(run.history, results.plots)
        if run.shapes:
            plot_shapes(run.shapes, results.plots, case.mechanics.formulation == "axisymmetric")
        for analysis in run.analyses:
            analysis.plots(run.history, run.shapes, results.plots)
        if run.em_snapshot is not None:
            plot_em_snapshot(*run.em_snapshot, results.plots, run.solver.time, box=_em_plot_box(case))
    return run


def _em_plot_box(case: Case) -> tuple[float, float, float, float] | None:
    """Region of interest (m) for the EM plot: the coil and workpiece with a margin."""
    g = case.geometry
    if g is None:
        return None
    if g.type == "flat_coil_sheet":
        r = 1.15 * g.sheet_radius
        return (0.0, r, -3 * g.turn_height, g.coil_gap + 0.25 * r)
    if g.type != "solenoid_tube":  # a user deck: the whole mesh
        return None
    half = 0.6 * max(g.tube_length, g.turns * (g.turn_height + g.turn_gap))
    return (0.0, 1.5 * (g.tube_inner_radius + g.tube_thickness), -half, half)


@contextmanager
def _nullcontext() -> Iterator[None]:
    yield
