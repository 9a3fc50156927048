"""3D EM meshes (tetrahedra) for the 3D deck: a sector of ring coils and disks/rings about the z-axis.

The geometry generator :func:`ring_sector_mesh` builds, with gmsh's OpenCASCADE kernel, the sector
0 <= phi <= ``sector_deg`` of an axisymmetric arrangement: ring turns of rectangular cross-section
(one stranded coil), massive rings or disks (conductors), an air sphere and optionally a spherical
shell (transformation to infinity). The two meridian faces are symmetry planes of type n x a = 0
(B tangential to a meridian plane when every current is azimuthal). Used by the 3D verification
(static Biot-Savart, fixed disk vs the axisymmetric solver).

Physical ids (as in 2D where they exist, :mod:`.mesh`):

====================  ==================================================================
1                     air
2                     shell (transformation to infinity)
100 + k               coil k, all its turns
200 + k               massive conductor k
12                    outer boundary (n x a = 0)
14                    symmetry planes of type n x a = 0 (the meridian faces of a sector)
15                    symmetry planes of type n x h = 0 (natural: nothing imposed)
400 + k               skin of conductor k (the tree of the gauge starts there)
500 + k, 600 + k      faces of coil k on the planes phi = 0 and phi = angle: the electrodes
                      (current in, out) of the electrokinetic pre-solve of its direction
700 + k               the cut of closed coil k: triangles spanning its whole cross-section,
                      conforming with its tetrahedra (``Coil3D(direction="cut")``; the current
                      crosses it along the triangles' normal (x1 - x0) x (x2 - x0))
====================  ==================================================================

:func:`physical_surface_area` measures a physical surface group of an MSH 2.2 file (an electrode's or a
cut's area: a coil's section); :func:`cut_orientation` checks a cut's triangles and gives the sign of its
normal against a direction.
"""
from __future__ import annotations

import functools
import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from .mesh import AIR, OUTER, SHELL, Rect, coil_tag, conductor_tag, gmsh_session

logger = logging.getLogger(__name__)

SYM_A, SYM_H, SKIN_BASE, ELEC_IN_BASE, ELEC_OUT_BASE = 14, 15, 400, 500, 600
CUT_BASE = 700  # the cut of closed coil k is physical CUT_BASE + k (Coil_DirType = 3)


def skin_tag(k: int) -> int:
    """Physical id of the skin (boundary surface) of massive conductor ``k`` (1-based)."""
    return SKIN_BASE + k


