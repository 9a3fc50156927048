"""Temperature per cell in a run (issue 33): the history columns (per body whose material carries one, its
largest cell temperature and its volume-weighted mean, K, current cell volumes) and the stop when a cell reaches
its material's melting temperature."""

from __future__ import annotations

from typing import Callable, Mapping

import numpy as np
from mpi4py import MPI

__all__ = ["temperature_columns", "MeltingReached", "check_melting", "melting_limits"]


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


class MeltingReached(RuntimeError):
    """A cell reached its material's melting temperature; ``str()`` is one line naming the body, the cell's
    centroid, its temperature and the simulated time."""

    def __init__(self, body: str, cell: int, centroid: np.ndarray, temperature: float, melting: float,
                 time_s: float) -> None:
        self.body, self.cell, self.temperature, self.melting, self.time = body, cell, temperature, melting, time_s
        self.centroid = np.asarray(centroid, float)
        where = ", ".join(f"{c:.6g}" for c in self.centroid)
        super().__init__(f"body {body!r} melts: cell {cell} at ({where}) m reached {temperature:.6g} K >= its "
                         f"melting temperature {melting:.6g} K at t = {time_s:.6g} s; the run stops there (the "
                         "model has no melting)")


def check_melting(solver, melting: Mapping[str, float], comm: MPI.Comm) -> None:
    """Raise :class:`MeltingReached` for the hottest cell, over every body named in ``melting`` (body name ->
    melting temperature, K), whose temperature is at or above its body's melting temperature (collective over
    ``comm``: every rank raises the same error); nothing when no cell has reached it.

    The cell compared is the one with the largest excess T − T_melt; its centroid is in the current
    configuration (m; (r, z) in axisymmetry)."""
    best = (-np.inf, "", -1, np.zeros(0), 0.0, 0.0)
    for name, t_melt in sorted(melting.items()):
        b = solver.bodies.get(name)
        if b is None or not b.material.thermal or not len(b.temperature):
            continue
        e = int(np.argmax(b.temperature))
        excess = float(b.temperature[e]) - t_melt
        if excess >= 0.0 and excess > best[0]:
            best = (excess, name, e, b.x[b.cells[e]].mean(axis=0), float(b.temperature[e]), t_melt)
    if comm.size > 1:
        rank_best = comm.allreduce((best[0], comm.rank), op=MPI.MAXLOC)
        best = comm.bcast(best, root=rank_best[1])
    if best[1]:
        _, name, e, centroid, temperature, t_melt = best
        raise MeltingReached(name, e, centroid, temperature, t_melt, float(solver.time))


def melting_limits(case) -> dict[str, float]:
    """Body name -> melting temperature (K) of every deformable body of ``case`` whose material carries a
    temperature and a melting temperature (:attr:`~..case.materials.MaterialTable.melting_limit`)."""
    out = {}
    for b in case.bodies:
        mat = case.materials[b.material]
        if not b.rigid and mat.specific_heat is not None and mat.melting_limit is not None:
            out[b.name] = float(mat.melting_limit)
    return out
