"""The EM mesh of a 3D geometry file (``[geometry] type = "geometry_3d"``): mesh the user's file, read its named
physical groups, map the role map onto the 3D deck's physical ids.

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

import json
import logging
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from pulseform.solvers.getdp.mesh import AIR, OUTER, SHELL, coil_tag, conductor_tag

from ..case.memory import available_memory, memory_needed
from pulseform.solvers.getdp.mesh3d import CUT_BASE, ELEC_IN_BASE, ELEC_OUT_BASE, SYM_A, SYM_H, Mesh3D, skin_tag

log = logging.getLogger(__name__)

#: gmsh's element kinds of interest in meshio's names
_TETRA, _TRIANGLE = "tetra", "triangle"
#: faces of a tetrahedron (local node indices), outward for a positively oriented one
_TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])


class GeometryError(RuntimeError):
    """A 3D geometry file or its role map is not usable (one line naming the file and the key).

    ``log_path``: the gmsh log it refers to, if any."""

    def __init__(self, message: str, *, log_path: Path | None = None) -> None:
        self.message = message
        self.log_path = None if log_path is None else Path(log_path)
        super().__init__(message if log_path is None else f"{message} (log: {log_path})")


# ----------------------------------------------------------------------------- 1. meshing
def mesh_file3d(g, work: Path, time_limit: float = 600.0) -> Path:
    """The raw mesh of ``g`` (a :class:`~pulseform.orchestrator.case.geometry3d.GeometryFile3D`): the
    ``.msh`` itself or the file meshed by a child process into ``work/geometry.msh`` (log
    ``work/gmsh.log``); raises :class:`GeometryError` with the log's tail when meshing fails or exceeds
    ``time_limit`` (s)."""
    from pulseform.solvers.getdp.runner import run_logged

    src = Path(g.file)
    if src.suffix.lower() == ".msh":
        return src
    work = Path(work).resolve()
    work.mkdir(parents=True, exist_ok=True)
    out = work / "geometry.msh"
    out.unlink(missing_ok=True)
    params = [f"{k}={float(v)!r}" for k, v in (g.parameters or {}).items()]
    factor = float(getattr(g, "mesh_size_factor", 1.0))
    if src.suffix.lower() == ".py":
        argv = [sys.executable, str(src), str(out)] + params + ([f"mesh_size_factor={factor!r}"] if factor != 1.0 else [])
        what = "the builder"
    else:
        argv = [sys.executable, "-m", __name__, str(src), str(out), json.dumps(g.mesh_sizes or {}), repr(factor)] + params
        what = "gmsh"
    log_path = work / "gmsh.log"
    try:
        code, text = run_logged(argv, src.parent, log_path, time_limit)
    except subprocess.TimeoutExpired:
        raise GeometryError(f"{src.name}: geometry.file: meshing exceeded its time limit of {time_limit:g} s "
                            "(limits.gmsh_time_limit_s) and was stopped", log_path=log_path) from None
    except OSError as exc:
        raise GeometryError(f"{src.name}: geometry.file: could not start {what}: {exc}", log_path=log_path) from None
    if code != 0 or not out.is_file():
        lines = [ln for ln in text.splitlines() if ln.strip()]
        last = next((ln for ln in reversed(lines) if "rror" in ln), lines[-1] if lines else f"exit code {code}")
        raise GeometryError(f"{src.name}: geometry.file: {what} failed: {last.strip()[:200]}", log_path=log_path)
    return out


class BuilderArgumentError(ValueError):
    """A gmsh builder script was called with arguments it does not know."""


def builder_arguments(argv: Sequence[str], known: Sequence[str], integers: Sequence[str] = ()
                      ) -> tuple[str, dict[str, float | int], float]:
    """The arguments a ``.py`` builder receives (``python FILE OUT.msh name=value ... [mesh_size_factor=f]``):
    (OUT.msh, the values by name -- ints for ``integers`` --, the mesh size factor, 1.0 when not given).
    A builder script calls this on ``sys.argv[1:]``; raises :class:`BuilderArgumentError` naming an unknown name
    (the builder prints it as an ``Error:`` line, which pulseform quotes)."""
    if not argv:
        raise BuilderArgumentError("usage: python BUILDER.py OUT.msh [name=value ...]")
    values: dict[str, float | int] = {}
    factor = 1.0
    for item in argv[1:]:
        name, _, text = item.partition("=")
        if name == "mesh_size_factor":   # pulseform's refinement (geometry.mesh_size_factor)
            factor = float(text)
        elif name in known:
            values[name] = int(float(text)) if name in integers else float(text)
        else:
            raise BuilderArgumentError(f"unknown parameter {name!r}; known: {', '.join(sorted(known))}")
    return argv[0], values, factor


def _child(src: str, out: str, sizes_json: str, factor: float, params: Sequence[str]) -> int:
    """The meshing child (module docstring, 1.): open ``src`` with ``params`` (``name=value``), size the
    named volume groups, every size times ``factor``, mesh in 3D, write MSH 2.2 to ``out``. Prints gmsh's
    messages (the log)."""
    import gmsh

    argv = ["gmsh"]
    for p in params:
        name, value = p.split("=", 1)
        argv += ["-setnumber", name, value]
    gmsh.initialize(argv, readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 1)
        try:
            gmsh.open(src)
        except Exception as exc:   # a parse error or the file's own Error(...): its message, not the traceback's
            print(f"Error: {exc}")
            return 3
        if Path(src).suffix.lower() != ".geo" and not gmsh.model.getPhysicalGroups():
            _name_cad_entities(gmsh)
        names = {gmsh.model.getPhysicalName(d, t): (d, t) for d, t in gmsh.model.getPhysicalGroups()}
        for group, h in json.loads(sizes_json).items():
            if group not in names or names[group][0] != 3:
                vols = sorted(n for n, (d, _) in names.items() if d == 3)
                print(f"Error: geometry.mesh_sizes: no physical volume group {group!r}; the file's: {vols}")
                return 3
            ents = gmsh.model.getEntitiesForPhysicalGroup(3, names[group][1])
            pts = gmsh.model.getBoundary([(3, int(e)) for e in ents], combined=False, oriented=False, recursive=True)
            gmsh.model.mesh.setSize([p for p in pts if p[0] == 0], float(h))
        if gmsh.model.getDimension() < 3 or not gmsh.model.getEntities(3):
            print("Error: the geometry has no volume")
            return 3
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.option.setNumber("Mesh.Optimize", 1)
        if factor != 1.0:
            gmsh.option.setNumber("Mesh.MeshSizeFactor", factor)
        gmsh.model.mesh.generate(3)
        gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(out)
    finally:
        gmsh.finalize()
    return 0


def _name_cad_entities(gmsh) -> None:
    """A CAD file without physical groups: make its volumes conforming (one fragment) and give every volume
    and surface a physical group named by its CAD label or ``volume_<tag>`` / ``surface_<tag>``."""
    vols = gmsh.model.getEntities(3)
    if len(vols) > 1:
        gmsh.model.occ.fragment(vols[:1], vols[1:])
        gmsh.model.occ.synchronize()
    for dim, what in ((3, "volume"), (2, "surface")):
        used: set[str] = set()
        for _, tag in gmsh.model.getEntities(dim):
            label = gmsh.model.getEntityName(dim, tag).split("/")[-1].strip()
            name = label if label and label not in used else f"{what}_{tag}"
            used.add(name)
            p = gmsh.model.addPhysicalGroup(dim, [tag])
            gmsh.model.setPhysicalName(dim, p, name)


# ----------------------------------------------------------------------------- 2. reading
@dataclass
class RawGroups:
    """A raw 3D mesh by named physical group: ``points`` (n, 3) m (only nodes of tetrahedra, file order);
    ``tets`` (m, 4) node rows, ``tet_group`` the group name of each; ``surfaces`` name -> (f, 3) node rows;
    ``volumes`` the volume groups' names; ``path`` the file."""

    points: np.ndarray
    tets: np.ndarray
    tet_group: np.ndarray
    surfaces: dict[str, np.ndarray]
    volumes: list[str]
    path: Path

    def listing(self) -> str:
        """The groups for a message: volumes then surfaces, each quoted."""
        return ("volumes " + ", ".join(repr(v) for v in self.volumes) + "; surfaces "
                + (", ".join(repr(s) for s in self.surfaces) or "(none)"))


