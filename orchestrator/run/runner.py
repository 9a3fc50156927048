"""Run one case into one results folder: logging, resolved case, dispatch, metrics, plots."""

from __future__ import annotations

import logging
import os
import shutil
import signal
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from mpi4py import MPI

from ..case.io import case_to_toml
from ..case.model import Case
from ..em.deck_sources import resolve_deck_sources
from ..em.skin_depth import DefaultSize, default_sizes, with_default_sizes
from . import interrupt
from .results import DISK_FULL_ERRNOS, ResultsFolder, refuse_if_in_use

log = logging.getLogger(__name__)


class RunFailed(RuntimeError):
    """A run started but did not finish; what was computed so far is on disk.

    ``str()`` is one line; ``details`` holds the tail of a failing external program's log ("" if none).
    """

    def __init__(self, message: str, details: str = "") -> None:
        self.details = details
        super().__init__(message)


class RunInterrupted(RuntimeError):
    """SIGINT / SIGTERM stopped the run at a safe point; a checkpoint was written.

    ``signum`` is the signal's number, ``time`` the simulated time reached (s), ``out`` the folder.
    """

    def __init__(self, signum: int, time_s: float | None, out: Path) -> None:
        self.signum, self.time, self.out = signum, time_s, out
        at = "before the first step" if time_s is None else f"at t = {time_s:.6g} s"
        super().__init__(f"interrupted {at}; continue with --resume (results in {out})")


class PicturesInterrupted(RunInterrupted):
    """SIGINT / SIGTERM while the pictures were drawn: the run itself is complete (metrics.json,
    status "ok"); some pictures are missing."""

    def __init__(self, signum: int, out: Path) -> None:
        self.signum, self.time, self.out = signum, None, out
        RuntimeError.__init__(self, f"interrupted while drawing the pictures; the run is complete (results in "
                              f"{out}); 'pulseform plot {out}' draws them")


class _RunLogHandler(logging.FileHandler):
    """run.log; a failing write (full disk) is dropped silently instead of printing a traceback:
    the run reports the full disk once, where the write that matters fails."""

    def handleError(self, record: logging.LogRecord) -> None:  # noqa: N802 - logging's name
        self.failed = True

    def close(self) -> None:
        try:
            super().close()
        except OSError:  # the last buffered lines could not be written (full disk)
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


@contextmanager
def native_stderr_to(path: Path) -> Iterator[None]:
    """Send file descriptor 2 to ``path`` while Python's ``sys.stderr`` keeps the terminal.

    C libraries (HDF5, PETSc, Open MPI) print their diagnostics straight to descriptor 2 — on a
    full disk HDF5 alone prints a 60-line error stack. Inside the block these go to the run's log;
    the console log, the progress bar and the CLI's one-line messages (all through ``sys.stderr``)
    still reach the terminal. A no-op when ``sys.stderr`` is not descriptor 2 (e.g. under pytest).
    """
    try:
        is_fd2 = sys.stderr.fileno() == 2
    except (AttributeError, OSError, ValueError):
        is_fd2 = False
    if not is_fd2:
        yield
        return
    old = sys.stderr
    old.flush()
    saved = os.dup(2)
    console = os.fdopen(os.dup(saved), "w", buffering=1, encoding=old.encoding, errors="backslashreplace")
    handlers = [h for h in logging.getLogger().handlers if getattr(h, "stream", None) is old]
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
    os.dup2(fd, 2)
    os.close(fd)
    sys.stderr = console
    for h in handlers:
        h.setStream(console)
    try:
        yield
    finally:
        console.flush()
        os.dup2(saved, 2)
        os.close(saved)
        sys.stderr = old
        for h in handlers:
            h.setStream(old)
        console.close()


