"""Mesh the 2D shapes of a case (rectangle, polygon) with gmsh into DOLFINx P1-triangle meshes."""

from __future__ import annotations

import logging

from dolfinx.io import gmshio
from dolfinx.mesh import Mesh
from mpi4py import MPI

from pulseform.solvers.getdp.mesh import gmsh_session

from .case import Polygon, Rectangle, Shape

log = logging.getLogger(__name__)


def shape_vertices(shape: Shape) -> list[tuple[float, float]]:
    """Corner points of a shape, counter-clockwise (m)."""
    if isinstance(shape, Rectangle):
        x0, y0 = shape.origin
        return [(x0, y0), (x0 + shape.width, y0), (x0 + shape.width, y0 + shape.height),
                (x0, y0 + shape.height)]
    assert isinstance(shape, Polygon)
    return list(shape.points)


def mesh_shape(shape: Shape, mesh_size: float, comm: MPI.Comm = MPI.COMM_WORLD,
               name: str = "body") -> Mesh:
    """Mesh ``shape`` with linear triangles of target size ``mesh_size`` (m).

    Rectangles get a structured-looking frontal mesh (gmsh "Frontal-Delaunay for quads" off,
    algorithm 6); the mesh is built on rank 0 and distributed by DOLFINx.
    """
    with gmsh_session(name) as gmsh:
        if comm.rank == 0:
            pts = [gmsh.model.geo.addPoint(x, y, 0.0, mesh_size) for x, y in shape_vertices(shape)]
            lines = [gmsh.model.geo.addLine(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
            loop = gmsh.model.geo.addCurveLoop(lines)
            surf = gmsh.model.geo.addPlaneSurface([loop])
            gmsh.model.geo.synchronize()
            gmsh.model.addPhysicalGroup(2, [surf], 1)
            gmsh.model.addPhysicalGroup(1, lines, 1)
            gmsh.option.setNumber("Mesh.Algorithm", 6)
            gmsh.option.setNumber("Mesh.CharacteristicLengthMax", mesh_size)
            gmsh.model.mesh.generate(2)
        mesh, _, _ = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=2)
    log.debug("meshed %s: %d cells on rank %d", name,
              mesh.topology.index_map(2).size_local, comm.rank)
    return mesh