def read_groups(path: Path, label: str) -> RawGroups:
    """Read a MSH file's tetrahedra and triangles by physical-group name (``label``: the file named in
    messages). Unnamed groups are named by their number. Nodes used by no tetrahedron are dropped (the
    order of the others kept)."""
    import meshio

    try:
        m = meshio.read(path)
    except Exception as exc:  # meshio raises many kinds for a file that is not a mesh
        raise GeometryError(f"{label}: geometry.file: not a readable mesh: {str(exc)[:150]}") from None
    names = {}
    for name, (tag, dim) in ((k, (int(v[0]), int(v[1]))) for k, v in (m.field_data or {}).items()):
        names[(dim, tag)] = name
    phys = m.cell_data.get("gmsh:physical")
    if phys is None:
        raise GeometryError(f"{label}: geometry.file: the mesh has no physical groups; name its volumes and "
                            "surfaces (Physical Volume(\"air\") = {...}; ...)")
    tets, tet_tag, tris = [], [], {}
    for block, tags in zip(m.cells, phys):
        if block.type == _TETRA:
            tets.append(block.data)
            tet_tag.append(np.asarray(tags, int))
        elif block.type == _TRIANGLE:
            for t in np.unique(tags):
                name = names.get((2, int(t)), str(int(t)))
                tris.setdefault(name, []).append(block.data[np.asarray(tags) == t])
    if not tets:
        raise GeometryError(f"{label}: geometry.file: the mesh has no tetrahedra in a physical volume group")
    tets_a, tag_a = np.concatenate(tets).astype(np.int64), np.concatenate(tet_tag)
    used = np.unique(tets_a)
    new = np.full(len(m.points), -1, dtype=np.int64)
    new[used] = np.arange(len(used))
    group_of = np.array([names.get((3, int(t)), str(int(t))) for t in np.unique(tag_a)], dtype=object)
    lookup = dict(zip(np.unique(tag_a).tolist(), group_of.tolist()))
    surfaces = {}
    for name, parts in tris.items():
        t = np.concatenate(parts).astype(np.int64)
        if np.all(new[t] >= 0):
            surfaces[name] = new[t]
    volumes = sorted(set(lookup.values()))
    return RawGroups(points=np.asarray(m.points[used], float)[:, :3].copy(), tets=new[tets_a],
                     tet_group=np.array([lookup[t] for t in tag_a.tolist()], dtype=object), surfaces=surfaces,
                     volumes=volumes, path=Path(path))


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
    ``surface_nodes`` physical surface group name -> its node rows (supports); ``shell`` (R_int, R_ext) m
    or None; ``planes`` the symmetry planes; ``groups`` the file's group listing (messages, ``check``).
    """

    mesh: Mesh3D
    conductors: dict[str, int]
    coils: dict[str, int]
    surface_nodes: dict[str, np.ndarray]
    shell: tuple[float, float] | None
    planes: list[PlaneSpec]
    groups: str
    coil_sections: dict[int, float] = field(default_factory=dict)


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
                      planes=list(planes), groups=raw.listing(), coil_sections=sections)


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
    raw_path = mesh_file3d(g, work, case.limits.gmsh_time_limit_s)
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
    :func:`~..mech.pulses.box_marker`, widened by 1e-9 of the mesh's size); raises :class:`GeometryError`
    naming the key otherwise: a support beyond its body is a mistake, not a free body."""
    from ..mech.pulses import box_marker

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


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m pulseform.orchestrator.mesh.geometry3d SRC OUT SIZES_JSON FACTOR [name=value ...]``: the meshing
    child."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) < 4:
        print("usage: python -m pulseform.orchestrator.mesh.geometry3d SRC OUT SIZES_JSON FACTOR [name=value ...]")
        return 2
    return _child(args[0], args[1], args[2], float(args[3]), args[4:])


if __name__ == "__main__":
    sys.exit(main())
