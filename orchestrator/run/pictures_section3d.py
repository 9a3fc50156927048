"""Sections of the 3D bodies of a coupled 3D geometry-file run (``[geometry] type = "geometry_3d"``), drawn
from its field files with matplotlib.

``plots/section_<plane>_{von_mises,plastic_strain}.png``: every 3D body cut by a plane, deformed (true scale),
coloured by its cell values (von Mises stress in MPa, equivalent plastic strain), at up to :data:`PANELS` output
times, one colour scale per picture. The planes: each axis-aligned ``[[symmetry]]`` plane of the case (the
planes of a quarter model: x = 0 and y = 0 are ``section_x0_*`` and ``section_y0_*``), or y = 0 when the case
has none. On a plane that bounds a body (a symmetry plane) the section is the body's faces on it; a plane
through a body cuts its tetrahedra (each cut a triangle or a quadrilateral, coloured by its cell; the cut's
points move with the edges they lie on).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from .mech_fields import read_fields
from .pictures_mech import _pick, _save_fig
from .pictures_solid import boundary_faces

log = logging.getLogger(__name__)

__all__ = ["draw_sections3d", "section_planes", "plane_faces", "cut_tets", "plot_section"]

#: output times shown per picture
PANELS = 6
#: (field, file stem, colour-bar title, scale, colour map) of the section pictures
FIELDS = (("von_mises_Pa", "von_mises", "von Mises stress [MPa]", 1e-6, "turbo"),
          ("plastic_strain", "plastic_strain", "equivalent plastic strain [-]", 1.0, "viridis"))
_TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])


def section_planes(case) -> list[tuple[int, float]]:
    """(axis, value) (m) of the section planes of ``case`` (module docstring)."""
    planes = []
    for s in getattr(case, "symmetry", ()) or ():
        if s.axis_aligned():
            axis = s.component()
            plane = (axis, float(s.point[axis]))
            if plane not in planes:
                planes.append(plane)
    return planes or [(1, 0.0)]


def plane_faces(points: np.ndarray, tets: np.ndarray, axis: int, value: float, tol: float = 1e-9):
    """Boundary faces (F, 3) of ``tets`` whose three nodes lie on the plane x_axis = value (reference
    coordinates ``points``, m, within ``tol``), and the cell of each."""
    faces, owner = boundary_faces(tets)
    on = np.all(np.abs(points[faces, axis] - value) <= tol, axis=1)
    return faces[on], owner[on]


def cut_tets(points: np.ndarray, tets: np.ndarray, axis: int, value: float, tol: float = 1e-9):
    """The plane x_axis = value through the tetrahedra: (edges (P, 2) node pairs, weights (P,), triangles (T, 3)
    rows of the cut's points, owner (T,) cells). A cut point is ``(1 - w) x[a] + w x[b]`` of its edge (a, b)
    (reference or current positions alike); a tetrahedron cut in a quadrilateral gives two triangles; a face on
    the plane (the plane through nodes of the mesh) is taken once, with one of its cells. Cells that only touch
    the plane with an edge or a node are not cut."""
    d = points[tets, axis] - value                           # (C, 4) signed distances
    d = np.where(np.abs(d) <= tol, 0.0, d)
    cut = np.flatnonzero((d.min(axis=1) < 0) & (d.max(axis=1) > 0))
    edges, weights, tris, owner = [], [], [], []
    seen: set[tuple[int, ...]] = set()
    for c in np.flatnonzero((d == 0.0).sum(axis=1) == 3):     # a face on the plane
        face = tets[c][d[c] == 0.0]
        key = tuple(sorted(face.tolist()))
        if key in seen:
            continue
        seen.add(key)
        base = len(edges)
        edges += [(a, a) for a in face]
        weights += [0.0, 0.0, 0.0]
        tris.append((base, base + 1, base + 2))
        owner.append(c)
    for c in cut:
        dc, pts = d[c], []
        for i in range(4):
            if dc[i] == 0.0:
                pts.append((tets[c, i], tets[c, i], 0.0))
        for i, j in _TET_EDGES:
            if dc[i] * dc[j] < 0:
                pts.append((tets[c, i], tets[c, j], dc[i] / (dc[i] - dc[j])))
        if len(pts) < 3:
            continue
        # order the 3 or 4 points around their centre (in the plane's two other coordinates)
        other = [k for k in range(3) if k != axis]
        xy = np.array([(1 - w) * points[a, other] + w * points[b, other] for a, b, w in pts])
        order = np.argsort(np.arctan2(*(xy - xy.mean(axis=0)).T[::-1]))
        base = len(edges)
        for k in order:
            a, b, w = pts[k]
            edges.append((a, b))
            weights.append(w)
        tris.append((base, base + 1, base + 2))
        owner.append(c)
        if len(pts) == 4:
            tris.append((base, base + 2, base + 3))
            owner.append(c)
    return (np.array(edges, dtype=np.int64).reshape(-1, 2), np.array(weights, float),
            np.array(tris, dtype=np.int64).reshape(-1, 3), np.array(owner, dtype=np.int64))


class _Section:
    """One body's section by one plane: its triangles on the plane (faces or cuts), the cell of each, and the
    section's points at given node positions."""

    def __init__(self, points: np.ndarray, tets: np.ndarray, axis: int, value: float) -> None:
        tol = 1e-9 * max(float(np.abs(points).max()), 1e-300)
        faces, owner = plane_faces(points, tets, axis, value, tol)
        if len(faces):
            self.edges = np.column_stack([np.arange(len(points))] * 2)
            self.weights = np.zeros(len(points))
            self.tris, self.owner = faces, owner
        else:
            self.edges, self.weights, self.tris, self.owner = cut_tets(points, tets, axis, value, tol)

    def __len__(self) -> int:
        return len(self.tris)

    def positions(self, x: np.ndarray) -> np.ndarray:
        """The section's points (P, 3) for node positions ``x`` (N, 3)."""
        w = self.weights[:, None]
        return (1 - w) * x[self.edges[:, 0]] + w * x[self.edges[:, 1]]


def _plane_name(axis: int, value: float) -> str:
    return "xyz"[axis] + ("0" if value == 0.0 else f"{value * 1e3:g}mm")


def plot_section(root: Path, folder: Path, axis: int, value: float, title: str = "") -> list[Path]:
    """The section pictures (module docstring) of the plane x_axis = value (m): one per field of :data:`FIELDS`;
    [] when the plane meets no body."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation

    bodies = {n: b for n, b in read_fields(root).items() if b.solid}
    sec = {n: _Section(b.points, b.triangles, axis, value) for n, b in bodies.items()}
    sec = {n: s for n, s in sec.items() if len(s)}
    if not sec:
        log.info("section %s: the plane meets no 3D body", _plane_name(axis, value))
        return []
    ref = max((bodies[n] for n in sec), key=lambda b: len(b.times))
    picks = _pick(len(ref.times), PANELS)
    h, v = [k for k in range(3) if k != axis]
    name = _plane_name(axis, value)
    paths = []
    for fld, stem, label, scale, cmap in FIELDS:
        data = {n: [bodies[n].read(min(k, len(bodies[n].times) - 1), ("displacement_m", fld)) for k in picks]
                for n in sec}
        top = max(float(np.percentile(d[fld][sec[n].owner], 99.5)) * scale for n in sec for d in data[n])
        top = top if top > 0 else 1.0
        cols = 2 if len(picks) > 1 else 1
        rows = int(np.ceil(len(picks) / cols))
        fig, axes = plt.subplots(rows, cols, figsize=(6 * cols, 2.6 * rows + 0.9), squeeze=False,
                                 constrained_layout=True)
        pc = None
        for i, k in enumerate(picks):
            ax = axes[i // cols, i % cols]
            for n, s in sec.items():
                d = data[n][i]
                x = s.positions(bodies[n].points + d["displacement_m"]) * 1e3
                pc = ax.tripcolor(Triangulation(x[:, h], x[:, v], s.tris), facecolors=d[fld][s.owner] * scale,
                                  cmap=cmap, vmin=0.0, vmax=top, edgecolors="face", linewidth=0.0)
            ax.set_aspect("equal")
            ax.set_title(f"t = {ref.times[k] * 1e6:.3g} µs", fontsize=10)
            ax.set_xlabel(f"{'xyz'[h]} [mm]")
            ax.set_ylabel(f"{'xyz'[v]} [mm]")
        for j in range(len(picks), rows * cols):
            axes[j // cols, j % cols].axis("off")
        fig.colorbar(pc, ax=axes, label=label, shrink=0.8, extend="max")
        fig.suptitle(f"{title}{', '.join(sec)} in the plane {'xyz'[axis]} = {value * 1e3:g} mm, deformed, true scale")
        paths.append(_save_fig(fig, Path(folder) / f"section_{name}_{stem}.png"))
        plt.close(fig)
    return paths


def draw_sections3d(root: Path, case=None) -> list[Path]:
    """The section pictures of a results folder ``root`` (module docstring) into its ``plots/``; [] unless it is
    a 3D geometry-file case (``case``: its resolved case, read from ``case.toml`` when not given)."""
    root = Path(root)
    if case is None:
        from ..case.io import load_resolved_case

        case = load_resolved_case(root / "case.toml")
    if getattr(case.geometry, "type", None) != "geometry_3d" or case.mechanics.formulation != "3d":
        return []
    folder = root / "plots"
    folder.mkdir(exist_ok=True)
    paths = []
    for axis, value in section_planes(case):
        paths += plot_section(root, folder, axis, value, f"{case.case.name}: ")
    return paths
