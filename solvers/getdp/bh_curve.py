"""Magnetic materials of the EM participant (issue 35): a constant relative permeability μ_r or a B–H curve.

A :class:`BHCurve` is the magnetisation curve B(H) of a soft magnetic material, piecewise linear through the
given points (H in A/m, B in T) from the origin, and beyond its last point (H_n, B_n) the vacuum slope:
B = B_n + μ0 (H − H_n). Both columns must be finite, non-negative and strictly increasing; the last point must
have B_n >= μ0 H_n (a magnetised material: B < μ0 H at the top of the curve is not a magnetisation curve); B >
μ0 H is not required at low field. The origin is added when the table does not start there.

How GetDP receives it (``decks/em_magnetic.pro``): the reluctivity ν = H/B as a function of |b|², the list
``{|b|², ν, ...}`` interpolated linearly (``InterpolationLinear`` / ``dInterpolationLinear`` for the Newton
Jacobian, as GetDP's ``Lib_Materials.pro``), sampled densely enough (:data:`SUBDIVISIONS` points per segment
of the curve and a geometric vacuum tail) that the deck's h(b) follows the piecewise-linear curve to 2e-4
relative (tests/getdp/test_magnetic.py); and the energy density w(b) = ∫_0^b H dB' (J/m³; exact for the
piecewise-linear curve) on the same |b|² points, for the magnetic energy.

Each region's choice reaches the deck as ``Cond_Mag_k`` / ``Core_Mag_k`` (0 vacuum, 1 μ_r, 2 curve) with
``Cond_MuR_k`` / ``Core_MuR_k`` or the lists ``Cond_BH_k`` / ``Cond_BHw_k`` (:func:`magnetic_inputs`).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace
from pathlib import Path
import numpy as np

from .runner import GetDPError

log = logging.getLogger(__name__)

MU0 = 4e-7 * math.pi   # H/m, as the decks' mu0 = 4e-7 * Pi
#: points per segment of the curve in the deck's |b|² table
SUBDIVISIONS = 64
#: the vacuum tail of the deck's table reaches B_n + μ0 * TAIL_H (T; at least 1e3 H_n): ~1.3e3 T, never reached
TAIL_H = 1e9

__all__ = ["MU0", "BHCurve", "check_relative_permeability", "magnetic_inputs", "read_newton", "NewtonFailed",
           "newton_factor_reuse", "step_newton",
           "MagneticRegions", "model_magnetic"]


@dataclass(frozen=True)
class BHCurve:
    """B(H) through the points (``h`` A/m, ``b`` T), piecewise linear, from the origin, the vacuum slope μ0
    beyond the last point. ValueError (one line: what is wrong and what is allowed) for a bad table."""

    h: tuple[float, ...]
    b: tuple[float, ...]

    def __post_init__(self):
        h, b = np.asarray(self.h, float).ravel(), np.asarray(self.b, float).ravel()
        if h.shape != b.shape:
            raise ValueError(f"H and B need as many values, got {h.size} and {b.size}")
        if not (np.all(np.isfinite(h)) and np.all(np.isfinite(b))):
            raise ValueError("every H and B must be a finite number")
        if np.any(h < 0) or np.any(b < 0):
            raise ValueError("H and B must be >= 0 (the curve from the origin; the deck uses |b|)")
        if h.size and h[0] == 0.0 and b[0] == 0.0:
            h, b = h[1:], b[1:]
        if h.size < 2:
            raise ValueError("a B-H curve needs at least 2 points besides the origin")
        hh, bb = np.concatenate([[0.0], h]), np.concatenate([[0.0], b])
        if np.any(np.diff(hh) <= 0) or np.any(np.diff(bb) <= 0):
            raise ValueError("H and B must both be strictly increasing from the origin (0, 0)")
        if bb[-1] < MU0 * hh[-1] * (1 - 1e-12):
            raise ValueError(f"the last point has B = {bb[-1]:.6g} T < mu0 H = {MU0 * hh[-1]:.6g} T: a "
                             "magnetisation curve has B >= mu0 H at high field")
        object.__setattr__(self, "h", tuple(hh.tolist()))
        object.__setattr__(self, "b", tuple(bb.tolist()))

    def h_of_b(self, b) -> np.ndarray:
        """H (A/m) at flux densities ``b`` >= 0 (T): the piecewise-linear curve, the vacuum slope beyond."""
        b = np.asarray(b, float)
        hh, bb = np.asarray(self.h), np.asarray(self.b)
        inside = np.interp(b, bb, hh)
        return np.where(b > bb[-1], hh[-1] + (b - bb[-1]) / MU0, inside)

    def b_of_h(self, h) -> np.ndarray:
        """B (T) at fields ``h`` >= 0 (A/m): the inverse of :meth:`h_of_b`."""
        h = np.asarray(h, float)
        hh, bb = np.asarray(self.h), np.asarray(self.b)
        return np.where(h > hh[-1], bb[-1] + MU0 * (h - hh[-1]), np.interp(h, hh, bb))

    def energy_density(self, b) -> np.ndarray:
        """w(b) = ∫_0^b H dB' (J/m³), exact for the piecewise-linear curve and its vacuum tail."""
        b = np.atleast_1d(np.asarray(b, float))
        knots = np.unique(np.concatenate([np.asarray(self.b), b]))
        hk = self.h_of_b(knots)
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (hk[1:] + hk[:-1]) * np.diff(knots))])
        return np.interp(b, knots, cum)

    def deck_tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(|b|² T², ν m/H, w J/m³): the deck's tables (module docstring), |b|² strictly increasing from 0."""
        bb = np.asarray(self.b)
        parts = [np.linspace(bb[i], bb[i + 1], SUBDIVISIONS + 1)[:-1] for i in range(len(bb) - 1)]
        hn = max(self.h[-1], 1.0)   # the tail: dense up to 100 H_n (where H/B still changes), then geometric
        tail = bb[-1] + MU0 * np.concatenate([np.geomspace(1e-3 * hn, 100 * hn, 256),
                                              np.geomspace(100 * hn, max(TAIL_H, 1e3 * hn), 128)[1:]])
        b = np.concatenate(parts + [[bb[-1]], tail])
        nu = np.empty_like(b)
        nu[1:] = self.h_of_b(b[1:]) / b[1:]
        nu[0] = self.h[1] / self.b[1]   # ν at b -> 0: the first segment's slope
        return b ** 2, nu, self.energy_density(b)

    @classmethod
    def from_any(cls, value) -> "BHCurve | None":
        """A curve from a :class:`BHCurve`, a dict ``{"h": [...], "b": [...]}`` (a state or a model's JSON), or
        None."""
        if value is None or isinstance(value, cls):
            return value
        return cls(h=tuple(value["h"]), b=tuple(value["b"]))


