"""The preform of the restrike corner-fill case (cases/corner_fill_restrike) on its own, and what its
results folder says of the preformed blank: the quasi-static check of docs/cases.md (the preform's
shape must not depend on how fast the pressure is ramped). Used by studies/corner_fill/preform.py and
tests/cases/test_corner_fill_sequences.py."""

from __future__ import annotations

import json
import logging
import time
from pathlib import Path

import numpy as np

from ..children import run_pulseform
from ..mech_fields import read_fields

log = logging.getLogger(__name__)

REPO = Path(__file__).resolve().parents[3]
CASE = REPO / "cases" / "corner_fill_restrike"
SHAPE_TOL = 2.0e-4  # m: 2 h0
FILL_TOL = 0.01


def run_preform(out: Path, duration: float, extra: list[str], reuse: bool = False) -> Path:
    """The preform of length ``duration`` (s) alone; returns its results folder (``reuse``: keep a
    finished one)."""
    folder = out / f"T_{duration:g}"
    if reuse and (folder / "metrics.json").is_file():
        return folder
    sets = [f"loads[0].omega={np.pi / duration:.9g}", f"loads[0].t_end={duration:.9g}",
            f"mechanics.mass_damping_until={duration:.9g}", f"mechanics.kinetic_damping_until={duration:.9g}",
            f"time.end={duration:.9g}",
            f"output.field_interval={duration / 20:.9g}"]
    t0 = time.perf_counter()
    proc = run_pulseform(["run", str(CASE), "--out", str(folder), "--force", "--quiet",
                          *[x for s in sets for x in ("--set", s)], *extra])
    log.info("T = %g ms: exit %d, %.0f s wall", duration * 1e3, proc.returncode, time.perf_counter() - t0)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-800:])
    return folder


def blank_at(folder: Path, t: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(reference coordinates, displacement) of the blank, m, at the field output nearest to t
    (s; None: the last one)."""
    blank = read_fields(folder)["blank"]
    k = len(blank.times) - 1 if t is None else int(np.argmin(np.abs(blank.times - t)))
    return blank.points[:, :2], blank.displacement(k)


def summary(folder: Path, t: float | None = None) -> dict[str, float]:
    """Fill fraction at time t (history row nearest below; None: the end) and the preform metrics."""
    m = json.loads((folder / "metrics.json").read_text())
    if t is not None:
        h = np.genfromtxt(folder / "history.csv", delimiter=",", names=True)
        i = np.flatnonzero(h["time_s"] <= t * (1 + 1e-9))[-1]
        m["fill_fraction"] = float(h["fill_fraction"][i])
        m["unfilled_length_mm"] = float(h["unfilled_length_m"][i]) * 1e3
        m["apex_gap_final_mm"] = float(h["blank_apex_gap_m"][i]) * 1e3
    return m
