"""EM meshes for the GetDP runner: a small array container, the MSH 2.2 writer, builders.

Physical ids (defined here once; ``decks/em_case.pro`` receives them with ``-setnumber``,
:func:`physical_numbers`):

====================  ==========================================
1                     air
2                     shell (transformation to infinity)
100 + k               coil k (k = 1..), all its turns
200 + k               massive conductor k (k = 1..)
800 + k               non-conducting magnetic core k (k = 1..)
11                    axis (a = 0, axisymmetric)
12                    outer boundary (a = 0)
13                    boundary with an imposed tangential field
====================  ==========================================

Element ids written to the MSH file: triangle ``i`` (0-based row of ``triangles``)
gets id ``i + 1``; boundary lines follow.  GetDP reports these ids, so per-element
outputs map back to rows of ``triangles``.
"""
from __future__ import annotations

import signal
import threading
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

AIR, SHELL, AXIS, OUTER, NEUMANN = 1, 2, 11, 12, 13
COIL_BASE, CONDUCTOR_BASE = 100, 200  # coil k: COIL_BASE + k, massive conductor k: CONDUCTOR_BASE + k
CORE_BASE = 800  # non-conducting magnetic core k: CORE_BASE + k


@contextmanager
def gmsh_session(model_name: str) -> Iterator[Any]:
    """The gmsh API, initialised (quiet, no config files) with one model, finalised on exit.

    gmsh 4.8's Python module sets SIGINT to the default action when imported and puts back, in
    ``finalize``, whatever was there at import: the caller's SIGINT / SIGTERM handlers are saved
    before and restored after, so that a Ctrl-C keeps meaning what the caller decided.
    Yields the ``gmsh`` module.
    """
    main = threading.current_thread() is threading.main_thread()
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)} if main else {}

    def restore() -> None:
        for s, h in saved.items():
            if h is not None and signal.getsignal(s) is not h:
                signal.signal(s, h)

    import gmsh

    restore()
    gmsh.initialize(readConfigFiles=False)
    restore()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(model_name)
        yield gmsh
    finally:
        gmsh.finalize()
        restore()


def default_name(tag: int) -> str:
    """Name of a physical id: air, shell, axis, outer, neumann, coil_k, conductor_k, core_k."""
    fixed = {AIR: "air", SHELL: "shell", AXIS: "axis", OUTER: "outer", NEUMANN: "neumann"}
    if tag in fixed:
        return fixed[tag]
    if tag > CORE_BASE:
        return f"core_{tag - CORE_BASE}"
    return f"coil_{tag - COIL_BASE}" if COIL_BASE < tag < CONDUCTOR_BASE else f"conductor_{tag - CONDUCTOR_BASE}"


def coil_tag(k: int) -> int:
    """Physical id of coil ``k`` (1-based)."""
    return COIL_BASE + k


def conductor_tag(k: int) -> int:
    """Physical id of massive conductor ``k`` (1-based)."""
    return CONDUCTOR_BASE + k


def core_tag(k: int) -> int:
    """Physical id of the non-conducting magnetic core ``k`` (1-based)."""
    return CORE_BASE + k


def physical_numbers() -> dict[str, int]:
    """The physical ids as the built-in deck ``decks/em_case.pro`` receives them with ``-setnumber``
    (its ``DefineConstant`` defaults repeat them, so the deck also runs alone): ``Phys_Air``,
    ``Phys_Shell``, ``Phys_Axis``, ``Phys_Outer``, ``Phys_Neumann``, and the bases
    ``Phys_Coil_Base`` / ``Phys_Cond_Base``: coil k is ``Phys_Coil_Base + k``, massive conductor k
    ``Phys_Cond_Base + k`` (:func:`coil_tag`, :func:`conductor_tag`); ``Phys_Core_Base``: magnetic core k
    is ``Phys_Core_Base + k`` (:func:`core_tag`; ``decks/em_magnetic.pro``)."""
    return {"Phys_Air": AIR, "Phys_Shell": SHELL, "Phys_Axis": AXIS, "Phys_Outer": OUTER, "Phys_Neumann": NEUMANN,
            "Phys_Coil_Base": COIL_BASE, "Phys_Cond_Base": CONDUCTOR_BASE, "Phys_Core_Base": CORE_BASE}