def check_relative_permeability(mu_r: float) -> float:
    """``mu_r`` as a float; ValueError unless it is finite and > 0."""
    v = float(mu_r)
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"a relative permeability must be a finite number > 0, got {mu_r!r}")
    return v


def _list_line(name: str, x: np.ndarray, y: np.ndarray) -> str:
    """``name() = {x0, y0, x1, y1, ...};`` with exact round-trip values."""
    pairs = [f"{float(a)!r}, {float(c)!r}" for a, c in zip(x, y)]
    body = ",\n  ".join(", ".join(pairs[j:j + 6]) for j in range(0, len(pairs), 6))
    return f"{name}() = {{\n  {body}}};"


def magnetic_inputs(prefix: str, k: int, mu_r: float, curve: BHCurve | None) -> tuple[dict[str, float], list[str]]:
    """The deck numbers and list lines of region ``prefix``\\ ``k`` (``"Cond"`` or ``"Core"``; module docstring):
    nothing for a conductor in vacuum (μ_r = 1, no curve) so that the default deck runs as before."""
    if curve is not None:
        b2, nu, w = curve.deck_tables()
        return ({f"{prefix}_Mag_{k}": 2},
                [_list_line(f"{prefix}_BH_{k}", b2, nu), _list_line(f"{prefix}_BHw_{k}", b2, w)])
    if prefix == "Cond" and mu_r == 1.0:
        return {}, []
    return {f"{prefix}_Mag_{k}": 1, f"{prefix}_MuR_{k}": float(mu_r)}, []


class NewtonFailed(GetDPError):
    """Newton's iterations of an EM step ended above the tolerance (a one-line message; the run's outputs so
    far are kept, as after any failed getdp run)."""


def read_newton(out_dir: Path, tol_rel: float, tol_abs: float, max_iter: int, *,
                log_path: Path | None = None, last: bool = False) -> list[int]:
    """The linear solves of every time step of a run (first solve + Newton iterations) from
    ``out_dir/newton.txt`` (``decks/Lib_Newton.pro``: time, iterations, residual norm, right-hand side's norm;
    [] without a nonlinear material). NewtonFailed when a step stopped with its residual above ``tol_rel`` times
    the right-hand side's norm and above ``tol_abs``. ``last``: only the file's last line, read from its end (the
    persistent getdp appends one line per EM step to the same file: :mod:`.persistent`)."""
    path = Path(out_dir) / "newton.txt"
    if not path.is_file():
        return []
    if last:
        with open(path, "rb") as f:
            f.seek(max(0, f.seek(0, 2) - 4096))
            lines = f.read().decode().split("\n")
        rows = np.array([[float(x) for x in ln.split()] for ln in lines if ln.strip()][-1:]).reshape(-1, 4)
    else:
        rows = np.loadtxt(path, ndmin=2)
    counts = []
    for t, it, res, rhs in rows:
        if not (res <= tol_abs or res <= tol_rel * rhs):
            raise NewtonFailed(f"Newton's iterations stopped at t = {t:.6g} s with a residual "
                               f"{res / rhs if rhs > 0 else math.inf:.2g} of the right-hand side after {int(it)} "
                               f"(em.newton_tolerance = {tol_rel:g}, em.newton_max_iterations = {max_iter})",
                               log_path=log_path, run_dir=Path(out_dir).parent)
        counts.append(int(it) + 1)
    return counts


