"""Drive a case through the staggered loop into a results folder.

A mechanics case is the loop with the pressure-pulse load provider and n = 1; a coupled case is
the same loop with the GetDP eddy-current load and the case's n. The run stops at output milestones (every
``output.field_interval``): there it writes fields, flushes ``history.csv`` and a checkpoint, so
``pulseform run --resume`` continues from the last milestone to the same result.
"""

from __future__ import annotations

import logging
import sys
import time as _time
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from pulseform.solvers import dolfinx as mech

from ..case.guards import check_steps_of_meshes
from ..case.model import Case
from ..coupling.interfaces import LoadProvider
from ..coupling.loop import LoopOptions, StaggeredLoop
from ..em.skin_depth import mesh_advice
from ..mech import probes as probe_mod
from ..mech.forming_limit import forming_limit_monitor
from ..mech.model import build_solver, stage_case
from ..mech.mixed import MixedMechanics, rigid_metrics
from ..mech.participants import DolfinxMechanics
from ..mech.rigid import RigidMechanics
from ..mech.springback import run_springback
from ..mesh.em_geometry import PendingEMGeometry
from . import interrupt
from .analyses import create as create_analysis
from .checkpoint import CHECKPOINT_NAME, load_checkpoint, save_checkpoint
from .em_fields import EMFieldWriter, write_peak_snapshot
from .em_fields3d import CONDUCTORS_PEAK
from .em_fields3d import FOLDER as EM3D_FOLDER
from .em_fields3d import STEM as EM3D_STEM
from .extremes import body_extremes
from .extremes3d import contact_columns_3d, contact_metrics_3d
from .shots import ShotSequence
from .temperature import MeltingReached, check_melting, melting_limits
from .history import History
from .impulse import impulse_metrics
from .mech_metrics import mech_metrics
from .output_times import default_interval, fixed_em_step, landing_note, milestones
from .progress import Progress
from .participants2d import coupled_participants, pressure_pulses
from .participants3d import participants_3d
from .stages import StagedRun
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
    shapes: list = field(default_factory=list)
    analyses: list = field(default_factory=list)
    wall_before_s: float = 0.0  # wall time of the earlier segments of a resumed run (s)
    pictures_stopped_by: int | None = None  # a stop signal that ended the pictures (the run is complete)


