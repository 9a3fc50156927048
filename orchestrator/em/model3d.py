"""The 3D EM model of a coupled 3D geometry-file case (:class:`~pulseform.solvers.getdp.solver3d.EM3DModel`):
its coils on their sources, the conductors (the bodies, then the fixed conductors), the shell and the
symmetry factor of the meshed :class:`~..mesh.geometry3d.Geometry3D`."""

from __future__ import annotations

from dataclasses import replace

from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel

from ..case.model import Case
from ..mesh.geometry3d import Geometry3D
from .solver import applied_field, coil_drives, coil_keywords, conductor_of


def em_model3d(case: Case, geo: Geometry3D) -> EM3DModel:
    """The EM3DModel of ``case`` on its meshed geometry ``geo``: coil k of ``[[geometry.coils]]`` with its
    turns, current path (terminals: electrokinetic; cut; axis: azimuthal) and source; conductor k the
    k-th body's region then the fixed conductors (their materials' conductivities, S/m, and σ(T) laws; the coils'
    σ(T) of ``[em]``, lumped per coil)."""
    g, em = case.geometry, case.em
    drives, circuit = coil_drives(case, [c.name for c in g.coils] if em.sources else [None] * len(g.coils))
    coils = []
    for k, (c, (wave, sign)) in enumerate(zip(g.coils, drives), start=1):
        section = c.section if c.section is not None else geo.coil_sections.get(k)
        axis = tuple(c.axis) if c.axis is not None else (0.0, 0.0)
        coils.append(Coil3D(turns=c.turns, waveform=wave, sign=sign, direction=c.direction, axis=axis,
                            section=section, name=c.name, **coil_keywords(case),
                            cut_normal=tuple(c.cut_direction) if c.cut_direction is not None else None))
    conductors = [conductor_of(case, b.material, b.name, "body") for b in case.bodies]
    conductors += [conductor_of(case, c.material, c.name, "fixed conductor") for c in g.conductors]
    model = EM3DModel(coils=coils, conductors=conductors, circuit=circuit, shell=geo.shell,
                      shell_centre=tuple(g.shell_centre), sector_deg=geo.mesh.sector_deg,
                      symmetry_factor=360.0 / geo.mesh.sector_deg, applied_field=applied_field(em.applied_field),
                      newton_tolerance=em.newton_tolerance, newton_max_iterations=em.newton_max_iterations)
    if g.em_order != 1:
        model = replace(model, order=g.em_order, order2_air=False)
    return model
