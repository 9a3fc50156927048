"""The time scale of a coupled case's sources: the EM step of a run whose bodies are all rigid.

A deformable body sets the step through its stability limit; rigid bodies have none, so the EM step
comes from the sources instead: a number of steps (``coupling.steps_per_period``) per period of the
shortest-period coil current. A sine (or the prescribed current I0 e^(−βt) sin(ωt)) has the period
1/f = 2π/ω; a capacitor bank rings with 2π√((L + L_ext) C), L the low-frequency inductance of the
coils in series on it from their windings' geometry (:func:`coils_on_bank`, signs and turns included;
the conductor's eddy currents lower the effective inductance, so the true period is somewhat
shorter — the steps per period are a resolution, not an exact figure). Direct currents and tables
have no period: such runs take ``time.dt_max`` (the case model asks for it).

Units: s, H, m.
"""

from __future__ import annotations

import math

from ..case.model import Case
from ..mesh.em_geometry import coaxial_coil_turns, flat_coil_turns, planar_turns, solenoid_turns
from .lumped import coil_inductance

__all__ = ["coil_windings", "rigid_mechanical_step", "source_period", "steps_per_period"]


def coil_windings(case: Case) -> list[list[tuple[float, float, float, float]]] | None:
    """The winding sections (r0, z0, r1, z1) (m) of each coil of the case's built-in geometry, in coil
    order; None for a user deck (its coils are known once meshed)."""
    g = case.geometry
    if g.type == "coaxial_coils":
        rects = coaxial_coil_turns(g)
    elif g.type == "flat_coil_sheet":
        rects = [flat_coil_turns(g)]
    elif g.type == "solenoid_tube":
        rects = [solenoid_turns(g)]
    elif g.type == "planar_coil_blank_die":
        rects = [planar_turns(g)]
    else:
        return None
    return [[(r.x0, r.y0, r.x1, r.y1) for r in coil] for coil in rects]


def _bank_inductance(case: Case, coils: list[tuple[int, int]]) -> float:
    """Inductance (H) of the coils ``(index, sign)`` in series: their turns spread over their windings by area."""
    windings = coil_windings(case)
    g = case.geometry
    rects, counts = [], []
    for k, sign in coils:
        turns = g.coils[k].turns if g.type == "coaxial_coils" else g.turns
        areas = [(w[2] - w[0]) * (w[3] - w[1]) for w in windings[k]]
        rects += windings[k]
        counts += [sign * turns * a / sum(areas) for a in areas]
    return coil_inductance(rects, counts)


def source_period(case: Case) -> float:
    """The shortest period (s) of the case's coil currents (see the module docstring).

    Raises
    ------
    ValueError
        No source has a period, or the bank's coils are a user deck's: the message asks for ``time.dt_max``.
    """
    em, g = case.em, case.geometry
    periods = []
    if not em.sources:
        if em.current is not None:
            return 2.0 * math.pi / em.current.omega
        if coil_windings(case) is not None:
            c = em.circuit
            periods.append(2.0 * math.pi * math.sqrt((_bank_inductance(case, [(0, 1)]) + c.inductance) * c.capacitance))
    else:
        order = [c.name for c in g.coils] if g.type == "coaxial_coils" else [c.name for c in em.coils]
        for s in em.sources:
            if s.type == "sine":
                periods.append(1.0 / s.frequency)
            elif s.type == "bank" and coil_windings(case) is not None:
                on_bank = [(order.index(c.name), c.sign) for c in em.coils if c.source == s.name]
                periods.append(2.0 * math.pi * math.sqrt((_bank_inductance(case, on_bank) + s.inductance)
                                                         * s.capacitance))
    if not periods:
        raise ValueError("time.dt_max: every body is rigid and no source has a period to resolve (a direct current, "
                         "a table, a user deck's coil on a bank, or a template deck's own source): give time.dt_max, the mechanical step (s)")
    return min(periods)


def steps_per_period(case: Case) -> float | None:
    """The EM steps per period of the shortest-period source that a run whose bodies are all rigid makes: the
    period over its EM step min(period / ``coupling.steps_per_period``, ``coupling.n`` · ``time.dt_max``)
    (the driver's rigid step); None when the case has deformable bodies (their stability limit sets the step), is
    3D (``geometry.em_step`` sets it) or has no source with a period."""
    if case.case.kind != "coupled" or not case.bodies or not all(b.rigid for b in case.bodies) \
            or case.mechanics.formulation == "3d":
        return None
    try:
        period = source_period(case)
    except ValueError:  # no source with a period: time.dt_max sets the step
        return None
    return period / (case.coupling.n * rigid_mechanical_step(case))


def rigid_mechanical_step(case: Case) -> float:
    """The mechanical step (s) of a run whose bodies are all rigid: a period of the shortest-period source over
    ``coupling.steps_per_period`` EM steps of ``coupling.n`` mechanical steps each, capped by ``time.dt_max``
    (which alone sets it when no source has a period: the case model has made sure it is given); an implicit run
    (``mechanics.integrator = "implicit"``): its ``mechanics.implicit.dt``, capped by ``time.dt_max``."""
    im = case.mechanics.implicit
    if case.mechanics.integrator == "implicit" and im.dt is not None:
        return im.dt if case.time.dt_max is None else min(im.dt, case.time.dt_max)
    try:
        dt = source_period(case) / (case.coupling.steps_per_period * case.coupling.n)
    except ValueError:
        return case.time.dt_max
    return dt if case.time.dt_max is None else min(dt, case.time.dt_max)
