"""Studies: a full grid or a sampled design of ``--set`` overrides, each member a ``pulseform run`` of its own.

The design (:mod:`.designs`): the full grid of ``--param key=v1,v2,...`` lists, or ``--sample N`` points of a
Latin hypercube or Sobol sequence over ``--param key=lo:hi`` ranges. Each member's folder is named by the hash of
its resolved case (:mod:`.study_store`), so a study that was interrupted, repeated or extended runs only the members
it lacks (``resume``; failed ones again only with ``retry_failed``). The members run through one backend
(:mod:`.executors`: local processes forked from the study's warm process, ``mpi4py.futures`` or
``dask.distributed``), each in its own process, so a crash or a bad value fails that member alone; without their
own pictures (``output.plots = false`` unless the study's ``--set`` says otherwise). Progress across the study:
:class:`..run.progress.StudyProgress`.

Written: ``design.json`` (at the start), each member's ``member.json`` (as it ends), the table ``sweep.csv``
(parameters, status, folder, every metric; rebuilt from the member folders), ``study.json`` and ``report.md`` (the
answer, :mod:`.study_answer`) and ``plots/`` (each main metric against each numeric parameter, and
:mod:`.study_plots`).
"""

from __future__ import annotations

import hashlib
import json
import logging
import threading
from dataclasses import dataclass, field
from pathlib import Path

from ..case.io import CaseError, resolve_case_file
from ..run.children import member_env, run_pulseform
from ..run.progress import StudyProgress
from ..run.results import ResultsFolder, atomic_write_text
from ..run.units import label
from ..run.warm import StudyInterrupted, WarmPool, failure_report, member_run_argv
from . import study_store as store
from .designs import Param, design_points, parse_params
from .executors import make_executor, serve_mpi_workers  # noqa: F401 - serve_mpi_workers: the CLI's MPI workers

log = logging.getLogger(__name__)

# what the plots show against each swept parameter, in this order, where the members report it: the
# coupled results, the contact results of a mechanics case (2D or 3D), each body's peak von Mises
# stress (any metric ending so), then the costs
MAIN_METRICS = ("max_deflection_mm", "force_impulse_Ns", "contact_stress_plateau_MPa", "contact_duration_ms",
                "em_time_s", "mech_time_s", "wall_time_s")
MAIN_SUFFIXES = ("_max_von_mises_MPa",)


@dataclass
class Member:
    """One run of a study."""

    index: int
    values: dict[str, str]
    out: Path
    returncode: int | None = None
    error: str = ""
    metrics: dict[str, float] = field(default_factory=dict)
    worker: str = ""
    log_tail: str = ""  # a failed member's last lines (its standard error, else its run.log)
    digest: str = ""    # the hash of its resolved case (study_store.member_hash)
    resume: bool = False  # continue its run from its checkpoint (`pulseform run --resume`)

    @property
    def overrides(self) -> list[str]:
        """The member's ``--set`` strings."""
        return [f"{k}={v}" for k, v in self.values.items()]


def _worker_id() -> str:
    import os
    import socket

    return f"{socket.gethostname()}:{os.getpid()}"


def run_member(case: str, member: Member, sets: list[str], pool: WarmPool | None = None) -> Member:
    """Run one member (``pulseform run``, :func:`..run.warm.member_run_argv`: the study's ``sets``, then the
    member's own; ``--resume`` instead of ``--force`` for a member that continues) in a child of the warm process
    ``pool``, or as a process of its own; fill in status and metrics."""
    argv = member_run_argv(case, member.out, [*sets, *member.overrides])
    if member.resume:
        argv[argv.index("--force")] = "--resume"
    r = pool.run(argv) if pool is not None else run_pulseform(argv, env=member_env())
    member.returncode = r.returncode
    member.worker = _worker_id()
    member.error = member.log_tail = ""
    if r.returncode != 0:
        member.error, member.log_tail = failure_report(r, member.out)
        log.warning("member %d (%s) failed: %s%s", member.index, " ".join(member.overrides), member.error,
                    "".join(f"\n  {ln}" for ln in member.log_tail.splitlines()))
    metrics_file = member.out / "metrics.json"
    member.metrics = {}
    if metrics_file.is_file():
        from ..run.results import read_metrics

        member.metrics = read_metrics(metrics_file)
    return member


