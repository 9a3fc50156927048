"""The skin-depth rule of the built-in geometries' conductor meshes, and where their sizes are set.

The eddy currents of a conductor flow within about a skin depth δ = sqrt(2 / (ω μ0 σ)) of its surface, ω
the drive's angular frequency. Elements coarser than a fraction of δ through the conductor under-resolve
the current layer and the force. The rule (one home: this module):

- :data:`SKIN_FRACTION`: elements no coarser than δ / 3. Chosen from the study in docs/workflow.md
  ("Conductor element sizes from the skin depth"): on the issue-19 disk the peak force is 0.26 % below
  the independent 15.18 kN and the impulse 0.75 % below its converged value at δ / 3, 2.6 % and 4.2 %
  at 0.74 δ (two layers);
- :data:`MIN_LAYERS`: and at least two elements through the conductor's thickness (when δ / 3 exceeds
  half of it, e.g. at low frequency): the mechanics shares these elements, and one P1 layer cannot bend.

A conductor whose size the case leaves out gets :func:`default_size` of its δ at the drive's frequency
(``orchestrator/em/skin_depth.py`` computes the frequency, from the coils' inductance for a bank, and
fills the case in before a run or a check); a set size coarser than the rule gets a warning there, not
an error. Before that, the resource guards (:mod:`.guards`) estimate an unset size with
:func:`provisional_size` from an upper bound of the source's period (:mod:`.rigid_steps`): a size no
smaller than the final one, so that the guards refuse only what is surely too large.

Units: m, rad/s, S/m.
"""

from __future__ import annotations

import math

from .rigid_steps import MU0, period_upper_bound

__all__ = ["SKIN_FRACTION", "MIN_LAYERS", "skin_depth", "default_size", "conductor_sizes", "region_sigma",
           "provisional_size"]

#: largest element size through a conductor, as a fraction of its skin depth (see the module docstring)
SKIN_FRACTION = 1.0 / 3.0
#: fewest elements through a conductor's thickness of a size that defaults from the skin depth
MIN_LAYERS = 2


def skin_depth(omega: float, sigma: float) -> float:
    """δ = sqrt(2 / (ω μ0 σ)) (m) at angular frequency ``omega`` (rad/s), conductivity ``sigma`` (S/m);
    inf for a non-conductor (σ = 0)."""
    if sigma <= 0.0:
        return math.inf
    return math.sqrt(2.0 / (omega * MU0 * sigma))


def default_size(delta: float, thickness: float) -> float:
    """The default element size (m) of a conductor of ``thickness`` (m; inf: none) with skin depth
    ``delta`` (m): min(:data:`SKIN_FRACTION` δ, thickness / :data:`MIN_LAYERS`)."""
    return min(SKIN_FRACTION * delta, thickness / MIN_LAYERS)


def conductor_sizes(g) -> list[tuple[str, float | None, float, str]]:
    """(key path, element size (m; None: unset), thickness it resolves (m; inf: none), EM region) of each
    conductor of the built-in geometry ``g``; empty for a user deck. Dies are listed with their set size
    (they default to none: a thick die meshed at δ / 3 throughout would be most of the cells)."""
    inf = math.inf
    if g.type == "flat_coil_sheet":
        out = [("geometry.mesh_size_sheet", g.mesh_size_sheet, g.sheet_thickness, "workpiece")]
        if g.die is not None:
            out.append(("geometry.die.mesh_size", g.die.mesh_size, inf, "die"))
        return out
    if g.type == "solenoid_tube":
        out = [("geometry.mesh_size_tube", g.mesh_size_tube, g.tube_thickness, "workpiece")]
        if g.outer_tube is not None:
            o = g.outer_tube
            out.append(("geometry.outer_tube.mesh_size", o.mesh_size, o.thickness, "outer_tube"))
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


def region_sigma(case, region: str) -> float:
    """Conductivity (S/m) of the body meshed in EM ``region`` (0 when no body is)."""
    body = next((b for b in case.bodies if b.region == region), None)
    return case.materials[body.material].electrical_conductivity if body is not None else 0.0


def provisional_size(case, key: str) -> float:
    """An upper estimate (m) of the default size of the unset conductor size ``key`` before the drive's
    frequency is known: :func:`default_size` at the skin depth of the lowest frequency the source's period
    bound allows; half the thickness when there is no bound."""
    _, _, thickness, region = next(c for c in conductor_sizes(case.geometry) if c[0] == key)
    period = period_upper_bound(case) if case.em is not None else None
    if period is None:
        return thickness / MIN_LAYERS
    return default_size(skin_depth(2.0 * math.pi / period, region_sigma(case, region)), thickness)
