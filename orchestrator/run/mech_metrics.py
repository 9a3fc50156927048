"""The scalars every mechanics run reports (metrics.json): energy balance, peak stresses, displacements and
contact figures from the history and the solver's state."""

from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI

from pulseform.solvers import dolfinx as mech

from ..case.model import Case
from .history import History

log = logging.getLogger(__name__)

__all__ = ["energy_scale", "mech_metrics"]


def energy_scale(history: History, e: dict[str, float]) -> float:
    """The energy (J) ``energy_error_rel`` is relative to: the largest of the initial kinetic energy and the
    external work over the run (``history``'s column, ``e`` the ledger at the end; the same as the work at the
    end while the loads only put energy in). Not the external work at the end alone: under an AC force the
    loads take back what they put in, the net work of a body in a converged periodic motion is near zero and
    any residual divided by it read as ~100 % (issue 32)."""
    w = history.column("energy_external_work_J") if "energy_external_work_J" in history.columns else np.zeros(0)
    largest = float(np.abs(w).max()) if len(w) else 0.0
    return max(history.column("energy_kinetic_J")[0], abs(e.get("external_work_J", 0.0)), largest, 1e-300)


def mech_metrics(solver, case: Case, history: History, e: dict[str, float]) -> dict[str, float]:
    """Scalars every mechanics run reports: energy balance (``e``: the run's energy ledger, J), peak
    stresses, contact figures; the rigid bodies' travel, speed and force (:func:`rigid_metrics`)."""
    out = {
        "energy_error_rel": abs(e["balance_error_J"]) / energy_scale(history, e),
        "kinetic_energy_final_J": e["kinetic_J"],
    }
    if "plastic_J" in e:  # deformable bodies
        out["plastic_work_J"] = e["plastic_J"]
    if solver is None:
        return out
    local = max((float(np.max(b.von_mises)) for b in solver.bodies.values() if len(b.von_mises)), default=0.0)
    out["von_mises_final_max_MPa"] = solver.comm.allreduce(local, op=MPI.MAX) / 1e6
    for b in case.bodies:
        if b.rigid:
            continue
        out[f"{b.name}_max_ux_mm"] = float(history.column(f"{b.name}_max_ux_m").max()) * 1e3
        out[f"{b.name}_max_uy_mm"] = float(history.column(f"{b.name}_max_uy_m").max()) * 1e3
        for c in ("z", "r"):   # 3D bodies: the z and radial (about the z-axis) displacements too
            if f"{b.name}_max_u{c}_m" in history.columns:
                out[f"{b.name}_max_u{c}_mm"] = float(history.column(f"{b.name}_max_u{c}_m").max()) * 1e3
        out[f"{b.name}_max_speed_m_s"] = float(history.column(f"{b.name}_max_speed_m_s").max())
        out[f"{b.name}_max_von_mises_MPa"] = float(history.column(f"{b.name}_max_von_mises_Pa").max()) / 1e6
        for q in ("max", "mean"):   # a body that carries a temperature: its largest cell and mean at the end
            if f"{b.name}_temperature_{q}_K" in history.columns:
                out[f"{b.name}_temperature_{q}_final_K"] = float(history.column(f"{b.name}_temperature_{q}_K")[-1])
        if b.region == "workpiece" and case.geometry is not None:
            if case.geometry.type == "flat_coil_sheet":  # the axial displacement: z in 3D, y in r-z
                out["max_deflection_mm"] = out.get(f"{b.name}_max_uz_mm", out[f"{b.name}_max_uy_mm"])
            elif case.geometry.type == "solenoid_tube":
                out["max_radial_displacement_mm"] = out[f"{b.name}_max_ux_mm"]
    for p in case.probes:
        if p.quantity in ("contact_pressure", "wall_pressure"):
            t = history.column("time_s")
            s = history.column(f"{p.name}_{p.quantity}_Pa")
            try:
                out.update(mech.contact_stress_metrics(t, s))
            except ValueError as exc:  # no contact, or not ended: say so in the log, report what is known
                log.warning("contact metrics of probe %s: %s", p.name, exc)
            break
    return out