@dataclass
class StudySpec:
    """What a study runs besides its case: the design, where, and what it answers.

    ``params`` (``--param``), ``sample``/``design``/``seed`` (:func:`.designs.design_points`), ``executor``
    (:data:`.executors.EXECUTORS`) with ``jobs`` and ``address`` (a Dask scheduler), ``resume`` / ``retry_failed``,
    ``metrics`` (the headline metrics; default: :func:`.study_answer.headline_metrics`), ``objective`` and
    ``constraints`` (:func:`.study_answer.best_member`)."""

    params: list[str]
    sample: int | None = None
    design: str = "lhs"
    seed: int = 1
    executor: str = "local"
    jobs: int = 1
    address: str | None = None
    resume: bool = False
    retry_failed: bool = False
    metrics: list[str] = field(default_factory=list)
    objective: str | None = None
    constraints: list[str] = field(default_factory=list)
    quiet: bool = False


def run_sweep(case: str, params: list[str] | StudySpec, out: Path, *, jobs: int = 1, force: bool = False,
              overrides: list[str] | None = None, mpi: bool = False) -> list[Member]:
    """Run the study of ``case`` into ``out`` (``params``: the ``--param`` strings of a local grid, or a
    :class:`StudySpec`); returns the design's members with their outcomes.

    Every member's overrides are validated first (a bad value makes that member fail alone with the validation
    message, exit code 2). Raises the loader's ``CaseError`` (bad ``--param``, ``--objective``, ...), or
    :class:`..run.results.ResultsExistError` before anything runs; :class:`StudyInterrupted` after a stop signal
    (the table then holds what the members reached; ``resume`` continues)."""
    from .study_answer import parse_constraint, parse_objective

    spec = params if isinstance(params, StudySpec) else StudySpec(list(params), executor="mpi" if mpi else "local",
                                                                 jobs=jobs)
    parsed = parse_params(spec.params)
    objective = parse_objective(spec.objective)
    constraints = [parse_constraint(c) for c in spec.constraints]
    points = design_points(parsed, spec.sample, spec.design, spec.seed)
    executor = make_executor(spec.executor, spec.jobs, address=spec.address)
    results = ResultsFolder(out, force=force and not spec.resume, resume=spec.resume)
    sets = list(overrides or [])
    where = str(resolve_case_file(case).resolve())  # members may run elsewhere (a cluster's workers): absolute paths
    todo = _members(where, points, sets, results.root.resolve())
    if hasattr(executor, "folder"):  # the local backend's warm process logs to the study's folder
        executor.folder = results.root
    store.write_design(results.root, parsed, spec.sample, spec.design, spec.seed, todo)
    keys = [p.key for p in parsed]
    try:
        runnable = _plan(todo, spec.retry_failed)
        waiting = {id(m) for m in runnable}
        left = [m for m in todo if id(m) not in waiting]
        progress = StudyProgress(len(todo), already=(sum(m.returncode == 0 for m in left),
                                                     sum(m.returncode != 0 for m in left)), quiet=spec.quiet)
        lock = threading.Lock()

        def done(m: Member) -> None:
            with lock:
                store.write_record(m)
            progress.ended(m.returncode == 0, f"member {m.index} ({m.out.name}) "
                                              f"{'ok' if m.returncode == 0 else f'FAILED({m.returncode})'}")

        try:
            if runnable:
                executor.run(where, runnable, sets, done, progress.started)
        finally:
            progress.close()
        _finish(case, todo, parsed, keys, spec, objective, constraints, results)
    except StudyInterrupted as exc:
        _table(todo, keys, results.root)  # a stopped study: what its members reached
        raise StudyInterrupted(exc.signum, f"sweep {exc}; table: {results.root / store.TABLE}; `--resume` "
                               "continues") from None
    except KeyboardInterrupt:
        _table(todo, keys, results.root)
        raise
    finally:
        results.release()
    return todo


