"""The coupled 3D racetrack case (issue 20, case (b)) as a case file run by the driver (``pulseform run
cases/emf_racetrack_groove``).

A case with a ``[racetrack]`` table (:mod:`pulseform.orchestrator.case.racetrack3d`) becomes the
:class:`~.coupled_racetrack.RacetrackOptions` of the study's run (:func:`racetrack_options`), and
:func:`~.coupled_racetrack.build_racetrack` builds the same participants: the driver
(:mod:`.driver`) then runs them in its loop with its outputs (history, XDMF fields of the sheet and
the die, the sheet's force density per tetrahedron, checkpoints, ``--resume``). What only the
racetrack has rides along in a :class:`RacetrackObserver` the driver calls after every EM step: the
per-body impulses and the momentum check of :class:`~.coupled_racetrack.RacetrackRecorder`, the
contact figures, the force density of both bodies at the peak coil current
(``em/force_density_peak.{vtu,npz}``, the pictures' input) and the study's metrics
(:func:`~.coupled_racetrack.racetrack_metrics`: the same names as
``studies/emf_racetrack_groove/reference/racetrack_metrics.json``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp import Circuit
from pulseform.solvers.getdp.racetrack_mesh import RacetrackGroove

from ..case.model import Case
from ..coupling.loop import LoopOptions
from ..mech.model import solver_material
from .coupled_racetrack import (RacetrackModel, RacetrackOptions, RacetrackRecorder, build_racetrack,
                                racetrack_metrics, write_force_density)

log = logging.getLogger(__name__)

#: the observer's history columns (the driver's own: per-body extremes, energies, the load's)
COLUMNS = ("sheet_max_draw_m", "sheet_min_uz_m", "die_max_u_m", "contact_nodes", "contact_pressure_max_Pa",
           "sheet_impulse_z_Ns", "die_impulse_z_Ns", "sheet_free_impulse_z_Ns", "die_free_impulse_z_Ns")
#: racetrack_metrics keys left out of metrics.json: wall times (the driver's ``setup_time_s`` and
#: ``wall_time_s`` count the whole run, resumed parts too) and what is not a scalar
_DROPPED = ("setup_s", "wall_s", "options", "impulse_quarter_Ns")


def racetrack_geometry(case: Case) -> RacetrackGroove:
    """The :class:`RacetrackGroove` (geometry and mesh sizes, m) of a case's ``[racetrack]``."""
    r = case.racetrack
    same = ("turns", "half_straight", "bend_radius", "turn_width", "turn_height", "turn_gap", "coil_gap",
            "sheet_thickness", "sheet_half_x", "sheet_half_y", "die_gap", "die_height", "die_half_x", "die_half_y",
            "groove_x0", "groove_x1", "groove_half_length", "groove_depth", "air_radius", "shell_radius",
            "sheet_layers")
    return RacetrackGroove(**{k: getattr(r, k) for k in same}, h_coil=r.mesh_size_coil, h_sheet=r.mesh_size_sheet,
                           h_die=r.mesh_size_die, h_air=r.mesh_size_air, grading=r.mesh_grading)


def racetrack_options(case: Case) -> RacetrackOptions:
    """The study's run options of a racetrack case file (its geometry, bank, materials, contact, EM step)."""
    r, em, c = case.racetrack, case.em, case.contact[0]
    bank = em.circuit
    mats = {b.region: case.materials[b.material] for b in case.bodies}
    return RacetrackOptions(geometry=racetrack_geometry(case),
                            bank=Circuit(C=bank.capacitance, V0=bank.voltage, R_ext=bank.resistance,
                                         L_ext=bank.inductance),
                            em_step=r.em_step, time_scheme=em.time_scheme, t_end=case.time.end,
                            contact_stiffness=c.stiffness, contact_h0=c.h0, friction=c.friction,
                            contact_two_pass=c.two_pass,
                            em_order=r.em_order, em_order2_air=False,
                            remesh_quality=r.break_quality, cfl=case.time.cfl, on_mesh_break=r.on_mesh_break,
                            sheet_material=solver_material(mats["workpiece"]), die_material=solver_material(mats["die"]),
                            sigma=(mats["workpiece"].electrical_conductivity, mats["die"].electrical_conductivity,
                                   em.coil_conductivity),
                            getdp_timeout=case.limits.getdp_time_limit_s)


def racetrack_participants(case: Case, work: Path):
    """(3D solver, load provider, loop options, :class:`RacetrackObserver`) of a racetrack case; the EM mesh
    and the getdp runs in ``work`` (the results folder's ``em/``)."""
    opt = racetrack_options(case)
    rm = build_racetrack(work, opt)
    n = max(1, round(opt.em_step / rm.solver.stable_time_step()))
    log.info("racetrack: %d EM tets, sheet %d tets, die %d tets, mechanical step %.3g s, n = %d", rm.mesh.n_tets,
             len(rm.solver.bodies["sheet"].cells), len(rm.solver.bodies["die"].cells), rm.solver.stable_time_step(), n)
    return rm.solver, rm.load, LoopOptions(n=n, n_min=1, n_max=n), RacetrackObserver(rm, opt, n, Path(work))


@dataclass
class _Counters:
    """What :func:`racetrack_metrics` reads of a loop: its counters."""

    counters: object


