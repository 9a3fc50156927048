"""EM figures for ``metrics.json``."""
from __future__ import annotations

from typing import Sequence

import numpy as np


def em_metrics(results: Sequence, conductors: Sequence[int] | None = None, *,
               axisymmetric: bool = False) -> dict[str, float]:
    """Metrics of an EM run from its consecutive :class:`EMStepResult` objects.

    - ``coil_current_peak_kA``: max |I| over all coils and sub-steps (kA);
    - ``force_impulse_Ns``: |integral of the net force on the selected conductors dt|
      (rectangle rule over implicit Euler sub-steps, consistent with the scheme);
      ``conductors`` are 0-based indices, default all massive conductors. With ``axisymmetric``
      the net force is the axial one (a ring's summed radial load has no net force: zero by
      symmetry), and ``radial_load_impulse_Ns`` is the integral of the summed radial load
      (N s, full ring, positive outward);
    - ``coil_joule_heat_J``: Joule heat accumulated in all coils (J);
    - ``coil_temperature_rise_K``: largest adiabatic temperature rise of a coil (K).
    """
    if not results:
        raise ValueError("no EM results")
    peak = max(float(np.abs(r.coil_current).max()) if r.coil_current.size else 0.0 for r in results)
    impulse = np.zeros(2)
    for r in results:
        f = r.conductor_force if conductors is None else r.conductor_force[:, list(conductors)]
        impulse += f.sum(axis=1).sum(axis=0) * r.dt
    last = results[-1]
    net = abs(float(impulse[1])) if axisymmetric else float(np.linalg.norm(impulse))
    radial = {"radial_load_impulse_Ns": float(impulse[0])} if axisymmetric else {}
    return {
        "coil_current_peak_kA": peak / 1e3,
        "force_impulse_Ns": net, **radial,
        "coil_joule_heat_J": float(np.sum(last.coil_heat)),
        "coil_temperature_rise_K": float(np.max(last.coil_temperature_rise)) if last.coil_heat.size else 0.0,
    }
