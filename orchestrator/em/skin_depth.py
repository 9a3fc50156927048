"""The skin depth of a coupled case's conductors, and advice when their elements are too coarse for it.

The eddy currents of a conductor flow within about a skin depth δ = sqrt(2 / (ω μ0 σ)) of its surface,
ω the drive's angular frequency (a prescribed current's ω, a sine's 2π f, a bank's ringing 2π / its
period from C and the coils' inductance: :func:`~.time_scale.source_period`). Elements coarser than a
fraction of δ through the conductor under-resolve the current layer and the force: measured with
``pulseform converge`` (docs/workflow.md), the issue-19 disk (δ = 0.67 mm) has its peak force 2.9 % low
at 0.75 δ, 0.4 % at 0.37 δ, 0.05 % at 0.19 δ; the demo's sheet (δ ≈ 0.8 mm) its max deflection 6.9 % low
at 0.6 δ and within 0.7 % at 0.3 δ. Hence the advice: elements no coarser than δ / 3
(:data:`SKIN_FRACTION`) — a warning naming δ and the size, not an error (a coarse mesh is a choice).

Units: m, rad/s, S/m.
"""

from __future__ import annotations

import math

from ..case.model import Case
from .lumped import MU0
from .time_scale import source_period

__all__ = ["SKIN_FRACTION", "skin_depth", "drive_omega", "mesh_advice"]

#: largest element size through a conductor, as a fraction of its skin depth (see the module docstring)
SKIN_FRACTION = 1.0 / 3.0


def skin_depth(omega: float, sigma: float) -> float:
    """δ = sqrt(2 / (ω μ0 σ)) (m) at angular frequency ``omega`` (rad/s), conductivity ``sigma`` (S/m)."""
    return math.sqrt(2.0 / (omega * MU0 * sigma))


def drive_omega(case: Case) -> float | None:
    """The highest angular frequency (rad/s) of the case's coil currents: 2π over the shortest period of
    its sources; None when none has a period (direct currents, tables, a user deck's coil on a bank)."""
    try:
        return 2.0 * math.pi / source_period(case)
    except ValueError:
        return None


def _conductor_sizes(case: Case) -> list[tuple[str, float, float, str]]:
    """(key path, element size (m), thickness it resolves (m; inf: none), region) of each conductor of a
    built-in geometry."""
    g = case.geometry
    inf = math.inf
    if g.type == "flat_coil_sheet":
        out = [("geometry.mesh_size_sheet", g.mesh_size_sheet, g.sheet_thickness, "workpiece")]
        if g.die is not None:
            out.append(("geometry.die.mesh_size", g.die.mesh_size, inf, "die"))
        return out
    if g.type == "solenoid_tube":
        out = [("geometry.mesh_size_tube", g.mesh_size_tube, g.tube_thickness, "workpiece")]
        if g.outer_tube is not None:
            out.append(("geometry.outer_tube.mesh_size", g.outer_tube.mesh_size, g.outer_tube.thickness, "outer_tube"))
        return out
    if g.type == "planar_coil_blank_die":
        out = [("geometry.mesh_size_blank", g.mesh_size_blank, g.blank_thickness, "workpiece")]
        if g.die is not None:
            out.append(("geometry.mesh_size_die", g.mesh_size_die, inf, "die"))
        return out
    if g.type == "coaxial_coils":
        w = g.workpiece
        return [("geometry.workpiece.mesh_size", w.mesh_size, min(w.r1 - w.r0, w.z1 - w.z0), "workpiece")]
    return []


def mesh_advice(case: Case) -> list[str]:
    """One line per conductor of a coupled case whose element size (capped by its thickness) is coarser
    than :data:`SKIN_FRACTION` of its skin depth at the drive's frequency, naming the key, the size and δ.
    Empty for other cases, user decks and drives without a frequency."""
    if case.case.kind != "coupled" or case.geometry is None or case.em is None or case.coupling.load != "getdp":
        return []
    sizes = _conductor_sizes(case)
    omega = drive_omega(case) if sizes else None
    if omega is None:
        return []
    out = []
    for key, size, thickness, region in sizes:
        body = next((b for b in case.bodies if b.region == region), None)
        sigma = case.materials[body.material].electrical_conductivity if body is not None else 0.0
        if sigma <= 0.0:
            continue
        delta = skin_depth(omega, sigma)
        h = min(size, thickness)
        if h > SKIN_FRACTION * delta * (1.0 + 1e-9):
            out.append(f"{key} = {size * 1e3:.3g} mm is coarser than δ/3 = {delta / 3 * 1e3:.3g} mm (skin depth "
                       f"{delta * 1e3:.3g} mm at ω = {omega:.3g} rad/s, σ = {sigma:.3g} S/m): forces and motion may be "
                       "a few % off (pulseform converge measures it)")
    return out
