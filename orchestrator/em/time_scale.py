"""The time scale of a coupled case's sources: the EM step of a run whose bodies are all rigid.

A deformable body sets the step through its stability limit; rigid bodies have none, so the EM step
comes from the sources instead: a number of steps (``coupling.steps_per_period``) per period of
the coil current. A prescribed current I0 e^(−βt) sin(ωt) has the period 2π/ω; a capacitor bank
rings with 2π√((L_coil + L_ext) C), L_coil the coil's low-frequency inductance from its turns'
geometry (:func:`coil_inductance`; the workpiece's eddy currents lower the effective inductance,
so the true period is somewhat shorter — the step count per period is a resolution, not an
exact figure).

Units: s, H, m.
"""

from __future__ import annotations

import math
from typing import Sequence

from ..case.model import Case
from .lumped import coil_inductance

__all__ = ["source_period"]


def source_period(case: Case, turns: Sequence[tuple[float, float, float, float]] | None) -> float:
    """Period (s) of the case's coil current: 2π/ω of a prescribed current, 2π√((L_coil + L_ext) C)
    of a capacitor bank with the coil's ``turns`` (r0, z0, r1, z1) (m; axisymmetric, None when not
    known: a user deck).

    Raises
    ------
    ValueError
        The period cannot be known (a direct current, or a bank whose coil geometry is a user deck's):
        the message asks for ``time.dt_max``.
    """
    em = case.em
    if em.current is not None:
        return 2.0 * math.pi / em.current.omega
    if turns is None:
        raise ValueError("time.dt_max: every body is rigid and the coil is a user deck's, so the EM step cannot "
                         "come from the bank's period; give time.dt_max (the mechanical step, s)")
    c = em.circuit
    return 2.0 * math.pi * math.sqrt((coil_inductance(turns) + c.inductance) * c.capacitance)
