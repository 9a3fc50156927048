"""Where a study's members run: one small seam, established engines behind it (no scheduler of our own).

Every backend runs :func:`.sweep.run_member` for each member (a ``pulseform run`` process of its own, so a
failing or crashing member fails alone) and calls ``on_done(member)`` with the filled-in member as each one
ends, in the study's process (the study records it at once: an interrupted study keeps every member that
ended). ``on_start(member)`` is called where the backend knows a member starts.

- ``local`` (:class:`LocalExecutor`): ``jobs`` members at a time on this machine, forked from the study's warm
  process (:mod:`..run.warm`); a stop signal starts no further member and stops the running ones at a
  checkpoint.
- ``mpi`` (:class:`MPIExecutor`): ``mpi4py.futures.MPICommExecutor`` under ``mpirun -n N``: rank 0 manages,
  ranks 1..N-1 (on any node of the allocation) each start their member's process.
- ``dask`` (:class:`DaskExecutor`): ``dask.distributed``: a ``LocalCluster`` of ``jobs`` single-threaded worker
  processes, or the scheduler of a running cluster (``address``: ``tcp://host:8786`` or a scheduler file, e.g.
  one started by ``dask-jobqueue``'s ``SLURMCluster`` or ``dask scheduler --scheduler-file`` in a batch job).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Callable, Protocol

from ..run import interrupt
from ..run.interrupt import StudyInterrupted
from ..run.warm import import_in_background, run_all, warm_pool

log = logging.getLogger(__name__)

__all__ = ["Executor", "LocalExecutor", "MPIExecutor", "DaskExecutor", "make_executor", "EXECUTORS",
           "ExecutorError"]

EXECUTORS = ("local", "mpi", "dask")

Callback = Callable[[object], None]


class ExecutorError(ValueError):
    """A backend that cannot be used here (one line: what is missing and how to get it)."""


class Executor(Protocol):
    """Runs a study's members (see the module docstring)."""

    name: str

    def run(self, case: str, members: list, sets: list[str], on_done: Callback, on_start: Callback) -> None:
        """Run ``members`` of ``case`` (each with the study's ``sets`` first); ``on_done`` as each ends."""


class LocalExecutor:
    """``jobs`` members at a time, forked from the study's warm process in ``folder`` (its ``warm.log``)."""

    name = "local"

    def __init__(self, jobs: int = 1, folder: Path | None = None) -> None:
        self.jobs, self.folder = jobs, folder

    def run(self, case: str, members: list, sets: list[str], on_done: Callback, on_start: Callback) -> None:
        from .sweep import run_member

        with warm_pool(self.folder) as pool:
            figures = import_in_background("matplotlib.pyplot", after=pool)  # for the study's figures at the end

            def one(m):
                on_start(m)
                on_done(run_member(case, m, sets, pool))

            run_all(one, members, self.jobs, pool)
        figures.join()  # matplotlib.use on a half-imported pyplot fails


class MPIExecutor:
    """Members through ``mpi4py.futures`` (rank 0's side; the other ranks run :func:`serve_mpi_workers`).
    (``MPIPoolExecutor``'s dynamic spawning is not used: Open MPI 4.1 singletons here fail MPI_Comm_spawn.)"""

    name = "mpi"

    def run(self, case: str, members: list, sets: list[str], on_done: Callback, on_start: Callback) -> None:
        from mpi4py import MPI
        from mpi4py.futures import MPICommExecutor

        from .sweep import run_member

        world = MPI.COMM_WORLD.Get_size()
        if world < 2:
            raise ExecutorError("--executor mpi needs mpirun with at least 2 ranks")
        log.info("study through mpi4py.futures: %d worker ranks", world - 1)
        with MPICommExecutor(MPI.COMM_WORLD, root=0) as pool:
            futures = {pool.submit(run_member, case, m, sets): m for m in members}
            _drain(futures, on_done, on_start, slots=world - 1, cancel=lambda fs: [f.cancel() for f in fs])


def serve_mpi_workers() -> None:
    """Ranks > 0 of ``mpirun -n N pulseform sweep ... --executor mpi``: run members sent by rank 0 until it is done."""
    from mpi4py import MPI
    from mpi4py.futures import MPICommExecutor

    with MPICommExecutor(MPI.COMM_WORLD, root=0) as pool:
        if pool is not None:  # only the root gets an executor
            raise RuntimeError("serve_mpi_workers called on rank 0")


class DaskExecutor:
    """Members as ``dask.distributed`` tasks: on a ``LocalCluster`` of ``jobs`` worker processes (one thread each),
    or on the cluster whose scheduler is ``address`` (``tcp://...`` or a scheduler file's path)."""

    name = "dask"

    def __init__(self, jobs: int = 1, address: str | None = None) -> None:
        try:
            import distributed  # noqa: F401
        except ImportError:
            raise ExecutorError("--executor dask: dask.distributed is not installed (Debian: apt-get install "
                                "python3-dask python3-distributed; pip: pip install 'dask[distributed]')") from None
        self.jobs, self.address = jobs, address

    def run(self, case: str, members: list, sets: list[str], on_done: Callback, on_start: Callback) -> None:
        from distributed import Client, LocalCluster

        from .sweep import run_member

        cluster = None
        if self.address is None:
            cluster = LocalCluster(n_workers=self.jobs, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.WARNING)
            client = Client(cluster)
        elif Path(self.address).is_file():
            client = Client(scheduler_file=self.address)
        else:
            client = Client(self.address)
        try:
            slots = max(1, sum(client.nthreads().values()))
            log.info("study through dask.distributed: %d worker threads (%s)", slots,
                     "LocalCluster" if cluster is not None else self.address)
            futures = {client.submit(run_member, case, m, sets, pure=False, key=f"member-{m.index}-{m.digest[:12]}"): m
                       for m in members}
            _drain(futures, on_done, on_start, slots=slots, cancel=client.cancel)
        finally:  # closing a LocalCluster ends its workers; their members get SIGTERM and stop at a checkpoint
            client.close()
            if cluster is not None:
                cluster.close()


def _drain(futures: dict, on_done: Callback, on_start: Callback, slots: int, cancel: Callable) -> None:
    """Wait for ``futures`` (future -> member), calling ``on_done`` as each ends; a stop signal cancels the members
    not started (the running ones end as their backend ends them) and raises :class:`StudyInterrupted`."""
    todo = dict(futures)
    for m in list(todo.values())[:slots]:
        on_start(m)
    queued = list(todo.values())[slots:]
    with interrupt.signals_stop_run():
        while todo:
            finished = [f for f in todo if f.done()]
            for f in finished:
                m = todo.pop(f)
                if not f.cancelled():
                    on_done(f.result())  # an error of run_member itself (not of a member) is the study's
                if queued:
                    on_start(queued.pop(0))
            if interrupt.pending() is not None:
                cancel(list(todo))
                signum = interrupt.pending()
                raise StudyInterrupted(signum, f"interrupted by {_name(signum)}: the members not started were "
                                       "cancelled")
            if not finished:
                time.sleep(0.1)


def _name(signum: int) -> str:
    import signal

    return signal.Signals(signum).name


def make_executor(name: str, jobs: int = 1, folder: Path | None = None, address: str | None = None) -> Executor:
    """The backend ``name`` (:data:`EXECUTORS`); :class:`ExecutorError` if it cannot be used."""
    if name == "local":
        return LocalExecutor(jobs, folder)
    if name == "mpi":
        return MPIExecutor()
    if name == "dask":
        return DaskExecutor(jobs, address)
    raise ExecutorError(f"--executor {name}: allowed: {', '.join(EXECUTORS)}")
