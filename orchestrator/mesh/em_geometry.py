"""EM geometries of the coupled cases, meshed with gmsh into one EM mesh with named regions.

The workpiece is massive conductor 1 (physical id 201), a die or outer tube massive conductor 2
(202), the coil is stranded coil 1 (101, all its turns in series), air 1, shell 2, axis (or
symmetry plane) 11, outer boundary 12 (the ids of :mod:`pulseform.solvers.getdp.mesh`). The
mechanical mesh of every conductor body is cut from this mesh (:mod:`.shared_mesh`), so both share
its nodes and the force transfer is exact.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from pulseform.solvers.getdp import EMMesh, Rect, coil_conductor_mesh, coil_tag, conductor_tag
from pulseform.solvers.getdp.mesh import core_tag
from pulseform.solvers.getdp.runner import ChildCall

from ..case.em_model import CoaxialCoils
from ..case.model import FlatCoilSheet, Geometry, PlanarCoilBlankDie, SolenoidTube

log = logging.getLogger(__name__)


@dataclass
class EMGeometry:
    """The meshed EM setup: mesh, region ids by role (coil 1 and conductors), turn rectangles (m).

    ``turns`` are coil 1's (``regions["coil"]``); ``more_coils`` the turn rectangles of coils 2, 3, ...
    (physical ids ``coil_tag(2)``, ...), empty for the one-coil geometries.
    ``planar``: a plane half model (a_z, per metre of depth) instead of an axisymmetric one.
    """

    mesh: EMMesh
    regions: dict[str, int]
    turns: list[Rect]
    planar: bool = False
    more_coils: list[list[Rect]] = field(default_factory=list)

    def conductor_roles(self) -> list[str]:
        """The conductor roles, in conductor order (physical ids 201, 202, ...)."""
        return sorted((r for r in self.regions if r != "coil"), key=self.regions.__getitem__)

    def coil_turns(self) -> list[tuple[int, list[Rect]]]:
        """(physical id, turn rectangles) of every coil, coil 1 first."""
        return [(self.regions["coil"], self.turns)] + [(coil_tag(k), t) for k, t in enumerate(self.more_coils, start=2)]


def flat_coil_turns(g: FlatCoilSheet) -> list[Rect]:
    """Turn cross-sections (m) of the flat spiral coil, modelled as coaxial rings."""
    out = []
    for k in range(g.turns):
        r0 = g.coil_inner_radius + k * (g.turn_width + g.turn_gap)
        out.append(Rect(r0, -g.turn_height, r0 + g.turn_width, 0.0))
    return out


def solenoid_turns(g: SolenoidTube) -> list[Rect]:
    """Turn cross-sections (m) of the solenoid, stacked along z and centred on z = 0."""
    pitch = g.turn_height + g.turn_gap
    z0 = -0.5 * (g.turns * pitch - g.turn_gap)
    return [Rect(g.coil_inner_radius, z0 + k * pitch, g.coil_inner_radius + g.turn_width,
                 z0 + k * pitch + g.turn_height) for k in range(g.turns)]


def planar_turns(g: PlanarCoilBlankDie) -> list[Rect]:
    """Turn cross-sections (m) of the planar half model's coil, side by side above the blank."""
    y0 = g.blank_thickness + g.coil_gap
    return [Rect(g.coil_inner_x + k * (g.turn_width + g.turn_gap), y0,
                 g.coil_inner_x + k * (g.turn_width + g.turn_gap) + g.turn_width, y0 + g.turn_height)
            for k in range(g.turns)]


def sheet_die_polygon(g: FlatCoilSheet, segments: int | None = None) -> np.ndarray:
    """Counter-clockwise (r, z) outline (m) of the die above the sheet: block minus the cavity,
    the cavity edge rounded with ``entry_radius`` (``segments`` chords; default: chords of about half
    the die's element size, so the fillet does not make elements, and the stable step, smaller)."""
    d = g.die
    if segments is None:
        segments = max(2, int(np.ceil(0.5 * np.pi * d.entry_radius / (0.5 * d.mesh_size))))
    z = g.coil_gap + g.sheet_thickness + d.gap  # the die's lower face
    rc, re = d.cavity_radius, d.entry_radius
    pts = [(rc + re, z), (d.outer_radius, z), (d.outer_radius, z + d.height), (0.0, z + d.height),
           (0.0, z + d.cavity_depth), (rc, z + d.cavity_depth), (rc, z + re)]
    if re > 0.0:  # quarter arc from (rc, z + re) down to (rc + re, z), centre (rc + re, z + re)
        a = np.linspace(np.pi, 1.5 * np.pi, segments + 1)[1:-1]
        pts += [(rc + re + re * np.cos(t), z + re + re * np.sin(t)) for t in a]
    return np.array(pts)


class PendingEMGeometry:
    """The EM mesh of a geometry being made by gmsh in a child process (:func:`start_em_geometry`):
    :meth:`result` waits for it; :meth:`cancel` ends the child when the mesh is no longer wanted."""

    def __init__(self, call: ChildCall, finish: Callable[[EMMesh], EMGeometry]) -> None:
        self._call, self._finish = call, finish

    def result(self) -> EMGeometry:
        """The meshed geometry (raises what meshing raised: ``TimeLimitExceeded``, ``ChildFailed``, ...)."""
        return self._finish(self._call.result())

    def cancel(self) -> None:
        self._call.cancel()


