"""Forming-limit check of the bodies whose material has a ``forming_limit`` curve.

Per cell: the minor and major in-plane true strains ε2 <= ε1 (:mod:`.sheet_strain`), the margin below the
forming limit curve, m = FLC(ε2) − ε1 (the major-strain margin; negative: above the curve), and its zone:
0 safe (m >= safety_margin), 1 marginal (0 <= m < safety_margin), 2 failed (m < 0). The curve is the
table's points joined by straight lines and flat beyond its first and last minor strain.

:class:`FormingLimitMonitor` gives the cell fields written with the mechanical fields (``minor_strain``,
``major_strain``, ``flc_margin``, ``flc_zone``), the history column ``<body>_flc_margin_min`` (the least
margin over the body) and keeps the worst cell over the run (its margin, time, strains, deformed centroid
and index in the field file) for ``metrics.json`` and the summary. The run's driver keeps it among its
analyses (:mod:`pulseform.orchestrator.run.analyses`: the same ``record``, ``metrics``, ``plots``,
``state_dict`` hooks; checkpoint keys ``analysis/forming_limit/<body>``); the forming limit diagram is drawn
from the field files (``run/pictures_flc.py``), so that ``pulseform plot`` draws it too.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from .sheet_strain import normal_of_moments, sheet_strains

__all__ = ["FormingLimitCurve", "FormingLimitMonitor", "ZONES", "FLC_FIELDS", "WORST_KEYS", "flc_bodies",
           "forming_limit_monitor"]

log = logging.getLogger(__name__)

#: names of the zones by their number in ``flc_zone``
ZONES = ("safe", "marginal", "failed")
#: a body whose RMS spread along its sheet normal exceeds this fraction of the next smallest is no sheet
#: (a warning): a 1 mm sheet of 50 mm radius has 0.02, a square bar 1
THIN = 0.3
#: the cell fields the monitor adds to a body's field file
FLC_FIELDS = ("minor_strain", "major_strain", "flc_margin", "flc_zone")
#: the worst cell's figures in ``metrics.json`` as ``<body>_flc_<key>``: least margin (-), its time (s),
#: the cell's index in the field file, its strains (-), its deformed centroid (m)
WORST_KEYS = ("margin_min", "worst_time_s", "worst_element", "worst_minor_strain", "worst_major_strain",
              "worst_x_m", "worst_y_m", "worst_z_m")


@dataclass(frozen=True)
class FormingLimitCurve:
    """A forming limit curve: limit major true strain (-) against minor true strain (-)."""

    minor: np.ndarray
    major: np.ndarray
    safety_margin: float = 0.1

    @classmethod
    def of(cls, table) -> "FormingLimitCurve":
        """The curve of a ``forming_limit`` table (:class:`~..case.forming_limit.FormingLimitTable`)."""
        return cls(np.asarray(table.minor_strain, dtype=float), np.asarray(table.major_strain, dtype=float),
                   float(table.safety_margin))

    def limit(self, minor: np.ndarray) -> np.ndarray:
        """Major strain at necking (-) at minor strains ``minor`` (-): linear between the points, flat beyond."""
        return np.interp(minor, self.minor, self.major)

    def margin(self, minor: np.ndarray, major: np.ndarray) -> np.ndarray:
        """FLC(ε2) − ε1 (-): how far the major strain ``major`` is below the curve at ``minor``."""
        return self.limit(minor) - np.asarray(major, dtype=float)

    def zone(self, margin: np.ndarray) -> np.ndarray:
        """0 safe, 1 marginal, 2 failed (:data:`ZONES`) of margins ``margin`` (-), as floats."""
        m = np.asarray(margin, dtype=float)
        return np.where(m < 0.0, 2.0, np.where(m < self.safety_margin, 1.0, 0.0))

    def outside(self, minor: float) -> bool:
        """``minor`` (-) lies beyond the table's minor strains (the flat extension)."""
        return bool(minor < self.minor[0] or minor > self.minor[-1])


def forming_limit_monitor(case, solver) -> "FormingLimitMonitor | None":
    """The check of ``case``'s bodies with a forming limit curve in ``solver`` (None: no such body, or no
    deformable bodies)."""
    curves = flc_bodies(case)
    if solver is None or not any(n in solver.bodies for n in curves):
        return None
    return FormingLimitMonitor(curves, solver)


def flc_bodies(case) -> dict[str, FormingLimitCurve]:
    """The deformable bodies of ``case`` whose material has a ``forming_limit``, with their curves."""
    out = {}
    for b in case.bodies:
        table = case.materials[b.material].forming_limit
        if table is not None and not b.rigid:
            out[b.name] = FormingLimitCurve.of(table)
    return out