def _members(case: str, points: list[dict[str, str]], sets: list[str], root: Path) -> list[Member]:
    """The design's members, each with its hash and folder; a member whose case does not load fails here with
    the validation's message (exit code 2; no folder)."""
    out = []
    case_bytes = resolve_case_file(case).read_bytes()
    for i, values in enumerate(points):
        m = Member(i, values, root)
        try:
            m.digest = store.member_hash(case, [*sets, *m.overrides])
        except CaseError as exc:
            m.returncode, m.error = 2, str(exc)
            m.digest = hashlib.sha256(case_bytes + json.dumps(values).encode()).hexdigest()
            log.warning("sweep member %d rejected: %s", m.index, exc)
        m.out = root / store.folder_name(values, m.digest)
        out.append(m)
    return out


def _plan(todo: list[Member], retry_failed: bool) -> list[Member]:
    """The members to run now: those without a successful record (a failed one only with ``retry_failed``); a
    stopped one continues from its checkpoint."""
    runnable = []
    for m in todo:
        if m.returncode == 2 and not m.out.exists():  # rejected by validation just now
            continue
        state = store.member_state(m)
        if state == "done" or (state == "failed" and not retry_failed):
            continue
        m.resume = state == "stopped"
        if not m.resume:
            store.clear_lone_record(m)
        if state != "new" or m.returncode is not None:
            log.info("member %d (%s): %s", m.index, m.out.name,
                     "continues from its checkpoint" if m.resume else "runs again (it failed)")
        runnable.append(m)
    skipped = len(todo) - len(runnable)
    if skipped:
        log.info("%d of %d members need not run (done%s)", skipped, len(todo),
                 ", failed or rejected" if not retry_failed else " or rejected")
    return runnable


def _table(todo: list[Member], keys: list[str], root: Path) -> None:
    store.write_table(store.collect(todo), keys, root / store.TABLE)


def _finish(case: str, todo: list[Member], parsed: list[Param], keys: list[str], spec: StudySpec, objective,
            constraints, results: ResultsFolder) -> None:
    """The table, ``study.json``, ``report.md`` and the pictures, from the member folders."""
    from .study_answer import analyse, json_ready, report_markdown
    from .study_plots import plot_study

    _table(todo, keys, results.root)
    answer = analyse(todo, parsed, spec.metrics or None, objective, constraints)
    design = json.loads((results.root / store.DESIGN).read_text())
    design.pop("members")
    study = {"case": str(case), "design": design, "executor": spec.executor,
             "members": [{"index": m.index, "folder": m.out.name, "values": m.values, "returncode": m.returncode,
                          "error": m.error, "metrics": m.metrics} for m in todo],
             "answer": answer}
    atomic_write_text(results.root / "study.json", json.dumps(json_ready(study), indent=1) + "\n")
    atomic_write_text(results.root / "report.md", report_markdown(study, str(case)))
    plot_sweep(todo, {k: [] for k in keys}, results.plots, lines=spec.sample is None)
    plot_study(todo, answer, results.plots, focus=objective[1] if objective else None)


def main_metrics(members: list[Member]) -> list[str]:
    """The metrics the sweep plots show, in :data:`MAIN_METRICS` order with each body's
    ``*_max_von_mises_MPa`` after the contact results, those the members report."""
    seen = {k for m in members for k in m.metrics}
    by_suffix = sorted(k for k in seen if k.endswith(MAIN_SUFFIXES))
    names = [k for k in MAIN_METRICS[:4] if k in seen] + by_suffix + [k for k in MAIN_METRICS[4:] if k in seen]
    return names


def plot_sweep(todo: list[Member], grid: dict[str, list[str]], folder: Path, lines: bool = True) -> None:
    """Main metrics against each numeric swept parameter (successful members only; joined by ``lines``: a grid's)."""
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
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-" if lines else "o", ms=4)
            ax.set_ylabel(label(metric), fontsize=8)
            ax.grid(alpha=0.3)
        axes[-1, 0].set_xlabel(key)
        fig.tight_layout()
        fig.savefig(folder / f"sweep_{key.replace('.', '_')}.png", dpi=110)
        plt.close(fig)
