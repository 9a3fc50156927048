"""History columns of the temperature per cell (issue 33): per body whose material carries one, its
largest cell temperature and its volume-weighted mean (K, current cell volumes)."""

from __future__ import annotations

from typing import Callable

import numpy as np
from mpi4py import MPI

__all__ = ["temperature_columns"]


def temperature_columns(name: str, body, reduce: Callable[[float, object], float]) -> dict[str, float]:
    """``<name>_temperature_max_K`` and ``<name>_temperature_mean_K`` of the solver body ``body`` (2D or 3D;
    empty without a temperature), reduced over the ranks by ``reduce`` (value, MPI op) -> value."""
    if not body.material.thermal:
        return {}
    T = body.temperature
    vol = np.abs(body.cell_volumes())
    tmax = reduce(float(T.max()) if len(T) else -np.inf, MPI.MAX)
    heat = reduce(float(vol @ T), MPI.SUM)
    total = reduce(float(vol.sum()), MPI.SUM)
    return {f"{name}_temperature_max_K": tmax, f"{name}_temperature_mean_K": heat / total if total > 0 else tmax}