class RacetrackObserver:
    """The racetrack's own bookkeeping in a driver run (module docstring): :meth:`on_em_step` after every
    EM step, :meth:`values` for each history row, :meth:`flush` at the driver's checkpoints,
    :meth:`metrics` at the end; :meth:`state_dict` / :meth:`load_state_dict` for ``--resume``."""

    columns = COLUMNS

    def __init__(self, rm: RacetrackModel, opt: RacetrackOptions, n: int, work: Path) -> None:
        self.rm, self.opt, self.n, self.work = rm, opt, n, Path(work)
        self.rec = RacetrackRecorder(rm, rm.solver)   # the solver's ``time`` is the mechanics' time
        self._peak_written = -1.0

    def on_em_step(self, row: dict[str, float]) -> None:
        """Record the EM step that just ended (``row``: the loop's scalars of the step)."""
        self.rec(row)

    def values(self) -> dict[str, float]:
        """The :data:`COLUMNS` at the last EM step (zeros before the first)."""
        if not self.rec.rows:
            return {k: 0.0 for k in COLUMNS}
        r = self.rec.rows[-1]
        return {"sheet_max_draw_m": r["sheet_max_uz_m"], **{k: r[k] for k in COLUMNS[1:]}}

    def flush(self) -> None:
        """Write the force density at the peak coil current when it is new (``em/force_density_peak.*``)."""
        if self.rec.peak is not None and self.rec.peak_current != self._peak_written:
            write_force_density(self.work, self.rec.peak)
            self._peak_written = self.rec.peak_current

    def metrics(self, history, counters) -> dict:
        """The study's figures (:func:`racetrack_metrics`; ``device_*``: times 4), the EM mesh's freeze and
        ``max_deflection_mm`` (= ``max_deflection_into_groove_mm``, the name of the other sheet cases)."""
        self.flush()
        if not self.rec.rows:
            return {}
        m = racetrack_metrics(self.rm, _Counters(counters), self.rec, self.opt, self.n, wall=(0.0, 0.0, 0.0))
        m.update({f"impulse_quarter_{c}_Ns": float(v) for c, v in zip("xyz", m["impulse_quarter_Ns"])})
        load = self.rm.load
        m["em_mesh_frozen_at_s"] = load.frozen_at if load.frozen_at is not None else float("nan")
        # metrics.json holds numbers: the reason goes to run.log (FreezingGetDPLoad3D.run_metrics)
        if load.frozen_at is not None:
            m["impulse_after_freeze_device_z_Ns"] = float(self.rm.model.symmetry_factor) * sum(
                r["force_z_N"] * r["dt_s"] * r["substeps"] for r in self.rec.rows if r.get("em_mesh_frozen", 0.0) > 0)
        m["max_deflection_mm"] = m["max_deflection_into_groove_mm"]
        return {k: v for k, v in m.items() if k not in _DROPPED}

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict[str, np.ndarray]:
        """The recorder's rows and sums, the peak snapshot and the load's freeze (all a resume needs)."""
        rec, load = self.rec, self.rm.load
        out: dict[str, np.ndarray] = {"sums": np.array([rec.first_contact_s, rec.peak_current, self._peak_written])}
        if rec.rows:
            keys = list(rec.rows[0])
            out["row_keys"] = np.array(keys)
            out["rows"] = np.array([[r.get(k, np.nan) for k in keys] for r in rec.rows], dtype=float)
        for name in rec.impulse:
            for what in ("impulse", "clamp_impulse", "half_step"):
                out[f"{what}/{name}"] = getattr(rec, what)[name].copy()
        if rec.peak is not None:
            out.update({f"peak/{k}": np.asarray(v) for k, v in rec.peak.items()})
        if load.frozen_at is not None:
            out["frozen_at"] = np.float64(load.frozen_at)
            out["freeze_reason"] = np.array(load.freeze_reason)
        out["last_valid"] = load._last_valid.copy()
        return out

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        if not state:
            return
        rec, load = self.rec, self.rm.load
        rec.first_contact_s, rec.peak_current, self._peak_written = (float(v) for v in state["sums"])
        rec.rows = [dict(zip((str(k) for k in state["row_keys"]), (float(v) for v in row)))
                    for row in state["rows"]] if "rows" in state else []
        for name in rec.impulse:
            for what in ("impulse", "clamp_impulse", "half_step"):
                getattr(rec, what)[name] = np.array(state[f"{what}/{name}"], dtype=float)
        peak = {k[5:]: v for k, v in state.items() if k.startswith("peak/")}
        rec.peak = None if not peak else {k: (float(v) if v.ndim == 0 else v) for k, v in peak.items()}
        if "frozen_at" in state:
            load.frozen_at, load.freeze_reason = float(state["frozen_at"]), str(state["freeze_reason"])
        load._last_valid = np.array(state["last_valid"], dtype=float)


def draw_racetrack_case(root: Path) -> list[Path]:
    """The racetrack's pictures (:func:`~.pictures_racetrack.draw_racetrack`: sections y = 0, the force
    density at the peak current, the 3D views of the sheet and the die) of a results folder ``root``, its
    geometry from the resolved ``case.toml``."""
    from ..case.io import load_resolved_case
    from .pictures_racetrack import draw_racetrack

    case = load_resolved_case(Path(root) / "case.toml")
    return draw_racetrack(Path(root), racetrack_geometry(case))
