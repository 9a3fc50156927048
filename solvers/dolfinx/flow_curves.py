"""Flow curves: the yield stress sigma_y(eps_p, eps_rate, T) of J2 plasticity, and its encoding for the
compiled kernels.

Laws (``Material.flow_curve``; ``None`` is the paper's linear law ``sigma_0 + A eps_p``):

* :class:`TabulatedFlow`: sigma_y(eps_p) piecewise linear through points, extrapolated beyond the last
  point as a constant or along the last segment; optionally one curve per strain rate (interpolated
  linearly in ln eps_rate) and per temperature (interpolated linearly in T), clamped outside the
  tabulated rates and temperatures;
* :class:`Swift`: ``K (eps_0 + eps_p)^n``;
* :class:`Voce`: ``sigma_0 + Q (1 - exp(-b eps_p))``;
* :class:`Ludwik`: ``sigma_0 + K eps_p^n``;
* :class:`JohnsonCookFlow`: ``(A + B eps_p^n) (1 + C ln eps_rate*) (1 - T*^m)`` with
  ``eps_rate* = eps_rate / eps_rate_0`` (the rate term is 1 below the reference rate, as the
  Johnson-Cook rate factor of :mod:`.material`) and ``T* = (T - T_room) / (T_melt - T_room)``
  (0 below room temperature; the yield stress is 0 at and above melting).

Strain rates are the element's equivalent total strain rate sqrt(2/3 d':d') (1/s), as for the rate
laws of :mod:`.material`; temperatures in K.

Encoding: the kernels' parameter vector (:func:`.kernels.pack_parameters`) holds a law id at
``P_FLOW`` and the law's parameters from ``P_FP`` on (:func:`encode`), so that one compiled kernel
serves every law. :func:`flow_stress` gives the yield stress and its slope d sigma_y / d eps_p,
:func:`flow_floor` a lower bound over every strain rate (the vectorised kernels' elastic screen),
:func:`plastic_return` the radial return's scalar equation (a safeguarded Newton iteration on the
plastic strain increment, converged to round-off).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Tuple, Union

import numba
import numpy as np

from .kernel_layout import FM, P_FLOW, P_FP, P_H, P_SY0, P_SYF, P_T0

__all__ = ["TabulatedFlow", "Swift", "Voce", "Ludwik", "JohnsonCookFlow", "FlowCurve", "encode",
           "flow_stress", "flow_floor", "plastic_return", "LAW_LINEAR", "LAW_TABLE", "LAW_SWIFT",
           "LAW_VOCE", "LAW_LUDWIK", "LAW_JOHNSON_COOK", "EXTRAPOLATIONS"]

LAW_LINEAR = 0
LAW_TABLE = 1
LAW_SWIFT = 2
LAW_VOCE = 3
LAW_LUDWIK = 4
LAW_JOHNSON_COOK = 5

#: beyond the last tabulated plastic strain: the last yield stress, or the last segment continued
EXTRAPOLATIONS = ("constant", "linear")


def _increasing(name: str, values) -> None:
    if any(not b > a for a, b in zip(values, values[1:])):
        raise ValueError(f"{name} must be strictly increasing, got {list(values)}")


@dataclass(frozen=True)
class TabulatedFlow:
    """Tabulated flow curve(s), piecewise linear in eps_p (like LS-DYNA's piecewise-linear plasticity).

    Parameters
    ----------
    plastic_strain : tuple of float
        Equivalent plastic strains of the points (-), starting at 0, strictly increasing.
    yield_stress : tuple of tuple of float
        Yield stresses (Pa, > 0): one curve (a row as long as ``plastic_strain``) per
        (temperature, strain rate), temperature-major: all strain rates of the first temperature,
        then those of the next.
    strain_rates : tuple of float
        Strain rates of the curves (1/s, > 0, strictly increasing); empty for one rate.
    temperatures : tuple of float
        Temperatures of the curves (K, > 0, strictly increasing); empty for one temperature.
    extrapolation : {"constant", "linear"}
        Beyond the last plastic strain: the last yield stress, or the last segment continued.
    """

    plastic_strain: Tuple[float, ...]
    yield_stress: Tuple[Tuple[float, ...], ...]
    strain_rates: Tuple[float, ...] = ()
    temperatures: Tuple[float, ...] = ()
    extrapolation: str = "linear"

    def __post_init__(self) -> None:
        eps = self.plastic_strain
        if len(eps) < 2 or eps[0] != 0.0:
            raise ValueError(f"plastic_strain needs at least 2 points starting at 0, got {list(eps)}")
        _increasing("plastic_strain", eps)
        _increasing("strain_rates", self.strain_rates)
        _increasing("temperatures", self.temperatures)
        if any(r <= 0 for r in self.strain_rates):
            raise ValueError(f"strain_rates must be > 0, got {list(self.strain_rates)}")
        if any(t <= 0 for t in self.temperatures):
            raise ValueError(f"temperatures must be > 0 K, got {list(self.temperatures)}")
        n_curves = max(len(self.strain_rates), 1) * max(len(self.temperatures), 1)
        if len(self.yield_stress) != n_curves:
            raise ValueError(f"yield_stress needs {n_curves} curves (one per temperature and strain rate), "
                             f"got {len(self.yield_stress)}")
        for row in self.yield_stress:
            if len(row) != len(eps):
                raise ValueError(f"each yield_stress curve needs {len(eps)} values (one per plastic_strain), "
                                 f"got {len(row)}")
            if any(not s > 0 for s in row):
                raise ValueError(f"yield stresses must be > 0, got {list(row)}")
        if self.extrapolation not in EXTRAPOLATIONS:
            raise ValueError(f"extrapolation must be one of {EXTRAPOLATIONS}, got {self.extrapolation!r}")

    @property
    def rate_dependent(self) -> bool:
        return len(self.strain_rates) > 1

    def params(self) -> np.ndarray:
        """[n_eps, n_rate, n_T, extrapolation (0 constant, 1 linear), eps..., ln rates..., T...,
        yield stresses (n_T x n_rate x n_eps)]."""
        lnr = [math.log(r) for r in self.strain_rates] or [0.0]
        temps = list(self.temperatures) or [0.0]
        head = [len(self.plastic_strain), len(lnr), len(temps), EXTRAPOLATIONS.index(self.extrapolation)]
        return np.array(head + list(self.plastic_strain) + lnr + temps
                        + [s for row in self.yield_stress for s in row], float)


@dataclass(frozen=True)
class Swift:
    """Swift law ``K (eps_0 + eps_p)^n``: K (Pa) > 0, eps_0 (-) > 0, n (-) >= 0."""

    K: float
    eps0: float
    n: float

    def __post_init__(self) -> None:
        if not (self.K > 0 and self.eps0 > 0 and self.n >= 0):
            raise ValueError("Swift needs K > 0, eps0 > 0 and n >= 0")

    def params(self) -> np.ndarray:
        return np.array([self.K, self.eps0, self.n], float)


@dataclass(frozen=True)
class Voce:
    """Voce law ``sigma_0 + Q (1 - exp(-b eps_p))``: sigma_0 (Pa) > 0, Q (Pa) >= 0, b (-) >= 0."""

    sigma0: float
    Q: float
    b: float

    def __post_init__(self) -> None:
        if not (self.sigma0 > 0 and self.Q >= 0 and self.b >= 0):
            raise ValueError("Voce needs sigma0 > 0, Q >= 0 and b >= 0")

    def params(self) -> np.ndarray:
        return np.array([self.sigma0, self.Q, self.b], float)


@dataclass(frozen=True)
class Ludwik:
    """Ludwik law ``sigma_0 + K eps_p^n``: sigma_0 (Pa) > 0, K (Pa) >= 0, n (-) > 0."""

    sigma0: float
    K: float
    n: float

    def __post_init__(self) -> None:
        if not (self.sigma0 > 0 and self.K >= 0 and self.n > 0):
            raise ValueError("Ludwik needs sigma0 > 0, K >= 0 and n > 0")

    def params(self) -> np.ndarray:
        return np.array([self.sigma0, self.K, self.n], float)


@dataclass(frozen=True)
class JohnsonCookFlow:
    """The full Johnson-Cook law ``(A + B eps_p^n) (1 + C ln eps_rate*) (1 - T*^m)``.

    Parameters
    ----------
    A : float
        Yield stress at zero plastic strain, reference rate and room temperature, Pa (> 0).
    B : float
        Hardening modulus, Pa (>= 0).
    n : float
        Hardening exponent (> 0).
    C : float
        Rate sensitivity (>= 0).
    reference_strain_rate : float
        eps_rate_0, 1/s (> 0).
    room_temperature : float
        T_room, K (> 0).
    melting_temperature : float
        T_melt, K (> T_room).
    m : float
        Thermal softening exponent (> 0).
    """

    A: float
    B: float
    n: float
    C: float = 0.0
    reference_strain_rate: float = 1.0
    room_temperature: float = 293.15
    melting_temperature: float = 1000.0
    m: float = 1.0

    def __post_init__(self) -> None:
        if not (self.A > 0 and self.B >= 0 and self.n > 0 and self.C >= 0 and self.m > 0
                and self.reference_strain_rate > 0 and self.room_temperature > 0):
            raise ValueError("JohnsonCookFlow needs A > 0, B >= 0, n > 0, C >= 0, m > 0, "
                             "reference_strain_rate > 0 and room_temperature > 0")
        if not self.melting_temperature > self.room_temperature:
            raise ValueError(f"melting_temperature ({self.melting_temperature} K) must be above "
                             f"room_temperature ({self.room_temperature} K)")

    def params(self) -> np.ndarray:
        return np.array([self.A, self.B, self.n, self.C, self.reference_strain_rate,
                         self.room_temperature, self.melting_temperature, self.m], float)


FlowCurve = Union[TabulatedFlow, Swift, Voce, Ludwik, JohnsonCookFlow]
_IDS = {TabulatedFlow: LAW_TABLE, Swift: LAW_SWIFT, Voce: LAW_VOCE, Ludwik: LAW_LUDWIK,
        JohnsonCookFlow: LAW_JOHNSON_COOK}


def encode(curve) -> Tuple[int, np.ndarray]:
    """The kernels' (law id, parameter vector) of a flow curve (``None``: the linear law, no
    parameters beyond ``P_SY0`` and ``P_H``)."""
    if curve is None:
        return LAW_LINEAR, np.zeros(0)
    try:
        return _IDS[type(curve)], curve.params()
    except KeyError:
        raise TypeError(f"unknown flow curve {curve!r}") from None


# ---------------------------------------------------------------------------------------- compiled
@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _power_slope(k, x, n):
    """(k x^n, d/dx k x^n) for x >= 0 (the slope at x = 0: inf for n < 1, k for n = 1, 0 above)."""
    if x > 0.0:
        p = k * x ** n
        return p, n * p / x
    if n < 1.0:
        return 0.0, math.inf
    return 0.0, k if n == 1.0 else 0.0


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _curve(prm, ne, ext, eo, so, ep):
    """Yield stress and slope of one tabulated curve: strains ``prm[eo:eo+ne]``, stresses
    ``prm[so:so+ne]`` at the plastic strain ``ep`` (>= 0)."""
    last = ne - 1
    if ep >= prm[eo + last]:
        if ext == 0:
            return prm[so + last], 0.0
        h = (prm[so + last] - prm[so + last - 1]) / (prm[eo + last] - prm[eo + last - 1])
        return prm[so + last] + h * (ep - prm[eo + last]), h
    lo = 0
    hi = last
    while hi - lo > 1:          # bisection: prm[eo + lo] <= ep < prm[eo + hi]
        mid = (lo + hi) // 2
        if prm[eo + mid] <= ep:
            lo = mid
        else:
            hi = mid
    e0 = prm[eo + lo]
    h = (prm[so + hi] - prm[so + lo]) / (prm[eo + hi] - e0)
    return prm[so + lo] + h * (ep - e0), h


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _bracket(prm, o, n, x):
    """Index i and weight w of ``x`` in the increasing ``prm[o:o+n]``: x ~ (1-w) p[i] + w p[i+1],
    clamped to the ends (w in [0, 1]; i = n - 1, w = 0 beyond the last)."""
    if n == 1 or x <= prm[o]:
        return 0, 0.0
    if x >= prm[o + n - 1]:
        return n - 1, 0.0
    i = 0
    while prm[o + i + 1] <= x:
        i += 1
    return i, (x - prm[o + i]) / (prm[o + i + 1] - prm[o + i])


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _table(prm, ep, rate, T, floor):
    """Tabulated law at (ep, rate 1/s, T K); ``floor``: the smallest over the rate curves instead."""
    b = P_FP
    ne = int(prm[b])
    nr = int(prm[b + 1])
    nt = int(prm[b + 2])
    ext = int(prm[b + 3])
    eo = b + 4
    ro = eo + ne
    to = ro + nr
    so = to + nt
    it, wt = _bracket(prm, to, nt, T)
    if floor and nr > 1:
        s_min = math.inf
        h_min = 0.0
        for ir in range(nr):
            s, h = _curve(prm, ne, ext, eo, so + (it * nr + ir) * ne, ep)
            if wt > 0.0:
                s1, h1 = _curve(prm, ne, ext, eo, so + ((it + 1) * nr + ir) * ne, ep)
                s = (1.0 - wt) * s + wt * s1
                h = (1.0 - wt) * h + wt * h1
            if s < s_min:
                s_min = s
                h_min = h
        return s_min, h_min
    ir, wr = 0, 0.0
    if nr > 1:
        ir, wr = _bracket(prm, ro, nr, math.log(rate) if rate > 0.0 else -math.inf)
    s = 0.0
    h = 0.0
    for jt in range(2):
        w_t = (1.0 - wt) if jt == 0 else wt
        if w_t == 0.0:
            continue
        for jr in range(2):
            w = w_t * ((1.0 - wr) if jr == 0 else wr)
            if w == 0.0:
                continue
            sc, hc = _curve(prm, ne, ext, eo, so + ((it + jt) * nr + ir + jr) * ne, ep)
            s += w * sc
            h += w * hc
    return s, h


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def flow_stress(prm, ep, rate, T):
    """Yield stress (Pa) and its slope d sigma_y / d eps_p (Pa; inf where a power law starts
    vertically) of the law in the kernel parameters ``prm`` at the equivalent plastic strain ``ep``,
    the equivalent strain rate ``rate`` (1/s) and the temperature ``T`` (K); without the rate
    factor of a separate rate law (:mod:`.material`)."""
    law = int(prm[P_FLOW])
    b = P_FP
    if law == LAW_LINEAR:
        return prm[P_SY0] + prm[P_H] * ep, prm[P_H]
    if law == LAW_TABLE:
        return _table(prm, ep, rate, T, False)
    if law == LAW_SWIFT:
        return _power_slope(prm[b], prm[b + 1] + ep, prm[b + 2])
    if law == LAW_VOCE:
        ex = math.exp(-prm[b + 2] * ep)
        return prm[b] + prm[b + 1] * (1.0 - ex), prm[b + 1] * prm[b + 2] * ex
    if law == LAW_LUDWIK:
        p, h = _power_slope(prm[b + 1], ep, prm[b + 2])
        return prm[b] + p, h
    # Johnson-Cook
    p, h = _power_slope(prm[b + 1], ep, prm[b + 2])
    f = _jc_factor(prm, rate, T)
    return (prm[b] + p) * f, h * f


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _jc_factor(prm, rate, T):
    """Johnson-Cook's rate and thermal factor (1 + C ln eps_rate*)(1 - T*^m) at ``rate`` (1/s) and ``T`` (K)."""
    b = P_FP
    r = 1.0
    if rate > prm[b + 4]:
        r = 1.0 + prm[b + 3] * math.log(rate / prm[b + 4])
    ts = (T - prm[b + 5]) / (prm[b + 6] - prm[b + 5])
    th = 1.0
    if ts >= 1.0:
        th = 0.0
    elif ts > 0.0:
        th = 1.0 - ts ** prm[b + 7]
    return r * th


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _hardening(prm, jc, ep, rate, T):
    """The yield stress and slope the return iterates on: Johnson-Cook's (A + B eps_p^n) alone (its rate
    and thermal factor, constant over a return, taken out once), any other law's :func:`flow_stress`."""
    if jc:
        p, h = _power_slope(prm[P_FP + 1], ep, prm[P_FP + 2])
        return prm[P_FP] + p, h
    return flow_stress(prm, ep, rate, T)


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def flow_floor(prm, ep, T):
    """A lower bound (Pa) of the yield stress at ``ep`` and ``T`` (K) over every strain rate, the
    rate laws' factors (>= 1) included: the vectorised kernels call a cell elastic when its trial
    stress is below it."""
    if ep == 0.0 and T == prm[P_T0]:   # a cell that has not yielded nor heated: the value at the start
        return prm[P_SYF]
    return floor_value(prm, ep, T)


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def floor_value(prm, ep, T):
    """:func:`flow_floor` evaluated (its value at the start, ``prm[P_SYF]``, is this one)."""
    if int(prm[P_FLOW]) == LAW_TABLE:
        return _table(prm, ep, 0.0, T, True)[0]
    return flow_stress(prm, ep, 0.0, T)[0]


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def plastic_return(q, G, ep, rate, T, fac, prm):
    """The plastic strain increment ``d`` of the radial return: the root of
    ``q - 3 G d - fac sigma_y(ep + d, rate, T) = 0`` (q: trial von Mises stress, Pa; G: shear
    modulus, Pa; fac: the rate law's factor), by Newton's method kept inside a bracket
    (bisection where a step leaves it, or the slope is not finite), iterated to round-off.
    Returns (d, yield stress after the return = q - 3 G d, Pa); d = 0 if q is not above the yield
    stress."""
    jc = int(prm[P_FLOW]) == LAW_JOHNSON_COOK
    if jc:
        fac = fac * _jc_factor(prm, rate, T)
    s, h = _hardening(prm, jc, ep, rate, T)
    s *= fac
    if not q > s:
        return 0.0, s
    g3 = 3.0 * G
    lo = 0.0
    hi = q / g3                   # f(hi) = -fac sigma_y <= 0
    den = g3 + fac * h
    if den > 0.0 and den < math.inf:
        d = (q - s) / den
    else:   # a power law starting vertically (eps_p = 0, n < 1): q - s = 3 G d + k d^n bounds d by each term
        law = int(prm[P_FLOW])
        k = fac * prm[P_FP + 1]
        n = prm[P_FP + 2]
        d = (q - s) / g3
        if (law == LAW_JOHNSON_COOK or law == LAW_LUDWIK) and k > 0.0:
            d = min(d, ((q - s) / k) ** (1.0 / n))
        hi = min(hi, d)           # f <= 0 there too
        d = 0.5 * d
    if not (d > lo and d < hi):
        d = 0.5 * (lo + hi)
    for _it in range(100):
        s, h = _hardening(prm, jc, ep + d, rate, T)
        f = q - g3 * d - fac * s
        if f == 0.0:
            break
        if f > 0.0:
            lo = d
        else:
            hi = d
        den = g3 + fac * h
        dn = d + f / den if (den > 0.0 and den < math.inf) else 0.5 * (lo + hi)
        if not (dn > lo and dn < hi):
            dn = 0.5 * (lo + hi)
        if abs(dn - d) <= 4e-16 * dn or hi - lo <= 4e-16 * hi:
            d = dn
            break
        d = dn
    return d, q - g3 * d
