"""The flow law of the implicit return mapping: yield stress and its slope as a function of the
equivalent plastic strain, the equivalent strain rate and the temperature, on numpy arrays (real or
complex: the implicit solver differentiates its element update by complex steps, :mod:`.implicit_element`).

One function, :func:`flow_stress`: the :class:`~.material.Material` law of the explicit kernels,
``sigma_s = sigma_y(eps_p, rate, T) * R(rate)``, with sigma_y the linear law ``sigma_0 + A eps_p`` or the
material's flow curve (:mod:`.flow_curves`: tables per strain rate and temperature, Swift, Voce, Ludwik,
Johnson-Cook; :func:`curve_stress`, the numpy twin of the compiled :func:`.flow_curves.flow_stress`) and the
optional Cowper-Symonds or Johnson-Cook factor ``R`` evaluated, as in the explicit kernels
(:func:`.element_math.rate_factor_at`, the scalar twin), at the element's total equivalent strain rate.
Complex-step safe: branches (table segments, clamps, the rate threshold) are chosen on the real parts, and
every value is an analytic function of the complex arguments within its branch. A temperature per cell
(``Material.thermal``) is not here yet: the laws are evaluated at the material's initial temperature.
"""
from __future__ import annotations

import math
from typing import Optional, Tuple

import numpy as np

from .flow_curves import JohnsonCookFlow, Ludwik, Swift, TabulatedFlow, Voce
from .material import CowperSymonds, JohnsonCook, Material

__all__ = ["flow_stress", "rate_factor", "unsupported_material", "curve_stress", "needs_rate", "is_linear"]


def rate_factor(material: Material, rate: np.ndarray) -> np.ndarray:
    """Yield-stress factor of the material's rate law at the equivalent strain rate ``rate`` (1/s).

    Parameters
    ----------
    material : Material
        Its ``rate_law`` (None: factor 1).
    rate : ndarray
        Equivalent strain rate sqrt(2/3 e:e), e the deviatoric rate of deformation, 1/s (real or complex).

    Returns
    -------
    ndarray
        The factor (dimensionless), of ``rate``'s shape and dtype.
    """
    law = material.rate_law
    one = np.ones_like(rate)
    if law is None:
        return one
    live = np.real(rate) > 0.0
    safe = np.where(live, rate, 1.0)
    if isinstance(law, CowperSymonds):
        return np.where(live, 1.0 + (safe / law.D) ** (1.0 / law.p), one)
    if isinstance(law, JohnsonCook):
        above = np.real(rate) > law.eps_rate0
        return np.where(above, 1.0 + law.C * np.log(np.where(above, safe, law.eps_rate0) / law.eps_rate0), one)
    raise TypeError(f"unknown rate law {law!r}")


def flow_stress(material: Material, eps_p: np.ndarray, rate: Optional[np.ndarray] = None,
                temperature: Optional[np.ndarray] = None) -> Tuple[np.ndarray, np.ndarray]:
    """Yield stress and its slope d sigma_s / d eps_p at the given state.

    Parameters
    ----------
    material : Material
        The material (linear hardening ``yield_stress + hardening_modulus * eps_p``, optional rate law).
    eps_p : ndarray
        Equivalent plastic strain (dimensionless), real or complex.
    rate : ndarray, optional
        Equivalent strain rate, 1/s (None: rate-independent evaluation, factor 1).
    temperature : ndarray, optional
        Temperature, K. Not used by the present laws (the hook for thermal softening).

    Returns
    -------
    sigma_s, slope : ndarray
        Yield stress (Pa) and d sigma_s / d eps_p (Pa), broadcast to ``eps_p``'s shape.
    """
    fac = 1.0 if rate is None or material.rate_law is None else rate_factor(material, rate)
    if material.flow_curve is not None:
        T = material.initial_temperature if temperature is None else temperature
        sy, slope = curve_stress(material.flow_curve, eps_p, rate, T)
        if material.rate_law is None:   # (no factor: inf * (1 + 0j) would be nan)
            return sy, slope
        return sy * fac, slope * fac
    sy = (material.yield_stress + material.hardening_modulus * eps_p) * fac
    slope = material.hardening_modulus * fac * np.ones_like(eps_p)
    return sy, slope


#: the flow curves :func:`curve_stress` evaluates
_CURVES = (TabulatedFlow, Swift, Voce, Ludwik, JohnsonCookFlow)


def needs_rate(material: Material) -> bool:
    """Whether the yield stress depends on the strain rate (a rate law, a Johnson-Cook flow curve, tables per
    strain rate)."""
    fc = material.flow_curve
    return material.rate_law is not None or isinstance(fc, JohnsonCookFlow) or (
        isinstance(fc, TabulatedFlow) and fc.rate_dependent)


def is_linear(material: Material) -> bool:
    """The yield stress is linear in eps_p at a fixed rate (the return is exact in one step)."""
    return material.flow_curve is None


def _power(k: float, x: np.ndarray, n: float) -> Tuple[np.ndarray, np.ndarray]:
    """(k x^n, d/dx k x^n) where Re x > 0; at x = 0 (0, slope inf for n < 1, k for n = 1, 0 above)."""
    pos = np.real(x) > 0.0
    xs = np.where(pos, x, 1.0)
    at0 = math.inf if n < 1.0 else (k if n == 1.0 else 0.0)
    return np.where(pos, k * xs ** n, 0.0), np.where(pos, n * k * xs ** (n - 1.0), at0)


