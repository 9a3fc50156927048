"""Run one case into one results folder: logging, resolved case, dispatch, metrics, plots."""

from __future__ import annotations

import logging
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from mpi4py import MPI

from .case import Case
from .caseio import case_to_toml
from .results import ResultsFolder

log = logging.getLogger(__name__)


class RunFailed(RuntimeError):
    """A run started but did not finish; what was computed so far is on disk."""


class ResumeError(ValueError):
    """``--resume`` cannot continue this folder (no checkpoint, or a different case)."""


@contextmanager
def run_log(path: Path) -> Iterator[None]:
    """Send every ``pulseform`` log record of this run to ``path`` (DEBUG and up)."""
    handler = logging.FileHandler(path, mode="a", encoding="utf-8")
    handler.setLevel(logging.DEBUG)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)-7s %(name)s: %(message)s"))
    root = logging.getLogger("pulseform")
    old_level = root.level
    root.setLevel(logging.DEBUG)
    root.addHandler(handler)
    try:
        yield
    finally:
        root.removeHandler(handler)
        root.setLevel(old_level)
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
        results = ResultsFolder(out, resume=True)
    wall0 = time.perf_counter()
    with run_log(results.log_file) if comm.rank == 0 else _nullcontext():
        log.info("case %s -> %s", case.case.name, results.root)
        if comm.rank == 0 and not resume:
            results.write_text("case.toml", case_to_toml(case))
        try:
            metrics = _dispatch(case, results, quiet=quiet, resume=resume, comm=comm)
        except Exception as exc:  # solver failures: keep what is on disk, report, re-raise as RunFailed
            log.debug("run failed: %s", exc, exc_info=True)  # the traceback goes to run.log only
            if comm.rank == 0:
                results.write_metrics({"status_ok": 0.0, "wall_time_s": time.perf_counter() - wall0})
            raise RunFailed(f"{case.case.name}: {exc} (partial results and log in {results.root})") from exc
        metrics["wall_time_s"] = time.perf_counter() - wall0
        metrics["status_ok"] = 1.0
        if comm.rank == 0:
            results.write_metrics(metrics)
        log.info("done in %.2f s; metrics in %s", metrics["wall_time_s"], results.root / "metrics.json")
    return metrics


def _check_resumable(case: Case, out: Path) -> None:
    stored = out / "case.toml"
    if not stored.is_file():
        raise ResumeError(f"{out}: nothing to resume (no case.toml from an earlier run)")
    if not any(out.glob("checkpoint*.npz")):
        raise ResumeError(f"{out}: nothing to resume (no checkpoint written yet)")
    if stored.read_text() != case_to_toml(case):
        raise ResumeError(f"{stored}: the case differs from the one this folder was run with; "
                          "resume needs the same case and --set overrides")


def _dispatch(case: Case, results: ResultsFolder, *, quiet: bool, resume: bool,
              comm: MPI.Comm) -> dict[str, float]:
    from .driver import run_case_loop
    from .plots import plot_energies, plot_probes, plot_time_step

    run = run_case_loop(case, results, quiet=quiet, resume=resume, comm=comm)
    if case.output.plots and comm.rank == 0:
        plot_energies(run.history, results.plots)
        plot_time_step(run.history, results.plots)
        plot_probes(run.history, results.plots)
    return run.metrics


@contextmanager
def _nullcontext() -> Iterator[None]:
    yield
