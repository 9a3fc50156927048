"""The numbers a library-deck run of GetDP gets with ``-setnumber`` (em_case.pro's ``DefineConstant``s): the
model's regions, coils, conductors, magnetic cores and materials, circuit, shell and applied field, checked
against the mesh."""
from __future__ import annotations

from typing import Mapping

import numpy as np

from .bh_curve import model_magnetic
from .files import element_volumes
from .mesh import AXIS, OUTER, EMMesh, coil_tag, conductor_tag, core_tag
from .model import CurrentTable, DampedSine, EMModel

__all__ = ["model_deck_numbers"]



def waveform_numbers(k: int, waveform) -> dict[str, float]:
    """The deck numbers of coil ``k``'s prescribed current (both dimensions' decks): a damped sine's
    ``Coil_Wave_k = 0`` with I0 (A), beta (1/s), omega (rad/s), phase (rad), t_on (s); a table's 1 (its values
    as a deck function, :func:`~.model.table_lines`); none for a coil on the circuit."""
    if isinstance(waveform, DampedSine):
        return {f"Coil_Wave_{k}": 0, f"Coil_I0_{k}": waveform.I0, f"Coil_beta_{k}": waveform.beta,
                f"Coil_omega_{k}": waveform.omega, f"Coil_phase_{k}": waveform.phase, f"Coil_ton_{k}": waveform.t_on}
    if isinstance(waveform, CurrentTable):
        return {f"Coil_Wave_{k}": 1, f"Coil_I0_{k}": 1.0}
    return {}


def body_numbers(model, tags: np.ndarray) -> dict[str, float]:
    """``Cond_sigma_k`` (S/m) of each conductor; a conductor or magnetic core whose region has no element in the
    mesh (``tags``: the element tags, triangles or tetrahedra) is refused."""
    nb = {}
    for k, c in enumerate(model.conductors, start=1):
        if not np.any(tags == conductor_tag(k)):
            raise ValueError(f"conductor {k}: region {conductor_tag(k)} is empty in the mesh")
        nb[f"Cond_sigma_{k}"] = c.sigma
    for k in range(1, len(model.cores) + 1):
        if not np.any(tags == core_tag(k)):
            raise ValueError(f"magnetic core {k}: region {core_tag(k)} is empty in the mesh")
    return nb

def model_deck_numbers(model: EMModel, mesh: EMMesh, extra_numbers: Mapping[str, float]) -> dict[str, float]:
    """``{name: value}`` for the run deck: the model ``model`` on ``mesh`` (``extra_numbers``: the solver's own,
    e.g. ``TimeTheta``). ValueError: a mesh without the axis or a Dirichlet boundary, an empty coil or conductor
    region, an applied field under a theta other than 1."""
    m = model
    if m.axisymmetric and not np.any(mesh.line_tags == AXIS):
        raise ValueError(f"axisymmetric mesh without axis lines (physical {AXIS}): a = 0 on the axis is mandatory")
    if not np.any(np.isin(mesh.line_tags, [AXIS, OUTER])):
        raise ValueError(f"mesh has no Dirichlet boundary (physical {AXIS} or {OUTER})")
    nb = {"Flag_Axi": int(m.axisymmetric), "NbCoils": len(m.coils), "NbConductors": len(m.conductors),
          "Flag_Circuit": int(m.circuit is not None), "H0_Neu": m.h0_step, "NbProbes": len(m.probes)}
    for i, (x, y) in enumerate(m.probes, start=1):
        nb[f"Probe_X_{i}"], nb[f"Probe_Y_{i}"] = x, y
    if m.shell is not None:
        nb.update(Flag_Shell=1, Val_Rint=m.shell[0], Val_Rext=m.shell[1],
                  Val_Cx=m.shell_centre[0], Val_Cy=m.shell_centre[1])
    for k, c in enumerate(m.coils, start=1):
        area = float(element_volumes(mesh, np.flatnonzero(mesh.tri_tags == coil_tag(k)), False).sum())
        if area <= 0:
            raise ValueError(f"coil {k}: region {coil_tag(k)} is empty in the mesh")
        nb[f"Coil_Ns_{k}"] = c.turns
        nb[f"Coil_Sc_{k}"] = area
        nb[f"Coil_sigma_{k}"] = c.sigma
        if c.sign != 1:  # the deck's default is +1
            nb[f"Coil_Sign_{k}"] = c.sign
        nb.update(waveform_numbers(k, c.waveform))
    nb.update(body_numbers(m, mesh.tri_tags))
    nb.update(model_magnetic(m)[0])
    if m.circuit is not None:
        nb.update(C_bank=m.circuit.C, R_ext=m.circuit.R_ext, L_ext=m.circuit.L_ext)
    if m.applied_field is not None:
        if extra_numbers.get("TimeTheta", 1.0) != 1.0:
            raise ValueError("an applied field needs TimeTheta = 1 (its source is the implicit-Euler / BDF2 "
                             "difference of the step)")
        nb.update(m.applied_field.numbers_2d(m.axisymmetric, mesh.points, mesh.lines, mesh.line_tags, m.h0_step))
    return nb
