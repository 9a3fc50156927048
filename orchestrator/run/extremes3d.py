"""History columns of a 3D body (tetrahedra): the 2D body's extremes (``extremes.body_extremes``) plus
the z displacement and z-momentum, with the speed and von Mises stress from all three components."""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from mpi4py import MPI


def body_extremes_3d(name: str, b, reduce: Callable[[float, object], float]) -> dict[str, float]:
    """Largest |u_x|, |u_y|, |u_z| and |u_r| (m; u_r the displacement along the node's initial direction away from
    the z-axis: a tube's compression or expansion, a disk's spreading), largest speed (m/s), y- and z-momentum
    Σ m v (N·s; velocities at the last half step) and largest cell von Mises stress (Pa) of the 3D body ``b``
    (a ``Body3D``), reduced over the ranks by ``reduce`` (value, MPI op) -> value."""
    n = b.n_owned
    u = b.x[:n] - b.X0[:n]
    ext = np.abs(u).max(axis=0) if n else np.zeros(3)
    r0 = np.hypot(b.X0[:n, 0], b.X0[:n, 1])
    off = r0 > 0.0   # a node on the axis has no radial direction
    ur = float(np.abs((u[off, 0] * b.X0[:n][off, 0] + u[off, 1] * b.X0[:n][off, 1]) / r0[off]).max()) \
        if off.any() else 0.0
    speed = float(np.sqrt((b.v[:n] ** 2).sum(axis=1)).max()) if n else 0.0
    vm = float(b.von_mises.max()) if len(b.cells) else 0.0
    return {f"{name}_max_ux_m": reduce(float(ext[0]), MPI.MAX),
            f"{name}_max_uy_m": reduce(float(ext[1]), MPI.MAX),
            f"{name}_max_uz_m": reduce(float(ext[2]), MPI.MAX),
            f"{name}_max_ur_m": reduce(ur, MPI.MAX),
            f"{name}_max_speed_m_s": reduce(speed, MPI.MAX),
            f"{name}_momentum_y_Ns": reduce(float(b.mass[:n] @ b.v[:n, 1]), MPI.SUM),
            f"{name}_momentum_z_Ns": reduce(float(b.mass[:n] @ b.v[:n, 2]), MPI.SUM),
            f"{name}_max_von_mises_Pa": reduce(vm, MPI.MAX)}


def contact_columns_3d(solver) -> dict[str, float]:
    """Per contact pair of a 3D solver: the largest contact stress (Pa) and the number of slave nodes in
    contact now, as ``<slave>_<master>_contact_pressure_max_Pa`` and ``..._contact_nodes``."""
    out = {}
    for i, pair in enumerate(solver.contact_pairs):
        _, _, p, _ = solver.contact_pressure(i)
        name = f"{pair.slave}_{pair.master}"
        out[f"{name}_contact_pressure_max_Pa"] = float(p.max()) if p.size else 0.0
        out[f"{name}_contact_nodes"] = float(p.size)
    return out


def contact_metrics_3d(solver, history) -> dict[str, float]:
    """The largest contact stress of every pair over the run (Pa) and the time of the first contact (s; NaN
    without one), from the history columns of :func:`contact_columns_3d`."""
    t = history.column("time_s")
    peak, first = 0.0, math.inf
    for pair in solver.contact_pairs:
        name = f"{pair.slave}_{pair.master}"
        p, n = history.column(f"{name}_contact_pressure_max_Pa"), history.column(f"{name}_contact_nodes")
        peak = max(peak, float(p.max()))
        touching = np.flatnonzero(n > 0)
        if touching.size:
            first = min(first, float(t[touching[0]]))
    return {"contact_pressure_peak_Pa": peak, "first_contact_s": first if math.isfinite(first) else math.nan}
