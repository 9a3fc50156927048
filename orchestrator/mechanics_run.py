"""Run a mechanics-only case: explicit dynamics with contact and pressure pulses, to a results folder.

The run stops at output milestones (every ``output.field_interval``): there it writes fields,
flushes ``history.csv`` and a checkpoint, so ``pulseform run --resume`` continues from the last
milestone to the same result as an uninterrupted run.
"""

from __future__ import annotations

import logging
import time as _time
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from pulseform.solvers import dolfinx as mech

from . import probes as probe_mod
from .case import Case
from .checkpoint import CHECKPOINT_NAME, load_checkpoint, save_checkpoint
from .history import History
from .loads import box_marker, pulse_pressure
from .mech_model import build_solver
from .progress import Progress
from .results import ResultsFolder

log = logging.getLogger(__name__)


class NothingToResume(FileNotFoundError):
    """``--resume`` was asked for but the results folder has no checkpoint."""


@dataclass
class MechanicsRun:
    """What a finished mechanics run hands back to the runner."""

    solver: object
    history: History
    metrics: dict[str, float] = field(default_factory=dict)


def milestones(end: float, interval: float) -> np.ndarray:
    """Output times interval, 2·interval, ... up to and including ``end`` (s)."""
    n = max(1, int(np.floor(end / interval + 1e-9)))
    times = interval * np.arange(1, n + 1)
    if end - times[-1] > 1e-12 * end:
        times = np.append(times, end)
    times[-1] = min(times[-1], end)
    return times


def next_step(stable_dt: float, dt_max: float | None, remaining: float) -> float:
    """The step (s): stable step capped by ``dt_max``, landing exactly on the next milestone.

    A step that would leave a sliver shorter than half a step before the milestone is split into
    two equal steps instead.
    """
    dt = stable_dt if dt_max is None else min(stable_dt, dt_max)
    if dt >= remaining * (1.0 - 1e-9):
        return remaining
    if dt > 0.5 * remaining:
        return 0.5 * remaining
    return dt


def external_forces(solver, case: Case, t: float) -> dict[str, np.ndarray] | None:
    """Nodal forces (N) of every active pressure pulse at time ``t`` (s), summed per body."""
    forces: dict[str, np.ndarray] = {}
    for ld in case.loads:
        p = pulse_pressure(ld, t)
        if p == 0.0:
            continue
        f = solver.pressure_nodal_forces(ld.body, box_marker(ld.surface), p)
        forces[ld.body] = forces[ld.body] + f if ld.body in forces else f
    return forces or None


