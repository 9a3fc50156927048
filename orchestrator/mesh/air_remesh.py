"""Re-triangulate the air regions of a user's EM mesh, keeping every other element and node.

A user's deck brings its own mesh (its own physical groups, ids and element sizes), so the
built-in remesh (:mod:`.remesh`, which rebuilds air, coil and shell from the case's numbers) does
not apply. Here only the triangles of the groups the case names as remeshable air
(``geometry.remesh_air``) are removed; the polygonal domain(s) they leave (outer loops with holes
for the coils, conductors and any other region) are meshed again with gmsh:

* every boundary edge of a removed region is a transfinite line with its two end nodes only, so
  gmsh puts no node on it and the new triangles stitch to the kept ones node for node (the
  boundary line groups — axis, outer boundary — keep their node pairs);
* element sizes follow the local edge lengths of a reference air mesh (the deck's fresh one:
  :class:`SizeField`; else the mesh being replaced): a gmsh ``PostView`` background field on the
  old air triangles holds that size at each of their nodes. Sizes from the mesh being replaced
  would drift, since gmsh's edges come out a few per cent shorter than asked (measured: +3 to +8 % air
  triangles per remesh), so repeated remeshes keep to the fresh mesh's sizes instead;
* every other triangle (coils, conductors, shell, air groups not named) and every node that is
  not inside a removed region keeps its coordinates and its order; the physical id of each
  remeshed group is kept.

The caller carries the EM state: the conductor and coil nodes are kept, so their values (and
material coordinates) travel unchanged.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from pulseform.solvers.getdp import EMMesh
from pulseform.solvers.getdp.mesh import gmsh_session
from pulseform.solvers.getdp.runner import call_in_child

from .triangles import triangle_areas

log = logging.getLogger(__name__)


class AirRemeshError(ValueError):
    """The named air regions cannot be re-triangulated (a pinched or open boundary, a line inside)."""


def boundary_loops(edges: np.ndarray) -> list[np.ndarray]:
    """Closed loops (node indices in order) of oriented boundary edges (K, 2).

    Raises
    ------
    AirRemeshError
        A node starts two boundary edges (a region touching itself at one node).
    """
    nxt: dict[int, int] = {}
    for a, b in edges:
        if int(a) in nxt:
            raise AirRemeshError(f"the air boundary is pinched at node {int(a)} (two regions touch at one node)")
        nxt[int(a)] = int(b)
    loops, seen = [], set()
    for start in nxt:
        if start in seen:
            continue
        loop = [start]
        seen.add(start)
        while True:
            n = nxt.get(loop[-1])
            if n is None:
                raise AirRemeshError(f"the air boundary is not closed at node {loop[-1]}")
            if n == start:
                break
            if n in seen:
                raise AirRemeshError(f"the air boundary is pinched at node {n}")
            loop.append(n)
            seen.add(n)
        loops.append(np.array(loop, dtype=np.int64))
    return loops


def polygon_area(x: np.ndarray) -> float:
    """Signed area (m²) of the polygon with vertices ``x`` (K, 2); positive counter-clockwise."""
    return 0.5 * float(np.dot(x[:, 0], np.roll(x[:, 1], -1)) - np.dot(np.roll(x[:, 0], -1), x[:, 1]))


def inside_polygon(p: np.ndarray, x: np.ndarray) -> bool:
    """True if point ``p`` (2,) lies inside the polygon ``x`` (K, 2) (even-odd ray casting)."""
    a, b = x, np.roll(x, -1, axis=0)
    crosses = (a[:, 1] > p[1]) != (b[:, 1] > p[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        xs = a[:, 0] + (p[1] - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return bool(np.count_nonzero(crosses & (p[0] < xs)) % 2)


def region_boundary(cells: np.ndarray) -> np.ndarray:
    """Boundary edges (K, 2) of triangles stored counter-clockwise (in the reference configuration,
    as every EM mesh is), oriented with the region on their left: by connectivity, not by the current
    coordinates, so that inverted elements of a moved mesh do not turn their edges."""
    edges = np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]])
    _, inverse, counts = np.unique(np.sort(edges, axis=1), axis=0, return_inverse=True, return_counts=True)
    return edges[counts[inverse] == 1]


def node_sizes(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Mean length (m) of the edges of ``cells`` at each node (0 where a node has none)."""
    edges = np.unique(np.sort(np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]]), axis=1), axis=0)
    length = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    total = np.bincount(edges.ravel(), np.repeat(length, 2), minlength=len(points))
    count = np.bincount(edges.ravel(), minlength=len(points))
    return np.divide(total, count, out=np.zeros(len(points)), where=count > 0)


