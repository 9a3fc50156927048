"""The step of a coupled case whose bodies are all rigid, bounded before anything is meshed: the
resource guards' estimate (:mod:`.guards`) and the check that such a case has a time scale at all.

A rigid body has no stability limit: its run's EM step is a period of the source over
``coupling.steps_per_period`` (``orchestrator/em/time_scale.py`` computes the period from the coils'
geometry when the run starts). Here only an **upper bound** of that period is needed, so that the
estimated step count is a lower bound (the guard then refuses only runs that are surely too long):

- a sine source or a prescribed current: its period 1/f = 2π/ω, exactly;
- a bank: 2π √((L_up + L_ext) C) with L_up = N² μ0 R_max max(ln(8 R_max / g_min) − 2, 1) ≥ the coils'
  inductance (N all turns on the bank, R_max their largest radius, g_min the smallest geometric mean
  distance 0.2235 (w + h) of a winding section: every mutual inductance is at most the largest self
  inductance, which Rosa's formula bounds);
- a direct current or a table has no period: such a case (and a user deck's coil on a bank, whose
  geometry is not known before meshing) must give ``time.dt_max``.

Units: s, H, m.
"""

from __future__ import annotations

import math

from .schema import SchemaError

MU0 = 4e-7 * math.pi  # H/m

__all__ = ["all_rigid", "period_upper_bound", "check_rigid_time_scale"]


def all_rigid(case) -> bool:
    """Every body of the case is rigid."""
    return bool(case.bodies) and all(b.rigid for b in case.bodies)


def _sections(g) -> list[tuple[float, float, float]] | None:
    """(outer radius, width, height) (m) of every winding section of the geometry's coils; None for a user deck."""
    if g.type == "coaxial_coils":
        return [(w[2], w[2] - w[0], w[3] - w[1]) for c in g.coils for w in c.windings]
    if g.type == "flat_coil_sheet":
        r = g.coil_inner_radius + g.turns * g.turn_width + (g.turns - 1) * g.turn_gap
        return [(r, g.turn_width, g.turn_height)]
    if g.type == "solenoid_tube":
        return [(g.coil_inner_radius + g.turn_width, g.turn_width, g.turn_height)]
    return None


def _bank_inductance_bound(case, turns: int) -> float | None:
    """L_up (H) of ``turns`` turns on the geometry's windings; None when the geometry is not known."""
    sections = _sections(case.geometry)
    if not sections:
        return None
    r = max(s[0] for s in sections)
    g = min(0.2235 * (s[1] + s[2]) for s in sections)
    return turns ** 2 * MU0 * r * max(math.log(8.0 * r / g) - 2.0, 1.0)


def period_upper_bound(case) -> float | None:
    """An upper bound (s) of the shortest period of the case's coil currents; None when no source has one
    (direct currents, tables) or the coils' geometry is not known (a user deck's coil on a bank)."""
    em, g = case.em, case.geometry
    if not em.sources:
        if em.current is not None:
            return 2.0 * math.pi / em.current.omega
        c = em.circuit
        turns = g.turns if hasattr(g, "turns") else None
        bound = _bank_inductance_bound(case, turns) if turns is not None else None
        return None if bound is None else 2.0 * math.pi * math.sqrt((bound + c.inductance) * c.capacitance)
    periods = []
    for s in em.sources:
        if s.type == "sine":
            periods.append(1.0 / s.frequency)
        elif s.type == "bank":
            names = {c.name for c in em.coils if c.source == s.name}
            if g.type == "coaxial_coils":
                turns = sum(c.turns for c in g.coils if c.name in names)
            else:
                turns = getattr(g, "turns", None)
            bound = _bank_inductance_bound(case, turns) if turns is not None else None
            if bound is not None:
                periods.append(2.0 * math.pi * math.sqrt((bound + s.inductance) * s.capacitance))
    return min(periods) if periods else None


def check_rigid_time_scale(case) -> None:
    """A case whose bodies are all rigid needs a time scale: a periodic source or ``time.dt_max``."""
    if case.case.kind != "coupled" or not all_rigid(case) or case.time.dt_max is not None:
        return
    if getattr(case.geometry, "type", None) == "geometry_3d":
        if case.geometry.em_step is None:
            raise SchemaError("geometry.em_step", "missing: every body is rigid (no stability limit): give the EM "
                              "step (s; the mechanical step is em_step / coupling.n) or time.dt_max")
        return
    if period_upper_bound(case) is None:
        raise SchemaError("time.dt_max", "missing: every body is rigid (no stability limit) and no source has a "
                          "period to resolve (a direct current, a table, a user deck's coil on a bank, or a template "
                          "deck's own source): give time.dt_max, the mechanical step (s)")
