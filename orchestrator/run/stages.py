"""Run a case's ``[[stages]]`` (issue 34, item 5) through the driver's participants, history and checkpoints.

One results folder and one history: time goes on across the stages (a springback stage takes none), history.csv
has a ``stage`` column (1, 2, ... in the order of ``[[stages]]``), every timed stage writes its field series
``fields/<case>_<stage>_<body>.xdmf`` (from its start to its end) and every springback stage
``fields/springback/<case>_<stage>_<body>.xdmf``. The state goes from stage to stage on the same meshes: positions,
stress, plastic strain, temperature; the velocities too unless a stage sets its bodies to rest (after a springback
they are at rest). Where the integrator changes (an implicit static preform, an explicit pulse) the next stage's
solver is built on the same bodies and the state handed over (:mod:`pulseform.solvers.dolfinx.handover`); a
springback stage releases the state with :func:`..mech.springback.spring_back` and hands the released state to the
solver of the next timed stage. A second pulse of a GetDP-coupled case (2D, or a 3D geometry file) with a capacitor
bank is a fresh discharge of the bank; without a bank the sources go on on the run's time axis.

Rigid bodies (:class:`~..mech.rigid.RigidMechanics`, one object for the whole run) go on from stage to stage as they
are: position, velocity, end-stop state, the totals of their ledger; a hand-over steps them with the next stage's
integrator's scheme (central differences, or the held force of implicit runs), and sets them at rest where it zeroes
the velocities (after a springback too: the release leaves them where they are).

The energy ledger of history.csv goes on across the stages: each stage's solver keeps its own ledger from its start,
the earlier stages' totals are added, and what a hand-over takes out (the kinetic energy of zeroed velocities, the
elastic energy a springback releases) is ``energy_stage_released_J``, counted as dissipated in
``energy_balance_error_J``.

Checkpoints at every output time and at the end of every stage hold the stage too: ``--resume`` continues in the
stage that was interrupted, with that stage's solver.
"""

from __future__ import annotations

import logging
import sys
from dataclasses import dataclass

import numpy as np

from pulseform.solvers import dolfinx as mech
from pulseform.solvers.dolfinx.handover import carry_state
from pulseform.solvers.dolfinx.implicit_ledger import IACC_KEYS

from ..case.model import Case
from ..case.springback import SpringbackTable
from ..case.stages import TIMED, StageTable, discharges
from ..mech.model import rebuild_solver, stage_case
from ..mech.springback import spring_back
from . import interrupt
from .output_times import default_interval, milestones
from .progress import Progress

log = logging.getLogger(__name__)

__all__ = ["Stage", "plan", "StagedRun"]

#: ledger entries that are the state's (no running totals to carry across a hand-over)
STATE_KEYS = ("kinetic_J", "elastic_J", "contact_stored_J")
#: the implicit ledger's entries beyond the explicit one's, in its order
IMPLICIT_KEYS = tuple(IACC_KEYS) + ("algorithmic_dissipation_J",)
RELEASED = "stage_released_J"


@dataclass(frozen=True)
class Stage:
    """One stage of the run: its table, its time span [t0, t1] (s; t0 = t1 for a springback), its output times
    and, for a timed stage, the case with its mechanics (:func:`..mech.model.stage_case`)."""

    index: int
    spec: StageTable
    t0: float
    t1: float
    stops: np.ndarray
    case: Case | None

    @property
    def timed(self) -> bool:
        """A stage that takes time (pulse, quasi_static)."""
        return self.spec.kind in TIMED


def plan(case: Case, em_step: float | None = None) -> list[Stage]:
    """The stages of ``case`` with their time spans and output times (``em_step``: the EM step the case sets, s,
    :func:`.output_times.fixed_em_step`, for the default output interval)."""
    out, t0 = [], 0.0
    for i, s in enumerate(case.stages):
        if s.kind not in TIMED:
            out.append(Stage(i, s, t0, t0, np.zeros(0), None))
            continue
        span = s.end - t0
        interval = s.field_interval or case.output.field_interval or default_interval(span, em_step)
        interval = min(interval, span)
        stops = milestones(span, interval) if t0 == 0.0 else t0 + milestones(span, interval)
        stops[-1] = s.end
        out.append(Stage(i, s, t0, s.end, stops, stage_case(case, s)))
        t0 = s.end
    return out


def _stored(e: dict[str, float]) -> float:
    return sum(e.get(k, 0.0) for k in STATE_KEYS)