class MechanicsDriver:
    """Time loop of a mechanics-only case writing into ``results``."""

    def __init__(self, case: Case, results: ResultsFolder, comm: MPI.Comm) -> None:
        self.case, self.results, self.comm = case, results, comm
        t0 = _time.perf_counter()
        self.solver = build_solver(case, comm)
        self.setup_s = _time.perf_counter() - t0
        self.probes = probe_mod.attach(self.solver, case.probes, comm)
        self.history = History(results.root / "history.csv")
        self.loop_s = 0.0
        self.part = 0
        self.last_dt = 0.0
        interval = case.output.field_interval or case.time.end / 20.0
        self.stops = milestones(case.time.end, interval)

    # ----------------------------------------------------------------- records
    def record(self) -> None:
        """Append the current state to the history."""
        s = self.solver
        row = {"time_s": s.time, "step": float(s.step_count), "dt_s": self.last_dt}
        row.update({f"energy_{k}": float(v) for k, v in s.energies().items()})
        row.update(probe_mod.sample(s, self.probes, self.comm))
        self.history.record(row)

    def checkpoint(self) -> None:
        """Write history and checkpoint (rank 0 writes; all ranks' states are gathered per rank file)."""
        arrays = {f"solver/{k}": v for k, v in self.solver.state_dict().items()}
        arrays["history/rows"] = np.array(self.history.rows)
        meta = {"columns": self.history.columns, "part": self.part, "loop_s": self.loop_s,
                "last_dt": self.last_dt, "ranks": self.comm.size}
        name = CHECKPOINT_NAME if self.comm.size == 1 else f"checkpoint.rank{self.comm.rank}.npz"
        save_checkpoint(self.results.root / name, arrays, meta)
        if self.comm.rank == 0:
            self.history.flush()

    def restore(self) -> None:
        """Continue from the checkpoint in the results folder."""
        name = CHECKPOINT_NAME if self.comm.size == 1 else f"checkpoint.rank{self.comm.rank}.npz"
        path = self.results.root / name
        if not path.is_file():
            raise NothingToResume(f"{self.results.root}: no {name} to resume from")
        arrays, meta = load_checkpoint(path)
        if meta["ranks"] != self.comm.size:
            raise NothingToResume(f"{path}: written by {meta['ranks']} ranks, resuming on {self.comm.size}")
        self.solver.load_state_dict({k[7:]: v for k, v in arrays.items() if k.startswith("solver/")})
        self.history.columns = list(meta["columns"])
        self.history.rows = [list(r) for r in arrays["history/rows"]]
        self.part = int(meta["part"]) + 1
        self.loop_s = float(meta["loop_s"])
        self.last_dt = float(meta["last_dt"])
        log.info("resumed at t = %.6g s, step %d (part %d)", self.solver.time, self.solver.step_count,
                 self.part)

    # ----------------------------------------------------------------- loop
    def run(self, quiet: bool) -> MechanicsRun:
        """Integrate to ``time.end``; fields, history and checkpoint at every milestone."""
        s, case = self.solver, self.case
        prefix = self.results.fields / (case.case.name + (f"_part{self.part}" if self.part else ""))
        writer = mech.FieldWriter(s, str(prefix))
        if not self.history.rows:
            self.record()
        writer.write(s.time)
        try:
            with Progress(case.time.end, quiet=quiet or self.comm.rank != 0, desc=case.case.name) as bar:
                bar.update_to(s.time)
                for stop in self.stops:
                    if s.time >= stop * (1.0 - 1e-12):
                        continue
                    t0 = _time.perf_counter()
                    while s.time < stop * (1.0 - 1e-12):
                        dt = next_step(s.stable_time_step(), case.time.dt_max, stop - s.time)
                        s.advance(dt, 1, external_forces(s, case, s.time))
                        self.last_dt = dt
                        if s.step_count % case.output.history_every == 0:
                            self.record()
                        bar.update_to(s.time)
                    self.loop_s += _time.perf_counter() - t0
                    if self.history.rows[-1][0] != s.time:
                        self.record()
                    writer.write(s.time)
                    self.checkpoint()
        except Exception:
            if self.comm.rank == 0:
                self.history.flush()  # keep what was computed up to the failure
            raise
        finally:
            writer.close()
        log.info("mechanics: %d steps to t = %.4g s in %.2f s", s.step_count, s.time, self.loop_s)
        metrics = {"mech_steps": float(s.step_count), "end_time_s": float(s.time),
                   "setup_time_s": self.setup_s, "mech_time_s": self.loop_s}
        metrics.update(mech_metrics(s, case, self.history))
        return MechanicsRun(s, self.history, metrics)


def run_mechanics(case: Case, results: ResultsFolder, *, quiet: bool = False, resume: bool = False,
                  comm: MPI.Comm = MPI.COMM_WORLD) -> MechanicsRun:
    """Integrate ``case`` to ``time.end`` and write history, fields and checkpoints into ``results``."""
    driver = MechanicsDriver(case, results, comm)
    if resume:
        driver.restore()
    return driver.run(quiet)


def mech_metrics(solver, case: Case, history: History) -> dict[str, float]:
    """Scalars every mechanics run reports: energy balance, peak stresses, contact figures."""
    e = solver.energies()
    ke0 = history.column("energy_kinetic_J")[0]
    scale = max(ke0, abs(e.get("external_work_J", 0.0)), 1e-300)
    out = {
        "energy_error_rel": abs(e["balance_error_J"]) / scale,
        "kinetic_energy_final_J": e["kinetic_J"],
        "plastic_work_J": e["plastic_J"],
    }
    local = max((float(np.max(b.von_mises)) for b in solver.bodies.values() if len(b.von_mises)), default=0.0)
    out["von_mises_final_max_MPa"] = solver.comm.allreduce(local, op=MPI.MAX) / 1e6
    for p in case.probes:
        if p.quantity == "contact_pressure":
            t = history.column("time_s")
            s = history.column(f"{p.name}_contact_pressure_Pa")
            out.update(mech.contact_stress_metrics(t, s))
            break
    return out
