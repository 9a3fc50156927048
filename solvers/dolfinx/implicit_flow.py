"""The flow law of the implicit return mapping: yield stress and its slope as a function of the
equivalent plastic strain, the equivalent strain rate and the temperature, on numpy arrays (real or
complex: the implicit solver differentiates its element update by complex steps, :mod:`.implicit_element`).

One function, :func:`flow_stress`, so that other flow curves plug in here. Today it is the
:class:`~.material.Material` law of the explicit kernels: ``sigma_s = (sigma_0 + A eps_p) * R(rate)``
with the optional Cowper-Symonds or Johnson-Cook factor ``R`` evaluated, as in the explicit kernels
(:func:`.element_math.rate_factor_at`, the scalar twin), at the element's total equivalent strain rate.
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from .material import CowperSymonds, JohnsonCook, Material

__all__ = ["flow_stress", "rate_factor", "unsupported_material"]


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
    fac = 1.0 if rate is None else rate_factor(material, rate)
    sy = (material.yield_stress + material.hardening_modulus * eps_p) * fac
    slope = material.hardening_modulus * fac * np.ones_like(eps_p)
    return sy, slope


def unsupported_material(material: Material) -> str:
    """What of ``material`` :func:`flow_stress` does not evaluate ("" when nothing): a flow curve in place of the
    linear law, or a temperature per cell (attributes of materials that carry them; the implicit solver refuses
    such a material rather than integrating it with the linear law)."""
    if getattr(material, "flow_curve", None) is not None:
        return f"flow curve ({type(material.flow_curve).__name__})"
    if getattr(material, "thermal", False):
        return "temperature (adiabatic heating, thermal softening)"
    return ""