@dataclass
class EMMesh:
    """A 2D triangle mesh with physical ids (x = r, y = z in axisymmetry)."""

    points: np.ndarray  # (N, 2) node coordinates (m)
    triangles: np.ndarray  # (M, 3) node indices, 0-based
    tri_tags: np.ndarray  # (M,) physical id per triangle
    lines: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    line_tags: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    names: dict[int, str] = field(default_factory=dict)  # physical id -> name (written as $PhysicalNames)

    def __post_init__(self):
        self.points = np.asarray(self.points, dtype=float)[:, :2].copy()
        self.triangles = np.asarray(self.triangles, dtype=np.int64).reshape(-1, 3)
        self.tri_tags = np.asarray(self.tri_tags, dtype=np.int64).ravel()
        self.lines = np.asarray(self.lines, dtype=np.int64).reshape(-1, 2)
        self.line_tags = np.asarray(self.line_tags, dtype=np.int64).ravel()
        if len(self.tri_tags) != len(self.triangles):
            raise ValueError("tri_tags must have one id per triangle")
        if len(self.line_tags) != len(self.lines):
            raise ValueError("line_tags must have one id per line")
        if len(self.triangles) and (self.triangles.min() < 0 or self.triangles.max() >= len(self.points)):
            raise ValueError("triangle node index out of range")

    @property
    def n_nodes(self) -> int:
        return len(self.points)

    def with_points(self, points: np.ndarray) -> "EMMesh":
        """Same connectivity, moved nodes."""
        points = np.asarray(points, dtype=float)
        if points.shape != self.points.shape:
            raise ValueError(f"points shape {points.shape} != {self.points.shape}")
        return EMMesh(points, self.triangles, self.tri_tags, self.lines, self.line_tags, self.names)

    def areas(self) -> np.ndarray:
        p = self.points[self.triangles]
        d1, d2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        return 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])

    def centroids(self) -> np.ndarray:
        return self.points[self.triangles].mean(axis=1)

    def volumes(self, axisymmetric: bool) -> np.ndarray:
        """Element volumes: 2 pi r_c A in axisymmetry (exact for straight triangles), A in planar."""
        a = np.abs(self.areas())
        return 2 * np.pi * self.centroids()[:, 0] * a if axisymmetric else a

    def region_area(self, tag: int) -> float:
        return float(np.abs(self.areas()[self.tri_tags == tag]).sum())

    def same_connectivity(self, other: "EMMesh") -> bool:
        return (
            self.triangles.shape == other.triangles.shape
            and self.points.shape == other.points.shape
            and np.array_equal(self.triangles, other.triangles)
            and np.array_equal(self.tri_tags, other.tri_tags)
            and np.array_equal(self.lines, other.lines)
        )

    @classmethod
    def from_meshio(cls, mesh) -> "EMMesh":
        """From a meshio mesh with ``gmsh:physical`` cell data (triangles and lines)."""
        pts = np.asarray(mesh.points)[:, :2]
        phys = mesh.cell_data_dict.get("gmsh:physical", {})
        tri = mesh.get_cells_type("triangle")
        if not len(tri) or "triangle" not in phys:
            raise ValueError("meshio mesh needs triangles with gmsh:physical tags")
        lines = mesh.get_cells_type("line")
        ltags = phys.get("line", np.zeros(len(lines), dtype=np.int64))
        return cls(pts, tri, phys["triangle"], lines, ltags)

    def to_dict(self) -> dict:
        d = {k: getattr(self, k).tolist() for k in ("points", "triangles", "tri_tags", "lines", "line_tags")}
        d["names"] = {str(k): v for k, v in self.names.items()}
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "EMMesh":
        names = {int(k): v for k, v in d.get("names", {}).items()}
        return cls(**{k: np.asarray(v) for k, v in d.items() if k != "names"}, names=names)


_ELEMENT_BLOCKS: dict[tuple, str] = {}


def _element_block(mesh: EMMesh) -> str:
    """The $Elements section, cached per connectivity (moved meshes only rewrite nodes)."""
    key = (mesh.n_nodes, mesh.triangles.tobytes(), mesh.tri_tags.tobytes(), mesh.lines.tobytes(),
           mesh.line_tags.tobytes())
    block = _ELEMENT_BLOCKS.get(key)
    if block is None:
        m, k = len(mesh.triangles), len(mesh.lines)
        parts = [f"$Elements\n{m + k}\n"]
        if m:
            t = mesh.tri_tags
            rows = np.column_stack([np.arange(1, m + 1), np.full(m, 2), np.full(m, 2), t, t, mesh.triangles + 1])
            parts.append(("%d %d %d %d %d %d %d %d\n" * m) % tuple(rows.ravel().tolist()))
        if k:
            t = mesh.line_tags
            rows = np.column_stack([np.arange(m + 1, m + k + 1), np.ones(k, np.int64), np.full(k, 2), t, t,
                                    mesh.lines + 1])
            parts.append(("%d %d %d %d %d %d %d\n" * k) % tuple(rows.ravel().tolist()))
        parts.append("$EndElements\n")
        block = "".join(parts)
        if len(_ELEMENT_BLOCKS) > 8:
            _ELEMENT_BLOCKS.clear()
        _ELEMENT_BLOCKS[key] = block
    return block


