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
    """Send this run's log records to ``path``: pulseform's from DEBUG, other libraries' as they come."""
    handler = logging.FileHandler(path, mode="a", encoding="utf-8")
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
    from .plots import plot_em_snapshot, plot_energies, plot_probes, plot_shapes, plot_time_step

    run = run_case_loop(case, results, quiet=quiet, resume=resume, comm=comm)
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
    return run.metrics


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
