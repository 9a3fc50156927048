"""The EM mesh of a 3D geometry file (``[geometry] type = "geometry_3d"``): the user's file meshed and its named
physical groups read (:mod:`.gmsh_file`, steps 1 and 2 below), the role map mapped onto the 3D deck's physical ids.

1. :func:`mesh_file3d`: a ``.msh`` is read as it is; a ``.geo`` or a CAD file (``.step``/``.stp``, ``.brep``,
   ``.iges``/``.igs``) is meshed with tetrahedra by gmsh in a child process (``python -m
   pulseform.orchestrator.mesh.geometry3d``: ``-setnumber`` parameters, the sizes of
   ``geometry.mesh_sizes`` on the points of each named volume group, MSH 2.2) under
   ``limits.gmsh_time_limit_s``; a CAD file without physical groups gets one per volume and per surface,
   named by its CAD label or ``volume_<tag>`` / ``surface_<tag>``; a ``.py`` builder runs as
   ``python FILE OUT.msh name=value ...`` (it writes OUT.msh with named physical groups).
2. :func:`read_groups`: the tetrahedra and triangles of every named group (meshio reads MSH 2.2 and 4.1).
3. :func:`map_roles`: the tetrahedra renumbered to the deck's ids (:mod:`pulseform.solvers.getdp.mesh3d`:
   1 air, 2 shell, 100+k coil k, 200+k conductor k -- the bodies in [[bodies]] order, then the fixed
   conductors), the surfaces the deck needs computed from the tetrahedra: the skins 400+k, the boundary
   faces on each ``[[symmetry]]`` plane (14 for ``field = "b_tangential"``: n x a = 0; 15 for "b_normal"),
   the rest of the boundary 12 (n x a = 0), and the coils' terminals 500+k / 600+k (or cuts 700+k);
   written as MSH 2.2 (node and tetrahedron order kept) for GetDP.

Every mistake of the role map is a :class:`GeometryError`: one line naming the file and the case key.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from pulseform.solvers.getdp.mesh import AIR, OUTER, SHELL, coil_tag, conductor_tag
from pulseform.solvers.getdp.mesh3d import CUT_BASE, ELEC_IN_BASE, ELEC_OUT_BASE, SYM_A, SYM_H, Mesh3D, skin_tag

from ..case.memory import available_memory, memory_needed
from .gmsh_file import GeometryError, RawGroups, mesh_file3d, read_groups
from .markers import box_marker

log = logging.getLogger(__name__)

#: faces of a tetrahedron (local node indices), outward for a positively oriented one
_TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])


# ----------------------------------------------------------------------------- 3. roles
@dataclass
class PlaneSpec:
    """A symmetry plane as the mesh sees it: ``point`` and unit ``normal`` (m), ``field`` its EM condition."""

    point: np.ndarray
    normal: np.ndarray
    field: str


@dataclass
class Geometry3D:
    """A 3D geometry file's EM mesh with the deck's ids (module docstring).

    ``mesh`` the :class:`Mesh3D` (``sector_deg`` = 360 / symmetry factor); ``conductors`` name -> k
    (physical 200 + k: the bodies then the fixed conductors); ``coils`` name -> k (100 + k);
    ``surface_nodes`` physical surface group name -> its node rows (supports), ``surface_tris`` -> its triangles
    (node rows; a ten-node body's supports hold the edge nodes on them too); ``shell`` (R_int, R_ext) m or None;
    ``planes`` the symmetry planes; ``groups`` the file's group listing (messages, ``check``).
    """

    mesh: Mesh3D
    conductors: dict[str, int]
    coils: dict[str, int]
    surface_nodes: dict[str, np.ndarray]
    shell: tuple[float, float] | None
    planes: list[PlaneSpec]
    groups: str
    coil_sections: dict[int, float] = field(default_factory=dict)
    surface_tris: dict[str, np.ndarray] = field(default_factory=dict)


def boundary_faces(tets: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """Faces (f, 3) of the tetrahedra ``rows`` (all by default) that belong to one of them only."""
    t = tets if rows is None else tets[rows]
    faces = t[:, _TET_FACES].reshape(-1, 3)
    _, inv, cnt = np.unique(np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True)
    return faces[cnt[inv.ravel()] == 1]


def _face_keys(faces: np.ndarray, n: int) -> np.ndarray:
    s = np.sort(faces, axis=1).astype(np.int64)
    return (s[:, 0] * n + s[:, 1]) * n + s[:, 2]


def triangle_area(points: np.ndarray, tris: np.ndarray) -> float:
    """Total area (m^2) of triangles ``tris`` (node rows of ``points``)."""
    p = points[tris]
    return float(0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum())


def outer_area(points: np.ndarray, tris: np.ndarray, planes: Sequence[PlaneSpec], rel_tol: float = 1e-7) -> float:
    """Area (m^2) of the triangles ``tris`` (node rows of ``points``) less those lying in one of the symmetry
    ``planes`` (all three nodes within ``rel_tol`` x the largest coordinate of ``points`` of the plane): a modelled
    part's outer surface, without the faces where the mirror images join it."""
    tris = np.asarray(tris, np.int64)
    if len(tris) == 0:
        return 0.0
    x = np.asarray(points, float)
    tol = rel_tol * max(float(np.abs(x).max()), 1e-300)
    inside = np.zeros(len(tris), bool)
    for p in planes:
        n = np.asarray(p.normal, float) / np.linalg.norm(p.normal)
        on = np.abs((x - np.asarray(p.point, float)) @ n) <= tol
        inside |= on[tris].all(axis=1)
    return triangle_area(x, tris[~inside]) if np.any(~inside) else 0.0


def shell_radii(x: np.ndarray, tets: np.ndarray, tet_tags: np.ndarray, centre) -> tuple[float, float]:
    """(R_int, R_ext) (m) of the shell region about ``centre`` as the mesh has it: R_ext the largest node
    radius, R_int the smallest distance from the centre to the planes of the shell's inner faces (their chords
    of the inner sphere lie inside it: every point of the shell's tetrahedra, GetDP's integration points
    among them, then has a radius within [R_int, R_ext])."""
    c = np.asarray(centre, float)
    rows = np.flatnonzero(tet_tags == SHELL)
    r = np.linalg.norm(x[np.unique(tets[rows])] - c, axis=1)
    faces = boundary_faces(tets, rows)
    inner = faces[np.isin(faces, tets[tet_tags != SHELL]).all(axis=1)]
    if not len(inner):
        return float(r.min()), float(r.max())
    p = x[inner]
    nrm = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    d = np.abs(np.einsum("ij,ij->i", nrm, p[:, 0] - c)) / np.linalg.norm(nrm, axis=1)
    return float(min(d.min(), r.min())), float(r.max())


def map_roles(raw: RawGroups, g, bodies: Sequence[tuple[str, str]], planes: Sequence[PlaneSpec], out: Path,
              symmetry_factor: float, label: str, max_cells: float | None = None,
              available: float | None = None) -> Geometry3D:
    """The deck's mesh of ``raw`` (module docstring, 3.), written to ``out`` (MSH 2.2).

    ``g`` the case's :class:`~pulseform.orchestrator.case.geometry3d.GeometryFile3D`; ``bodies`` (key, group)
    of the conductor bodies in [[bodies]] order; ``planes`` the symmetry planes; ``label`` the file named in
    messages; ``max_cells`` ``limits.max_cells``; ``available`` the memory (bytes; default: the machine's
    available memory). Raises :class:`GeometryError` naming the case key."""
    vols, surfs = set(raw.volumes), raw.surfaces

    def need(group: str, key: str, kind: str) -> None:
        if group not in (vols if kind == "volume" else surfs):
            raise GeometryError(f"{label}: {key}: got {group!r}, not a physical {kind} group of the mesh; its groups: "
                                f"{raw.listing()}")

    if max_cells is not None and len(raw.tets) > max_cells:
        raise GeometryError(f"{label}: limits.max_cells: the mesh has {len(raw.tets)} tetrahedra, above "
                            f"limits.max_cells = {max_cells:.3g}; coarsen geometry.mesh_sizes or raise the limit")
    memory, have = memory_needed(len(raw.tets)), available_memory() if available is None else available
    if have is not None and memory > have:
        raise GeometryError(f"{label}: geometry.mesh_sizes: the mesh has {len(raw.tets)} tetrahedra, a run needs "
                            f"~{memory / 1e9:.3g} GB and {have / 1e9:.3g} GB are available; coarsen the mesh")
    need(g.air, "geometry.air", "volume")
    role = {g.air: AIR}
    if g.shell is not None:
        need(g.shell, "geometry.shell", "volume")
        role[g.shell] = SHELL
    coils = {}
    for k, c in enumerate(g.coils, start=1):
        need(c.group, f"geometry.coils[{k - 1}].group", "volume")
        role[c.group] = coil_tag(k)
        coils[c.name] = k
    conductors = {}
    cond_keys = [(key, grp, grp) for key, grp in bodies] + \
        [(f"geometry.conductors[{i}].group", c.group, c.name) for i, c in enumerate(g.conductors)]
    for k, (key, grp, name) in enumerate(cond_keys, start=1):
        need(grp, key, "volume")
        role[grp] = conductor_tag(k)
        conductors[name] = k
    unmapped = sorted(vols - set(role))
    if unmapped:
        raise GeometryError(f"{label}: geometry: the volume group {unmapped[0]!r} has no role; name it as "
                            "geometry.air / shell, a coil, a [[bodies]] region or a [[geometry.conductors]] group "
                            f"(the mesh's volumes: {', '.join(repr(v) for v in raw.volumes)})")
    tet_tags = np.array([role[gname] for gname in raw.tet_group.tolist()], dtype=np.int64)
    x, tets, n = raw.points, raw.tets, len(raw.points)
    scale = float(np.abs(x).max())
    # the domain's boundary: on a plane (14 / 15) or the outer boundary (12)
    outer_faces = boundary_faces(tets)
    on_plane = np.zeros(len(outer_faces), dtype=bool)
    tri_parts, tag_parts = [], []
    for i, p in enumerate(planes):
        hit = np.all(np.abs((x[outer_faces] - p.point) @ p.normal) <= 1e-7 * scale, axis=1) & ~on_plane
        if not hit.any():   # a plane the model does not end on: its factor and roller would be wrong
            raise GeometryError(f"{label}: symmetry[{i}]: the plane through {p.point.tolist()} with normal "
                                f"{p.normal.tolist()} holds no boundary face of the mesh; a symmetry plane is "
                                "where the model ends: remove the [[symmetry]] entry or cut the geometry there")
        on_plane |= hit
        tri_parts.append(outer_faces[hit])
        tag_parts.append(np.full(hit.sum(), SYM_A if p.field == "b_tangential" else SYM_H))
    outer = outer_faces[~on_plane]
    if len(outer) == 0:
        raise GeometryError(f"{label}: geometry: the mesh has no outer boundary besides its symmetry planes")
    tri_parts.append(outer)
    tag_parts.append(np.full(len(outer), OUTER))
    outer_nodes = np.unique(outer)
    # conductors and coils must not touch the outer boundary (n x a = 0 there would short their field)
    for name, k in list(conductors.items()) + [(c, None) for c in coils]:
        tag = conductor_tag(k) if k is not None else coil_tag(coils[name])
        rows = np.flatnonzero(tet_tags == tag)
        if np.isin(tets[rows], outer_nodes).any():
            key = next((kk for kk, grp, nm in cond_keys if nm == name), f"geometry.coils[{coils.get(name, 1) - 1}].group")
            raise GeometryError(f"{label}: {key}: the group touches the outer boundary of the air; leave air "
                                "around it (or cut it with a [[symmetry]] plane)")
    # skins of the conductors (the tree of the gauge starts there)
    for name, k in conductors.items():
        skin = boundary_faces(tets, np.flatnonzero(tet_tags == conductor_tag(k)))
        tri_parts.append(skin)
        tag_parts.append(np.full(len(skin), skin_tag(k)))
    # the coils' current paths
    electrode_area, sections = {}, {}
    for k, c in enumerate(g.coils, start=1):
        key = f"geometry.coils[{k - 1}]"
        coil_skin = _face_keys(boundary_faces(tets, np.flatnonzero(tet_tags == coil_tag(k))), n)
        if c.terminals is not None:
            for j, (grp, base) in enumerate(zip(c.terminals, (ELEC_IN_BASE, ELEC_OUT_BASE))):
                need(grp, f"{key}.terminals[{j}]", "surface")
                tri = surfs[grp]
                if not np.isin(_face_keys(tri, n), coil_skin).all():
                    raise GeometryError(f"{label}: {key}.terminals[{j}]: the surface {grp!r} is not on the boundary "
                                        f"of the coil's volume {c.group!r}; a terminal is a face of the coil")
                tri_parts.append(tri)
                tag_parts.append(np.full(len(tri), base + k))
            electrode_area[k] = triangle_area(x, surfs[c.terminals[0]])
            sections[k] = electrode_area[k]
        elif c.cut is not None:
            need(c.cut, f"{key}.cut", "surface")
            tri = surfs[c.cut]
            coil_nodes = np.unique(tets[tet_tags == coil_tag(k)])
            if not np.isin(tri, coil_nodes).all():
                raise GeometryError(f"{label}: {key}.cut: the surface {c.cut!r} does not lie in the coil {c.group!r}")
            tri_parts.append(tri)
            tag_parts.append(np.full(len(tri), CUT_BASE + k))
            sections[k] = triangle_area(x, tri)
    surface_nodes = {name: np.unique(t) for name, t in surfs.items()}
    shell = None
    if g.shell is not None:
        shell = g.shell_radii if g.shell_radii is not None else shell_radii(x, tets, tet_tags, g.shell_centre)
        if not shell[1] > shell[0] * (1 + 1e-6):
            raise GeometryError(f"{label}: geometry.shell: the group {g.shell!r} is not a layer between two spheres "
                                f"about geometry.shell_centre = {list(g.shell_centre)}")
    out = Path(out).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    from .remesh3d import write_msh22_3d

    tris = np.concatenate(tri_parts) if tri_parts else np.zeros((0, 3), np.int64)
    ids = write_msh22_3d(out, x, tets, tet_tags, tris, np.concatenate(tag_parts))
    mesh = Mesh3D(points=x.copy(), tets=tets, tet_ids=ids, tet_tags=tet_tags, path=out,
                  sector_deg=360.0 / symmetry_factor, electrode_area=electrode_area or None)
    log.debug("3D geometry %s: %d tetrahedra, %d nodes; coils %s, conductors %s", label, mesh.n_tets, mesh.n_nodes,
             coils, conductors)
    return Geometry3D(mesh=mesh, conductors=conductors, coils=coils, surface_nodes=surface_nodes, shell=shell,
                      planes=list(planes), groups=raw.listing(), coil_sections=sections,
                      surface_tris=dict(surfs))


def plane_specs(symmetry) -> list[PlaneSpec]:
    """The :class:`PlaneSpec` of the case's ``[[symmetry]]`` planes."""
    out = []
    for s in symmetry:
        nrm = np.asarray(s.normal, float)
        out.append(PlaneSpec(np.asarray(s.point, float), nrm / np.linalg.norm(nrm), s.field))
    return out


def build_geometry3d(case, work: Path) -> Geometry3D:
    """Mesh the case's geometry file in ``work`` and map its roles (:func:`mesh_file3d`, :func:`read_groups`,
    :func:`map_roles`): the EM mesh ``work/em3d.msh``."""
    g = case.geometry
    label = Path(g.file).name
    raw_path = mesh_file3d(g, work, case.limits.gmsh_time_limit_s, case.limits.max_cells)
    raw = read_groups(raw_path, label)
    planes = plane_specs(case.symmetry)
    bodies = [(f"bodies[{i}].region", b.region) for i, b in enumerate(case.bodies)]
    for i, b in enumerate(case.bodies):
        for j, f in enumerate(b.fixed):
            if f.group is not None and f.group not in raw.surfaces:
                raise GeometryError(f"{label}: bodies[{i}].fixed[{j}].group: got {f.group!r}, not a physical surface "
                                    f"group of the mesh; its groups: {raw.listing()}")
    geo = map_roles(raw, g, bodies, planes, Path(work) / "em3d.msh",
                    symmetry_factor(g, planes, raw.points, label), label, case.limits.max_cells)
    check_fixed_boxes(case, geo, label)
    return geo


def check_fixed_boxes(case, geo: Geometry3D, label: str) -> None:
    """Every ``[[bodies.fixed]]`` box of a deformable body holds at least one of its nodes (the 3D semantics of
    :func:`~.markers.box_marker`, widened by 1e-9 of the mesh's size); raises :class:`GeometryError`
    naming the key otherwise: a support beyond its body is a mistake, not a free body."""
    m = geo.mesh
    tol = 1e-9 * float(np.abs(m.points).max())
    for i, b in enumerate(case.bodies):
        if b.rigid or not any(f.where is not None for f in b.fixed):
            continue
        x = m.points[np.unique(m.tets[m.tet_tags == conductor_tag(geo.conductors[b.region])])].T
        for j, f in enumerate(b.fixed):
            if f.where is not None and not np.any(box_marker(f.where, tol)(x)):
                raise GeometryError(f"{label}: bodies[{i}].fixed[{j}].where: the box holds no node of body "
                                    f"{b.name!r} (bounds x, y, z, and rmin/rmax about the z-axis, m)")


def symmetry_factor(g, planes: Sequence[PlaneSpec], points: np.ndarray, label: str) -> float:
    """Whole device / modelled part: ``geometry.symmetry_factor`` when given; else 2^k for k (<= 3) mutually
    perpendicular planes; else, for two planes (a wedge: a sector about their common line), 360 degrees over the
    wedge's angle, the angular extent of the mesh's ``points`` about that line. Raises :class:`GeometryError`
    for other plane sets without ``geometry.symmetry_factor``."""
    if g.symmetry_factor is not None:
        return float(g.symmetry_factor)
    n = [p.normal for p in planes]
    if all(abs(float(a @ b)) <= 1e-9 for i, a in enumerate(n) for b in n[:i]):
        return float(2 ** len(n))
    if len(planes) != 2:
        raise GeometryError(f"{label}: geometry.symmetry_factor: missing; {len(planes)} [[symmetry]] planes, not "
                            "mutually perpendicular: give the whole device / modelled part")
    axis = np.cross(n[0], n[1])
    axis /= np.linalg.norm(axis)
    # a point on both planes: the least-squares solution of n_i . x = n_i . p_i
    a = np.array(n)
    x0 = np.linalg.lstsq(a, np.array([float(p.normal @ p.point) for p in planes]), rcond=None)[0]
    e1 = np.cross(n[0], axis)   # in plane 0, normal to the axis
    e2 = np.cross(axis, e1)
    d = points - x0
    d = d - np.outer(d @ axis, axis)
    far = np.linalg.norm(d, axis=1) > 1e-6 * float(np.abs(points).max())
    phi = np.arctan2(d[far] @ e2, d[far] @ e1)
    phi = np.where(phi < -1e-9, phi + 2 * np.pi, phi)   # angles from plane 0, in [0, 2 pi)
    span = float(phi.max() - phi.min())
    if not 1e-6 < span < 2 * np.pi - 1e-6:
        raise GeometryError(f"{label}: geometry.symmetry_factor: missing; the mesh does not lie in one wedge of the "
                            "two [[symmetry]] planes: give the whole device / modelled part")
    return 2 * np.pi / span


def stable_step_estimate(case, geo: Geometry3D) -> float:
    """An upper bound (s) of the explicit stable step of the case's deformable bodies on the mapped mesh: cfl x
    the smallest altitude of their tetrahedra (3 V / largest face area) over the dilatational wave speed
    sqrt((K + 4 G / 3) / rho) -- the solver's own rule without the bulk viscosity's reduction; inf without
    deformable bodies. What ``pulseform check`` holds against ``limits.max_steps`` before a run."""
    m = geo.mesh
    dt = float("inf")
    for k, b in enumerate(case.bodies, start=1):
        if b.rigid:
            continue
        rows = np.flatnonzero(m.tet_tags == conductor_tag(k))
        vol, t = m.volumes(rows), m.points[m.tets[rows]]
        faces = t[:, _TET_FACES]
        area = 0.5 * np.linalg.norm(np.cross(faces[:, :, 1] - faces[:, :, 0], faces[:, :, 2] - faces[:, :, 0]), axis=2)
        mat = case.materials[b.material]
        c = np.sqrt((mat.bulk_modulus + 4.0 * mat.shear_modulus / 3.0) / mat.density)
        dt = min(dt, float((3.0 * vol / area.max(axis=1)).min()) / c)
    return case.time.cfl * dt