class SizeField:
    """Element sizes (m) of a reference air mesh as a function of position: the mean length of the air
    edges at each node (:func:`node_sizes`), linear on the reference air triangles, the nearest
    reference node's value outside them (where a body moved away).

    Parameters
    ----------
    mesh : EMMesh
        The reference mesh (the deck's fresh mesh), its triangles valid (counter-clockwise).
    air_tags : sequence of int
        Physical ids of its air regions.
    """

    def __init__(self, mesh: EMMesh, air_tags: Sequence[int]) -> None:
        pts = np.asarray(mesh.points, float)[:, :2]
        cells = mesh.triangles[np.isin(mesh.tri_tags, list(air_tags))]
        nodes = np.unique(cells)
        local = np.full(len(pts), -1, dtype=np.int64)
        local[nodes] = np.arange(len(nodes))
        self.points, self.cells = pts[nodes], local[cells]
        self.sizes = node_sizes(pts, cells)[nodes]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Sizes (m) at the points ``x`` (K, 2) (m)."""
        import matplotlib.tri as mtri
        from scipy.spatial import cKDTree

        tri = mtri.Triangulation(self.points[:, 0], self.points[:, 1], self.cells)
        h = np.asarray(mtri.LinearTriInterpolator(tri, self.sizes)(x[:, 0], x[:, 1]).filled(np.nan))
        miss = np.isnan(h)
        if miss.any():
            h[miss] = self.sizes[cKDTree(self.points).query(x[miss])[1]]
        return h


def retriangulate_air(mesh: EMMesh, air_tags: Sequence[int], time_limit: float | None = None,
                      sizes: SizeField | None = None) -> tuple[EMMesh, np.ndarray, np.ndarray]:
    """The mesh with the triangles of physical ids ``air_tags`` meshed again (module docstring).

    gmsh runs in a child process (:func:`~pulseform.solvers.getdp.runner.call_in_child`) under
    ``time_limit`` (s; None: no limit).

    Parameters
    ----------
    mesh : EMMesh
        The EM mesh in its current (moved) configuration (m), its triangles counter-clockwise in the
        reference configuration; air elements may be inverted.
    air_tags : sequence of int
        Physical ids of the surfaces to re-triangulate.
    time_limit : float, optional
        Wall-time limit of the gmsh run (s).
    sizes : SizeField, optional
        Element sizes (m) by position (default: the local edge lengths of ``mesh``'s own air).

    Returns
    -------
    (EMMesh, ndarray, ndarray)
        The new mesh: the kept nodes first in their old order, then the new air nodes; the kept
        triangles first in their old order, then the new air triangles; the lines as before.
        Then, per old node, its index in the new mesh (-1: an air node that was removed), and
        per old triangle its row in the new mesh (-1: removed).

    Raises
    ------
    AirRemeshError
        No triangle has one of ``air_tags``, a line element lies inside the air, or a boundary is pinched.
    """
    air_tags = [int(t) for t in air_tags]
    air = np.isin(mesh.tri_tags, air_tags)
    if not air.any():
        raise AirRemeshError(f"no triangle has the air ids {air_tags}")
    pts = np.asarray(mesh.points, float)[:, :2]
    kept_tri = mesh.triangles[~air]
    on_boundary = np.zeros(len(pts), bool)
    for tag in air_tags:
        cells = mesh.triangles[mesh.tri_tags == tag]
        if len(cells):
            on_boundary[region_boundary(cells).ravel()] = True
    interior = np.zeros(len(pts), bool)
    interior[mesh.triangles[air].ravel()] = True
    interior &= ~on_boundary
    if interior[mesh.lines.ravel()].any() or interior[kept_tri.ravel()].any():
        raise AirRemeshError("a line element or a kept triangle has a node inside the remeshed air")
    h = node_sizes(pts, mesh.triangles[air])
    if sizes is not None:
        used = np.unique(mesh.triangles[air])
        h[used] = sizes(pts[used])
    new_pts, new_tri, new_tags = call_in_child(_mesh_air, pts, mesh.triangles, mesh.tri_tags, air_tags, h,
                                               time_limit=time_limit,
                                               what="re-triangulating the user mesh's air with gmsh")
    keep = ~interior
    old_to_new = np.full(len(pts), -1, dtype=np.int64)
    old_to_new[keep] = np.arange(int(keep.sum()))
    n_kept = int(keep.sum())
    ext = np.concatenate([old_to_new, n_kept + np.arange(len(new_pts))])  # gmsh's indices: old nodes, then new
    tri_new = ext[new_tri]
    if (tri_new < 0).any():
        raise AirRemeshError("gmsh used an air node that was not on the air boundary")
    points = np.vstack([np.asarray(mesh.points, float)[keep], _with_columns(new_pts, mesh.points.shape[1])])
    neg = triangle_areas(points, tri_new) < 0
    tri_new[neg] = tri_new[neg][:, [0, 2, 1]]
    row_map = np.full(len(mesh.triangles), -1, dtype=np.int64)
    row_map[~air] = np.arange(int((~air).sum()))
    out = EMMesh(points, np.vstack([old_to_new[kept_tri], tri_new]), np.concatenate([mesh.tri_tags[~air], new_tags]),
                 old_to_new[mesh.lines], mesh.line_tags.copy())
    out.names = dict(getattr(mesh, "names", {}) or {})
    log.info("user-mesh air remesh (ids %s): %d air triangles -> %d, %d nodes -> %d", air_tags, int(air.sum()),
             len(tri_new), len(pts), len(points))
    return out, old_to_new, row_map


def _with_columns(p: np.ndarray, ncol: int) -> np.ndarray:
    """``p`` (M, 2) padded with zero columns to ``ncol`` columns."""
    return p if ncol == 2 else np.hstack([p, np.zeros((len(p), ncol - 2))])


def _mesh_air(pts: np.ndarray, triangles: np.ndarray, tri_tags: np.ndarray, air_tags: list[int], h: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The gmsh part of :func:`retriangulate_air` (runs in the child process; does not log); ``h``: the
    element size (m) at each node.

    Returns the new interior nodes (M, 2), the new triangles indexing [old nodes, then new nodes],
    and their physical ids."""
    air = np.isin(tri_tags, air_tags)
    with gmsh_session("pulseform_air_remesh") as gmsh:
        geo = gmsh.model.geo
        point_tag: dict[int, int] = {}
        line_tag: dict[tuple[int, int], int] = {}
        surfaces: list[tuple[int, int]] = []  # (gmsh surface, physical id)

        def point(n: int) -> int:
            if n not in point_tag:
                point_tag[n] = geo.addPoint(float(pts[n, 0]), float(pts[n, 1]), 0.0, float(h[n]), n + 1)
            return point_tag[n]

        def line(a: int, b: int) -> int:
            if (b, a) in line_tag:
                return -line_tag[(b, a)]
            if (a, b) not in line_tag:
                line_tag[(a, b)] = geo.addLine(point(a), point(b))
            return line_tag[(a, b)]

        for tag in air_tags:
            cells = triangles[tri_tags == tag]
            if not len(cells):
                continue
            loops = boundary_loops(region_boundary(cells))
            areas = [polygon_area(pts[lp]) for lp in loops]
            outers = [i for i, a in enumerate(areas) if a > 0]
            holes: dict[int, list[int]] = {i: [] for i in outers}
            for i, a in enumerate(areas):
                if a > 0:
                    continue
                around = [o for o in outers if inside_polygon(pts[loops[i][0]], pts[loops[o]])]
                if not around:
                    raise AirRemeshError(f"a hole of air id {tag} lies in no outer boundary")
                holes[min(around, key=lambda o: areas[o])].append(i)
            for o in outers:
                curve_loops = []
                for i in [o] + holes[o]:
                    lp = loops[i]
                    curve_loops.append(geo.addCurveLoop([line(int(a), int(b)) for a, b in zip(lp, np.roll(lp, -1))]))
                surfaces.append((geo.addPlaneSurface(curve_loops), tag))
        geo.synchronize()
        for c in line_tag.values():
            gmsh.model.mesh.setTransfiniteCurve(c, 2)
        view = gmsh.view.add("old air edge lengths")
        cells = triangles[air]
        data = np.hstack([pts[cells, 0], pts[cells, 1], np.zeros((len(cells), 3)), h[cells]])
        gmsh.view.addListData(view, "ST", len(cells), data.ravel().tolist())
        field = gmsh.model.mesh.field.add("PostView")
        gmsh.model.mesh.field.setNumber(field, "ViewTag", view)
        gmsh.model.mesh.field.setAsBackgroundMesh(field)
        for k, v in (("Mesh.MeshSizeFromPoints", 0), ("Mesh.MeshSizeExtendFromBoundary", 0),
                     ("Mesh.MeshSizeFromCurvature", 0), ("Mesh.Algorithm", 6)):
            gmsh.option.setNumber(k, v)
        gmsh.model.mesh.generate(2)
        node_of_point = {}
        for n, ptag in point_tag.items():
            tags, _, _ = gmsh.model.mesh.getNodes(0, ptag)
            node_of_point[int(tags[0])] = n
        lookup = dict(node_of_point)
        new_xy: list[np.ndarray] = []
        n_old = len(pts)
        for s, _ in surfaces:
            ntags, coords, _ = gmsh.model.mesh.getNodes(2, s, includeBoundary=False)
            for t, xyz in zip(ntags, np.asarray(coords).reshape(-1, 3)):
                lookup[int(t)] = n_old + len(new_xy)
                new_xy.append(xyz[:2])
        tris, tri_ids = [], []
        for s, tag in surfaces:
            etypes, _, enodes = gmsh.model.mesh.getElements(2, s)
            for et, en in zip(etypes, enodes):
                if et != 2:
                    raise AirRemeshError(f"gmsh made elements of type {et}, not triangles")
                tri = np.array([lookup[int(t)] for t in en], dtype=np.int64).reshape(-1, 3)
                tris.append(tri)
                tri_ids.append(np.full(len(tri), tag, dtype=np.int64))
        new = np.array(new_xy, float).reshape(-1, 2)
        return new, np.vstack(tris), np.concatenate(tri_ids)