@dataclass
class Mesh3D:
    """A tetrahedral mesh as written to MSH 2.2 for GetDP.

    ``points`` (n, 3) m; ``tets`` (m, 4) 0-based node rows; ``tet_ids`` the element ids in the
    MSH file (GetDP reports them); ``tet_tags`` the physical id of each tetrahedron; ``path`` the
    .msh file; ``sector_deg`` the modelled sector angle (degrees).
    """

    points: np.ndarray
    tets: np.ndarray
    tet_ids: np.ndarray
    tet_tags: np.ndarray
    path: Path
    sector_deg: float
    electrode_area: dict[int, float] | None = None  # coil k -> area (m^2) of its faces on phi = 0

    def moved(self, points: np.ndarray, path: str | Path) -> "Mesh3D":
        """The same mesh (connectivity, element ids, physical groups) with the nodes at ``points``
        (n, 3) m, written to ``path`` (MSH 2.2): the mesh of a following step whose run restarts from
        this one's solution."""
        points = np.asarray(points, float)
        if points.shape != self.points.shape or not np.all(np.isfinite(points)):
            raise ValueError(f"points must be finite and of shape {self.points.shape}")
        text = Path(self.path).read_text()
        head, rest = text.split("$Nodes\n", 1)
        count, rest = rest.split("\n", 1)
        ids = np.array(rest.split("$EndNodes", 1)[0].split(), dtype=float).reshape(-1, 4)[:, 0].astype(np.int64)
        tail = rest.split("$EndNodes", 1)[1]
        rows = "\n".join(f"{i} {x!r} {y!r} {z!r}" for i, (x, y, z) in zip(ids.tolist(), points.tolist()))
        path = Path(path).resolve()
        path.write_text(f"{head}$Nodes\n{count}\n{rows}\n$EndNodes{tail}")
        return Mesh3D(points=points.copy(), tets=self.tets, tet_ids=self.tet_ids, tet_tags=self.tet_tags, path=path,
                      sector_deg=self.sector_deg, electrode_area=self.electrode_area)

    @property
    def n_tets(self) -> int:
        return int(self.tets.shape[0])

    @property
    def n_nodes(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_edges(self) -> int:
        """Number of distinct edges (the unknowns of lowest-order edge elements, before constraints)."""
        e = self.tets[:, [0, 0, 0, 1, 1, 2, 1, 2, 3, 2, 3, 3]].reshape(-1, 6, 2)
        e = np.sort(e.reshape(-1, 2), axis=1)
        return int(np.unique(e[:, 0] * self.n_nodes + e[:, 1]).size)

    def volumes(self, rows: np.ndarray | None = None) -> np.ndarray:
        """Volumes (m^3) of the tetrahedra ``rows`` (all by default)."""
        return tet_volumes(self.points, self.tets if rows is None else self.tets[rows])

    def centroids(self, rows: np.ndarray | None = None) -> np.ndarray:
        """Centroids (m) of the tetrahedra ``rows`` (all by default)."""
        t = self.tets if rows is None else self.tets[rows]
        return self.points[t].mean(axis=1)

    def rows_of_ids(self, ids: np.ndarray) -> np.ndarray:
        """Rows of ``tets`` for MSH element ids."""
        order = np.argsort(self.tet_ids)
        pos = np.searchsorted(self.tet_ids, ids, sorter=order)
        rows = order[np.clip(pos, 0, len(order) - 1)]
        if not np.array_equal(self.tet_ids[rows], ids):
            raise KeyError("element ids not in the mesh")
        return rows


def cut_tag(k: int) -> int:
    """Physical id of the cut surface of closed coil ``k`` (1-based)."""
    return CUT_BASE + k


@functools.lru_cache(maxsize=16)
def _triangles_cached(path: str, mtime_ns: int, size: int, tag: int) -> tuple[np.ndarray, np.ndarray]:
    text = Path(path).read_text()
    nodes = text.split("$Nodes\n", 1)[1].split("$EndNodes", 1)[0].split("\n", 1)[1]
    nd = np.array(nodes.split(), dtype=float).reshape(-1, 4)
    body = text.split("$Elements\n", 1)[1].split("$EndElements", 1)[0].split("\n", 1)[1]
    tris = []
    for line in body.splitlines():
        r = line.split()
        # id, type (2: 3-node triangle), number of tags, tags (the first: the physical id), nodes
        if len(r) > 3 and r[1] == "2" and int(r[3]) == tag:
            tris.append([int(v) for v in r[3 + int(r[2]):]])
    if not tris:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    tri = np.array(tris, dtype=np.int64)
    used = np.unique(tri)
    index = {int(n): i for i, n in enumerate(used)}
    node_row = np.zeros(int(nd[:, 0].max()) + 1, dtype=np.int64)
    node_row[nd[:, 0].astype(np.int64)] = np.arange(len(nd))
    points = nd[node_row[used], 1:]
    return points, np.vectorize(index.__getitem__, otypes=[np.int64])(tri)


def read_surface_triangles(path: str | Path, tag: int) -> tuple[np.ndarray, np.ndarray]:
    """The 3-node triangles of physical surface group ``tag`` of an ASCII MSH 2.2 file: (points (n, 3) m,
    the nodes they use; triangles (m, 3), rows of ``points`` in the file's node order, so that
    (x1 - x0) x (x2 - x0) is the normal GetDP sees). Both empty when the group has no triangle.
    Cached per file (path, modification time and size)."""
    st = os.stat(path)
    points, tri = _triangles_cached(str(Path(path).resolve()), st.st_mtime_ns, st.st_size, int(tag))
    return points.copy(), tri.copy()


def _triangle_normals(path: str | Path, tag: int) -> np.ndarray:
    """(m, 3) half cross products 0.5 (x1 - x0) x (x2 - x0) (m^2) of the triangles of group ``tag``."""
    points, tri = read_surface_triangles(path, tag)
    p = points[tri]
    return 0.5 * np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])