def write_msh22(mesh: EMMesh, path: str | Path) -> Path:
    """Write ``mesh`` as an ASCII MSH 2.2 file (the only format this GetDP reads)."""
    path = Path(path)
    n = mesh.n_nodes
    rows = np.column_stack([np.arange(1, n + 1), mesh.points]).ravel().tolist()
    with open(path, "w") as fh:
        fh.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n")
        if mesh.names:
            dims = {int(t): 2 for t in np.unique(mesh.tri_tags)} | {int(t): 1 for t in np.unique(mesh.line_tags)}
            named = [(dims[t], t, n) for t, n in sorted(mesh.names.items()) if t in dims]
            fh.write(f"$PhysicalNames\n{len(named)}\n" + "".join(f'{d} {t} "{n}"\n' for d, t, n in named)
                     + "$EndPhysicalNames\n")
        fh.write(f"$Nodes\n{n}\n")
        fh.write(("%d %.17g %.17g 0\n" * n) % tuple(rows))
        fh.write("$EndNodes\n")
        fh.write(_element_block(mesh))
    return path


# ----------------------------------------------------------------------------- builders
def slab_mesh(length: float, h: float, width: float | None = None) -> EMMesh:
    """Structured 2D planar strip [0, length] x [0, width] (one element row, width = h).

    The whole strip is conductor 1 (id 201); x = 0 is the imposed-field boundary (13),
    x = length has a = 0 (12).  Used for the step-field diffusion test.
    """
    width = h if width is None else width
    nx = int(round(length / h))
    if nx < 2 or not np.isclose(nx * h, length, rtol=1e-9):
        raise ValueError("length must be a multiple of h, with at least two elements")
    x = np.linspace(0.0, length, nx + 1)
    pts = np.vstack([np.column_stack([x, np.zeros_like(x)]), np.column_stack([x, np.full_like(x, width)])])
    i = np.arange(nx)
    b0, b1, t0, t1 = i, i + 1, i + nx + 1, i + nx + 2
    tris = np.vstack([np.column_stack([b0, b1, t1]), np.column_stack([b0, t1, t0])])
    lines = np.array([[0, nx + 1], [nx, 2 * nx + 1]])
    return EMMesh(pts, tris, np.full(len(tris), conductor_tag(1)), lines, [NEUMANN, OUTER])


@dataclass
class Rect:
    """An axis-aligned rectangle (x0, y0) - (x1, y1) in the (r, z) or (x, y) plane."""

    x0: float
    y0: float
    x1: float
    y1: float


def _bbox(shape: "Rect | np.ndarray") -> tuple[float, float, float, float]:
    """(x0, y0, x1, y1) of a rectangle or a polygon (m)."""
    if isinstance(shape, Rect):
        return shape.x0, shape.y0, shape.x1, shape.y1
    p = np.asarray(shape, dtype=float)
    return float(p[:, 0].min()), float(p[:, 1].min()), float(p[:, 0].max()), float(p[:, 1].max())


