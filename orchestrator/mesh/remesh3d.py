"""Re-tetrahedralise the air of a 3D EM mesh, keeping every other tetrahedron and its boundary triangles.

When the harmonically moved air (:class:`~.motion3d.MeshMover3D`) degrades, only the air (physical ids
``air_tags``) is meshed again, in the current configuration:

* every tetrahedron that is not air (conductors: their nodes are the mechanics'; coil; shell) is kept
  node for node, with its surface elements (skins, electrodes, outer sphere, its faces on the symmetry
  planes);
* the air's faces on each symmetry plane are re-triangulated in the plane
  (:func:`~.air_remesh.retriangulate_air`: every boundary edge of the plane's air keeps its two nodes,
  in-plane coordinates from the plane's normal, so an oblique plane -- a sector's second meridian face --
  is one too, and the nodes on a line shared by two planes -- a sector's axis -- are kept by both); the
  sizes come from a reference: the air faces of the *fresh* mesh on that plane (:class:`PlaneAir`,
  :func:`plane_air`), so that repeated remeshes do not drift (sizes from the mesh being replaced grow the
  mesh by a few per cent per remesh: gmsh's edges come out shorter than asked); the air's other boundary
  triangles (interfaces with the kept tetrahedra, any outer boundary of the air) are kept;
* gmsh (4.8) meshes the volume bounded by these triangles (a discrete surface (``addDiscreteEntity``
  + ``addNodes`` / ``addElementsByType`` for the boundary triangles, a surface loop and volume of the built-in
  kernel, ``generate(3)``; a discrete volume is not meshed by 4.8): it adds nodes inside only, so the
  new air stitches to the kept triangles node for node.

The new mesh lists the kept nodes first in their old order, then the new ones (so every pair of kept
nodes keeps its order: GetDP orients an edge from the lower node number to the higher, the conductors'
edges keep their orientation), and the kept tetrahedra first in their old order, then the new air (the
conductors' element order, hence GetDP's per-element output order, is unchanged). Written as MSH 2.2
with the physical ids of :mod:`pulseform.solvers.getdp.mesh3d`.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
from scipy.spatial import cKDTree

from pulseform.solvers.getdp import EMMesh
from pulseform.solvers.getdp.mesh import AIR, gmsh_session
from pulseform.solvers.getdp.mesh3d import read_msh22_triangles
from pulseform.solvers.getdp.mesh3d import SYM_A, Mesh3D, read_msh22_tets
from pulseform.solvers.getdp.runner import call_in_child

from .air_remesh import SizeField, retriangulate_air
from .motion3d import tet_quality

log = logging.getLogger(__name__)

__all__ = ["remesh_air3d", "plane_air", "PlaneAir", "read_msh22_triangles", "write_msh22_3d",
           "AIR_REMESH_TAG_PLANE"]

#: a temporary 2D id of the kept (non-air) faces on a plane while the plane's air is re-triangulated
AIR_REMESH_TAG_PLANE = 999
_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])


def write_msh22_3d(path: str | Path, points: np.ndarray, tets: np.ndarray, tet_tags: np.ndarray,
                   tris: np.ndarray, tri_tags: np.ndarray) -> np.ndarray:
    """Write an ASCII MSH 2.2 file (nodes 1..n in row order, the triangles then the tetrahedra, each with
    its physical id as both tags); returns the tetrahedra's element ids."""
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$Nodes", str(len(points))]
    lines += [f"{i + 1} {x!r} {y!r} {z!r}" for i, (x, y, z) in enumerate(np.asarray(points, float).tolist())]
    lines += ["$EndNodes", "$Elements", str(len(tris) + len(tets))]
    k = 0
    for t, g in zip((tris + 1).tolist(), np.asarray(tri_tags).tolist()):
        k += 1
        lines.append(f"{k} 2 2 {g} {g} {t[0]} {t[1]} {t[2]}")
    ids = np.arange(k + 1, k + 1 + len(tets), dtype=np.int64)
    for i, t, g in zip(ids.tolist(), (tets + 1).tolist(), np.asarray(tet_tags).tolist()):
        lines.append(f"{i} 4 2 {g} {g} {t[0]} {t[1]} {t[2]} {t[3]}")
    lines.append("$EndElements")
    Path(path).write_text("\n".join(lines) + "\n")
    return ids