class FormingLimitMonitor:
    """The forming-limit check of a run (module docstring).

    Parameters
    ----------
    curves : dict
        Body name -> :class:`FormingLimitCurve`; bodies of ``solver`` only.
    solver : ExplicitSolver or ExplicitSolver3D
        The mechanics (its ``bodies``: ``X0``, ``x``, ``cells``, ``n_owned``; ``formulation``, ``comm``).
    """

    def __init__(self, curves: dict[str, FormingLimitCurve], solver) -> None:
        self.solver = solver
        self.comm = solver.comm
        self.curves = {n: c for n, c in curves.items() if n in solver.bodies}
        self.normals: dict[str, np.ndarray] = {}
        self.offsets: dict[str, int] = {}
        for name in self.curves:
            b = solver.bodies[name]
            own = b.X0[: b.n_owned]
            n, first, second = self._sum((float(len(own)), own.sum(axis=0), own.T @ own))
            self.normals[name], thin = normal_of_moments(n, first, second)
            # index of this rank's first cell in the field file (the writer stacks the ranks' cells in order)
            self.offsets[name] = int(self.comm.exscan(len(b.cells)) or 0) if self.comm.size > 1 else 0
            if solver.formulation != "plane_stress":
                log.info("forming limit of %s: reference sheet normal %s", name,
                         np.array2string(self.normals[name], precision=3))
                if thin > THIN and self.comm.rank == 0:
                    log.warning("forming limit of %s: the body is not thin along any axis (spread across / along "
                                "%.2g): the check assumes a sheet, its thickness direction is uncertain", name, thin)
        self.worst = {n: np.full(len(WORST_KEYS), np.nan) for n in self.curves}
        self._cache: tuple = (None, {})

    def _sum(self, parts):
        return parts if self.comm.size == 1 else tuple(self.comm.allreduce(p) for p in parts)

    def cell_fields(self, name: str, body=None) -> dict[str, np.ndarray]:
        """This rank's cell fields of body ``name`` now (:data:`FLC_FIELDS`; none for a body without a curve)."""
        if name not in self.curves:
            return {}
        key = (self.solver.step_count, self.solver.time)
        if self._cache[0] != key:
            self._cache = (key, {})
        done = self._cache[1]
        if name not in done:
            b, curve = self.solver.bodies[name], self.curves[name]
            minor, major = sheet_strains(b.X0, b.x, b.cells[:, :b.x.shape[1] + 1],   # a ten-node cell: corners
                                         self.solver.formulation, self.normals[name])
            margin = curve.margin(minor, major)
            done[name] = {"minor_strain": minor, "major_strain": major, "flc_margin": margin,
                          "flc_zone": curve.zone(margin)}
        return done[name]

    def record(self, solver=None, row: dict[str, float] | None = None) -> dict[str, float]:
        """History columns ``<body>_flc_margin_min`` (-) now; the worst cell so far is updated (``solver``,
        ``row``: an analysis's arguments, unused: the monitor knows its solver)."""
        row = {}
        for name in self.curves:
            f = self.cell_fields(name)
            local = np.full(len(WORST_KEYS), np.nan)
            if len(f["flc_margin"]):
                b = self.solver.bodies[name]
                k = int(np.argmin(f["flc_margin"]))
                centre = np.zeros(3)
                centre[: b.x.shape[1]] = b.x[b.cells[k]].mean(axis=0)
                local = np.array([f["flc_margin"][k], self.solver.time, self.offsets[name] + k,
                                  f["minor_strain"][k], f["major_strain"][k], *centre])
            best = local
            if self.comm.size > 1:   # the rank with the least margin tells its cell
                best = min(self.comm.allgather(local), key=lambda w: np.inf if np.isnan(w[0]) else w[0])
            row[f"{name}_flc_margin_min"] = float(best[0])
            if not np.isnan(best[0]) and not best[0] >= self.worst[name][0]:
                self.worst[name] = best.copy()
        return row

    def metrics(self, solver=None, history=None) -> dict[str, float]:
        """The worst cell of each body over the run: ``<body>_flc_<key>`` for :data:`WORST_KEYS`, and its
        zone ``<body>_flc_worst_zone`` (0 safe, 1 marginal, 2 failed)."""
        out = {}
        for name, w in self.worst.items():
            if np.isnan(w[0]):
                continue
            out.update({f"{name}_flc_{k}": float(v) for k, v in zip(WORST_KEYS, w)})
            out[f"{name}_flc_worst_zone"] = float(self.curves[name].zone(w[0]))
            if self.curves[name].outside(w[3]):
                log.warning("forming limit of %s: the worst cell's minor strain %.4g lies beyond the curve's "
                            "points [%.4g, %.4g]: its limit is the end point's (flat extension)", name, w[3],
                            self.curves[name].minor[0], self.curves[name].minor[-1])
        return out

    def plots(self, history, shapes, folder) -> None:
        """Nothing: the forming limit diagram is drawn from the field files (``run/pictures_flc.py``)."""

    def springback_metrics(self, sb) -> dict[str, float]:
        """Nothing after a springback (``[springback]``, a springback stage): the margin is the forming's, the worst
        over the run so far (its history columns and metrics); a springback's elastic release does not form."""
        return {}

    def state_dict(self) -> dict[str, np.ndarray]:
        """The worst cells so far, for the checkpoint."""
        return {name: w.copy() for name, w in self.worst.items()}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Take back :meth:`state_dict` (a checkpoint without it: nothing so far)."""
        for name in self.worst:
            if name in state:
                self.worst[name] = np.asarray(state[name], dtype=float).copy()