def _bracket(grid: np.ndarray, x: np.ndarray, real: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Index i and weight w of ``x`` in the increasing ``grid`` (x ~ (1 - w) g[i] + w g[i + 1]), clamped to the
    ends (w = 0 there); the interval chosen on ``real`` (the real parts), w analytic in x."""
    n = len(grid)
    if n == 1:
        return np.zeros(x.shape, int), np.zeros_like(x)
    i = np.clip(np.searchsorted(grid, real, side="right") - 1, 0, n - 2)
    w = (x - grid[i]) / (grid[i + 1] - grid[i])
    inside = (real > grid[0]) & (real < grid[-1])
    i = np.where(real >= grid[-1], n - 1, i)
    return i, np.where(inside, w, 0.0)


def _table_curve(e: np.ndarray, S: np.ndarray, ep: np.ndarray, linear: bool) -> Tuple[np.ndarray, np.ndarray]:
    """One tabulated curve (strains ``e``, stresses ``S``) at ``ep``: piecewise linear, beyond the last point
    constant or along the last segment (``linear``)."""
    er = np.real(ep)
    i = np.clip(np.searchsorted(e, er, side="right") - 1, 0, len(e) - 2)
    h = (S[i + 1] - S[i]) / (e[i + 1] - e[i])
    s = S[i] + h * (ep - e[i])
    if not linear:
        beyond = er >= e[-1]
        s = np.where(beyond, S[-1], s)
        h = np.where(beyond, 0.0, h)
    return s, h * np.ones_like(s)


def curve_stress(curve, eps_p: np.ndarray, rate: Optional[np.ndarray], temperature) -> Tuple[np.ndarray, np.ndarray]:
    """Yield stress (Pa) and slope d sigma_y / d eps_p (Pa) of a flow curve (:mod:`.flow_curves`) at the
    equivalent plastic strain ``eps_p``, strain rate ``rate`` (1/s; None: the lowest tabulated rate, Johnson-Cook's
    reference) and temperature (K, scalar or per value): the compiled :func:`.flow_curves.flow_stress` on numpy
    arrays, complex-step safe."""
    ep = np.asarray(eps_p)
    T = np.broadcast_to(np.asarray(temperature, float), ep.shape)
    r = np.zeros(ep.shape) if rate is None else np.broadcast_to(rate, ep.shape)
    if isinstance(curve, Swift):
        return _power(curve.K, curve.eps0 + ep, curve.n)
    if isinstance(curve, Voce):
        ex = np.exp(-curve.b * ep)
        return curve.sigma0 + curve.Q * (1.0 - ex), curve.Q * curve.b * ex
    if isinstance(curve, Ludwik):
        p, h = _power(curve.K, ep, curve.n)
        return curve.sigma0 + p, h
    if isinstance(curve, JohnsonCookFlow):
        p, h = _power(curve.B, ep, curve.n)
        above = np.real(r) > curve.reference_strain_rate
        fr = np.where(above, 1.0 + curve.C * np.log(np.where(above, r, 1.0) / curve.reference_strain_rate), 1.0)
        ts = (T - curve.room_temperature) / (curve.melting_temperature - curve.room_temperature)
        th = np.where(ts >= 1.0, 0.0, np.where(ts > 0.0, 1.0 - np.clip(ts, 0.0, None) ** curve.m, 1.0))
        fin = np.isfinite(np.real(h))   # a vertical start stays inf (not inf times a complex factor: nan)
        return (curve.A + p) * fr * th, np.where(fin, np.where(fin, h, 0.0) * fr * th, np.inf)
    if isinstance(curve, TabulatedFlow):
        e = np.asarray(curve.plastic_strain, float)
        S = np.asarray(curve.yield_stress, float)
        nr, nt = max(len(curve.strain_rates), 1), max(len(curve.temperatures), 1)
        lnr = np.log(np.asarray(curve.strain_rates, float)) if curve.strain_rates else np.zeros(1)
        live = np.real(r) > 0.0
        lx = np.where(live, np.log(np.where(live, r, 1.0)), lnr[0] - 1.0)   # no rate: below the first curve's
        ir, wr = _bracket(lnr, lx, np.real(lx))
        it, wt = _bracket(np.asarray(curve.temperatures, float) if curve.temperatures else np.zeros(1), T, T)
        linear = curve.extrapolation == "linear"
        s = np.zeros(ep.shape, dtype=np.result_type(ep, r, float))
        h = np.zeros_like(s)
        for jt in range(2 if nt > 1 else 1):
            for jr in range(2 if nr > 1 else 1):
                w = ((1.0 - wt) if jt == 0 else wt) * ((1.0 - wr) if jr == 0 else wr)
                kt, kr = np.minimum(it + jt, nt - 1), np.minimum(ir + jr, nr - 1)
                for c in np.unique(kt * nr + kr):
                    on = (kt * nr + kr) == c
                    sc, hc = _table_curve(e, S[c], ep, linear)
                    s = s + np.where(on, w * sc, 0.0)
                    h = h + np.where(on, w * hc, 0.0)
        return s, h
    raise TypeError(f"unknown flow curve {curve!r}")


def unsupported_material(material: Material) -> str:
    """What of ``material`` :func:`flow_stress` does not evaluate ("" when nothing): a flow curve of a kind
    :func:`curve_stress` does not know, or a temperature per cell (the implicit solver refuses such a material
    rather than integrating it with another law, or at a constant temperature)."""
    fc = getattr(material, "flow_curve", None)
    if fc is not None and not isinstance(fc, _CURVES):
        return f"flow curve ({type(fc).__name__})"
    if getattr(material, "thermal", False):
        return "temperature (adiabatic heating, thermal softening)"
    return ""
