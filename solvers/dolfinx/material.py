"""Material data: isotropic elasticity, J2 plasticity with linear hardening or a flow curve
(:mod:`.flow_curves`), optional rate laws, optional temperature per cell (adiabatic heating)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Union

from .flow_curves import FlowCurve, JohnsonCookFlow, TabulatedFlow, _IDS as _FLOW_TYPES

__all__ = ["CowperSymonds", "JohnsonCook", "Material", "RATE_NONE", "RATE_COWPER_SYMONDS",
           "RATE_JOHNSON_COOK"]

RATE_NONE = 0
RATE_COWPER_SYMONDS = 1
RATE_JOHNSON_COOK = 2


@dataclass(frozen=True)
class CowperSymonds:
    """Cowper-Symonds rate factor ``1 + (eps_rate / D) ** (1 / p)`` on the yield stress.

    Parameters
    ----------
    D : float
        Reference strain rate, 1/s.
    p : float
        Exponent (dimensionless).
    """

    D: float
    p: float

    def __post_init__(self) -> None:
        if not (self.D > 0 and self.p > 0):
            raise ValueError("CowperSymonds needs D > 0 and p > 0")


@dataclass(frozen=True)
class JohnsonCook:
    """Johnson-Cook rate factor ``1 + C ln(max(eps_rate / eps_rate0, 1))`` on the yield stress.

    Parameters
    ----------
    C : float
        Rate sensitivity (dimensionless).
    eps_rate0 : float
        Reference strain rate, 1/s.
    """

    C: float
    eps_rate0: float = 1.0

    def __post_init__(self) -> None:
        if not (self.C >= 0 and self.eps_rate0 > 0):
            raise ValueError("JohnsonCook needs C >= 0 and eps_rate0 > 0")


RateLaw = Union[CowperSymonds, JohnsonCook]


@dataclass(frozen=True)
class Material:
    """Isotropic hypo-elastic, J2-plastic material with isotropic hardening.

    The yield stress is ``sigma_s = (yield_stress + hardening_modulus * eps_p) * rate_factor``
    (the paper's ``sigma_s = sigma_0 + A eps``), or, with a ``flow_curve``, that curve's
    sigma_y(eps_p, eps_rate, T) times the rate factor.  The rate factor of the optional rate law is
    evaluated with the element's total equivalent strain rate (as LS-DYNA does by default).

    With a ``specific_heat`` every cell carries a temperature T (K), raised by the plastic work
    alone, adiabatically (no conduction: the pulse lasts microseconds to a millisecond, far shorter
    than heat diffusion over an element): ``rho c_p dT = beta sigma_y d eps_p`` per cell (the
    solver's ``heat_cells`` adds Joule heat). The flow curve softens with it (Johnson-Cook's T*
    term, or per-temperature tables).

    Parameters
    ----------
    density : float
        Mass density, kg/m^3.
    shear_modulus : float
        G, Pa.
    bulk_modulus : float
        K, Pa.
    yield_stress : float
        Initial yield stress sigma_0, Pa.
    hardening_modulus : float
        Linear hardening modulus A (d sigma_s / d eps_p), Pa.
    rate_law : CowperSymonds or JohnsonCook, optional
        Strain-rate hardening law; ``None`` for rate independence.
    flow_curve : TabulatedFlow, Swift, Voce, Ludwik or JohnsonCookFlow, optional
        Flow curve (:mod:`.flow_curves`) in place of the linear law (``yield_stress`` and
        ``hardening_modulus`` are then not used by the kernels); ``None``: the linear law.
    specific_heat : float, optional
        c_p, J/(kg K): track a temperature per cell; ``None``: no temperature.
    taylor_quinney : float
        beta, the fraction of the plastic work turned into heat (0..1, default 0.9).
    initial_temperature : float
        Temperature of every cell at the start, K (default 293.15).
    """

    density: float
    shear_modulus: float
    bulk_modulus: float
    yield_stress: float
    hardening_modulus: float
    rate_law: Optional[RateLaw] = None
    flow_curve: Optional[FlowCurve] = None
    specific_heat: Optional[float] = None
    taylor_quinney: float = 0.9
    initial_temperature: float = 293.15

    def __post_init__(self) -> None:
        for name in ("density", "shear_modulus", "bulk_modulus", "yield_stress"):
            if not getattr(self, name) > 0:
                raise ValueError(f"Material.{name} must be > 0, got {getattr(self, name)!r}")
        if self.hardening_modulus < 0:
            raise ValueError("Material.hardening_modulus must be >= 0")
        if self.rate_law is not None and not isinstance(self.rate_law, (CowperSymonds, JohnsonCook)):
            raise TypeError("rate_law must be CowperSymonds, JohnsonCook or None")
        fc = self.flow_curve
        if fc is not None and type(fc) not in _FLOW_TYPES:
            raise TypeError(f"flow_curve must be one of {[t.__name__ for t in _FLOW_TYPES]} or None")
        if self.rate_law is not None and (isinstance(fc, JohnsonCookFlow) or (
                isinstance(fc, TabulatedFlow) and fc.rate_dependent)):
            raise ValueError("a rate_law with a flow_curve that has its own rate dependence "
                             "(Johnson-Cook, or tables per strain rate) would count the rate twice")
        if self.specific_heat is not None and not self.specific_heat > 0:
            raise ValueError(f"Material.specific_heat must be > 0, got {self.specific_heat!r}")
        if not 0.0 <= self.taylor_quinney <= 1.0:
            raise ValueError(f"Material.taylor_quinney must be in [0, 1], got {self.taylor_quinney!r}")
        if not self.initial_temperature > 0:
            raise ValueError(f"Material.initial_temperature must be > 0 K, got {self.initial_temperature!r}")
        if isinstance(fc, JohnsonCookFlow) and not self.initial_temperature < fc.melting_temperature:
            raise ValueError(f"Material.initial_temperature ({self.initial_temperature} K) must be below "
                             f"the melting temperature ({fc.melting_temperature} K)")

    @property
    def thermal(self) -> bool:
        """Whether every cell carries a temperature (a specific heat is given)."""
        return self.specific_heat is not None

    @property
    def youngs_modulus(self) -> float:
        """E = 9KG / (3K + G), Pa."""
        K, G = self.bulk_modulus, self.shear_modulus
        return 9.0 * K * G / (3.0 * K + G)

    @property
    def poisson_ratio(self) -> float:
        """nu = (3K - 2G) / (2 (3K + G)), dimensionless."""
        K, G = self.bulk_modulus, self.shear_modulus
        return (3.0 * K - 2.0 * G) / (2.0 * (3.0 * K + G))

    @property
    def dilatational_wave_speed(self) -> float:
        """sqrt((K + 4G/3) / rho), m/s (the fastest wave; used for the stable time step)."""
        return math.sqrt((self.bulk_modulus + 4.0 * self.shear_modulus / 3.0) / self.density)

    @property
    def bar_wave_speed(self) -> float:
        """1D bar speed sqrt(E / rho), m/s."""
        return math.sqrt(self.youngs_modulus / self.density)

    @property
    def plane_strain_bar_wave_speed(self) -> float:
        """Bar speed in plane strain sqrt(E / (rho (1 - nu^2))), m/s."""
        nu = self.poisson_ratio
        return math.sqrt(self.youngs_modulus / (self.density * (1.0 - nu * nu)))

    def rate_parameters(self) -> tuple[int, float, float]:
        """Kernel encoding of the rate law: (law id, parameter 1, parameter 2)."""
        law = self.rate_law
        if law is None:
            return RATE_NONE, 0.0, 0.0
        if isinstance(law, CowperSymonds):
            return RATE_COWPER_SYMONDS, float(law.D), float(law.p)
        return RATE_JOHNSON_COOK, float(law.C), float(law.eps_rate0)