def run_case(case: Case, out: Path, *, force: bool = False, resume: bool = False,
             quiet: bool = False, comm: MPI.Comm = MPI.COMM_WORLD,
             native_stderr_to_log: bool = False) -> dict[str, float]:
    """Run ``case`` and write its results folder ``out``.

    With ``native_stderr_to_log`` (the CLI), what C libraries print to descriptor 2 goes to the
    run's log (:func:`native_stderr_to`), and a run stopped by a signal leaves SIGTERM ignored (the process exits
    next: :func:`~.interrupt.signals_stop_run`).

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
    SchemaError
        A conductor size left to the skin depth has no frequency to take it from, or its default exceeds
        ``[limits]`` (the CLI refuses both before: :func:`~..em.skin_depth.resolve_defaults`).
    DeckContractError
        A case that leaves its source to its template deck (:func:`~..em.deck_sources.resolve_deck_sources`,
        done before anything is written: ``out/case.toml`` holds the deck's source) and a deck that does not
        give one (the CLI refuses it before).
    """
    filled = default_sizes(case)  # conductor sizes the case leaves to the skin depth
    case = with_default_sizes(case)
    case = resolve_deck_sources(case)  # a template deck's own bank or current (the CLI has done it already)
    if resume:
        refuse_if_in_use(Path(out))  # "in use" before "nothing to resume yet"
        _check_resumable(case, Path(out))
    results = ResultsFolder(out, force=force, resume=resume) if comm.rank == 0 else None
    comm.Barrier()
    if results is None:
        results = ResultsFolder(out, resume=True, lock=False)
    try:
        with interrupt.signals_stop_run(leaving_after_stop=native_stderr_to_log), \
                native_stderr_to(results.log_file) if native_stderr_to_log and comm.rank == 0 else _nullcontext():
            return _run_in(case, results, resume=resume, quiet=quiet, comm=comm, filled=filled)
    finally:
        results.release()


def _run_in(case: Case, results: ResultsFolder, *, resume: bool, quiet: bool, comm: MPI.Comm,
            filled: list[DefaultSize] | tuple = ()) -> dict[str, float]:
    wall0 = time.perf_counter()
    with run_log(results.log_file) if comm.rank == 0 else _nullcontext():
        log.info("case %s -> %s", case.case.name, results.root)
        for d in filled:
            log.info("%s", d.text())
        try:
            if comm.rank == 0 and not resume:
                results.write_text("case.toml", case_to_toml(case))
            run = _dispatch(case, results, quiet=quiet, resume=resume, comm=comm, wall_start=wall0)
        except interrupt.StopRequested as exc:
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
            text, details = _failure_text(exc, results.root)
            raise RunFailed(f"{case.case.name}: {text} (partial results and log in {results.root})",
                            details) from exc
        metrics = run.metrics
        metrics["wall_time_s"] = run.wall_before_s + time.perf_counter() - wall0
        metrics["status_ok"] = 1.0
        _final_metrics(results, comm, {**metrics, "status": "ok"})
        log.info("done in %.2f s; metrics in %s", metrics["wall_time_s"], results.root / "metrics.json")
        if run.pictures_stopped_by is not None:
            raise PicturesInterrupted(run.pictures_stopped_by, results.root)
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
        log.debug("could not write %s: %s", results.root / "metrics.json", exc.strerror)


def _failure_text(exc: BaseException, root: Path) -> tuple[str, str]:
    """(one line saying what went wrong, the failing program's log tail or ""): a full disk, an
    out-of-memory and an external program's time limit are named plainly."""
    from pulseform.solvers.getdp import GetDPError
    from pulseform.solvers.getdp.runner import ChildFailed, TimeLimitExceeded

    at = "".join(f" {n}" for n in getattr(exc, "__notes__", ()))  # the driver notes the simulated time
    seen: BaseException | None = exc
    while seen is not None:
        if isinstance(seen, OSError) and seen.errno in DISK_FULL_ERRNOS:
            return (f"no space left to write {seen.filename or root} ({seen.strerror}){at}; what was written "
                    "before stays readable"), ""
        if isinstance(seen, MemoryError):
            return (f"out of memory{at} (the case's meshes or fields do not fit: coarsen the mesh or use a larger "
                    "machine)"), ""
        if isinstance(seen, TimeLimitExceeded):
            return f"{seen.what}{at} exceeded limits.gmsh_time_limit_s = {seen.time_limit:g} s and was stopped", ""
        if isinstance(seen, ChildFailed):
            return f"{seen}{at}", ""
        if isinstance(seen, GetDPError):
            where = f" in {seen.run_dir.name}" if seen.run_dir is not None else ""
            log = f" (log: {seen.log_path})" if seen.log_path is not None else ""
            if seen.time_limit is not None:
                return (f"the EM step{at}{where}: getdp exceeded limits.getdp_time_limit_s = {seen.time_limit:g} s "
                        f"and was stopped{log}"), ""
            return f"EM step{at}{where}: {seen.summary}{log}", seen.log_tail
        seen = seen.__cause__ or seen.__context__
    text = " ".join(str(exc).split()) or type(exc).__name__
    if "No space left on device" in text or "Disk quota exceeded" in text or _nearly_full(root):
        # libraries (HDF5 through DOLFINx) report a failed write without its errno
        return (f"no space left to write {root} ({text}){at}; what was written before stays readable"), ""
    return text + at, ""


