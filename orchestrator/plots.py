"""Figures of a run as PNGs (matplotlib, Agg backend, no display needed)."""

from __future__ import annotations

import logging
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .history import History  # noqa: E402
from .units import TimeAxis, label, shown, time_axis, unit_of  # noqa: E402

log = logging.getLogger(__name__)


DPI = 100


def _save(fig, path: Path, close: bool = True) -> Path:
    """Write ``fig`` atomically; fixed margins (no ``bbox_inches="tight"``, which draws twice)."""
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=DPI, pil_kwargs={"compress_level": 1})   # fast zlib level: encoding dominated
    if close:
        plt.close(fig)
    tmp.replace(path)
    return path


def _figure(height: float = 4.0):
    fig, ax = plt.subplots(figsize=(7, height))
    fig.subplots_adjust(left=0.13, right=0.97, bottom=0.13, top=0.91)
    return fig, ax


def _time_axis(history: History, axis: TimeAxis | None) -> TimeAxis:
    """The run's time unit; from the history's last time when the caller does not give it."""
    if axis is not None:
        return axis
    t = history.column("time_s")
    return time_axis(float(t[-1]) if len(t) else 0.0)


def plot_energies(history: History, folder: Path, axis: TimeAxis | None = None) -> Path:
    """Energy ledger (J) vs time (the run's time unit)."""
    axis = _time_axis(history, axis)
    t = history.column("time_s") * axis.scale
    fig, ax = _figure()
    for c in history.columns:
        if c.startswith("energy_"):
            ax.plot(t, shown(c, history.column(c)), label=c.removeprefix("energy_").removesuffix("_J"))
    ax.set_xlabel(axis.label)
    ax.set_ylabel(f"energy [{unit_of('energy_kinetic_J').shown}]")
    ax.set_title("Energy ledger")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, folder / "energies.png")


#: history columns without a plot of their own (counters, the time axis, the energies' own plot)
NOT_PLOTTED = ("time_s", "step", "dt_s", "substeps", "iterations", "em_remeshes", "coil_current_abs_max_A")


def plot_probes(history: History, folder: Path, references: dict[str, float] | None = None,
                axis: TimeAxis | None = None) -> list[Path]:
    """One figure per history column (probes, body extremes, load values), labelled with the unit
    of :mod:`.units` (``[?]`` for a column it does not know); ``references`` maps a column to a
    horizontal reference line (stored unit)."""
    references = references or {}
    axis = _time_axis(history, axis)
    t = history.column("time_s") * axis.scale
    paths = []
    fig, ax = _figure()   # one figure, its line updated per column (rebuilding axes costs more than drawing)
    (line,) = ax.plot(t, t, lw=1.0, label="computed")
    ax.set_xlabel(axis.label)
    ax.grid(alpha=0.3)
    try:
        for c in history.columns:
            if c in NOT_PLOTTED or c.startswith("energy_"):
                continue
            scale = unit_of(c).scale
            line.set_ydata(history.column(c) * scale)
            extra = []
            if c in references:
                extra = [ax.axhline(references[c] * scale, color="k", ls="--", label="reference"), ax.legend()]
            ax.relim()
            ax.autoscale_view()
            ax.set_ylabel(label(c))
            paths.append(_save(fig, folder / f"{c}.png", close=False))
            for artist in extra:
                artist.remove()
    finally:
        plt.close(fig)
    return paths


def plot_time_step(history: History, folder: Path, axis: TimeAxis | None = None) -> Path:
    """Mechanical time step (µs) vs time (the run's time unit)."""
    axis = _time_axis(history, axis)
    t = history.column("time_s") * axis.scale
    fig, ax = _figure(3.0)
    ax.plot(t[1:], shown("dt_s", history.column("dt_s")[1:]))
    ax.set_xlabel(axis.label)
    ax.set_ylabel(f"dt [{unit_of('dt_s').shown}]")
    ax.grid(alpha=0.3)
    return _save(fig, folder / "time_step.png")


def plot_em_snapshot(points, triangles, data: dict, folder: Path, t: float, box=None) -> Path:
    """Force-density magnitude (N/m³, log scale) on the moved EM mesh, mesh edges in grey."""
    import numpy as np
    from matplotlib.colors import LogNorm
    from matplotlib.tri import Triangulation

    f = np.linalg.norm(data["force_density_N_m3"][:, :2], axis=1)
    tri = Triangulation(points[:, 0] * 1e3, points[:, 1] * 1e3, triangles)
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.triplot(tri, color="0.8", lw=0.2)
    pos = f > 0
    if pos.any():
        tri_c = Triangulation(points[:, 0] * 1e3, points[:, 1] * 1e3, triangles[pos])
        pc = ax.tripcolor(tri_c, facecolors=f[pos], norm=LogNorm(vmin=f[pos].max() * 1e-3, vmax=f[pos].max()),
                          cmap="inferno")
        fig.colorbar(pc, ax=ax, label="|j × B| [N/m³]")
    coil = data["region"] // 100 == 1
    if coil.any():
        tri_k = Triangulation(points[:, 0] * 1e3, points[:, 1] * 1e3, triangles[coil])
        ax.tripcolor(tri_k, facecolors=np.ones(coil.sum()), cmap="Greens", vmin=0, vmax=2, alpha=0.6)
    if box is not None:
        ax.set_xlim(box[0] * 1e3, box[1] * 1e3)
        ax.set_ylim(box[2] * 1e3, box[3] * 1e3)
    ax.set_aspect("equal")
    ax.set_xlabel("r [mm]")
    ax.set_ylabel("z [mm]")
    ax.set_title(f"Lorentz force density, t = {t * 1e6:.1f} µs (coil in green)")
    return _save(fig, folder / "em_force_density.png")


def plot_shapes(shapes: list, folder: Path, axisymmetric: bool) -> Path:
    """Node positions of every body at each field-output time (mm), coloured by time."""
    import numpy as np

    fig, ax = plt.subplots(figsize=(8, 4))
    cmap = plt.get_cmap("viridis")
    times = [t for t, _ in shapes]
    tmax = max(times[-1], 1e-300)
    for t, bodies in shapes:
        for x in bodies.values():
            ax.plot(x[:, 0] * 1e3, x[:, 1] * 1e3, ".", ms=1.0, color=cmap(t / tmax))
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(0, tmax * 1e6))
    fig.colorbar(sm, ax=ax, label="time [µs]")
    ax.set_xlabel("r [mm]" if axisymmetric else "x [mm]")
    ax.set_ylabel("z [mm]" if axisymmetric else "y [mm]")
    ax.set_title("Shapes at the field-output times (axes not to scale)")
    ax.grid(alpha=0.3)
    return _save(fig, folder / "shapes.png")
