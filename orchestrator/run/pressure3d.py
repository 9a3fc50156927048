"""The pressure-driven run of a coupled 3D sector (``coupling.load = "pressure"`` with ``[[loads]]``).

The counterpart of :func:`~.coupled3d.sector_participants` for ``pulseform compare``: the same EM mesh
is meshed (gmsh is deterministic: the same nodes) and the sheet cut from it with the same clamp and
sliding meridian faces (:func:`~.coupled3d.sector_mechanics`); the same loop (n = sector.em_step /
stable step mechanical steps per EM step); the load is the [[loads]] pulses with their boxes in (r, z)
(:class:`~..mech.sector_pulses.SectorPressurePulses`) instead of getdp.
"""

from __future__ import annotations

import logging
from pathlib import Path

from ..case.model import Case
from ..coupling.loop import LoopOptions
from ..mech.participants import DolfinxMechanics
from ..mech.sector_pulses import SectorPressurePulses
from .coupled3d import sector_mechanics, sector_options

log = logging.getLogger(__name__)


def sector_pressure_participants(case: Case, work: Path):
    """(3D solver, :class:`SectorPressurePulses`, loop options) of a coupled 3D case with
    ``coupling.load = "pressure"``; the EM mesh is written in ``work``. Raises ValueError naming the
    load whose (r, z) box holds no boundary triangle of its body."""
    opt = sector_options(case)
    _, _, solver = sector_mechanics(case, Path(work), opt)
    mo = case.mechanics
    load = SectorPressurePulses(case.loads, 360.0 / opt.sector_deg, mo.mass_damping, mo.mass_damping_until,
                                mo.mass_damping_from, mo.kinetic_damping_until)
    mechanics = DolfinxMechanics(solver)
    areas = load.loaded_areas(mechanics, solver.bodies)
    for i, (ld, a) in enumerate(zip(case.loads, areas)):
        if a <= 0.0:
            b = ld.surface
            raise ValueError(f"loads[{i}].surface: the box r in [{b.xmin:g}, {b.xmax:g}] m, z in [{b.ymin:g}, "
                             f"{b.ymax:g}] m holds no boundary triangle of body {ld.body!r} (the sector's boxes "
                             "are in (r, z): xmin/xmax bound r, ymin/ymax bound z)")
    n = max(1, round(opt.em_step / solver.stable_time_step()))
    log.info("3D sector %.4g deg driven by %d pressure pulse(s) on %s m^2 (sector), mechanical step %.3g s, n = %d",
             opt.sector_deg, len(case.loads), ", ".join(f"{a:.6g}" for a in areas), solver.stable_time_step(), n)
    return solver, load, LoopOptions(n=n, n_min=1, n_max=n)
