"""Mesh the 3D shapes of a case (box, cylinder or a sector of one) with gmsh (OpenCASCADE) into
DOLFINx P1-tetrahedron meshes (3D cases, :mod:`..case.solid3d`)."""

from __future__ import annotations

import logging

import numpy as np
from dolfinx.cpp.mesh import to_type
from dolfinx.io import gmshio
from dolfinx.mesh import Mesh, create_mesh
from mpi4py import MPI

from pulseform.solvers.getdp.mesh import gmsh_session
from pulseform.solvers.getdp.runner import call_in_child

from ..case.solid3d import SolidBox, SolidCylinder

log = logging.getLogger(__name__)

#: gmsh's element type of a 4-node tetrahedron
_GMSH_TETRA = 4


def solid_description(shape: SolidBox | SolidCylinder) -> tuple:
    """The shape as plain data for the gmsh child: ("box", origin, size) or
    ("cylinder", base, axis, radius, angle), lengths in m, angle in rad."""
    if isinstance(shape, SolidBox):
        return ("box", tuple(shape.origin), tuple(shape.size))
    return ("cylinder", tuple(shape.base), tuple(shape.axis), shape.radius, shape.angle)


def mesh_solid(shape: SolidBox | SolidCylinder, mesh_size: float, comm: MPI.Comm = MPI.COMM_WORLD,
               name: str = "body", time_limit: float | None = None) -> Mesh:
    """Mesh ``shape`` with linear tetrahedra of target size ``mesh_size`` (m).

    gmsh (OpenCASCADE kernel, Delaunay 3D) runs on rank 0 in a child process under ``time_limit``
    (s; None: no limit, see :func:`~pulseform.solvers.getdp.runner.call_in_child`); DOLFINx
    distributes the mesh as ``gmshio.model_to_mesh`` does.
    """
    if comm.rank == 0:
        x, cells = call_in_child(_gmsh_tetrahedra, solid_description(shape), mesh_size, name,
                                 time_limit=time_limit, what=f"meshing body {name!r} with gmsh")
    else:
        x, cells = np.empty((0, 3)), np.empty((0, 4), dtype=np.int64)
    domain = gmshio.ufl_mesh(_GMSH_TETRA, 3)
    perm = gmshio.cell_perm_array(to_type(str(domain.ufl_cell())), 4)
    mesh = create_mesh(comm, cells[:, perm], x[:, :3], domain)
    log.debug("meshed %s: %d tetrahedra on rank %d", name, mesh.topology.index_map(3).size_local, comm.rank)
    return mesh


def _gmsh_tetrahedra(desc: tuple, mesh_size: float, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(node coordinates (n, 3), tetrahedra (m, 4) as gmsh orders them) of the solid ``desc``
    (:func:`solid_description`; runs in the child process of :func:`mesh_solid`)."""
    with gmsh_session(name) as gmsh:
        occ = gmsh.model.occ
        if desc[0] == "box":
            (x0, y0, z0), (lx, ly, lz) = desc[1], desc[2]
            vol = occ.addBox(x0, y0, z0, lx, ly, lz)
        else:
            (x0, y0, z0), (ax, ay, az), radius, angle = desc[1:]
            vol = occ.addCylinder(x0, y0, z0, ax, ay, az, radius, angle=angle)
        occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [vol], 1)
        gmsh.option.setNumber("Mesh.MeshSizeMax", mesh_size)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        gmsh.model.mesh.generate(3)
        x = gmshio.extract_geometry(gmsh.model)
        topologies = gmshio.extract_topology_and_markers(gmsh.model)
    return np.asarray(x), np.asarray(topologies[_GMSH_TETRA]["topology"], dtype=np.int64)