class CaseDriver:
    """Participants, loop, history, fields and checkpoints of one case."""

    def __init__(self, case: Case, results: ResultsFolder, comm: MPI.Comm,
                 em_geometry: PendingEMGeometry | None = None, wall_start: float | None = None) -> None:
        self.case, self.results, self.comm = case, results, comm
        t0 = _time.perf_counter()
        # the run's wall clock (time.perf_counter, s) starts where the runner's does: a checkpoint's
        # wall time then counts the imports and meshing before this driver too, as metrics.json does
        self.wall_start = t0 if wall_start is None else wall_start
        self.wall_before_s = 0.0
        cp = case.coupling
        self.rigid: RigidMechanics | None = None  # the rigid bodies (coupled cases), None without
        # a coupled 3D case: any 3D geometry file (run/participants3d.py), its first body's EM fields in fields/em3d
        self.three_d = case.case.kind == "coupled" and case.mechanics.formulation == "3d"
        self.staged: StagedRun | None = None
        built = case
        if case.stages:  # the solver of the first timed stage (its integrator); the stages hand the state on
            built = stage_case(case, next(s for s in case.stages if s.kind != "springback"))
        if self.three_d:
            self.solver, self.rigid, load, options, _ = participants_3d(built, results.root / "em")
        elif case.case.kind == "coupled":
            self.solver, load, self.rigid = coupled_participants(built, results, comm, em_geometry)
            options = LoopOptions.from_coupling(cp)
        else:
            # the explicit mechanics alone has no step-ratio limit: full steps, one shorter step at a milestone
            self.solver, options = build_solver(built, comm), LoopOptions(n=1, n_max=1, landing="last",
                                                                       block=case.output.history_every)
            load = pressure_pulses(case)
        deformable = DolfinxMechanics(self.solver) if self.solver is not None else None
        self.mechanics = deformable if self.rigid is None else MixedMechanics(deformable, self.rigid)
        check_steps_of_meshes(case, self.mechanics.stable_time_step())  # a user deck's mesh is known only now
        self.setup_s = _time.perf_counter() - t0
        self.load: LoadProvider = load
        self.loop = StaggeredLoop(load, self.mechanics, options, dt_max=case.time.dt_max)
        self.probes = probe_mod.attach(self.solver, case.probes, comm) if self.solver is not None else []
        self.analyses = [create_analysis(name, case) for name in case.analysis]
        self.analysis_names = list(case.analysis)
        self.flc = forming_limit_monitor(case, self.solver)  # None without a material's forming_limit
        self.melting = melting_limits(case) if self.solver is not None else {}  # body -> T_melt (K)
        if self.flc is not None:  # it records, reports and checkpoints as an analysis does
            self.analyses.append(self.flc)
            self.analysis_names.append("forming_limit")
        self.load_columns = self.load.columns
        self.history = History(results.root / "history.csv")
        self.part = 0
        self._since_record = 0
        self._last_row: dict[str, float] | None = None
        self.shapes: list[tuple[float, dict[str, np.ndarray]]] = []  # rank 0: node positions per milestone
        self.em_step = fixed_em_step(self.loop, all_rigid=self.solver is None)
        interval = case.output.field_interval or default_interval(case.time.end, self.em_step)
        self.stops = milestones(case.time.end, interval)
        self.shots = ShotSequence.of_case(case)  # em.shots: the window time.end again after cooling pauses, or None
        self.landing_note = landing_note(self.stops, self.em_step)  # said at the start of run()
        if case.stages:
            self.staged = StagedRun(self)

    def set_solver(self, solver) -> None:
        """Make ``solver`` (on the same bodies) the run's mechanics: a stage's own (:mod:`.stages`), stepped with the
        rigid bodies if the case has any."""
        self.solver = solver
        self.mechanics = DolfinxMechanics(solver) if self.rigid is None else \
            MixedMechanics(DolfinxMechanics(solver), self.rigid)
        self.loop.mech = self.mechanics
        if self.flc is not None:
            self.flc.solver = solver

    # ----------------------------------------------------------------- records
    def record(self, step_row: dict[str, float] | None = None) -> None:
        """Append the current state to the history."""
        s, m = self.solver, self.mechanics
        row = {"time_s": m.time} if self.staged is None else {"time_s": m.time, "stage": self.staged.number}
        row.update({"step": float(m.step_count),
               "dt_s": step_row["dt_s"] if step_row else 0.0,
               "substeps": step_row.get("substeps", 0.0) if step_row else 0.0,
               "iterations": step_row.get("iterations", 0.0) if step_row else 0.0})
        row.update({f"energy_{k}": float(v) for k, v in self.energies().items()})
        if s is not None:
            row.update(probe_mod.sample(s, self.probes, self.comm))
            row.update(body_extremes(s, self.comm))
            if s.formulation == "3d" and s.contact_pairs:
                row.update(contact_columns_3d(s))
        if self.rigid is not None:
            row.update(self.rigid.history())
        for a in self.analyses:
            row.update(a.record(s, row))
        for key in self.load_columns:
            row[key] = step_row.get(key, 0.0) if step_row else 0.0
        self.history.record(row)

    def energies(self) -> dict[str, float]:
        """The run's energy ledger (J): the solver's, with the rigid bodies' added (and a staged run's earlier
        stages' totals, :meth:`.stages.StagedRun.ledger`)."""
        e = self.own_energies(self.solver)
        return e if self.staged is None else self.staged.ledger(e)

    def own_energies(self, solver) -> dict[str, float]:
        """The energy ledger (J) of ``solver`` (the run's, or a stage's new one) with the rigid bodies' added."""
        e = solver.energies() if solver is not None else None
        return e if self.rigid is None else self.mechanics.energies(e)

    def initial_row(self) -> dict[str, float]:
        """The load columns at t = 0 (the first history row): the provider's true initial values
        (:meth:`pulseform.orchestrator.coupling.interfaces.LoadProvider.initial`; zeros for a provider
        whose ``initial`` gives None)."""
        row = {"dt_s": 0.0, "substeps": 0.0, "iterations": 0.0}
        step = self.load.initial(self.mechanics)
        if step is not None:
            resultant = self.mechanics.total_force(step.forces) if step.forces else np.zeros(2)
            row.update({"force_x_N": float(resultant[0]), "force_y_N": float(resultant[1]),
                        "conservation_error_rel": 0.0, **step.values})
        return row

    def _on_em_step(self, row: dict[str, float]) -> None:
        self._last_row = row
        self._since_record += 1
        if self._since_record >= self.case.output.history_every:
            self._since_record = 0
            self.record(row)

    def reach(self, stop: float, on_step, writer, em_writer) -> float:
        """Integrate to the output time ``stop`` (s) and write its outputs: the history row of the step that reached
        it, the fields, the kept shape, the EM snapshot; returns the output's time (the milestone itself, not the
        sum of the steps that reached it: 6.0000000000000035e-05)."""
        s = self.mechanics

        def after_steps() -> None:
            """Checks once the rows of an EM step, or of a whole compiled block of them, are recorded: a stop
            raised between a block's rows would checkpoint the block's end state with its history row missing."""
            if self.melting:
                self._check_melting()
            if self.comm.size == 1 and interrupt.pending() is not None and s.time < stop * (1.0 - 1e-12):
                interrupt.check()  # a step that reaches a milestone first writes its outputs

        self.loop.run_until(stop, on_step, after_steps)
        if self.history.rows[-1][0] != s.time:
            self.record(self._last_row)  # the values of the step that reached the milestone
        t_out = stop if abs(s.time - stop) <= 1e-9 * stop else s.time
        writer.write(t_out)
        self._keep_shape()
        snap = self.load.snapshot() if em_writer is not None else None
        if snap is not None:
            em_writer.write(t_out, *snap)
        return t_out

    def _keep_shape(self) -> None:
        """Gather every body's owned node positions on rank 0 (for the shapes plot)."""
        local = {n: b.x[: b.n_owned].copy() for n, b in self.solver.bodies.items()} if self.solver is not None else {}
        if self.rigid is not None:
            local.update(self.rigid.positions())  # coupled runs are serial
        gathered = self.comm.gather(local, root=0)
        if self.comm.rank == 0:
            self.shapes.append((self.mechanics.time, {n: np.vstack([g[n] for g in gathered]) for n in local}))

    def _rank_file(self) -> str:
        return CHECKPOINT_NAME if self.comm.size == 1 else f"checkpoint.rank{self.comm.rank}.npz"

    def checkpoint(self) -> None:
        """Write the checkpoint (one file per rank) and flush the history and the EM snapshot at the
        peak coil current (the checkpoint's EM state counts it as written)."""
        peak = self.load.take_peak_snapshot() if self.comm.rank == 0 else None
        if peak is not None:
            write_peak_snapshot(self.results.fields / (EM3D_FOLDER if self.three_d else "em"), *peak)
        conductors = self.load.take_peak_conductors() if self.comm.rank == 0 else None
        if conductors is not None:   # every 3D conductor (bodies and fixed ones: a field shaper's current)
            write_peak_snapshot(self.results.fields / EM3D_FOLDER, *conductors, name=CONDUCTORS_PEAK)
        arrays = {f"solver/{k}": v for k, v in self.mechanics.state_dict().items()}
        arrays.update({f"loop/{k}": v for k, v in self.loop.counters.state_dict().items()})
        arrays.update({f"load/{k}": v for k, v in self.load.checkpoint_state_dict().items()})
        for name, a in zip(self.analysis_names, self.analyses):
            arrays.update({f"analysis/{name}/{k}": v for k, v in a.state_dict().items()})
        arrays["history/rows"] = self.history.array()
        meta = {"columns": self.history.columns, "part": self.part, "ranks": self.comm.size,
                "since_record": self._since_record,
                "wall_time_s": self.wall_before_s + _time.perf_counter() - self.wall_start}
        if self.shots is not None:
            meta["shots"] = self.shots.state(self.load)
        if self.staged is not None:
            meta["stages"] = self.staged.state()
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
        # analysis states: "analysis/<name>/..." (checkpoints before 2026-11-25: "solver/analysis/<name>/...")
        for name, a in zip(self.analysis_names, self.analyses):
            pre = [f"analysis/{name}/", f"solver/analysis/{name}/"]
            a.load_state_dict({k[len(p):]: v for k, v in arrays.items() for p in pre if k.startswith(p)})
        if self.staged is not None:  # the solver of the stage that wrote the checkpoint
            self.staged.before_restore(meta.get("stages"))
        self.mechanics.load_state_dict({k[7:]: v for k, v in arrays.items()
                                        if k.startswith("solver/") and not k.startswith("solver/analysis/")})
        self.loop.counters.load_state_dict({k[5:]: v for k, v in arrays.items() if k.startswith("loop/")})
        self.load.load_state_dict({k[5:]: v for k, v in arrays.items() if k.startswith("load/")})
        self.history.columns = list(meta["columns"])
        self.history.rows = [list(r) for r in arrays["history/rows"]]
        self.part = int(meta["part"]) + 1
        self._since_record = int(meta["since_record"])
        self.wall_before_s = float(meta.get("wall_time_s", 0.0))
        if self.shots is not None:
            self.shots.load_state(meta.get("shots"), self.load)
        log.info("resumed at t = %.6g s, step %d (part %d)", self.mechanics.time, self.mechanics.step_count, self.part)

    def _shot_stops(self) -> list[tuple[int, float]]:
        """(shot, milestone time) of the whole run (one shot without em.shots)."""
        return self.shots.milestones(self.stops) if self.shots is not None else [(1, t) for t in self.stops]

    def _check_interrupt(self) -> None:
        """Stop here if a stop signal reached any rank (all ranks stop at the same step)."""
        signum = interrupt.pending() or 0
        if self.comm.size > 1:
            signum = self.comm.allreduce(signum, op=MPI.MAX)
        if signum:
            raise interrupt.StopRequested(signum)

    def _check_melting(self) -> None:
        """Stop when a cell reaches its material's melting temperature, the step's history row recorded."""
        try:
            check_melting(self.solver, self.melting, self.comm)
        except MeltingReached:
            if self._since_record:
                self.record(self._last_row)
            raise

    # ----------------------------------------------------------------- loop
    def run(self, quiet: bool) -> MechanicsRun:
        """Integrate to ``time.end``; fields, history and checkpoint at every milestone (a case with ``[[stages]]``:
        :meth:`.stages.StagedRun.run`)."""
        if self.staged is not None:
            return self.staged.run(quiet)
        s, case = self.mechanics, self.case
        # elements coarse for the skin depth: a warning on the console (run.log only with --quiet, where a
        # failing run must stay one line), and the run goes on
        for line in mesh_advice(case) if case.case.kind == "coupled" and self.comm.rank == 0 else ():
            log.log(logging.INFO if quiet else logging.WARNING, "%s", line)
        if self.landing_note and self.comm.rank == 0:  # output times that shorten the EM step the case sets
            log.log(logging.INFO if quiet else logging.WARNING, "%s", self.landing_note)
        prefix = self.results.fields / (case.case.name + (f"_part{self.part}" if self.part else ""))
        writer = mech.FieldWriter(self.solver, str(prefix), self.flc and self.flc.cell_fields) \
            if self.solver is not None else _NoFieldWriter()
        em_writer = self.em_field_writer()
        if em_writer is not None:
            self.load.request_fields(np.array([t for _, t in self._shot_stops()]))  # whole-domain EM fields only on the snapshot steps
        if not self.history.rows:
            self.record(self.initial_row())
        writer.write(s.time)
        self._keep_shape()
        stop = s.time

        def on_step(row: dict[str, float]) -> None:
            self._on_em_step(row)
            bar.update_to(s.time)

        log.debug("loop from t = %.6g s", s.time)  # bench/sweep_split.py: set-up ends, the loop starts
        try:
            self._check_interrupt()  # a signal during set-up (meshing, deck check)
            n_shots = self.shots.count if self.shots is not None else 1
            with Progress(case.time.end * n_shots, quiet=quiet or self.comm.rank != 0, desc=case.case.name) as bar:
                bar.update_to(s.time)
                for shot, stop in self._shot_stops():
                    if s.time >= stop * (1.0 - 1e-12):
                        continue
                    if self.shots is not None and shot > 1 and s.time <= self.shots.start(shot) * (1.0 + 1e-12):
                        self.shots.begin(shot, self.load, self.solver, self.results.root, self.comm.rank == 0)
                    self.reach(stop, on_step, writer, em_writer)
                    if self.shots is not None and stop == self.shots.start(shot) + self.stops[-1]:
                        self.shots.end(shot, self.history, self.load, self.solver, self.results.root,
                                       self.comm.rank == 0)
                    self.checkpoint()
                    interrupt.rearm()  # a library (gmsh, at import) may have replaced the handlers
                    self._check_interrupt()
        except interrupt.StopRequested as exc:
            exc.time = s.time
            self.checkpoint()  # at an EM-step boundary: --resume continues exactly from here
            log.info("interrupted at t = %.6g s (step %d); checkpoint written", s.time, s.step_count)
            raise
        except Exception as exc:
            if not isinstance(exc, MeltingReached):  # its line names the time
                exc.add_note(f"at t = {s.time:.6g} s")
            if self.comm.rank == 0:
                try:
                    self.history.flush()  # keep what was computed up to the failure
                except OSError as write_error:  # a full disk: report the run's own failure
                    log.debug("could not flush the history: %s", write_error)
            raise
        finally:
            writer.close()
            if sys.exc_info()[0] is not None:
                self.load.close()  # a failed or interrupted run ends its persistent getdp too
        metrics = self.run_metrics()
        metrics.update(run_springback(case, self.solver, str(prefix), self.analyses)
                       if case.springback and self.solver else {})
        self.load.close()  # old getdp run folders are deleted in the background: wait for them
        return self.finish(metrics)

    def em_field_writer(self) -> EMFieldWriter | None:
        """The writer of the EM field series (rank 0; None without one): ``fields/em`` of a 2D coupled case,
        ``fields/em3d`` of a GetDP-coupled 3D case (the first body's force density); ``_part<n>`` when resumed."""
        if self.comm.rank != 0:
            return None
        part = f"_part{self.part}" if self.part else ""
        if self.three_d and self.case.coupling.load == "getdp":
            return EMFieldWriter(self.results.fields / f"{EM3D_FOLDER}{part}", stem=EM3D_STEM)
        return EMFieldWriter(self.results.fields / f"em{part}") if self.load.em_fields else None

    def finish(self, metrics: dict[str, float]) -> MechanicsRun:
        """What the run hands back to the runner, with its ``metrics``."""
        return MechanicsRun(self.solver, self.history, metrics, self.shapes, self.analyses, self.wall_before_s)

    def run_metrics(self) -> dict[str, float]:
        """The metrics of the run's end: steps and times, impulse, the mechanics' scalars, the load's, the rigid
        bodies', the analyses' and the shots'."""
        s, case = self.mechanics, self.case
        c = self.loop.counters
        log.info("mechanics: %d steps to t = %.4g s in %.2f s", s.step_count, s.time, c.mech_time_s)
        metrics = {"mech_steps": float(s.step_count), "em_steps": float(c.em_steps), "n_final": float(c.n),
                   "coupling_iterations_total": float(c.iterations),
                   "coupling_iterations_max": float(c.iterations_max),
                   "coupling_unconverged_steps": float(c.unconverged),
                   **({"mech_rejected_steps": float(c.retries)} if getattr(s, "retries_steps", False) else {}),
                   "end_time_s": float(s.time), "setup_time_s": self.setup_s,
                   "mech_time_s": c.mech_time_s, "load_time_s": c.em_time_s}
        if case.loads or case.case.kind == "coupled":
            metrics.update(impulse_metrics(c.impulse, case.mechanics.formulation))
        metrics.update(mech_metrics(self.solver, case, self.history, self.energies()))
        if self.solver is not None and self.solver.formulation == "3d" and self.solver.contact_pairs:
            metrics.update(contact_metrics_3d(self.solver, self.history))
        metrics.update(self.load.run_metrics(self.history, c))  # in 3D: the device's figures (x symmetry factor)
        if self.rigid is not None:
            metrics.update(rigid_metrics(case, self.history, {n: b.mass for n, b in self.rigid.bodies.items()}))
        for a in self.analyses:
            metrics.update(a.metrics(self.solver, self.history))
        if self.shots is not None:
            metrics.update(self.shots.metrics())
        return metrics



class _NoFieldWriter:
    """The field writer of a run without deformable bodies: nothing to write (the rigid bodies' motion
    is in history.csv, their moved EM mesh in fields/em/)."""

    def write(self, t: float) -> None:
        """Nothing (t in s)."""

    def close(self) -> None:
        """Nothing."""


def run_case_loop(case: Case, results: ResultsFolder, *, quiet: bool = False, resume: bool = False,
                  comm: MPI.Comm = MPI.COMM_WORLD, em_geometry: PendingEMGeometry | None = None,
                  wall_start: float | None = None) -> MechanicsRun:
    """Integrate ``case`` to ``time.end`` and write history, fields and checkpoints into ``results``
    (``em_geometry``: the EM mesh of a coupled case, started before, :func:`start_em_geometry`;
    ``wall_start``: ``time.perf_counter()`` at the run's start, the origin of its wall time)."""
    driver = CaseDriver(case, results, comm, em_geometry, wall_start)
    if resume:
        driver.restore()
    return driver.run(quiet)
