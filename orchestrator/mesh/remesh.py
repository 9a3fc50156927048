"""Remesh the EM domain around a deformed workpiece, keeping the workpiece's own (mechanical) mesh.

When the harmonically smoothed air mesh degrades, the air, coil and shell are meshed again with gmsh
around the conductor bodies' *current* boundary polygons; each body keeps its triangles and nodes
(they are the mechanical mesh's), so the shared-node transfer stays exact. Every boundary segment
of a polygon is a transfinite line with its two end nodes only, so gmsh puts no node on it that the
body does not have, and the meshes are stitched by coordinates.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.spatial import cKDTree

from pulseform.solvers.getdp import EMMesh
from pulseform.solvers.getdp.mesh import AIR, AXIS, OUTER, SHELL, Rect, gmsh_physical_elements, gmsh_session
from pulseform.solvers.getdp.runner import call_in_child

from .triangles import boundary_facets, triangle_areas

log = logging.getLogger(__name__)


def boundary_loop(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Node indices of the (single) boundary loop of a triangle mesh, counter-clockwise."""
    edges = boundary_facets(cells, points)
    nxt = {int(a): int(b) for a, b in edges}
    if len(nxt) != len(edges):
        raise ValueError("the workpiece boundary is not a simple loop")
    start = int(edges[0, 0])
    loop = [start]
    while True:
        n = nxt[loop[-1]]
        if n == start:
            break
        loop.append(n)
        if len(loop) > len(edges):
            raise ValueError("the workpiece boundary is not a single closed loop")
    if len(loop) != len(edges):
        raise ValueError("the workpiece has holes or several parts; remeshing supports one simple loop")
    return np.array(loop)


def remesh_around(parts: list[tuple[np.ndarray, np.ndarray, int]], coils: list[tuple[int, list[Rect]]],
                  r_domain: float, r_shell: float, h_coil: float, h_air: float,
                  time_limit: float | None = None) -> tuple[EMMesh, list[np.ndarray]]:
    """New half-disk EM mesh (x >= 0) around conductor bodies in their current configuration.

    gmsh runs in a child process (:func:`~pulseform.solvers.getdp.runner.call_in_child`) under
    ``time_limit`` (s; None: no limit): a breach raises ``TimeLimitExceeded``, a gmsh crash ``ChildFailed``.

    Parameters
    ----------
    parts : list of (points, cells, tag)
        Each conductor body: its node coordinates (m), triangles, and physical id.
    coils : list of (int, list of Rect)
        Each coil's physical id and turn rectangles (m).
    r_domain, r_shell : float
        Radii (m) of the air half-disk and of the shell's outer boundary.
    h_coil, h_air : float
        Element sizes (m) near the coil and the bodies, and far in the air.

    Returns
    -------
    (EMMesh, list of ndarray)
        The mesh, and per part, for each of its nodes (row of its ``points``) the node index in the mesh.
    """
    mesh, indices = call_in_child(_remesh_with_gmsh, parts, coils, r_domain, r_shell, h_coil, h_air,
                                  time_limit=time_limit, what="remeshing the EM air with gmsh")
    log.info("EM remesh: %d nodes, %d triangles (%d in the conductor bodies)", len(mesh.points), len(mesh.triangles),
             sum(len(c) for _, c, _ in parts))
    return mesh, indices