def newton_factor_reuse(model, factor_reuse):
    """A persistent getdp's :class:`~.persistent_process.FactorReuse` for ``model``: with a B–H curve every
    Newton iteration factorises its own Jacobian (``decks/Lib_PersistentStep.pro``), so no factors are kept
    (``tol`` 0; logged when the case asked for them); unchanged for a linear model."""
    if not model.is_nonlinear or factor_reuse.tol <= 0.0:
        return factor_reuse
    log.info("a B-H curve: every Newton iteration factorises its Jacobian, no LU factors are kept across EM steps "
             "(em.factor_reuse_tol %g not used)", factor_reuse.tol)
    return replace(factor_reuse, tol=0.0)


def step_newton(model, proc) -> list[int] | None:
    """The linear solves (first + Newton's) of the step a persistent getdp process ``proc``
    (:class:`~.persistent_process.PersistentProcess`) has just answered: the last line of its ``newton.txt``
    (:func:`read_newton`; NewtonFailed above the tolerance). None for a linear model."""
    if not model.is_nonlinear:
        return None
    return read_newton(proc.out_dir, model.newton_tolerance, 0.0, model.newton_max_iterations,
                       log_path=proc.log_path, last=True)


def model_magnetic(model) -> tuple[dict[str, float], list[str]]:
    """The deck numbers and list lines of an :class:`~.model.EMModel`'s magnetic materials: each conductor's
    and core's (:func:`magnetic_inputs`), ``NbCores``, and Newton's ``NL_tol_rel`` / ``NL_iter_max`` when a
    region has a B–H curve. Nothing for a model in vacuum (the decks' defaults)."""
    numbers: dict[str, float] = {}
    lines: list[str] = []
    for prefix, regions in (("Cond", model.conductors), ("Core", model.cores)):
        for k, r in enumerate(regions, start=1):
            nb, ln = magnetic_inputs(prefix, k, r.mu_r, r.bh_curve)
            numbers.update(nb)
            lines += ln
    if model.cores:
        numbers["NbCores"] = len(model.cores)
    if model.is_nonlinear:
        numbers.update(NL_tol_rel=model.newton_tolerance, NL_iter_max=model.newton_max_iterations)
    return numbers, lines


class MagneticRegions:
    """What the 2D and 3D EM models (:class:`~.model.EMModel`, :class:`~.solver3d.EM3DModel`) share about their
    magnetic materials: their ``conductors`` and ``cores`` (each with ``mu_r`` and ``bh_curve``), Newton's
    ``newton_tolerance`` (relative to the right-hand side's norm) and ``newton_max_iterations``, and ``applied_field``."""

    def check_magnetic(self) -> None:
        """Build the cores from dicts and check Newton's settings; ValueError for an applied field beside a
        magnetic material (the reduced-field split's source is exact only with μ0 everywhere)."""
        from .model import MagneticCore

        self.cores = [c if isinstance(c, MagneticCore) else MagneticCore(**c) for c in self.cores]
        if not (0 < self.newton_tolerance < 1) or int(self.newton_max_iterations) < 1:
            raise ValueError("newton_tolerance must be in (0, 1) and newton_max_iterations >= 1")
        self.newton_max_iterations = int(self.newton_max_iterations)
        if self.applied_field is not None and self.is_magnetic:
            raise ValueError("an applied field (the reduced-field split) needs mu0 everywhere: its source is "
                             "exact only where nu is uniform; model the field's source as a coil instead")

    @property
    def is_magnetic(self) -> bool:
        """True when a conductor or a core has μ_r != 1 or a B–H curve."""
        return any(r.mu_r != 1.0 or r.bh_curve is not None for r in list(self.conductors) + list(self.cores))

    @property
    def is_nonlinear(self) -> bool:
        """True when a conductor or a core has a B–H curve (Newton's iterations in every step)."""
        return any(r.bh_curve is not None for r in list(self.conductors) + list(self.cores))
