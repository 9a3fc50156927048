"""EM geometries of the coupled cases, meshed with gmsh into one EM mesh with named regions.

The workpiece is massive conductor 1 (physical id 201), the coil is stranded coil 1 (101, all its
turns in series), air 1, shell 2, axis 11, outer boundary 12 (the ids of
:mod:`pulseform.solvers.getdp.mesh`). The mechanical mesh of the workpiece is cut from this mesh
(:mod:`.shared_mesh`), so both share its nodes and the force transfer is exact.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from pulseform.solvers.getdp import EMMesh, Rect, coil_conductor_mesh, coil_tag, conductor_tag

from .case import FlatCoilSheet, Geometry, SolenoidTube

log = logging.getLogger(__name__)


@dataclass
class EMGeometry:
    """The meshed EM setup: mesh, region ids by role, turn rectangles."""

    mesh: EMMesh
    regions: dict[str, int]
    turns: list[Rect]


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


def build_em_geometry(g: Geometry) -> EMGeometry:
    """Mesh the EM setup ``g`` (axisymmetric, r = x, z = y)."""
    if isinstance(g, FlatCoilSheet):
        turns = flat_coil_turns(g)
        work = Rect(0.0, g.coil_gap, g.sheet_radius, g.coil_gap + g.sheet_thickness)
        h_work = g.mesh_size_sheet
    else:
        assert isinstance(g, SolenoidTube)
        turns = solenoid_turns(g)
        work = Rect(g.tube_inner_radius, -0.5 * g.tube_length, g.tube_inner_radius + g.tube_thickness,
                    0.5 * g.tube_length)
        h_work = g.mesh_size_tube
    mesh = coil_conductor_mesh([turns], [work], axisymmetric=True, r_domain=g.air_radius,
                               r_shell=g.shell_radius, h_fine=g.mesh_size_coil, h_coarse=g.mesh_size_air,
                               h_conductor=h_work)
    log.info("EM mesh (%s): %d nodes, %d triangles", g.type, mesh.n_nodes, len(mesh.triangles))
    return EMGeometry(mesh, {"coil": coil_tag(1), "workpiece": conductor_tag(1)}, turns)
