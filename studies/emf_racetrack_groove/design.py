"""The racetrack / sheet / grooved-die design of issue 20, case (b): geometry, bank and materials in one
place, for the study's own coupled run (:mod:`racetrack_run`, ``run_racetrack.py``) and its EM convergence
study (``em_convergence.py``). The case file ``cases/emf_racetrack_groove`` holds the same design in its
``[geometry.parameters]``, ``[em]`` and ``[materials]`` (run on the 3D geometry path; its slow test compares it
with this study's reference run).

Why these numbers (docs/em_geometries.md, racetrack section): the first design (C = 50 uF at 6 kV,
straight sides 50 mm long, 4 sheet layers, 2.5 mm in-plane over the coil) rang at omega ~ 1.6e5 rad/s
(skin depth 0.6 mm in Al against a 1 mm sheet) and its sheet force was not mesh-converged at an
affordable size (GCI 52 %). This design discharges a larger bank (C = 400 uF at 2.5 kV): the current's
first quarter period is ~3x longer, the skin depth ~1 mm >= the sheet's thickness, so the eddy
currents in the sheet vary more smoothly; the straight sides are shorter (30 mm, groove 20 mm long:
still a finite groove, shorter than the straight sides) and the in-plane size over the coil finer
(2 mm) for about the same number of tetrahedra. The die sits 2 mm above the sheet (0.5 mm in the first
design): the air tetrahedra between the sheet and the groove's edges invert once the sheet wraps an
edge (then the air is meshed again, orchestrator/em/remesh3d.py); with 0.5 mm that happened at 30 us
(1.2 mm deep), with 1 mm at 31-38 us, with 2 mm after the current's first half wave (52 us, coarse mesh). Lengths m, conductivities S/m,
stresses Pa.
"""

from __future__ import annotations

from dataclasses import replace

from pulseform.solvers import dolfinx as mech
from pulseform.solvers.getdp import Circuit, Conductor
from pulseform.solvers.getdp.racetrack_mesh import RacetrackGroove
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel

#: the geometry and default mesh of the coupled racetrack case
RACETRACK = replace(RacetrackGroove(), half_straight=15e-3, groove_half_length=10e-3, sheet_half_y=45e-3,
                    die_half_y=45e-3, die_gap=2e-3, sheet_layers=3, h_sheet=2e-3)
#: its capacitor bank (C F, V0 V, R_ext ohm, L_ext H)
RACETRACK_BANK = Circuit(C=400e-6, V0=2.5e3, R_ext=0.01, L_ext=0.5e-6)
#: the first design (docs/em_geometries.md): default RacetrackGroove on C = 50 uF, 6 kV
OLD_DESIGN = (RacetrackGroove(), Circuit(C=50e-6, V0=6e3, R_ext=0.01, L_ext=0.5e-6))

#: electrical conductivities (S/m) of the aluminium sheet, the steel die and the copper coil
SIGMA_SHEET, SIGMA_DIE, SIGMA_COIL = 2.5e7, 1.4e6, 5.8e7

#: aluminium sheet (AA5754-like: E 70 GPa, nu 0.33; yield 100 MPa, linear hardening 500 MPa)
SHEET_MATERIAL = mech.Material(density=2700.0, shear_modulus=26.3e9, bulk_modulus=68.6e9, yield_stress=100e6,
                               hardening_modulus=500e6)
#: tool-steel die (E 210 GPa, nu 0.3; yield 1.5 GPa: elastic in this case)
DIE_MATERIAL = mech.Material(density=7850.0, shear_modulus=80.8e9, bulk_modulus=175e9, yield_stress=1.5e9,
                             hardening_modulus=0.0)


def em_model(g: RacetrackGroove = RACETRACK, bank: Circuit | None = None, *, die_conducts: bool = True,
             sigma: tuple[float, float, float] = (SIGMA_SHEET, SIGMA_DIE, SIGMA_COIL)) -> EM3DModel:
    """The quarter model's 3D EM model: the coil (``g.turns`` turns, electrokinetic direction), the sheet
    (conductor 1) and the die (conductor 2, unless ``die_conducts`` is False: then the mesh must have the
    die as air), the bank (default :data:`RACETRACK_BANK`), the shell transformation to infinity;
    ``sigma``: the conductivities (S/m) of the sheet, the die and the coil."""
    conductors = [Conductor(sigma[0], name="sheet")] + ([Conductor(sigma[1], name="die")] if die_conducts else [])
    return EM3DModel(coils=[Coil3D(g.turns, sigma=sigma[2], direction="electrokinetic")], conductors=conductors,
                     circuit=bank or RACETRACK_BANK, shell=(g.air_radius, g.shell_radius), sector_deg=90.0)
