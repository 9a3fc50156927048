"""Parameter sweeps: a full grid of ``--set`` overrides, each member a ``pulseform run`` of its own.

Members run in processes forked from the study's warm process (:mod:`..run.warm`: the libraries
imported once; each member its own process, ended when the sweep dies), ``jobs`` at a time, so a crash
or a bad value fails that member alone; without their own pictures (``output.plots = false`` unless
the sweep's ``--set`` says otherwise). The table ``sweep.csv`` holds the parameters, the status and
every metric; ``plots/`` shows the main metrics against each numeric parameter.
"""

from __future__ import annotations

import itertools
import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..case.io import CaseError, load_case, parse_override
from ..run.children import member_env, run_pulseform
from ..run.results import ResultsFolder, read_metrics, write_csv
from ..run.units import label
from ..run.warm import (StudyInterrupted, WarmPool, failure_report, import_in_background, member_run_argv, run_all,
                        warm_pool)

log = logging.getLogger(__name__)

# what the plots show against each swept parameter, in this order, where the members report it: the
# coupled results, the contact results of a mechanics case (2D or 3D), each body's peak von Mises
# stress (any metric ending so), then the costs
MAIN_METRICS = ("max_deflection_mm", "force_impulse_Ns", "contact_stress_plateau_MPa", "contact_duration_ms",
                "em_time_s", "mech_time_s", "wall_time_s")
MAIN_SUFFIXES = ("_max_von_mises_MPa",)


@dataclass
class Member:
    """One run of the sweep."""

    index: int
    values: dict[str, str]
    out: Path
    returncode: int | None = None
    error: str = ""
    metrics: dict[str, float] = field(default_factory=dict)
    worker: str = ""
    log_tail: str = ""  # a failed member's last lines (its standard error, else its run.log)

    @property
    def overrides(self) -> list[str]:
        """The member's ``--set`` strings."""
        return [f"{k}={v}" for k, v in self.values.items()]


def parse_params(params: list[str]) -> dict[str, list[str]]:
    """``key=v1,v2,...`` strings -> {key: [v1, v2, ...]} (values stay TOML literals).

    Commas inside brackets belong to the value (``bodies.left.initial_velocity=[1,0],[2,0]``).
    """
    grid: dict[str, list[str]] = {}
    for text in params:
        if "=" not in text:
            raise CaseError(f"--param {text}", text, "expected key.path=v1,v2,...")
        key, raw = text.split("=", 1)
        values = [v.strip() for v in _split_top_level(raw) if v.strip()]
        if not values:
            raise CaseError(f"--param {text}", key, "no values after '='")
        if key in grid:
            raise CaseError(f"--param {text}", key, "the same key is swept twice")
        grid[key.strip()] = values
    return grid


def _split_top_level(raw: str) -> list[str]:
    parts, depth, cur = [], 0, ""
    for ch in raw:
        depth += ch in "[{"
        depth -= ch in "]}"
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    return parts


def members(grid: dict[str, list[str]], root: Path) -> list[Member]:
    """Every combination of the grid, each with its own results folder."""
    keys = list(grid)
    out = []
    for i, combo in enumerate(itertools.product(*(grid[k] for k in keys))):
        values = dict(zip(keys, combo))
        label = "_".join(f"{k.split('.')[-1]}-{_slug(v)}" for k, v in values.items())
        out.append(Member(i, values, root / f"{i:03d}_{label}"[:120]))
    return out


def _slug(v: str) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "", v) or "x"


def _worker_id() -> str:
    import os
    import socket

    return f"{socket.gethostname()}:{os.getpid()}"


def run_member(case: str, member: Member, sets: list[str], pool: WarmPool | None = None) -> Member:
    """Run one member (``pulseform run``, :func:`..run.warm.member_run_argv`: the study's ``sets``, then the
    member's own) in a child of the warm process ``pool``, or as a process of its own; fill in status and metrics."""
    argv = member_run_argv(case, member.out, [*sets, *member.overrides])
    r = pool.run(argv) if pool is not None else run_pulseform(argv, env=member_env())
    member.returncode = r.returncode
    member.worker = _worker_id()
    if r.returncode != 0:
        member.error, member.log_tail = failure_report(r, member.out)
        log.warning("member %d (%s) failed: %s%s", member.index, " ".join(member.overrides), member.error,
                    "".join(f"\n  {ln}" for ln in member.log_tail.splitlines()))
    metrics_file = member.out / "metrics.json"
    if metrics_file.is_file():
        member.metrics = read_metrics(metrics_file)
    return member


