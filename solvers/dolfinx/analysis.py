"""Post-processing helpers: bar-impact contact-stress metrics and the energy error."""
from __future__ import annotations

from typing import Dict, Mapping, Sequence, Tuple

import numpy as np

__all__ = ["contact_stress_metrics", "energy_error_rel", "bar_impact_metrics"]


def contact_stress_metrics(t: Sequence[float], stress: Sequence[float],
                           window: Tuple[float, float] = (0.25, 0.75),
                           threshold: float = 0.0) -> Dict[str, float]:
    """Plateau and duration of a contact-stress history (e.g. the middle of the contact surface).

    The contact lasts from the first to the last sample whose stress exceeds ``threshold``
    (the first contiguous episode); the plateau is the mean and standard deviation over the
    fraction ``window`` of that episode (the default skips the first quarter, where plane strain
    shows a plane-wave spike, and the last, where unloading begins).

    Parameters
    ----------
    t : sequence of float
        Times, s (increasing).
    stress : sequence of float
        Contact stress, Pa (compressive contact positive).
    window : (float, float)
        Start and end of the averaging window as fractions of the contact duration.
    threshold : float
        Stress above which the surfaces count as in contact, Pa.

    Returns
    -------
    dict
        ``contact_stress_plateau_MPa``, ``contact_stress_std_MPa``, ``contact_duration_ms``,
        ``contact_start_ms``, ``contact_end_ms``.
    """
    t = np.asarray(t, dtype=float)
    s = np.asarray(stress, dtype=float)
    if t.shape != s.shape or t.ndim != 1 or t.size < 3:
        raise ValueError("t and stress must be 1D arrays of equal length >= 3")
    on = s > threshold
    if not on.any():
        raise ValueError("no contact in the history")
    i0 = int(np.argmax(on))
    off = np.flatnonzero(~on[i0:])
    if off.size == 0:
        raise ValueError("contact has not ended within the history")
    i1 = i0 + int(off[0])          # first sample out of contact
    # interpolate the crossing times linearly
    def cross(j):
        if j == 0:
            return t[0]
        s0, s1 = s[j - 1] - threshold, s[j] - threshold
        return t[j - 1] + (t[j] - t[j - 1]) * (s0 / (s0 - s1)) if s1 != s0 else t[j]
    ts = cross(i0)
    te = cross(i1)
    dur = te - ts
    a, b = ts + window[0] * dur, ts + window[1] * dur
    sel = (t >= a) & (t <= b)
    # a contact shorter than the history's sampling leaves no sample in the window: no plateau (NaN)
    plateau, std = (float(s[sel].mean()), float(s[sel].std())) if sel.any() else (float("nan"), float("nan"))
    return {"contact_stress_plateau_MPa": plateau / 1e6,
            "contact_stress_std_MPa": std / 1e6,
            "contact_duration_ms": float(dur * 1e3),
            "contact_start_ms": float(ts * 1e3), "contact_end_ms": float(te * 1e3)}


def energy_error_rel(energies: Mapping[str, float], reference_energy: float) -> float:
    """|balance_error_J| / reference energy (e.g. the initial kinetic energy), dimensionless."""
    if not reference_energy > 0:
        raise ValueError("reference_energy must be > 0")
    return abs(float(energies["balance_error_J"])) / float(reference_energy)


def bar_impact_metrics(t, stress, energies_history, reference_energy,
                       window=(0.25, 0.75), threshold=0.0) -> Dict[str, float]:
    """Metrics for ``metrics.json``: contact-stress plateau, std, duration and the largest
    relative energy-balance error over the run (``energy_error_rel``)."""
    m = contact_stress_metrics(t, stress, window, threshold)
    m["energy_error_rel"] = max(energy_error_rel(e, reference_energy) for e in energies_history)
    return m