def physical_surface_area(path: str | Path, tag: int) -> float:
    """Area (m^2) of the physical surface group ``tag`` of an ASCII MSH 2.2 file: the sum of its triangles'
    areas (exact for a plane face; a curved face's facets otherwise). 0.0 for a group without triangles.
    Used for a coil's conductor section: its electrode 500 + k or its cut 700 + k."""
    return float(np.linalg.norm(_triangle_normals(path, tag), axis=1).sum())


def cut_orientation(path: str | Path, tag: int, direction: tuple[float, float, float] | None = None) -> int:
    """Check the cut surface ``tag`` of an MSH 2.2 file and return the sign that makes a coil's current
    cross it along ``direction``.

    The cut must have triangles, oriented consistently (every edge shared by two triangles runs once each
    way: what GetDP's ``OnPositiveSideOf`` needs to tell the sides apart). With ``direction`` None the
    current crosses the cut along its triangles' normal (x1 - x0) x (x2 - x0): +1. Otherwise +1 or -1,
    the sign of (sum of the triangles' vector areas) . ``direction``; a direction within about 6 degrees
    of the cut's plane (|cos| < 0.1 against the mean normal) is refused as ambiguous.

    Raises
    ------
    ValueError
        No triangle in the group, inconsistent orientation, or an ambiguous ``direction``.
    """
    points, tri = read_surface_triangles(path, tag)
    if tri.shape[0] == 0:
        raise ValueError(f"{path}: the cut (physical surface {tag}) has no triangles")
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    n = points.shape[0]
    directed = edges[:, 0] * n + edges[:, 1]
    if np.unique(directed).size != directed.size:
        raise ValueError(f"{path}: the triangles of the cut {tag} are not consistently oriented (an edge runs "
                         "twice the same way): reorient its surfaces so that their normals agree")
    if direction is None:
        return 1
    d = np.asarray(direction, float)
    if d.shape != (3,) or not np.linalg.norm(d) > 0:
        raise ValueError(f"the cut's direction must be a non-zero 3-vector, got {direction!r}")
    normals = _triangle_normals(path, tag)
    along = float(normals.sum(axis=0) @ d) / float(np.linalg.norm(d))
    area = float(np.linalg.norm(normals, axis=1).sum())
    if abs(along) < 0.1 * area:
        raise ValueError(f"{path}: the direction {tuple(d)} is nearly tangent to the cut {tag} "
                         f"(its vector area along it {along:.3g} m^2 of {area:.3g} m^2)")
    return 1 if along > 0 else -1


