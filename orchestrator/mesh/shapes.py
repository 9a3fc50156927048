"""Mesh the 2D shapes of a case (rectangle, polygon) with gmsh into DOLFINx P1-triangle meshes."""

from __future__ import annotations

import logging

import numpy as np
from dolfinx.cpp.mesh import to_type
from dolfinx.io import gmshio
from dolfinx.mesh import Mesh, create_mesh
from mpi4py import MPI

from pulseform.solvers.getdp.mesh import gmsh_session
from pulseform.solvers.getdp.runner import call_in_child

from ..case.model import Polygon, Rectangle, Shape

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
               name: str = "body", time_limit: float | None = None) -> Mesh:
    """Mesh ``shape`` with linear triangles of target size ``mesh_size`` (m).

    Rectangles get a structured-looking frontal mesh (gmsh "Frontal-Delaunay for quads" off,
    algorithm 6). gmsh runs on rank 0 in a child process under ``time_limit`` (s; None: no limit,
    see :func:`~pulseform.solvers.getdp.runner.call_in_child`); DOLFINx distributes the mesh
    exactly as ``gmshio.model_to_mesh`` does.
    """
    if comm.rank == 0:
        x, cells = call_in_child(_gmsh_triangles, shape_vertices(shape), mesh_size, name, time_limit=time_limit,
                                 what=f"meshing body {name!r} with gmsh")
    else:
        x, cells = np.empty((0, 3)), np.empty((0, 3), dtype=np.int64)
    domain = gmshio.ufl_mesh(_GMSH_TRIANGLE, 2)
    perm = gmshio.cell_perm_array(to_type(str(domain.ufl_cell())), 3)
    mesh = create_mesh(comm, cells[:, perm], x[:, :2], domain)
    log.debug("meshed %s: %d cells on rank %d", name,
              mesh.topology.index_map(2).size_local, comm.rank)
    return mesh


#: gmsh's element type of a 3-node triangle
_GMSH_TRIANGLE = 2


def _gmsh_triangles(vertices: list[tuple[float, float]], mesh_size: float, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(node coordinates (n, 3), triangles (m, 3) as gmsh orders them) of the polygon ``vertices``
    (runs in the child process of :func:`mesh_shape`)."""
    with gmsh_session(name) as gmsh:
        pts = [gmsh.model.geo.addPoint(x, y, 0.0, mesh_size) for x, y in vertices]
        lines = [gmsh.model.geo.addLine(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
        loop = gmsh.model.geo.addCurveLoop(lines)
        surf = gmsh.model.geo.addPlaneSurface([loop])
        gmsh.model.geo.synchronize()
        gmsh.model.addPhysicalGroup(2, [surf], 1)
        gmsh.model.addPhysicalGroup(1, lines, 1)
        gmsh.option.setNumber("Mesh.Algorithm", 6)
        gmsh.option.setNumber("Mesh.CharacteristicLengthMax", mesh_size)
        gmsh.model.mesh.generate(2)
        x = gmshio.extract_geometry(gmsh.model)
        topologies = gmshio.extract_topology_and_markers(gmsh.model)
    return np.asarray(x), np.asarray(topologies[_GMSH_TRIANGLE]["topology"], dtype=np.int64)