def build_em_geometry(g: Geometry, time_limit: float | None = None) -> EMGeometry:
    """Mesh the EM setup ``g`` (axisymmetric: r = x, z = y; planar: half model x >= 0).

    gmsh runs in a child process under ``time_limit`` (s; None: no limit), see
    :func:`~pulseform.solvers.getdp.runner.call_in_child`.
    """
    return start_em_geometry(g, time_limit).result()


def start_em_geometry(g: Geometry, time_limit: float | None = None) -> PendingEMGeometry:
    """:func:`build_em_geometry` started in a child process now, collected later: a run starts it
    before importing DOLFINx, so that gmsh (its import ~0.4 s and the meshing) runs on the other core."""
    what = f"meshing the {g.type} EM geometry with gmsh"
    common = dict(axisymmetric=not g.planar, half=True, r_domain=g.air_radius, r_shell=g.shell_radius,
                  h_fine=g.mesh_size_coil, h_coarse=g.mesh_size_air, time_limit=time_limit, what=what)
    if isinstance(g, CoaxialCoils):
        coils = coaxial_coil_turns(g)
        names = {coil_tag(k): c.name for k, c in enumerate(g.coils, start=1)}
        names[conductor_tag(1)] = "workpiece"
        cores = [(c.name if len(c.boxes) == 1 else f"{c.name}_{j}", Rect(*box))   # core k: physical 800 + k
                 for c in g.cores for j, box in enumerate(c.boxes, start=1)]
        names.update({core_tag(k): name for k, (name, _) in enumerate(cores, start=1)})
        _require_sizes([g.workpiece.mesh_size])
        call = ChildCall(coil_conductor_mesh, coils, [Rect(*g.workpiece.box)], h_conductor=[g.workpiece.mesh_size],
                         names=names, cores=[r for _, r in cores], **common)

        def finish_coaxial(mesh: EMMesh) -> EMGeometry:
            log.info("EM mesh (%s): %d nodes, %d triangles, %d coils, groups %s", g.type, mesh.n_nodes,
                     len(mesh.triangles), len(coils), ", ".join(f"{n} ({t})" for t, n in sorted(mesh.names.items())))
            return EMGeometry(mesh, {"coil": coil_tag(1), "workpiece": conductor_tag(1)}, coils[0], planar=g.planar,
                              more_coils=coils[1:])

        return PendingEMGeometry(call, finish_coaxial)
    conductors, sizes = [], []
    if isinstance(g, FlatCoilSheet):
        turns = flat_coil_turns(g)
        conductors.append(Rect(0.0, g.coil_gap, g.sheet_radius, g.coil_gap + g.sheet_thickness))
        sizes.append(g.mesh_size_sheet)
        if g.die is not None:
            conductors.append(sheet_die_polygon(g))
            sizes.append(g.die.mesh_size)
    elif isinstance(g, SolenoidTube):
        turns = solenoid_turns(g)
        conductors.append(Rect(g.tube_inner_radius, -0.5 * g.tube_length, g.tube_inner_radius + g.tube_thickness,
                               0.5 * g.tube_length))
        sizes.append(g.mesh_size_tube)
        o = g.outer_tube
        if o is not None:
            conductors.append(Rect(o.inner_radius, -0.5 * o.length, o.inner_radius + o.thickness, 0.5 * o.length))
            sizes.append(o.mesh_size)
    else:
        assert isinstance(g, PlanarCoilBlankDie)
        turns = planar_turns(g)
        conductors.append(Rect(0.0, 0.0, g.blank_half_width, g.blank_thickness))
        sizes.append(g.mesh_size_blank)
        if g.die is not None:
            conductors.append(np.array(g.die, dtype=float))
            sizes.append(g.mesh_size_die)
    _require_sizes(sizes)
    regions = {"coil": coil_tag(1)}
    regions.update({role: conductor_tag(k) for k, role in enumerate(g.conductor_roles(), start=1)})
    call = ChildCall(coil_conductor_mesh, [turns], conductors, h_conductor=sizes,
                     names={tag: role for role, tag in regions.items()}, **common)

    def finish(mesh: EMMesh) -> EMGeometry:
        log.info("EM mesh (%s): %d nodes, %d triangles, groups %s", g.type, mesh.n_nodes, len(mesh.triangles),
                 ", ".join(f"{n} ({t})" for t, n in sorted(mesh.names.items())))
        return EMGeometry(mesh, regions, turns, planar=g.planar)

    return PendingEMGeometry(call, finish)


def _require_sizes(sizes: list[float | None]) -> None:
    """Conductor sizes a case leaves to the skin depth are filled in before meshing (``pulseform run`` does
    it: ``orchestrator/em/skin_depth.with_default_sizes``); meshing without them is a programming error."""
    if any(s is None for s in sizes):
        raise ValueError("a conductor element size is unset: fill the case's defaults in first "
                         "(em.skin_depth.with_default_sizes)")


def coaxial_coil_turns(g: CoaxialCoils) -> list[list[Rect]]:
    """The winding rectangles (m) of every coil of ``coaxial_coils``, in the geometry's coil order."""
    return [[Rect(*w) for w in c.windings] for c in g.coils]