def read_msh22_triangles(path: str | Path, tags: Sequence[int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(triangles (m, 3) as 0-based node rows -- the rows of :func:`read_msh22_tets`' points --, their
    physical ids) of the triangles of an ASCII MSH 2.2 file whose physical id is one of ``tags`` (None: all;
    a triangle in two physical groups appears twice)."""
    text = Path(path).read_text()
    nodes = text.split("$Nodes\n", 1)[1].split("$EndNodes", 1)[0].split("\n", 1)[1]
    ids = np.array(nodes.split(), dtype=float).reshape(-1, 4)[:, 0].astype(np.int64)
    index = np.zeros(int(ids.max()) + 1, dtype=np.int64)
    index[ids] = np.arange(len(ids))
    body = text.split("$Elements\n", 1)[1].split("$EndElements", 1)[0].split("\n", 1)[1]
    want = None if tags is None else {str(int(t)) for t in tags}
    rows = [r.split() for r in body.splitlines() if r]
    tri = [(int(r[3]), [int(v) for v in r[3 + int(r[2]):6 + int(r[2])]]) for r in rows
           if r[1] == "2" and (want is None or r[3] in want)]
    if not tri:
        return np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    return index[np.array([c for _, c in tri], np.int64)], np.array([t for t, _ in tri], np.int64)


def tet_volumes(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Volumes (m^3, positive) of the tetrahedra ``cells`` (M, 4) on nodes ``x`` (N, 3) m: the one home of
    this formula (EM meshes, the force transfer, masses, pictures)."""
    p = x[cells]
    return np.abs(np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])) / 6.0


