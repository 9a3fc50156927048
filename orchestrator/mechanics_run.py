"""Run a mechanics-only case: explicit dynamics with contact and pressure pulses, to a results folder."""

from __future__ import annotations

import logging
import time as _time
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from pulseform.solvers import dolfinx as mech

from . import probes as probe_mod
from .case import Case
from .history import History
from .loads import box_marker, pulse_pressure
from .mech_model import build_solver
from .progress import Progress
from .results import ResultsFolder

log = logging.getLogger(__name__)


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


def _external_forces(solver, case: Case, t: float) -> dict[str, np.ndarray] | None:
    if not case.loads:
        return None
    forces: dict[str, np.ndarray] = {}
    for ld in case.loads:
        p = pulse_pressure(ld, t)
        if p == 0.0:
            continue
        f = solver.pressure_nodal_forces(ld.body, box_marker(ld.surface), p)
        forces[ld.body] = forces.get(ld.body, 0.0) + f
    return forces or None


def energy_row(solver) -> dict[str, float]:
    """The solver's energy ledger as history columns (J)."""
    return {f"energy_{k}": float(v) for k, v in solver.energies().items()}


def run_mechanics(case: Case, results: ResultsFolder, *, quiet: bool = False,
                  comm: MPI.Comm = MPI.COMM_WORLD) -> MechanicsRun:
    """Integrate ``case`` to ``time.end`` and write history, fields and metrics into ``results``.

    The step is the solver's stable step (× cfl), capped by ``time.dt_max`` and shortened to land
    exactly on every field-output time. Pressure pulses are evaluated at the start of each step.
    """
    t0 = _time.perf_counter()
    solver = build_solver(case, comm)
    setup_s = _time.perf_counter() - t0
    attached = probe_mod.attach(solver, case.probes, comm)
    history = History(results.root / "history.csv")
    writer = mech.FieldWriter(solver, str(results.fields / case.case.name))
    interval = case.output.field_interval or case.time.end / 20.0
    stops = milestones(case.time.end, interval)

    def record() -> None:
        row = {"time_s": solver.time, "step": float(solver.step_count), "dt_s": last_dt}
        row.update(energy_row(solver))
        row.update(probe_mod.sample(solver, attached, comm))
        history.record(row)

    last_dt = 0.0
    record()
    writer.write(solver.time)
    loop_t0 = _time.perf_counter()
    with Progress(case.time.end, quiet=quiet or comm.rank != 0, desc=case.case.name) as bar:
        for stop in stops:
            while solver.time < stop * (1.0 - 1e-12):
                dt = solver.stable_time_step()
                if case.time.dt_max is not None:
                    dt = min(dt, case.time.dt_max)
                remaining = stop - solver.time
                if dt >= remaining * (1.0 - 1e-9):
                    dt = remaining
                elif dt > 0.5 * remaining:  # two equal steps rather than one tiny sliver
                    dt = 0.5 * remaining
                solver.advance(dt, 1, _external_forces(solver, case, solver.time))
                last_dt = dt
                if solver.step_count % case.output.history_every == 0:
                    record()
                bar.update_to(solver.time)
            writer.write(solver.time)
            history.flush() if comm.rank == 0 else None
    writer.close()
    loop_s = _time.perf_counter() - loop_t0
    if history.rows and history.rows[-1][0] != solver.time:
        record()
    if comm.rank == 0:
        history.flush()
    metrics = {
        "mech_steps": float(solver.step_count),
        "end_time_s": float(solver.time),
        "setup_time_s": setup_s,
        "mech_time_s": loop_s,
    }
    metrics.update(mech_metrics(solver, case, history))
    log.info("mechanics: %d steps to t = %.4g s in %.2f s", solver.step_count, solver.time, loop_s)
    return MechanicsRun(solver, history, metrics)


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
    vm = [float(np.max(b.von_mises)) if len(b.von_mises) else 0.0 for b in solver.bodies.values()]
    out["von_mises_final_max_MPa"] = max(vm) / 1e6 if vm else 0.0
    for p in case.probes:
        if p.quantity == "contact_pressure":
            t = history.column("time_s")
            s = history.column(f"{p.name}_contact_pressure_Pa")
            out.update(mech.contact_stress_metrics(t, s))
            break
    return out
