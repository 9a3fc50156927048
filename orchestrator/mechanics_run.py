"""Drive a case through the staggered loop into a results folder.

A mechanics case is the loop with the pressure-pulse load provider and n = 1; the coupled cases
plug the GetDP load in through the same path. The run stops at output milestones (every
``output.field_interval``): there it writes fields, flushes ``history.csv`` and a checkpoint, so
``pulseform run --resume`` continues from the last milestone to the same result.
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
from .loop import StaggeredLoop
from .mech_model import build_solver
from .mech_participants import DolfinxMechanics, PressurePulses
from .progress import Progress
from .results import ResultsFolder

log = logging.getLogger(__name__)


class NothingToResume(FileNotFoundError):
    """``--resume`` was asked for but the results folder has no usable checkpoint."""


@dataclass
class MechanicsRun:
    """What a finished run hands back to the runner."""

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


class CaseDriver:
    """Participants, loop, history, fields and checkpoints of one case."""

    def __init__(self, case: Case, results: ResultsFolder, comm: MPI.Comm) -> None:
        self.case, self.results, self.comm = case, results, comm
        t0 = _time.perf_counter()
        self.solver = build_solver(case, comm)
        self.setup_s = _time.perf_counter() - t0
        self.mechanics = DolfinxMechanics(self.solver)
        self.loop = StaggeredLoop(PressurePulses(case.loads), self.mechanics, n=1, dt_max=case.time.dt_max)
        self.probes = probe_mod.attach(self.solver, case.probes, comm)
        self.history = History(results.root / "history.csv")
        self.part = 0
        self._since_record = 0
        interval = case.output.field_interval or case.time.end / 20.0
        self.stops = milestones(case.time.end, interval)

    # ----------------------------------------------------------------- records
    def record(self, step_row: dict[str, float] | None = None) -> None:
        """Append the current state to the history."""
        s = self.solver
        row = {"time_s": s.time, "step": float(s.step_count),
               "dt_s": step_row["dt_s"] if step_row else 0.0}
        row.update({f"energy_{k}": float(v) for k, v in s.energies().items()})
        row.update(probe_mod.sample(s, self.probes, self.comm))
        if self.case.loads:
            for i in range(len(self.case.loads)):
                row[f"load{i}_pressure_Pa"] = step_row.get(f"load{i}_pressure_Pa", 0.0) if step_row else 0.0
        self.history.record(row)

    def _on_em_step(self, row: dict[str, float]) -> None:
        self._since_record += 1
        if self._since_record >= self.case.output.history_every:
            self._since_record = 0
            self.record(row)

    def _rank_file(self) -> str:
        return CHECKPOINT_NAME if self.comm.size == 1 else f"checkpoint.rank{self.comm.rank}.npz"

    def checkpoint(self) -> None:
        """Write the checkpoint (one file per rank) and flush the history."""
        arrays = {f"solver/{k}": v for k, v in self.mechanics.state_dict().items()}
        arrays.update({f"loop/{k}": v for k, v in self.loop.counters.state_dict().items()})
        arrays["history/rows"] = np.array(self.history.rows)
        meta = {"columns": self.history.columns, "part": self.part, "ranks": self.comm.size,
                "since_record": self._since_record}
        save_checkpoint(self.results.root / self._rank_file(), arrays, meta)
        if self.comm.rank == 0:
            self.history.flush()

    def restore(self) -> None:
        """Continue from the checkpoint in the results folder."""
        path = self.results.root / self._rank_file()
        if not path.is_file():
            raise NothingToResume(f"{self.results.root}: no {path.name} to resume from")
        arrays, meta = load_checkpoint(path)
        if meta["ranks"] != self.comm.size:
            raise NothingToResume(f"{path}: written by {meta['ranks']} ranks, resuming on {self.comm.size}")
        self.mechanics.load_state_dict({k[7:]: v for k, v in arrays.items() if k.startswith("solver/")})
        self.loop.counters.load_state_dict({k[5:]: v for k, v in arrays.items() if k.startswith("loop/")})
        self.history.columns = list(meta["columns"])
        self.history.rows = [list(r) for r in arrays["history/rows"]]
        self.part = int(meta["part"]) + 1
        self._since_record = int(meta["since_record"])
        log.info("resumed at t = %.6g s, step %d (part %d)", self.solver.time, self.solver.step_count, self.part)

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

                def on_step(row: dict[str, float]) -> None:
                    self._on_em_step(row)
                    bar.update_to(s.time)

                for stop in self.stops:
                    if s.time >= stop * (1.0 - 1e-12):
                        continue
                    self.loop.run_until(stop, on_step)
                    if self.history.rows[-1][0] != s.time:
                        self.record({"dt_s": float("nan")})
                    writer.write(s.time)
                    self.checkpoint()
        except Exception:
            if self.comm.rank == 0:
                self.history.flush()  # keep what was computed up to the failure
            raise
        finally:
            writer.close()
        c = self.loop.counters
        log.info("mechanics: %d steps to t = %.4g s in %.2f s", s.step_count, s.time, c.mech_time_s)
        metrics = {"mech_steps": float(s.step_count), "em_steps": float(c.em_steps),
                   "end_time_s": float(s.time), "setup_time_s": self.setup_s,
                   "mech_time_s": c.mech_time_s, "load_time_s": c.em_time_s}
        if case.loads:
            metrics["force_impulse_Ns"] = float(np.linalg.norm(c.impulse))
        metrics.update(mech_metrics(s, case, self.history))
        return MechanicsRun(s, self.history, metrics)


def run_mechanics(case: Case, results: ResultsFolder, *, quiet: bool = False, resume: bool = False,
                  comm: MPI.Comm = MPI.COMM_WORLD) -> MechanicsRun:
    """Integrate ``case`` to ``time.end`` and write history, fields and checkpoints into ``results``."""
    driver = CaseDriver(case, results, comm)
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
            try:
                out.update(mech.contact_stress_metrics(t, s))
            except ValueError as exc:  # no contact, or not ended: say so in the log, report what is known
                log.warning("contact metrics of probe %s: %s", p.name, exc)
            break
    return out
