"""History columns of every body's extremes, written at each history row: displacements, speed, momentum,
peak von Mises stress and, with a temperature per cell, its largest and mean value (3D bodies:
:mod:`.extremes3d`)."""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

from pulseform.solvers.dolfinx.cell_fields import j2_times_3_max, nodal_extremes

from .extremes3d import body_extremes_3d
from .temperature import temperature_columns

__all__ = ["body_extremes", "max_von_mises"]


def body_extremes(solver, comm: MPI.Comm) -> dict[str, float]:
    """Per body: largest |u_x| and |u_y| (m), largest speed (m/s), y-momentum Σ m v_y (N·s;
    full ring in axisymmetry; velocities as the solver stores them, at the last half step) and
    largest cell von Mises stress (Pa); with a temperature per cell its largest and mean value (K,
    :mod:`.temperature`). The maxima in one compiled pass over the nodes."""
    out = {}
    serial = comm.size == 1

    def reduce(value: float, op) -> float:
        return value if serial else comm.allreduce(value, op=op)

    for name, b in solver.bodies.items():
        if b.gdim == 3:
            out.update(body_extremes_3d(name, b, reduce))
            out.update(temperature_columns(name, b, reduce))
            continue
        own = slice(0, b.n_owned)
        ux, uy, sp = nodal_extremes(b.x, b.X0, b.v, b.n_owned) if b.n_owned else (0.0, 0.0, 0.0)
        out[f"{name}_max_ux_m"] = reduce(ux, MPI.MAX)
        out[f"{name}_max_uy_m"] = reduce(uy, MPI.MAX)
        out[f"{name}_max_speed_m_s"] = reduce(sp, MPI.MAX)
        out[f"{name}_momentum_y_Ns"] = reduce(float(b.mass[own] @ b.v[own, 1]), MPI.SUM)
        out[f"{name}_max_von_mises_Pa"] = reduce(max_von_mises(b.cell_stress), MPI.MAX)
        out.update(temperature_columns(name, b, reduce))
    return out


def max_von_mises(stress: np.ndarray) -> float:
    """Largest von Mises stress (Pa) of cell stresses (C, 4: xx, yy, zz, xy), as ``body.von_mises``
    but in less time (3 J2 = s·s + s_xy² − tr²/3: numpy's einsum for s·s, the rest in one compiled
    pass; it runs at every history row)."""
    if not len(stress):
        return 0.0
    q = j2_times_3_max(stress, np.einsum("ij,ij->i", stress, stress))
    return float(np.sqrt(1.5 * max(float(q), 0.0)))