def _plane_frame(normal: np.ndarray) -> np.ndarray:
    """Two unit vectors (2, 3) spanning the plane of unit ``normal``, (e1, e2, normal) right-handed."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    e1 = np.cross(n, [0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.cross(n, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(n, e1)])


@dataclass(frozen=True)
class PlaneAir:
    """The air's faces of a mesh on one symmetry plane, in the plane's coordinates: ``uv`` (k, 2) m in the
    frame of :func:`_plane_frame` about the plane's point, ``tris`` (m, 3) rows of ``uv``, counter-clockwise.
    The reference whose edge lengths set the sizes of the plane's re-triangulation (module docstring)."""

    uv: np.ndarray
    tris: np.ndarray

    def size_field(self, factor: float = 1.0) -> SizeField:
        """The element sizes (m) of these faces by in-plane position (:class:`~.air_remesh.SizeField`), times
        ``factor``."""
        field = SizeField(EMMesh(self.uv, self.tris, np.full(len(self.tris), AIR)), [AIR])
        field.sizes = field.sizes * factor
        return field

    @property
    def density(self) -> float:
        """Triangles per unit area (1/m²) of these faces."""
        return len(self.tris) / _area2d(self.uv, self.tris).sum()


def _area2d(uv: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Unsigned areas (m²) of the triangles ``tris`` (rows of ``uv``, (k, 2) m)."""
    a = uv[tris]
    return 0.5 * np.abs(np.cross(a[:, 1] - a[:, 0], a[:, 2] - a[:, 0]))


def _air_boundary(mesh: Mesh3D, air_tags: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """(air mask per tetrahedron, the air's boundary faces (f, 3), outward in the mesh's configuration)."""
    air = np.isin(mesh.tet_tags, list(air_tags))
    faces = mesh.tets[air][:, _FACES].reshape(-1, 3)
    _, inv, cnt = np.unique(np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True)
    return air, faces[cnt[inv.ravel()] == 1]


def _on_plane(x: np.ndarray, tris: np.ndarray, p0: np.ndarray, nrm: np.ndarray, tol: float) -> np.ndarray:
    """Which triangles (rows of ``x``) lie in the plane (point ``p0``, unit normal ``nrm``) within ``tol`` m."""
    return np.abs((x[tris] - p0) @ nrm).max(axis=1) <= tol


def _in_plane(x: np.ndarray, tris: np.ndarray, p0: np.ndarray, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the nodes of ``tris``, their in-plane coordinates (k, 2), the triangles as rows of those, turned
    counter-clockwise in the plane's frame)."""
    nodes, local = np.unique(tris, return_inverse=True)
    local = local.reshape(-1, 3)
    uv = (x[nodes] - p0) @ frame.T
    a = uv[local]
    area = np.cross(a[:, 1] - a[:, 0], a[:, 2] - a[:, 0])
    local[area < 0] = local[area < 0][:, [0, 2, 1]]
    return nodes, uv, local


def plane_air(mesh: Mesh3D, planes: Sequence[tuple[np.ndarray, np.ndarray]], *,
              air_tags: Sequence[int] = (AIR,)) -> list[PlaneAir | None]:
    """Per plane (point, unit normal) the air's faces of ``mesh`` on it at ``mesh.points`` (None: none):
    the fresh mesh's are the size reference of every remesh (:func:`remesh_air3d`)."""
    x = np.asarray(mesh.points, float)
    _, bnd = _air_boundary(mesh, air_tags)
    tol = 1e-9 * float(np.ptp(x, axis=0).max())
    out: list[PlaneAir | None] = []
    for p0, nrm in planes:
        nrm = np.asarray(nrm, float) / np.linalg.norm(nrm)
        mine = _on_plane(x, bnd, p0, nrm, tol)
        if not mine.any():
            out.append(None)
            continue
        _, uv, local = _in_plane(x, bnd[mine], p0, _plane_frame(nrm))
        out.append(PlaneAir(uv, local))
    return out


def remesh_air3d(mesh: Mesh3D, points: np.ndarray, path: str | Path,
                 planes: Sequence[tuple[np.ndarray, np.ndarray]], *, air_tags: Sequence[int] = (AIR,),
                 reference: Sequence[PlaneAir | None] | None = None,
                 time_limit: float | None = 600.0) -> tuple[Mesh3D, np.ndarray]:
    """The mesh with its air meshed again (module docstring) around the nodes at ``points`` (n, 3) m.

    Parameters
    ----------
    mesh : Mesh3D
        The EM mesh (its file holds the surface elements); its ``points`` orient the faces on the planes.
    points : ndarray
        Current node positions (m); air tetrahedra may be inverted.
    path : Path
        The new MSH 2.2 file.
    planes : sequence of (point, unit normal)
        The symmetry planes whose air faces are re-triangulated.
    air_tags : sequence of int
        Physical ids of the air to mesh again.
    reference : sequence of PlaneAir or None, optional
        Per plane the faces whose edge lengths set the plane's sizes (:func:`plane_air` of the fresh mesh:
        no drift over repeated remeshes); default, or None for a plane: the air faces of ``mesh`` itself.
    time_limit : float
        Wall-time limit (s) of each gmsh run (child processes).

    Returns
    -------
    (Mesh3D, ndarray)
        The new mesh (nodes at their current positions; ``path``), and per old node its row in the new
        mesh (-1: an air node that was removed).
    """
    x = np.asarray(points, float)
    x_ref = np.asarray(mesh.points, float)
    if reference is not None and len(reference) != len(planes):
        raise ValueError(f"{len(reference)} plane references for {len(planes)} planes")
    air, bnd = _air_boundary(mesh, air_tags)             # faces outward in the reference configuration
    kept = mesh.tets[~air]
    scale = float(np.ptp(x_ref, axis=0).max())
    on_plane = np.zeros(len(bnd), bool)
    plane_tris: list[np.ndarray] = []
    n_nodes = len(x)
    extra: list[np.ndarray] = []                          # new plane nodes (m), numbered from n_nodes on
    kept_faces = kept[:, _FACES].reshape(-1, 3)
    for k, (p0, nrm) in enumerate(planes):
        nrm = np.asarray(nrm, float) / np.linalg.norm(nrm)
        mine = _on_plane(x_ref, bnd, p0, nrm, 1e-9 * scale)
        if not mine.any():
            continue
        on_plane |= mine
        kf = kept_faces[_on_plane(x_ref, kept_faces, p0, nrm, 1e-9 * scale)]
        frame = _plane_frame(nrm)
        # 2D: counter-clockwise in the plane's frame (the faces' outward normal is +-nrm)
        tags = np.r_[np.full(mine.sum(), AIR), np.full(len(kf), AIR_REMESH_TAG_PLANE)]
        nodes, uv_ref, local = _in_plane(x_ref, np.vstack([bnd[mine], kf]), p0, frame)
        uv = (x[nodes] - p0) @ frame.T
        ref = reference[k] if reference is not None else None
        current = EMMesh(uv, local, tags)
        if ref is None:
            sizes = SizeField(EMMesh(uv_ref, local, tags), [AIR])
            new2d, old_to_new, _ = retriangulate_air(current, [AIR], time_limit=time_limit, sizes=sizes)
        else:
            new2d, old_to_new = _retriangulate_as(current, ref, time_limit)
        n_old = int((old_to_new >= 0).sum())
        glob = np.empty(len(new2d.points), dtype=np.int64)   # 2D rows -> 3D node rows
        glob[old_to_new[old_to_new >= 0]] = nodes[old_to_new >= 0]
        m = len(new2d.points) - n_old
        glob[n_old:] = n_nodes + sum(len(e) for e in extra) + np.arange(m)
        uvw = new2d.points[n_old:]
        extra.append(p0 + uvw[:, :1] * frame[0] + uvw[:, 1:2] * frame[1])
        air2d = new2d.triangles[new2d.tri_tags == AIR]
        plane_tris.append(glob[air2d])
    x_all = np.vstack([x] + extra) if extra else x
    boundary = np.vstack([bnd[~on_plane]] + plane_tris)
    new_pts, new_tets = call_in_child(_mesh_volume, x_all, boundary, time_limit=time_limit,
                                      what="re-tetrahedralising the 3D EM air with gmsh")
    # the new mesh: kept nodes (of kept tets and of the air's boundary) in their old order, then the new ones
    keep = np.zeros(len(x_all), bool)
    keep[kept.ravel()] = True
    keep[boundary.ravel()] = True
    order = np.flatnonzero(keep)
    old_rows = order[order < n_nodes]
    plane_new = order[order >= n_nodes]
    rows = np.full(len(x_all) + len(new_pts), -1, dtype=np.int64)
    rows[order] = np.arange(len(order))
    rows[len(x_all):] = len(order) + np.arange(len(new_pts))
    pts = np.vstack([x_all[order], new_pts])
    air_tets = rows[new_tets]
    if (air_tets < 0).any():
        raise RuntimeError("the new air uses a node that is neither kept nor new")
    q = tet_quality(pts, air_tets)
    flip = q < 0
    air_tets[flip] = air_tets[flip][:, [0, 2, 1, 3]]
    tets = np.vstack([rows[kept], air_tets])
    tet_tags = np.r_[mesh.tet_tags[~air], np.full(len(air_tets), air_tags[0])]
    # surface elements: the file's, except the air's faces on the planes, which the new plane faces replace
    tris, tri_tags = read_msh22_triangles(mesh.path)
    plane_air = {tuple(t) for t in np.sort(bnd[on_plane], axis=1).tolist()}
    drop = np.array([tuple(t) in plane_air for t in np.sort(tris, axis=1).tolist()], dtype=bool)
    if (rows[tris[~drop]] < 0).any():
        raise RuntimeError("a kept surface element has a node inside the remeshed air")
    new_plane = np.vstack(plane_tris) if plane_tris else np.zeros((0, 3), np.int64)
    tris = np.vstack([rows[tris[~drop]], rows[new_plane]])
    tri_tags = np.r_[tri_tags[~drop], np.full(len(new_plane), SYM_A)]
    path = Path(path).resolve()
    path.parent.mkdir(parents=True, exist_ok=True)
    ids = write_msh22_3d(path, pts, tets, tet_tags, tris, tri_tags)
    out = Mesh3D(points=pts, tets=tets, tet_ids=ids, tet_tags=tet_tags, path=path, sector_deg=mesh.sector_deg,
                 electrode_area=mesh.electrode_area)
    old_to_new = rows[:n_nodes].copy()
    log.info("3D air remesh: %d air tets -> %d, %d nodes -> %d (%d new on the planes), worst new air quality %.3g",
             int(air.sum()), len(air_tets), n_nodes, len(pts), len(plane_new), float(np.abs(q).min()))
    return out, old_to_new


#: the plane's new air may differ from the reference's triangle density by this fraction before its sizes are
#: corrected (:func:`_retriangulate_as`)
DENSITY_TOLERANCE = 0.02


def _retriangulate_as(current: EMMesh, ref: PlaneAir, time_limit: float | None) -> tuple[EMMesh, np.ndarray]:
    """The air (id AIR) of the plane's 2D mesh ``current`` re-triangulated at the sizes of ``ref``, then, if
    its triangles per area differ from the reference's by more than :data:`DENSITY_TOLERANCE` (gmsh's edges
    come out a few per cent shorter than asked), once more with the sizes scaled by the square root of that
    ratio; returns the new 2D mesh and per old node its row (-1: removed)."""
    new2d, old_to_new, _ = retriangulate_air(current, [AIR], time_limit=time_limit, sizes=ref.size_field())
    air = new2d.triangles[new2d.tri_tags == AIR]
    ratio = len(air) / _area2d(new2d.points, air).sum() / ref.density
    if abs(ratio - 1.0) > DENSITY_TOLERANCE:
        new2d, old_to_new, _ = retriangulate_air(current, [AIR], time_limit=time_limit,
                                                 sizes=ref.size_field(float(np.sqrt(ratio))))
    return new2d, old_to_new


def _mesh_volume(x: np.ndarray, boundary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The gmsh part (a child process; does not log): the volume bounded by the triangles ``boundary``
    (rows of ``x``) meshed in tetrahedra; returns the new interior nodes (m, 3) and the tetrahedra as
    rows of [x, new nodes]."""
    used = np.unique(boundary)
    with gmsh_session("pulseform_air_remesh3d") as gmsh:
        s = gmsh.model.addDiscreteEntity(2)
        gmsh.model.mesh.addNodes(2, s, (used + 1).tolist(), x[used].ravel().tolist())
        gmsh.model.mesh.addElementsByType(s, 2, [], (boundary + 1).ravel().tolist())
        # gmsh 4.8 does not mesh a discrete volume (``addDiscreteEntity(3, ...)``: "No elements in volume"),
        # but a volume of the built-in kernel bounded by the discrete surface (its triangles are kept)
        v = gmsh.model.geo.addVolume([gmsh.model.geo.addSurfaceLoop([s])])
        gmsh.model.geo.synchronize()
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.option.setNumber("Mesh.Optimize", 1)
        gmsh.model.mesh.generate(3)
        # gmsh renumbers the nodes when it meshes: the boundary's nodes are found again by their coordinates
        stags, scoords, _ = gmsh.model.mesh.getNodes(2, s, includeBoundary=True)
        dist, row = cKDTree(x[used]).query(np.asarray(scoords, float).reshape(-1, 3))
        if len(stags) != len(used) or dist.max() > 1e-12 * float(np.ptp(x[used], axis=0).max()):
            raise RuntimeError(f"gmsh changed the kept boundary triangles ({len(stags)} nodes on them, {len(used)} given)")
        lookup = {int(t): int(used[r]) for t, r in zip(stags, row)}
        tags, coords, _ = gmsh.model.mesh.getNodes(3, v, includeBoundary=False)
        for k, t in enumerate(tags):
            lookup[int(t)] = len(x) + k
        etypes, _, enodes = gmsh.model.mesh.getElements(3, v)
        tets = [np.array([lookup[int(t)] for t in en], dtype=np.int64).reshape(-1, 4) for et, en in zip(etypes, enodes)
                if et == 4]
        if not tets or any(et != 4 for et in etypes):
            raise RuntimeError(f"gmsh made volume elements of types {list(etypes)}, not only tetrahedra")
        return np.asarray(coords, float).reshape(-1, 3), np.vstack(tets)