class StagedRun:
    """The stages of one :class:`~.driver.CaseDriver`'s run (its ``run`` when the case has ``[[stages]]``)."""

    def __init__(self, driver) -> None:
        self.d = driver
        self.stages = plan(driver.case, None)
        self.current = 0          # index of the stage in progress (or just done)
        self.done = False         # the current stage is complete
        self.holder = self.first_timed().index   # the timed stage whose mechanics holds the state now
        self.at_rest = False      # the state was just handed over with its bodies at rest
        self.offsets: dict[str, float] = {}
        self.released = 0.0
        self.metrics: dict[str, float] = {}
        self.keys: list[str] | None = None
        self.resumed = False
        self.implicit = any(s.case is not None and s.case.mechanics.integrator == "implicit" for s in self.stages)

    def first_timed(self) -> Stage:
        """The first stage that takes time (the solver built by the driver is its)."""
        return next(s for s in self.stages if s.timed)

    @property
    def number(self) -> float:
        """The history's ``stage`` column: the stage in progress, 1-based."""
        return float(self.current + 1)

    # ----------------------------------------------------------------- energy ledger
    def ledger(self, e: dict[str, float]) -> dict[str, float]:
        """The run's energy ledger (J) from the present solver's ``e``: the earlier stages' totals added, the same
        entries in every stage (the implicit ledger's extra ones where any stage is implicit), and
        ``stage_released_J``."""
        if self.keys is None:
            extra = [k for k in IMPLICIT_KEYS if k not in e] if self.implicit else []
            self.keys = [k for k in e if k != RELEASED] + extra
        out = {k: e.get(k, 0.0) + self.offsets.get(k, 0.0) for k in self.keys}
        out[RELEASED] = self.released
        return out

    def _handover(self, new, velocities: str, implicit: bool, sb=None, bodies=None) -> None:
        """Carry the driver's solver state into ``new`` (and the springback ``sb``'s released ``bodies``), the rigid
        bodies' to the scheme of the ``implicit`` or explicit integrator (at rest too when the velocities are
        zeroed), keep the ledger going, make ``new`` the driver's solver."""
        d = self.d
        before = d.energies()
        carry_state(d.solver, new, velocities)
        if sb is not None:
            carry_state(sb, new, "zeroed", bodies=bodies, clock=False)
        if d.rigid is not None:
            d.rigid.use_scheme(implicit)
            if velocities == "zeroed":
                d.rigid.rest()
        after = d.own_energies(new)
        for k in self.keys or []:
            if k not in STATE_KEYS:
                self.offsets[k] = before[k] - after.get(k, 0.0)
        self.released += _stored(before) - _stored(after)
        d.set_solver(new)
        self.at_rest = velocities == "zeroed"

    # ----------------------------------------------------------------- checkpoints
    def state(self) -> dict:
        """What a checkpoint keeps (JSON)."""
        return {"current": self.current, "done": self.done, "holder": self.holder, "at_rest": self.at_rest,
                "offsets": self.offsets, "released": self.released, "metrics": self.metrics, "keys": self.keys}

    def before_restore(self, state: dict | None) -> None:
        """Restore :meth:`state` and give the driver the solver of the stage that wrote it (its state dict follows)."""
        if state is None:
            raise ValueError("the checkpoint was written by a run without [[stages]]: run again with --force")
        self.current, self.done, self.holder = int(state["current"]), bool(state["done"]), int(state["holder"])
        self.at_rest = bool(state["at_rest"])
        self.offsets = {k: float(v) for k, v in state["offsets"].items()}
        self.released = float(state["released"])
        self.metrics = {k: float(v) for k, v in state["metrics"].items()}
        self.keys = list(state["keys"]) if state["keys"] is not None else None
        self.resumed = True
        case = self.stages[self.holder].case
        if case.mechanics != self.first_timed().case.mechanics:
            self.d.set_solver(rebuild_solver(case, self.d.solver))
        if self.d.rigid is not None:   # the scheme of the stage's integrator (the checkpoint's state follows)
            self.d.rigid.use_scheme(case.mechanics.integrator == "implicit")

    # ----------------------------------------------------------------- the run
    def run(self, quiet: bool):
        """Every stage in turn; returns the driver's :class:`~.driver.MechanicsRun`."""
        d, case = self.d, self.d.case
        em_writer = d.em_field_writer()
        if em_writer is not None:
            d.load.request_fields(np.concatenate([st.stops for st in self.stages]))
        if not d.history.rows:
            d.record(d.initial_row())
        d._keep_shape()
        try:
            d._check_interrupt()
            with Progress(case.time.end, quiet=quiet or d.comm.rank != 0, desc=case.case.name) as bar:
                for st in self.stages[self.current:]:
                    if st.index == self.current and self.done:
                        continue
                    self.current, self.done = st.index, False
                    if st.timed:
                        self._timed(st, bar, em_writer)
                    else:
                        self._release(st)
                    self.done = True
                    self.resumed = False
                    d.checkpoint()
                    interrupt.rearm()
                    d._check_interrupt()
        except interrupt.StopRequested as exc:
            exc.time = d.mechanics.time
            d.checkpoint()
            log.info("interrupted in stage %d (%s) at t = %.6g s; checkpoint written", self.current + 1,
                     self.stages[self.current].spec.name, d.mechanics.time)
            raise
        except Exception as exc:
            exc.add_note(f"in stage {self.current + 1} ({self.stages[self.current].spec.name!r}) at "
                         f"t = {d.mechanics.time:.6g} s")
            if d.comm.rank == 0:
                try:
                    d.history.flush()
                except OSError as write_error:
                    log.debug("could not flush the history: %s", write_error)
            raise
        finally:
            if sys.exc_info()[0] is not None:
                d.load.close()
        metrics = d.run_metrics()
        metrics.update(self.metrics)
        metrics["stages"] = float(len(self.stages))
        d.load.close()
        return d.finish(metrics)

    def _begin(self, st: Stage) -> None:
        """The start of timed stage ``st``: its solver (a hand-over where the integrator changes or the bodies are
        set to rest), a new discharge for a GetDP-coupled case's later pulse, a history row at its start."""
        d = self.d
        zeroed = st.spec.velocities == "zeroed" and not self.at_rest
        if st.case.mechanics != self.stages[self.holder].case.mechanics or zeroed:
            velocities = "zeroed" if zeroed or self.at_rest else "kept"
            self._handover(rebuild_solver(st.case, d.solver), velocities, _implicit(st))
        self.holder = st.index
        pulses_before = sum(p.spec.kind == "pulse" for p in self.stages[: st.index])
        if st.spec.kind == "pulse" and pulses_before and discharges(d.case):
            voltage = st.spec.voltage or _bank_voltage(d.case)
            d.load.begin_shot(st.t0, voltage, d.load.coil_temperatures())
            log.info("stage %s: a new discharge at t = %.6g s, %.6g V", st.spec.name, st.t0, voltage)
        if st.index > 0:
            d.record()

    def _timed(self, st: Stage, bar, em_writer) -> None:
        """Integrate stage ``st`` to its end: fields, history and checkpoints at its output times."""
        d = self.d
        if not self.resumed:
            self._begin(st)
        s = d.mechanics
        log.info("stage %d (%s, %s): t = %.6g s to %.6g s, %s", st.index + 1, st.spec.name, st.spec.kind, s.time,
                 st.t1, st.case.mechanics.integrator)
        name = f"{d.case.case.name}_{st.spec.name}" + (f"_part{d.part}" if self.resumed and d.part else "")
        writer = mech.FieldWriter(d.solver, str(d.results.fields / name), d.flc and d.flc.cell_fields)

        def on_step(row: dict[str, float]) -> None:
            d._on_em_step(row)
            bar.update_to(d.mechanics.time)

        try:
            writer.write(s.time)
            for stop in st.stops:
                if s.time >= stop * (1.0 - 1e-12):
                    continue
                d.reach(stop, on_step, writer, em_writer)
                if stop != st.stops[-1]:
                    d.checkpoint()
                    interrupt.rearm()
                    d._check_interrupt()
        finally:
            writer.close()
        self.metrics.update(self._stage_metrics(st))

    def _release(self, st: Stage) -> None:
        """Springback stage ``st``: release the state, hand it to the next timed stage's solver (the last one's when
        none follows), a history row."""
        d = self.d
        cfg = st.spec.springback or SpringbackTable()
        sb, m = spring_back(d.case, d.solver, d.results.fields / "springback", f"{d.case.case.name}_{st.spec.name}",
                            cfg, d.analyses)
        self.metrics.update({f"stage_{st.spec.name}_{k}": v for k, v in m.items()})
        later = [x for x in self.stages[st.index + 1:] if x.timed]
        holder = later[0] if later else self.stages[self.holder]
        self._handover(rebuild_solver(holder.case, d.solver), "zeroed", _implicit(holder), sb,
                       list(cfg.bodies) or list(sb.bodies))
        self.holder = holder.index
        d.record()
        d._keep_shape()
        log.info("stage %d (%s): springback at t = %.6g s", st.index + 1, st.spec.name, d.mechanics.time)

    def _stage_metrics(self, st: Stage) -> dict[str, float]:
        """``stage_<name>_end_time_s``, ``..._mech_steps`` and per deformable body the largest displacement
        components (mm) and von Mises stress (MPa) over the stage's history rows."""
        h, key = self.d.history, f"stage_{st.spec.name}"
        rows = h.column("stage") == self.number
        out = {f"{key}_end_time_s": float(self.d.mechanics.time),
               f"{key}_mech_steps": float(h.column("step")[rows].max() - h.column("step")[rows].min())}
        for b in self.d.case.bodies:
            for c in "xyzr":
                col = f"{b.name}_max_u{c}_m"
                if col in h.columns:
                    out[f"{key}_{b.name}_max_u{c}_mm"] = float(h.column(col)[rows].max()) * 1e3
            if f"{b.name}_max_von_mises_Pa" in h.columns:
                out[f"{key}_{b.name}_max_von_mises_MPa"] = float(h.column(f"{b.name}_max_von_mises_Pa")[rows].max()) / 1e6
        return out


def _implicit(st: Stage) -> bool:
    """Whether timed stage ``st`` runs the implicit integrator."""
    return st.case.mechanics.integrator == "implicit"


def _bank_voltage(case: Case) -> float:
    """The charging voltage (V) of the case's capacitor bank."""
    em = case.em
    return em.circuit.voltage if em.circuit is not None else next(s.voltage for s in em.sources if s.type == "bank")