def _add_shape(occ, shape: "Rect | np.ndarray") -> int:
    """An OCC surface for a rectangle or a simple polygon (vertices (x, y) in m, either orientation)."""
    if isinstance(shape, Rect):
        return occ.addRectangle(shape.x0, shape.y0, 0, shape.x1 - shape.x0, shape.y1 - shape.y0)
    p = np.asarray(shape, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3:
        raise ValueError("a conductor polygon needs at least 3 vertices (x, y)")
    pts = [occ.addPoint(float(x), float(y), 0.0) for x, y in p]
    lines = [occ.addLine(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
    return occ.addPlaneSurface([occ.addCurveLoop(lines)])


def coil_conductor_mesh(
    coils: list[list[Rect]],
    conductors: "list[Rect | np.ndarray]",
    *,
    axisymmetric: bool = True,
    half: bool | None = None,
    r_domain: float = 0.2,
    r_shell: float | None = None,
    h_fine: float = 1e-3,
    h_coarse: float | None = None,
    h_conductor: float | list[float] | None = None,
    names: dict[int, str] | None = None,
    cores: "list[Rect | np.ndarray] | None" = None,
) -> EMMesh:
    """Gmsh mesh of coils (each a list of turn rectangles), conductors and magnetic cores in air.

    A conductor or a core (non-conducting magnetic region 800+k, meshed at ``h_fine``) is a :class:`Rect` or
    a simple polygon (array of vertices (x, y), m).
    Air fills a (half-)disk of radius ``r_domain`` centred at the origin; with ``r_shell``
    a shell region (id 2) between ``r_domain`` and ``r_shell`` carries the transformation
    to infinity.  With ``half`` (default: ``axisymmetric``) only x >= 0 is meshed and x = 0
    is line 11 with a = 0: the axis in axisymmetry, an antisymmetry plane of a_z in a planar
    half model (currents mirrored with opposite sign). Physical groups are named (``names``
    overrides :func:`default_name` for coil and conductor ids) in gmsh and in the mesh's
    ``$PhysicalNames``.
    """
    h_coarse = h_coarse or r_domain / 10
    h_conductor = h_conductor or h_fine
    half = axisymmetric if half is None else half
    with gmsh_session("pulseform_em") as gmsh:
        occ = gmsh.model.occ
        r_out = r_shell or r_domain
        outer = occ.addDisk(0, 0, 0, r_out, r_out)
        inner = occ.addDisk(0, 0, 0, r_domain, r_domain) if r_shell else None
        if half:
            box = occ.addRectangle(0, -2 * r_out, 0, 2 * r_out, 4 * r_out)
            outer = occ.intersect([(2, outer)], [(2, box)], removeTool=not r_shell)[0][0][1]
            if r_shell:
                inner = occ.intersect([(2, inner)], [(2, box)])[0][0][1]
        rect_tags: list[tuple[str, int, int]] = []  # (kind, index, occ tag)
        for k, turns in enumerate(coils, start=1):
            for r in turns:
                rect_tags.append(("coil", k, occ.addRectangle(r.x0, r.y0, 0, r.x1 - r.x0, r.y1 - r.y0)))
        for k, r in enumerate(conductors, start=1):
            rect_tags.append(("cond", k, _add_shape(occ, r)))
        for k, r in enumerate(cores or [], start=1):
            rect_tags.append(("core", k, _add_shape(occ, r)))
        tools = [(2, t) for _, _, t in rect_tags] + ([(2, inner)] if r_shell else [])
        out, out_map = occ.fragment([(2, outer)], tools)
        occ.synchronize()
        # out_map[0] -> pieces of outer; then one entry per tool
        groups: dict[int, list[int]] = {}
        for (kind, k, _), pieces in zip(rect_tags, out_map[1 : 1 + len(rect_tags)]):
            tag = {"coil": coil_tag, "cond": conductor_tag, "core": core_tag}[kind](k)
            groups.setdefault(tag, []).extend(p[1] for p in pieces)
        used = {s for v in groups.values() for s in v}
        inner_pieces = {p[1] for p in out_map[-1]} if r_shell else set()
        shell_surfs, air_surfs = [], []
        for _, s in gmsh.model.getEntities(2):
            if s in used:
                continue
            (shell_surfs if (r_shell and s not in inner_pieces) else air_surfs).append(s)
        for tag, surfs in groups.items():
            gmsh.model.addPhysicalGroup(2, sorted(set(surfs)), tag)
            gmsh.model.setPhysicalName(2, tag, (names or {}).get(tag, default_name(tag)))
        gmsh.model.addPhysicalGroup(2, air_surfs, AIR)
        gmsh.model.setPhysicalName(2, AIR, "air")
        if shell_surfs:
            gmsh.model.addPhysicalGroup(2, shell_surfs, SHELL)
            gmsh.model.setPhysicalName(2, SHELL, "shell")
        axis_curves, outer_curves = [], []
        tol = 1e-6 * r_out
        all_surfs = [(2, s) for _, s in gmsh.model.getEntities(2)]
        for _, c in gmsh.model.getBoundary(all_surfs, combined=True, oriented=False):
            xmin, _, _, xmax, _, _ = gmsh.model.getBoundingBox(1, abs(c))
            xc = occ.getCenterOfMass(1, abs(c))[0]
            if half and abs(xc) < tol and xmax - xmin < 2 * tol + 2e-7:
                axis_curves.append(abs(c))
            else:
                outer_curves.append(abs(c))
        if half:
            gmsh.model.addPhysicalGroup(1, sorted(set(axis_curves)), AXIS)
            gmsh.model.setPhysicalName(1, AXIS, "axis" if axisymmetric else "symmetry")
        gmsh.model.addPhysicalGroup(1, sorted(set(abs(c) for c in outer_curves)), OUTER)
        gmsh.model.setPhysicalName(1, OUTER, "outer")
        # mesh size: fine in and near coils/conductors, coarse far away
        fine_curves = [abs(c) for _, c in gmsh.model.getBoundary([(2, s) for s in used], oriented=False)]
        f_dist = gmsh.model.mesh.field.add("Distance")
        gmsh.model.mesh.field.setNumbers(f_dist, "EdgesList", sorted(set(fine_curves)))
        gmsh.model.mesh.field.setNumber(f_dist, "NumPointsPerCurve", 200)
        f_thr = gmsh.model.mesh.field.add("Threshold")
        gmsh.model.mesh.field.setNumber(f_thr, "InField", f_dist)
        gmsh.model.mesh.field.setNumber(f_thr, "SizeMin", h_fine)
        gmsh.model.mesh.field.setNumber(f_thr, "SizeMax", h_coarse)
        gmsh.model.mesh.field.setNumber(f_thr, "DistMin", 0.0)
        gmsh.model.mesh.field.setNumber(f_thr, "DistMax", 0.5 * r_domain)
        fields = [f_thr]
        h_cond = h_conductor if isinstance(h_conductor, (list, tuple)) else [h_conductor] * len(conductors)
        for r, h_c in zip(conductors, h_cond):
            x0, y0, x1, y1 = _bbox(r)
            f_c = gmsh.model.mesh.field.add("Box")
            for name, val in (("VIn", h_c), ("VOut", 1e22), ("XMin", x0), ("XMax", x1),
                              ("YMin", y0), ("YMax", y1)):
                gmsh.model.mesh.field.setNumber(f_c, name, val)
            fields.append(f_c)
        f_min = gmsh.model.mesh.field.add("Min")
        gmsh.model.mesh.field.setNumbers(f_min, "FieldsList", fields)
        gmsh.model.mesh.field.setAsBackgroundMesh(f_min)
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        gmsh.option.setNumber("Mesh.Algorithm", 6)
        gmsh.model.mesh.generate(2)
        return _mesh_from_gmsh(gmsh)


def gmsh_physical_elements(gmsh) -> tuple[np.ndarray, ...]:
    """The current gmsh model's nodes and the triangles and lines of its physical groups.

    Returns
    -------
    (points, triangles, tri_tags, lines, line_tags, used)
        All node coordinates (x, y) in m, elements as 0-based rows of ``points`` with their
        physical ids, and ``used``: the sorted nodes the elements reference (gmsh may keep a few
        nodes on removed construction entities).
    """
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    index = np.full(int(node_tags.max()) + 1, -1, dtype=np.int64)
    index[node_tags.astype(np.int64)] = np.arange(len(node_tags))
    tris, ttags, lines, ltags = [], [], [], []
    for dim, ptag in gmsh.model.getPhysicalGroups():
        for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, ptag):
            etypes, _, enodes = gmsh.model.mesh.getElements(dim, ent)
            for et, en in zip(etypes, enodes):
                if (dim, et) in ((2, 2), (1, 1)):
                    c = index[en.astype(np.int64)].reshape(-1, dim + 1)
                    (tris if dim == 2 else lines).append(c)
                    (ttags if dim == 2 else ltags).append(np.full(len(c), ptag))
    tri, line = np.vstack(tris), np.vstack(lines)
    used = np.unique(np.concatenate([tri.ravel(), line.ravel()]))
    return coords.reshape(-1, 3)[:, :2], tri, np.concatenate(ttags), line, np.concatenate(ltags), used


def _mesh_from_gmsh(gmsh) -> EMMesh:
    pts, tri, ttags, lines, ltags, used = gmsh_physical_elements(gmsh)
    remap = np.full(len(pts), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    names = {int(t): gmsh.model.getPhysicalName(d, t) for d, t in gmsh.model.getPhysicalGroups()}
    m = EMMesh(pts[used], remap[tri], ttags, remap[lines], ltags, {t: n for t, n in names.items() if n})
    neg = m.areas() < 0  # orient triangles counter-clockwise
    m.triangles[neg] = m.triangles[neg][:, [0, 2, 1]]
    return m
