"""Repeated shots (issue 33, ``[em.shots]``): a sequence of bank discharges with a cooling pause between them.

Each shot is the case's time window ``time.end`` again, appended on the time axis (shot n runs from
(n − 1) × time.end to n × time.end in history.csv; the pause itself is not a time span of the history). Between
two shots:

* the coil and every deformable body with a temperature cool towards ``ambient_temperature`` by Newton's law,
  lumped per body: dT/dt = −h A (T − T_amb) / (m c_p) over the ``pause``, i.e. every cell (and the coil)
  T ← T_amb + (T − T_amb) exp(−h A pause / (m c_p)), with A the body's (the coil's) current outer surface (the
  2π r-weighted boundary in axisymmetry; per metre of depth in planar models, the faces along the depth left out;
  in 3D the modelled part's boundary triangles less those on the symmetry planes, :func:`outer_surface`) and m c_p
  its heat capacity (the modelled part's in 3D, like A: their ratio is the whole body's). There is no conduction inside a body: its temperature differences only
  shrink in proportion;
* the deformed shape, the stresses and the plastic strain carry over, the velocities and accelerations are set to
  rest (the pause is taken as long enough for the body to come to rest; its elastic stresses are kept as they
  are, not relaxed to a static equilibrium);
* the EM state starts from rest (no field, no current), the bank charged to the shot's voltage; the coil starts at
  its cooled temperature, so its σ(T) (and resistance) differ from the first shot's.

The report per shot (``shots.csv`` and the summary): the peak |coil current|, the coil's temperature at the end of
the shot and after the pause, and each body's largest and mean cell temperature at the end of the shot.
"""

from __future__ import annotations

import csv
import logging
import math
from pathlib import Path
from typing import Sequence

import numpy as np

from ..mesh.geometry3d import PlaneSpec, outer_area
from .temperature import temperature_columns

log = logging.getLogger(__name__)

__all__ = ["cooling_factor", "outer_surface", "ShotSequence"]


def cooling_factor(h: float, area: float, mass_cp: float, pause: float) -> float:
    """exp(−h A t / (m c_p)): the share of T − T_amb left after a pause of ``pause`` s (lumped Newton cooling;
    ``h`` W/(m²·K), ``area`` m², ``mass_cp`` J/K)."""
    if mass_cp <= 0:
        raise ValueError("cooling_factor: m c_p must be > 0 (J/K)")
    return math.exp(-h * area * pause / mass_cp)


def outer_surface(body, planes: Sequence[PlaneSpec] = ()) -> float:
    """The outer surface (m²) of a mechanical solver body at its current positions: in 2D its boundary's tributary
    areas (2π r-weighted in axisymmetry, per metre of depth in planar); in 3D its exterior triangles less those on
    the symmetry ``planes`` (:func:`~..mesh.geometry3d.outer_area`)."""
    if body.segments.shape[1] == 3:
        return outer_area(body.x, body.segments, planes)
    return float(body.tributary_areas(body.segments, body.x).sum())