def _nearly_full(folder: Path, margin: int = 1 << 20) -> bool:
    """Less than ``margin`` bytes (1 MiB) free on the file system of ``folder``."""
    try:
        return shutil.disk_usage(folder).free < margin
    except OSError:
        return False


def _check_resumable(case: Case, out: Path) -> None:
    stored = out / "case.toml"
    if not stored.is_file():
        raise ResumeError(f"{out}: nothing to resume (no case.toml from an earlier run)")
    if not any(out.glob("checkpoint*.npz")):
        raise ResumeError(f"{out}: nothing to resume (no checkpoint written yet)")
    if stored.read_text() != case_to_toml(case):
        raise ResumeError(f"{stored}: the case differs from the one this folder was run with; "
                          "resume needs the same case and --set overrides")


def _dispatch(case: Case, results: ResultsFolder, *, quiet: bool, resume: bool, comm: MPI.Comm,
              wall_start: float | None = None):
    # gmsh meshes the EM setup in a child process while this one imports DOLFINx (the other core)
    em_geometry = _early_em_geometry(case, comm)
    from .driver import run_case_loop

    log.debug("driver imported")  # bench/sweep_split.py: DOLFINx's import (none in a warm member) ends here

    # the 3D renderer starts now: its imports and graphics start-up (~1 s) overlap the run
    fields = any(not b.rigid for b in case.bodies)  # rigid bodies write no field files to render
    renderer = _early_renderer() if case.output.plots and comm.rank == 0 and fields else None
    try:
        run = run_case_loop(case, results, quiet=quiet, resume=resume, comm=comm, em_geometry=em_geometry,
                            wall_start=wall_start)
        interrupt.check()  # a signal after the last step still ends with an honest status
        if case.output.plots and comm.rank == 0:
            from .plots import draw_all

            # the pictures `pulseform plot` draws from the folder, from what the run holds in memory; a stop
            # signal now ends the drawing (the results are complete): PicturesInterrupted after the metrics
            drawn = draw_all(results.root, case=case, history=run.history, shapes=run.shapes,
                             analyses=run.analyses, stop=lambda: interrupt.pending() is not None,
                             renderer=renderer)
    finally:
        if renderer is not None:
            renderer.close()
        if em_geometry is not None:
            em_geometry.cancel()  # a run that failed before it took the mesh
    if case.output.plots and comm.rank == 0:
        log.info("%d pictures in %s", len(drawn.paths), results.plots)
        if drawn.stopped:
            log.info("pictures stopped by %s; the results are complete", signal.Signals(interrupt.pending()).name)
            run.pictures_stopped_by = interrupt.pending()
    return run


def _early_em_geometry(case: Case, comm: MPI.Comm):
    """The EM mesh of a coupled case on a built-in geometry, started now in a child process
    (``mesh.em_geometry.start_em_geometry``); None for other cases (and under MPI: coupled runs
    are serial and say so)."""
    if case.case.kind != "coupled" or case.mechanics.formulation == "3d" or case.geometry.type == "user_deck" \
            or comm.size > 1:  # a 3D case (a sector, a racetrack) meshes its own
        return None
    from ..mesh.em_geometry import start_em_geometry

    return start_em_geometry(case.geometry, time_limit=case.limits.gmsh_time_limit_s)


def _early_renderer():
    """A ``pictures_mech.Renderer`` started now, or None when the 3D pictures cannot be drawn here
    (the module or a child process unavailable: the pictures then report it as before)."""
    try:
        from .pictures_child import Renderer

        return Renderer()
    except (ImportError, OSError) as exc:
        log.debug("no early 3D renderer: %s", exc)
        return None


@contextmanager
def _nullcontext() -> Iterator[None]:
    yield