def read_msh22_tets(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(points (n, 3) m, tets (m, 4) 0-based, element ids, physical ids) of the tetrahedra of an ASCII
    MSH 2.2 file. Read from the file, not from gmsh's API: gmsh renumbers the elements it writes
    once per physical group (a face in two groups is written twice), and GetDP reports the file's ids."""
    text = Path(path).read_text()
    nodes = text.split("$Nodes\n", 1)[1].split("$EndNodes", 1)[0].split("\n", 1)[1]
    nd = np.array(nodes.split(), dtype=float).reshape(-1, 4)
    index = np.zeros(int(nd[:, 0].max()) + 1, dtype=np.int64)
    index[nd[:, 0].astype(np.int64)] = np.arange(len(nd))
    body = text.split("$Elements\n", 1)[1].split("$EndElements", 1)[0].split("\n", 1)[1]
    rows = [r.split() for r in body.splitlines() if r]
    tet = np.array([[int(v) for v in r] for r in rows if r[1] == "4"], dtype=np.int64)
    if tet.size == 0:
        raise ValueError(f"{path}: no tetrahedra")
    ntag = tet[:, 2]
    if np.any(ntag != ntag[0]):
        raise ValueError(f"{path}: tetrahedra with different numbers of tags")
    conn = tet[:, 3 + ntag[0]: 7 + ntag[0]]
    return nd[:, 1:], index[conn], tet[:, 0], tet[:, 3]


def ring_sector_mesh(
    path: str | Path,
    coil_turns: list[Rect],
    conductors: list[Rect],
    *,
    sector_deg: float = 90.0,
    r_air: float = 0.1,
    r_shell: float | None = 0.125,
    h_coil: float = 2e-3,
    h_conductor: float = 1e-3,
    h_air: float = 0.02,
    h_centre: float | None = None,
    grading: float = 0.3,
    conductor_layers: int | None = None,
    fine_box: tuple[tuple[float, float, float, float, float, float], float] | None = None,
    z_cut: float | None = None,
    racetrack: float = 0.0,
    conductor_names: Sequence[str] = (),
) -> Mesh3D:
    """Tetrahedral mesh of a sector of ring turns (one coil) and conductor rings/disks about the z-axis.

    Parameters
    ----------
    path : MSH 2.2 file to write.
    coil_turns : the turns' cross-sections, ``Rect(r0, z0, r1, z1)`` (m) in the meridian plane.
    conductors : massive conductors, ``Rect(r0, z0, r1, z1)`` (m); ``r0 = 0`` is a disk.
    sector_deg : sector angle (degrees, 0 < angle <= 180); its two meridian faces are id 14.
    r_air, r_shell : radius of the air sphere (m) and of the shell region 2 (m, or None).
    h_coil, h_conductor, h_air : element sizes (m) in the turns, the conductors, at the sphere.
    h_centre : element size at the origin (m), growing by ``grading`` per metre of distance (the
        region where the centre field is probed); None: no local refinement.
    conductor_names : names of the conductors' physical groups (:func:`group_name`; default "conductor_k").
    """
    if not 0 < sector_deg <= 180:
        raise ValueError("sector_deg must be in (0, 180]")
    if racetrack and sector_deg != 90:
        raise ValueError("racetrack turns need a quarter model (sector_deg = 90)")
    alpha = math.radians(sector_deg)
    path = Path(path).resolve()
    with gmsh_session("pulseform_em3d") as gmsh:
        occ = gmsh.model.occ

        def ring(rc: Rect) -> int:
            outer = occ.addCylinder(0, 0, rc.y0, 0, 0, rc.y1 - rc.y0, rc.x1, angle=alpha)
            if rc.x0 <= 0:
                return outer
            inner = occ.addCylinder(0, 0, rc.y0, 0, 0, rc.y1 - rc.y0, rc.x0, angle=alpha)
            return occ.cut([(3, outer)], [(3, inner)])[0][0][1]

        def racetrack_turn(rc: Rect) -> int:
            """Quarter racetrack turn: straight bar along y, then a quarter ring about (0, racetrack)."""
            h = rc.y1 - rc.y0
            bar = occ.addBox(rc.x0, 0, rc.y0, rc.x1 - rc.x0, racetrack, h)
            arc = occ.addCylinder(0, racetrack, rc.y0, 0, 0, h, rc.x1, angle=math.pi / 2)
            hole = occ.addCylinder(0, racetrack, rc.y0, 0, 0, h, rc.x0, angle=math.pi / 2)
            arc = occ.cut([(3, arc)], [(3, hole)])[0][0][1]
            return occ.fuse([(3, bar)], [(3, arc)])[0][0][1]

        def layered(rc: Rect) -> int:
            """The sector of the ring/disk rc as its face at z = y0 extruded in conductor_layers layers."""
            z = rc.y0
            arc = lambda r: (occ.addPoint(r, 0, z), occ.addPoint(r * math.cos(alpha), r * math.sin(alpha), z))
            centre = occ.addPoint(0, 0, z)
            a1, b1 = arc(rc.x1)
            if rc.x0 <= 0:
                curves = [occ.addLine(centre, a1), occ.addCircleArc(a1, centre, b1), occ.addLine(b1, centre)]
            else:
                a0, b0 = arc(rc.x0)
                curves = [occ.addLine(a0, a1), occ.addCircleArc(a1, centre, b1), occ.addLine(b1, b0),
                          occ.addCircleArc(b0, centre, a0)]
            face = occ.addPlaneSurface([occ.addCurveLoop(curves)])
            ext = occ.extrude([(2, face)], 0, 0, rc.y1 - rc.y0, numElements=[conductor_layers], recombine=False)
            return [t for d, t in ext if d == 3][0]

        turn_vols = [racetrack_turn(t) if racetrack else ring(t) for t in coil_turns]
        cond_vols = [layered(c) if conductor_layers else ring(c) for c in conductors]
        sphere = occ.addSphere(0, 0, 0, r_air, angle3=alpha)
        objects = [(3, sphere)]
        if r_shell:
            objects.append((3, occ.addSphere(0, 0, 0, r_shell, angle3=alpha)))
        if z_cut is not None:   # keep z >= z_cut: cut what reaches below, one volume at a time
            big = 4 * (r_shell or r_air)
            box = occ.addBox(-big, -big, -big, 2 * big, 2 * big, z_cut + big)

            def above(v: int) -> int | None:
                occ.synchronize()
                if gmsh.model.getBoundingBox(3, v)[2] >= z_cut:
                    return v
                kept = [t for d, t in occ.cut([(3, v)], [(3, box)], removeTool=False)[0] if d == 3]
                return kept[0] if kept else None

            turn_vols = [t for t in map(above, turn_vols) if t is not None]
            cond_vols = [t for t in map(above, cond_vols) if t is not None]
            objects = [(3, above(t)) for d, t in objects]
            occ.remove([(3, box)], recursive=True)
        tools = [(3, v) for v in turn_vols + cond_vols]
        out, out_map = occ.fragment(objects, tools)
        occ.synchronize()
        model = gmsh.model
        n_obj = len(objects)
        # out_map follows the input order: objects, then tools
        shell_parts = set()
        if r_shell:
            shell_parts = {t for d, t in out_map[1]} - {t for d, t in out_map[0]}
        turn_parts = [t for m in out_map[n_obj:n_obj + len(turn_vols)] for d, t in m]
        cond_parts = [[t for d, t in m] for m in out_map[n_obj + len(turn_vols):]]
        used = set(turn_parts) | {t for c in cond_parts for t in c} | shell_parts
        air_parts = [t for d, t in out if d == 3 and t not in used]
        model.addPhysicalGroup(3, air_parts, AIR)
        if shell_parts:
            model.addPhysicalGroup(3, sorted(shell_parts), SHELL)
        model.addPhysicalGroup(3, turn_parts, coil_tag(1))
        for k, parts in enumerate(cond_parts, start=1):
            model.addPhysicalGroup(3, parts, conductor_tag(k))
            skin = model.getBoundary([(3, t) for t in parts], combined=True, oriented=False)
            model.addPhysicalGroup(2, [abs(t) for d, t in skin], skin_tag(k))
        # boundary faces of the whole domain: meridian planes and the outer sphere
        sym, sym_h, outer = [], [], []
        r_out = r_shell or r_air
        n0 = np.array([0.0, 1.0, 0.0])                        # normal of the plane phi = 0
        n1 = np.array([-math.sin(alpha), math.cos(alpha), 0.0])  # normal of the plane phi = alpha
        e0, e1 = np.array([1.0, 0.0, 0.0]), np.array([math.cos(alpha), math.sin(alpha), 0.0])  # their radial directions
        for d, t in model.getBoundary([(3, v) for v in {t for d, t in out if d == 3}], combined=True,
                                      oriented=False):
            c = np.array(occ.getCenterOfMass(2, abs(t)))
            lo, hi = model.getParametrizationBounds(2, abs(t))
            nrm = np.array(model.getNormal(abs(t), [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])]))
            on_plane = any(abs(c @ n) < 1e-6 * r_out and abs(nrm @ n) > 1 - 1e-9 for n in (n0, n1))
            if z_cut is not None and abs(c[2] - z_cut) < 1e-6 * r_out and abs(nrm[2]) > 1 - 1e-9:
                sym_h.append(abs(t))
            else:
                (sym if on_plane else outer).append(abs(t))
        model.addPhysicalGroup(2, sym, SYM_A)
        if sym_h:
            model.addPhysicalGroup(2, sym_h, SYM_H)
        model.addPhysicalGroup(2, outer, OUTER)
        # the coil's faces on the two planes: electrodes of the electrokinetic pre-solve
        faces_in, faces_out = [], []
        for d, t in model.getBoundary([(3, v) for v in turn_parts], combined=False, oriented=False):
            c = np.array(occ.getCenterOfMass(2, abs(t)))   # on a plane, on its side of the axis
            if abs(c @ n0) < 1e-6 * r_out and c @ e0 > 0:
                faces_in.append(abs(t))
            elif abs(c @ n1) < 1e-6 * r_out and c @ e1 > 0:
                faces_out.append(abs(t))
        model.addPhysicalGroup(2, sorted(set(faces_in)), ELEC_IN_BASE + 1)
        model.addPhysicalGroup(2, sorted(set(faces_out)), ELEC_OUT_BASE + 1)
        electrode_area = {1: float(sum(occ.getMass(2, t) for t in set(faces_in)))}
        # sizes: points of each part, then the refinement at the centre (the minimum wins)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h_air)
        for tags, h in ((air_parts + sorted(shell_parts), h_air), (turn_parts, h_coil),
                        ([t for c in cond_parts for t in c], h_conductor)):
            pts = model.getBoundary([(3, t) for t in tags], combined=False, oriented=False, recursive=True)
            model.mesh.setSize([p for p in pts if p[0] == 0], h)
        fields = []
        if h_centre is not None:
            fields.append(model.mesh.field.add("MathEval"))
            model.mesh.field.setString(fields[-1], "F", f"{h_centre} + {grading} * Sqrt(x*x + y*y + z*z)")
        if fine_box is not None:
            (x0, x1, y0, y1, z0, z1), hb = fine_box
            fields.append(model.mesh.field.add("MathEval"))   # h_b + grading * (distance to the box)
            d = [f"Max(Max({lo} - {v}, {v} - {hi}), 0)" for v, lo, hi in (("x", x0, x1), ("y", y0, y1), ("z", z0, z1))]
            model.mesh.field.setString(fields[-1], "F", f"{hb} + {grading} * Sqrt(({d[0]})^2 + ({d[1]})^2 + ({d[2]})^2)")
        if fields:
            fmin = model.mesh.field.add("Min")
            model.mesh.field.setNumbers(fmin, "FieldsList", fields)
            model.mesh.field.setAsBackgroundMesh(fmin)
        name_groups(gmsh, conductor_names)
        generate_tets(gmsh, path)
    mesh = read_mesh3d(path, float(sector_deg), electrode_area)
    logger.info("3D mesh %s: %d tetrahedra, %d nodes", path.name, mesh.n_tets, mesh.n_nodes)
    return mesh


