"""Figures of a run as PNGs (matplotlib, Agg backend, no display needed)."""

from __future__ import annotations

import logging
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .history import History  # noqa: E402

log = logging.getLogger(__name__)


def _save(fig, path: Path) -> Path:
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=110, bbox_inches="tight")
    plt.close(fig)
    tmp.replace(path)
    return path


def plot_energies(history: History, folder: Path) -> Path:
    """Energy ledger vs time (ms, J)."""
    t = history.column("time_s") * 1e3
    fig, ax = plt.subplots(figsize=(7, 4))
    for c in history.columns:
        if c.startswith("energy_"):
            ax.plot(t, history.column(c), label=c.removeprefix("energy_").removesuffix("_J"))
    ax.set_xlabel("time [ms]")
    ax.set_ylabel("energy [J]")
    ax.set_title("Energy ledger")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, folder / "energies.png")


def plot_probes(history: History, folder: Path, references: dict[str, float] | None = None) -> list[Path]:
    """One figure per probe column; ``references`` maps a column to a horizontal reference (same unit)."""
    references = references or {}
    t = history.column("time_s") * 1e3
    paths = []
    skip = ("time_s", "step", "dt_s")
    for c in history.columns:
        if c in skip or c.startswith("energy_"):
            continue
        y = history.column(c)
        scale, unit = (1e-6, "MPa") if c.endswith("_Pa") else (1.0, c.rsplit("_", 1)[-1])
        fig, ax = plt.subplots(figsize=(7, 4))
        ax.plot(t, y * scale, lw=1.0, label="computed")
        if c in references:
            ax.axhline(references[c] * scale, color="k", ls="--", label="reference")
            ax.legend()
        ax.set_xlabel("time [ms]")
        ax.set_ylabel(f"{c} [{unit}]")
        ax.grid(alpha=0.3)
        paths.append(_save(fig, folder / f"{c}.png"))
    return paths


def plot_time_step(history: History, folder: Path) -> Path:
    """Mechanical time step vs time (µs)."""
    t = history.column("time_s") * 1e3
    fig, ax = plt.subplots(figsize=(7, 3))
    ax.plot(t[1:], history.column("dt_s")[1:] * 1e6)
    ax.set_xlabel("time [ms]")
    ax.set_ylabel("dt [µs]")
    ax.grid(alpha=0.3)
    return _save(fig, folder / "time_step.png")