def _remesh_with_gmsh(parts, coils, r_domain, r_shell, h_coil, h_air) -> tuple[EMMesh, list[np.ndarray]]:
    """The gmsh part of :func:`remesh_around` (runs in the child process; does not log)."""
    loops = [boundary_loop(pts, cells) for pts, cells, _ in parts]
    segs = [np.linalg.norm(pts[np.roll(lp, -1)] - pts[lp], axis=1) for (pts, _, _), lp in zip(parts, loops)]
    with gmsh_session("pulseform_remesh") as gmsh:
        occ = gmsh.model.occ
        outer = occ.addDisk(0, 0, 0, r_shell, r_shell)
        inner = occ.addDisk(0, 0, 0, r_domain, r_domain)
        box = occ.addRectangle(0, -2 * r_shell, 0, 2 * r_shell, 4 * r_shell)
        outer = occ.intersect([(2, outer)], [(2, box)], removeTool=False)[0][0][1]
        inner = occ.intersect([(2, inner)], [(2, box)])[0][0][1]
        bodies = []
        for (pts_all, _, _), lp, seg in zip(parts, loops, segs):
            pts = [occ.addPoint(x, y, 0.0, float(h)) for (x, y), h in zip(pts_all[lp], seg)]
            lines = [occ.addLine(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
            bodies.append(occ.addPlaneSurface([occ.addCurveLoop(lines)]))
        coil = [(tag, occ.addRectangle(r.x0, r.y0, 0, r.x1 - r.x0, r.y1 - r.y0)) for tag, turns in coils for r in turns]
        tools = [(2, w) for w in bodies] + [(2, c) for _, c in coil] + [(2, inner)]
        _, out_map = occ.fragment([(2, outer)], tools)
        occ.synchronize()
        nb = len(bodies)
        work_surfs = {p[1] for m in out_map[1:1 + nb] for p in m}
        by_coil: dict[int, set[int]] = {}
        for (tag, _), m in zip(coil, out_map[1 + nb:1 + nb + len(coil)]):
            by_coil.setdefault(tag, set()).update(p[1] for p in m)
        coil_surfs = set().union(*by_coil.values()) if by_coil else set()
        inner_surfs = {p[1] for p in out_map[-1]}
        air, shell = [], []
        for _, s in gmsh.model.getEntities(2):
            if s in work_surfs or s in coil_surfs:
                continue
            (air if s in inner_surfs else shell).append(s)
        for tag, surfs in by_coil.items():
            gmsh.model.addPhysicalGroup(2, sorted(surfs), tag)
        gmsh.model.addPhysicalGroup(2, air, AIR)
        gmsh.model.addPhysicalGroup(2, shell, SHELL)
        tol = 1e-6 * r_shell  # OCC bounding boxes carry its tolerance (~1e-7)
        axis, rim = [], []
        everything = [(2, s) for _, s in gmsh.model.getEntities(2)]
        for _, c in gmsh.model.getBoundary(everything, combined=True, oriented=False):
            x0, _, _, x1, _, _ = gmsh.model.getBoundingBox(1, abs(c))
            (axis if abs(x0) < tol and abs(x1) < tol else rim).append(abs(c))
        gmsh.model.addPhysicalGroup(1, sorted(set(axis)), AXIS)
        gmsh.model.addPhysicalGroup(1, sorted(set(rim)), OUTER)
        work_curves = {abs(c) for _, c in gmsh.model.getBoundary([(2, s) for s in work_surfs], oriented=False)}
        for c in work_curves:
            gmsh.model.mesh.setTransfiniteCurve(c, 2)
        f_dist = gmsh.model.mesh.field.add("Distance")
        coil_curves = {abs(c) for _, c in gmsh.model.getBoundary([(2, s) for s in coil_surfs], oriented=False)}
        gmsh.model.mesh.field.setNumbers(f_dist, "EdgesList", sorted(coil_curves | work_curves))
        gmsh.model.mesh.field.setNumber(f_dist, "NumPointsPerCurve", 50)
        f_thr = gmsh.model.mesh.field.add("Threshold")
        h_min = min(h_coil, min(float(sg.max()) for sg in segs))
        for k, v in (("InField", f_dist), ("SizeMin", h_min), ("SizeMax", h_air),
                     ("DistMin", 0.0), ("DistMax", 0.5 * r_domain)):
            gmsh.model.mesh.field.setNumber(f_thr, k, v)
        gmsh.model.mesh.field.setAsBackgroundMesh(f_thr)
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        gmsh.option.setNumber("Mesh.Algorithm", 6)
        gmsh.model.mesh.generate(2)
        return _collect(gmsh, parts)


def _collect(gmsh, parts: list[tuple[np.ndarray, np.ndarray, int]]) -> tuple[EMMesh, list[np.ndarray]]:
    """gmsh's air/coil/shell triangles and lines, stitched to the bodies' triangles by coordinates."""
    pts, tri, ttags, lines, ltags, used = gmsh_physical_elements(gmsh)
    scale = float(np.abs(pts).max())
    tree = cKDTree(pts[used])
    remap = np.full(len(pts), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    points, n = [pts[used]], len(used)
    indices, body_tris, body_tags = [], [], []
    for work_points, work_cells, work_tag in parts:
        # a body's boundary nodes coincide with gmsh nodes, its interior nodes are new
        dist, hit = tree.query(work_points)
        on_gmsh = dist <= 1e-9 * scale
        work_index = np.empty(len(work_points), dtype=np.int64)
        work_index[on_gmsh] = hit[on_gmsh]
        extra = np.flatnonzero(~on_gmsh)
        work_index[extra] = n + np.arange(len(extra))
        n += len(extra)
        points.append(work_points[extra])
        points[0][work_index[on_gmsh]] = work_points[on_gmsh]  # exactly the body's coordinates
        indices.append(work_index)
        body_tris.append(work_index[work_cells])
        body_tags.append(np.full(len(work_cells), work_tag))
    mesh = EMMesh(np.vstack(points), np.vstack([remap[tri]] + body_tris), np.concatenate([ttags] + body_tags),
                  remap[lines], ltags)
    neg = triangle_areas(mesh.points, mesh.triangles) < 0
    mesh.triangles[neg] = mesh.triangles[neg][:, [0, 2, 1]]
    return mesh, indices