def group_name(dim: int, tag: int, conductors: Sequence[str] = ()) -> str:
    """The name of the physical group ``tag`` of dimension ``dim`` (the ids of the module docstring) in the
    meshes written here: "air", "shell", "outer", "symmetry", "symmetry_h", "coil" (coil 1; "coil_k"),
    its terminals "coil_in" / "coil_out" ("coil_k_in", ...), conductor k ``conductors[k-1]`` (default
    "conductor_k") and its skin "<conductor>_skin": what a 3D geometry file's role map names."""
    fixed = {(3, 1): "air", (3, 2): "shell", (2, 12): "outer", (2, SYM_A): "symmetry", (2, SYM_H): "symmetry_h"}
    if (dim, tag) in fixed:
        return fixed[(dim, tag)]
    base, k = divmod(tag, 100)
    coil = "coil" if k == 1 else f"coil_{k}"
    cond = conductors[k - 1] if 0 < k <= len(conductors) else f"conductor_{k}"
    named = {(3, 1): coil, (3, 2): cond, (2, 4): f"{cond}_skin", (2, 5): f"{coil}_in", (2, 6): f"{coil}_out"}
    return named.get((dim, base), f"group_{dim}_{tag}")


def name_groups(gmsh, conductors: Sequence[str] = ()) -> None:
    """Give every physical group of the open gmsh model its :func:`group_name`."""
    for dim, tag in gmsh.model.getPhysicalGroups():
        gmsh.model.setPhysicalName(dim, tag, group_name(dim, tag, conductors))


def generate_tets(gmsh, path: Path) -> None:
    """Mesh the open gmsh model in 3D (Delaunay, optimised) and write it as ASCII MSH 2.2 (what GetDP
    reads) at ``path``."""
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)
    gmsh.option.setNumber("Mesh.Optimize", 1)
    gmsh.model.mesh.generate(3)
    gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
    gmsh.option.setNumber("Mesh.Binary", 0)
    path.parent.mkdir(parents=True, exist_ok=True)
    gmsh.write(str(path))


def read_mesh3d(path: Path, sector_deg: float, electrode_area: dict[int, float]) -> Mesh3D:
    """The :class:`Mesh3D` of an MSH 2.2 file written by :func:`generate_tets`."""
    points, tets, ids, tags = read_msh22_tets(path)
    return Mesh3D(points=points, tets=tets, tet_ids=ids, tet_tags=tags, path=path, sector_deg=sector_deg,
                  electrode_area=electrode_area)