def run_sweep(case: str, params: list[str], out: Path, *, jobs: int = 1, force: bool = False,
              overrides: list[str] | None = None, mpi: bool = False) -> list[Member]:
    """Run the full grid of ``params`` on ``case`` into ``out``; returns the members with results.

    Every member's overrides are validated first (a bad value makes that member fail alone with
    the validation message). With ``mpi`` (under ``mpirun -n N pulseform sweep ... --mpi``), members
    go to an ``mpi4py.futures.MPICommExecutor``: its N - 1 worker ranks, on any node of the
    allocation, each start the member's ``pulseform run`` process.
    """
    grid = parse_params(params)
    for key, values in grid.items():
        parse_override(f"{key}={values[0]}")
    results = ResultsFolder(out, force=force)
    todo = members(grid, results.root)
    sets = list(overrides or [])
    try:
        if mpi:
            _run_mpi(case, _runnable(case, todo, sets), sets)
        else:
            with warm_pool(results.root) as pool:  # its imports overlap the members' checks
                figures = import_in_background("matplotlib.pyplot", after=pool)  # for the study's figures at the end
                run_all(lambda m: run_member(case, m, sets, pool), _runnable(case, todo, sets), jobs, pool)
            figures.join()
        write_table(todo, grid, results.root / "sweep.csv")
        plot_sweep(todo, grid, results.plots)
    except StudyInterrupted as exc:
        write_table(todo, grid, results.root / "sweep.csv")  # a stopped sweep: what its members reached
        raise StudyInterrupted(exc.signum, f"sweep {exc}; table: {results.root / 'sweep.csv'}") from None
    except KeyboardInterrupt:
        write_table(todo, grid, results.root / "sweep.csv")
        raise
    finally:
        results.release()
    return todo


def _runnable(case: str, todo: list[Member], sets: list[str]) -> list[Member]:
    """The members whose case loads; the others fail here with the validation's message (exit code 2)."""
    runnable = []
    for m in todo:
        try:
            load_case(case, sets + m.overrides)
            runnable.append(m)
        except CaseError as exc:
            m.returncode, m.error = 2, str(exc)
            log.warning("sweep member %d rejected: %s", m.index, exc)
    return runnable


def _run_mpi(case: str, runnable: list[Member], sets: list[str]) -> None:
    """Members through ``mpi4py.futures``: rank 0's side of an ``MPICommExecutor`` whose other ranks
    run :func:`serve_mpi_workers` (``mpirun -n N pulseform sweep ... --mpi``, N >= 2). Each worker
    returns its filled-in member. (``MPIPoolExecutor``'s dynamic spawning is not used: Open MPI 4.1
    singletons here fail MPI_Comm_spawn.)"""
    from mpi4py import MPI
    from mpi4py.futures import MPICommExecutor

    world = MPI.COMM_WORLD.Get_size()
    if world < 2:
        raise ValueError("sweep --mpi needs mpirun with at least 2 ranks")
    log.info("sweep through mpi4py.futures: %d worker ranks", world - 1)
    with MPICommExecutor(MPI.COMM_WORLD, root=0) as pool:
        done = list(pool.map(run_member, [case] * len(runnable), runnable, [sets] * len(runnable)))
    for m, d in zip(runnable, done):
        m.returncode, m.error, m.metrics, m.worker, m.log_tail = d.returncode, d.error, d.metrics, d.worker, d.log_tail


def serve_mpi_workers() -> None:
    """Ranks > 0 of ``mpirun -n N pulseform sweep ... --mpi``: run members sent by rank 0 until it is done."""
    from mpi4py import MPI
    from mpi4py.futures import MPICommExecutor

    with MPICommExecutor(MPI.COMM_WORLD, root=0) as pool:
        assert pool is None  # only the root gets an executor


def write_table(todo: list[Member], grid: dict[str, list[str]], path: Path) -> None:
    """``sweep.csv``: parameters, exit code, error, then every metric any member reported."""
    keys = sorted({k for m in todo for k in m.metrics})
    header = list(grid) + ["returncode", "error", "worker"] + keys
    rows = [[m.values[k] for k in grid] + [m.returncode, m.error, m.worker] + [m.metrics.get(k, "") for k in keys]
            for m in todo]
    write_csv(path, header, rows)


def main_metrics(members: list[Member]) -> list[str]:
    """The metrics the sweep plots show, in :data:`MAIN_METRICS` order with each body's
    ``*_max_von_mises_MPa`` after the contact results, those the members report."""
    seen = {k for m in members for k in m.metrics}
    by_suffix = sorted(k for k in seen if k.endswith(MAIN_SUFFIXES))
    names = [k for k in MAIN_METRICS[:4] if k in seen] + by_suffix + [k for k in MAIN_METRICS[4:] if k in seen]
    return names


def plot_sweep(todo: list[Member], grid: dict[str, list[str]], folder: Path) -> None:
    """Main metrics against each numeric swept parameter (successful members only)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [m for m in todo if m.returncode == 0]
    for key in grid:
        try:
            xs = [float(m.values[key]) for m in ok]
        except ValueError:
            continue
        shown = main_metrics(ok)
        if not xs or not shown:
            continue
        fig, axes = plt.subplots(len(shown), 1, figsize=(6, 2.2 * len(shown)), sharex=True, squeeze=False)
        for ax, metric in zip(axes[:, 0], shown):
            pts = sorted((x, m.metrics[metric]) for x, m in zip(xs, ok) if metric in m.metrics)
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-")
            ax.set_ylabel(label(metric), fontsize=8)
            ax.grid(alpha=0.3)
        axes[-1, 0].set_xlabel(key)
        fig.tight_layout()
        fig.savefig(folder / f"sweep_{key.replace('.', '_')}.png", dpi=110)
        plt.close(fig)
