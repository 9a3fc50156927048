"""Pressure pulses of the paper: eq. (7) P0 e^(−βt) sin²(ωt) and eq. (8) p0 e^(−t/T)."""

from __future__ import annotations

import math

import numba
import numpy as np

from ..case.model import Load, PulseExp, PulseSin2


#: columns of :func:`pulse_table`
KIND, AMPLITUDE, BETA, OMEGA, DECAY, T_START, T_END, SQUARE = range(8)


def pulse_pressure(load: Load, t: float) -> float:
    """Pressure (Pa) of a pulse at time ``t`` (s); zero outside [t_start, t_end)."""
    if t < load.t_start or t >= load.t_end:
        return 0.0
    tau = t - load.t_start
    if isinstance(load, PulseSin2):
        return load.amplitude * math.exp(-load.beta * tau) * math.sin(load.omega * tau) ** 2
    assert isinstance(load, PulseExp)
    return load.amplitude * math.exp(-tau / load.decay_time)


def sin2_pulse(t: np.ndarray, p0: float, beta: float, omega: float) -> np.ndarray:
    """Eq. (7) with its time origin at the pulse's start, vectorised (Pa; for fits and plots):
    ``p0 e^(−βt) sin²(ωt)``. :func:`pulse_pressure` and the compiled :func:`pulse_value` evaluate the
    same formula at one time (with ``math``: the run's bits)."""
    return p0 * np.exp(-beta * t) * np.sin(omega * t) ** 2


def exp_pulse(t: np.ndarray, p0: float, decay: float) -> np.ndarray:
    """Eq. (8) with its time origin at the pulse's start, vectorised (Pa): ``p0 e^(−t/T)``."""
    return p0 * np.exp(-t / decay)


def pulse_table(loads: tuple[Load, ...]) -> np.ndarray:
    """The pulses as rows [kind (0: eq. 7, 1: eq. 8), amplitude (Pa), beta (1/s), omega (rad/s),
    decay time (s), t_start (s), t_end (s), 2.0] for :func:`pulse_value`.

    The last column is the exponent of sin², read at run time so that the compiled code calls the
    C library's ``pow`` as Python's ``x ** 2`` does (with a constant 2, LLVM turns it into x·x,
    which differs from ``pow`` in the last bit for ~0.1 % of arguments; that grew to 2e-10 in the
    corner-fill history over 5000 steps)."""
    out = np.zeros((len(loads), 8))
    for i, ld in enumerate(loads):
        if isinstance(ld, PulseSin2):
            out[i] = (0.0, ld.amplitude, ld.beta, ld.omega, 0.0, ld.t_start, ld.t_end, 2.0)
        else:
            assert isinstance(ld, PulseExp)
            out[i] = (1.0, ld.amplitude, 0.0, 0.0, ld.decay_time, ld.t_start, ld.t_end, 2.0)
    return out


@numba.njit(cache=True)
def pulse_value(row: np.ndarray, t: float) -> float:
    """:func:`pulse_pressure` (Pa) of a :func:`pulse_table` row at ``t`` (s), compiled; same bits."""
    if t < row[T_START] or t >= row[T_END]:
        return 0.0
    tau = t - row[T_START]
    if row[KIND] == 0.0:
        return row[AMPLITUDE] * math.exp(-row[BETA] * tau) * math.pow(math.sin(row[OMEGA] * tau),
                                                                       row[SQUARE])
    return row[AMPLITUDE] * math.exp(-tau / row[DECAY])


def pulse_impulse_per_area(load: Load) -> float:
    """∫ p dt over the pulse window (Pa·s), closed form.

    eq. (7): ∫0^τ P0 e^(−βt) sin²(ωt) dt with sin² = (1 − cos 2ωt)/2;
    eq. (8): p0 T (1 − e^(−τ/T)).
    """
    tau = load.t_end - load.t_start
    if isinstance(load, PulseSin2):
        b, w, p0 = load.beta, load.omega, load.amplitude
        first = tau / 2.0 if b == 0.0 else (1.0 - math.exp(-b * tau)) / (2.0 * b)
        # ∫ e^(−bt) cos(2wt) dt from 0 to τ
        den = b * b + 4.0 * w * w
        second = (b + math.exp(-b * tau) * (2.0 * w * math.sin(2.0 * w * tau)
                                            - b * math.cos(2.0 * w * tau))) / den
        return p0 * (first - 0.5 * second)
    assert isinstance(load, PulseExp)
    return load.amplitude * load.decay_time * (1.0 - math.exp(-tau / load.decay_time))