class ShotSequence:
    """The shots of a run: their plan (``[em.shots]``), the hand-over between two shots and the report.

    Parameters
    ----------
    shots
        The case's ``em.shots`` table.
    window : float
        One shot's time window, ``time.end`` (s).
    v0 : float
        The bank's own charging voltage (V), for shots without their own.
    """

    COLUMNS = ("shot", "start_s", "end_s", "voltage_V", "peak_current_A", "coil_temperature_end_K",
               "coil_temperature_after_pause_K")

    def __init__(self, shots, window: float, v0: float) -> None:
        self.spec = shots
        self.count = int(shots.count)
        self.window = float(window)
        self.voltages = [float(v) for v in shots.voltages] or [float(v0)] * self.count
        self.rows: list[dict[str, float]] = []

    @classmethod
    def of_case(cls, case) -> "ShotSequence | None":
        """The shots of a coupled case with ``[em.shots]`` (its bank's voltage for shots without their own), else
        None."""
        if case.case.kind != "coupled" or case.em is None or case.em.shots is None:
            return None
        bank = case.em.circuit.voltage if case.em.circuit is not None else next(
            s.voltage for s in case.em.sources if s.type == "bank")
        return cls(case.em.shots, case.time.end, bank)

    def state(self, load) -> dict:
        """What a checkpoint keeps: the rows so far, the bank's voltage and the coils' start temperatures."""
        return {"rows": self.rows, **load.shot_state()}

    def load_state(self, d: dict | None, load) -> None:
        """Restore :meth:`state` (None: a checkpoint without shots, nothing to do)."""
        if d is not None:
            self.rows = [dict(r) for r in d["rows"]]
            load.load_shot_state(d)

    def start(self, n: int) -> float:
        """Start time (s) of shot ``n`` (1-based) on the history's time axis."""
        return (n - 1) * self.window

    def shot_at(self, t: float) -> int:
        """The shot (1-based) whose window holds time ``t`` (its end belongs to it)."""
        return min(self.count, max(1, math.ceil(t / self.window * (1.0 - 1e-12))))

    # ------------------------------------------------------------------ hand-over
    def cool_bodies(self, solver, planes: Sequence[PlaneSpec] = ()) -> dict[str, float]:
        """Cool every deformable body with a temperature over the pause (lumped, every cell), set its nodes to
        rest; returns the factor exp(−h A t/(m c_p)) per body (A: :func:`outer_surface`, 3D less the faces on the
        symmetry ``planes``)."""
        s = self.spec
        factors = {}
        if solver is None:
            return factors
        for name, b in solver.bodies.items():
            b.v[:] = 0.0
            b.a[:] = 0.0
            if not b.material.thermal:
                continue
            area = outer_surface(b, planes)
            mass_cp = b.total_mass() * float(b.material.specific_heat)
            f = cooling_factor(s.body_heat_transfer, area, mass_cp, s.pause)
            b.temperature[:] = s.ambient_temperature + (b.temperature - s.ambient_temperature) * f
            factors[name] = f
        return factors

    def cool_coil(self, temperature: np.ndarray, area: np.ndarray, mass_cp: np.ndarray) -> np.ndarray:
        """The coils' temperatures (K) after the pause, from ``temperature`` at the end of the shot (lumped)."""
        s = self.spec
        f = np.array([cooling_factor(s.coil_heat_transfer, a, m, s.pause) for a, m in zip(area, mass_cp)])
        return s.ambient_temperature + (np.asarray(temperature, float) - s.ambient_temperature) * f

    # ------------------------------------------------------------------ the run's shots
    def milestones(self, stops) -> list[tuple[int, float]]:
        """(shot, time) of every output milestone of the run: the milestones ``stops`` of one window, every shot."""
        return [(n, self.start(n) + float(t)) for n in range(1, self.count + 1) for t in stops]

    def end(self, n: int, history, load, solver, root: Path, write: bool) -> None:
        """Shot ``n`` reached its end: its report row from the ``history``, the EM ``load``'s coil temperatures and
        the mechanics ``solver``'s bodies (``shots.csv`` in ``root`` rewritten when ``write``)."""
        temps: dict[str, float] = {}
        for name, b in (solver.bodies.items() if solver is not None else ()):
            temps.update(temperature_columns(name, b, lambda v, op: v))   # coupled runs are serial
        row = self.record(n, history, load.coil_temperatures(), None, temps)
        if write:
            self.write(root / "shots.csv")
        log.info("shot %d of %d: peak current %.4g kA, coil at %.2f K", n, self.count, row["peak_current_A"] / 1e3,
                 row["coil_temperature_end_K"])

    def begin(self, n: int, load, solver, root: Path, write: bool) -> None:
        """The pause before shot ``n``: cool the coil and the bodies (lumped), bodies to rest, a fresh discharge of
        the EM ``load`` (``shots.csv`` in ``root`` rewritten when ``write``)."""
        coil = self.cool_coil(load.coil_temperatures(), *load.coil_heat_paths())
        self.set_after_pause(n - 1, coil)
        self.cool_bodies(solver, load.symmetry_planes)
        load.begin_shot(self.start(n), self.voltages[n - 1], coil)
        if write:
            self.write(root / "shots.csv")

    # ------------------------------------------------------------------ report
    def record(self, n: int, history, coil_end: np.ndarray, coil_after: np.ndarray | None,
               body_temps: dict[str, float]) -> dict[str, float]:
        """The report row of shot ``n`` from the history rows of its window (peak |coil current|) and the
        temperatures at its end (and the coil's after the pause; None after the last shot)."""
        t = history.column("time_s")
        t0, t1 = self.start(n), self.start(n) + self.window
        on = (t > t0 * (1 + 1e-12)) & (t <= t1 * (1 + 1e-12)) if n > 1 else (t <= t1 * (1 + 1e-12))
        cur = np.abs(history.column("coil_current_abs_max_A")[on]) if "coil_current_abs_max_A" in history.columns \
            else np.zeros(0)
        row = {"shot": float(n), "start_s": t0, "end_s": t1, "voltage_V": self.voltages[n - 1],
               "peak_current_A": float(cur.max()) if cur.size else 0.0,
               "coil_temperature_end_K": float(np.max(coil_end)) if len(coil_end) else float("nan"),
               "coil_temperature_after_pause_K": float(np.max(coil_after)) if coil_after is not None
               and len(coil_after) else float("nan")}
        row.update(body_temps)
        self.rows = [r for r in self.rows if int(r["shot"]) != n] + [row]
        return row

    def set_after_pause(self, n: int, coil_after: np.ndarray) -> None:
        """Fill shot ``n``'s coil temperature after the pause that follows it."""
        for r in self.rows:
            if int(r["shot"]) == n:
                r["coil_temperature_after_pause_K"] = float(np.max(coil_after)) if len(coil_after) else float("nan")

    def write(self, path: Path) -> None:
        """``shots.csv``: one row per shot done."""
        cols = list(self.COLUMNS) + sorted({k for r in self.rows for k in r} - set(self.COLUMNS))
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(cols)
            for r in self.rows:
                w.writerow([int(r[c]) if c == "shot" else repr(float(r.get(c, float("nan")))) for c in cols])

    def metrics(self) -> dict[str, float]:
        """metrics.json entries: per shot ``shot<n>_peak_current_kA``, ``shot<n>_coil_temperature_K`` and each
        body's ``shot<n>_<body>_temperature_max_K`` / ``_mean_K``."""
        out = {}
        for r in self.rows:
            n = int(r["shot"])
            out[f"shot{n}_peak_current_kA"] = r["peak_current_A"] / 1e3
            out[f"shot{n}_coil_temperature_K"] = r["coil_temperature_end_K"]
            for k, v in r.items():
                if k.endswith("_temperature_max_K") or k.endswith("_temperature_mean_K"):
                    out[f"shot{n}_{k}"] = v
        out["shots"] = float(len(self.rows))
        return out
