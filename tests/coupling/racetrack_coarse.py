"""The coarse racetrack case of the tests built in Python on the 3D geometry path (the case file
cases/emf_racetrack_groove with the design's element sizes x 2: 8.2k EM tets, sheet 1.6k, die 0.6k), and the
per-EM-step bookkeeping the tests check: the loop's row, the sheet's and the die's momentum and the impulse of the
held forces on their free nodes (the nodes outside their [[bodies.fixed]] supports)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
CASE = REPO / "cases/emf_racetrack_groove"
#: the coarse sizes (the builder's parameters)
COARSE_SIZES = ("geometry.parameters.h_sheet=4e-3", "geometry.parameters.sheet_layers=2",
                "geometry.parameters.h_coil=6e-3", "geometry.parameters.h_die=8e-3")


def coarse_case(*overrides: str):
    """The validated coarse racetrack case (``overrides``: more ``key=value`` of ``--set``)."""
    from pulseform.orchestrator.case.io import load_case

    return load_case(CASE, [*COARSE_SIZES, *overrides])[0]


def coarse_participants(work: Path, *overrides: str):
    """(case, 3D solver, load, loop options, Geometry3D) of the coarse case, meshed in ``work``."""
    from pulseform.orchestrator.run.participants3d import participants_3d

    case = coarse_case(*overrides)
    solver, rigid, load, options, geo = participants_3d(case, work)
    assert rigid is None
    return case, solver, load, options, geo


def held_nodes(case, solver) -> dict[str, np.ndarray]:
    """Per body the mask of its nodes held by its [[bodies.fixed]] boxes (all components; reference positions)."""
    out = {}
    for b in case.bodies:
        X = solver.bodies[b.name].X0
        mask = np.zeros(len(X), dtype=bool)
        for f in b.fixed:
            w = f.where
            lo = np.array([w.xmin, w.ymin, w.zmin], float) - 1e-12
            hi = np.array([w.xmax, w.ymax, w.zmax], float) + 1e-12
            mask |= np.all((X >= lo) & (X <= hi), axis=1)
        out[b.name] = mask
    return out


class StepRecorder:
    """After every EM step: the loop's row with each body's momentum Σ m v_z (``<body>_momentum_z_kg_m_s``) and
    the z-impulse of the held forces on its free nodes, less the half mechanical step of the first force (the
    explicit scheme's first velocity update is a half step): ``<body>_free_impulse_z_Ns``; and the largest
    |u_z| of the sheet (``sheet_max_uz_m``)."""

    def __init__(self, case, solver, load) -> None:
        self.solver, self.load = solver, load
        self.held = held_nodes(case, solver)
        self.free = {n: 0.0 for n in self.held}
        self.first = {n: None for n in self.held}
        self.rows: list[dict] = []

    def __call__(self, row: dict) -> None:
        out = dict(row)
        for n, held in self.held.items():
            b = self.solver.bodies[n]
            own = slice(0, b.n_owned)
            f = self.load.last_forces[n][own]
            f_free = float(f[~held[own], 2].sum())
            if self.first[n] is None:
                self.first[n] = 0.5 * row["dt_s"] * f_free
            self.free[n] += row["dt_s"] * row["substeps"] * f_free
            out[f"{n}_momentum_z_kg_m_s"] = float(b.mass[own] @ b.v[own, 2])
            out[f"{n}_free_impulse_z_Ns"] = self.free[n] - self.first[n]
        sheet = self.solver.bodies["sheet"]
        out["sheet_max_uz_m"] = float(np.abs(sheet.x[:, 2] - sheet.X0[:, 2]).max())
        self.rows.append(out)
