"""The magnetisation force on a magnetised body (issue 35, item 3): a surface force on its boundary.

A body of a magnetic material (μ_r, or a B–H curve) in air feels, besides the Lorentz force j × B of its
currents, the force of its magnetisation. For a homogeneous isotropic material without magnetostriction that
force sits on the body's surface: the jump of the Maxwell stress T = H ⊗ B − w' I (w' the co-energy density,
∫_0^H B·dH') from the material to the air, with B_n and H_t continuous, is normal to the surface:

    f_s = [ (H_n,air − H_n,mat) B_n − w'_air + w'_mat ] n      (N/m², n the outward normal)

(linear material: f_s = ½ (ν0 − ν) B_n² + ½ (μ − μ0) H_t² along n, which pulls the surface into the air). The
total force on the body is then the Lorentz force plus ∮ f_s dS: the Maxwell stress integrated over any closed
surface in the air around it (Korteweg–Helmholtz; tests/getdp/test_magnetic_force.py checks it against the
Maxwell stress on two contours and against virtual work). With μ_r = 1 every term vanishes identically: the
Lorentz force alone, to the last bit.

Discrete (2D triangles and 3D tetrahedra alike): each boundary face of the body (an edge in 2D, a triangle in
3D) takes B of its own cell (first-order elements: B is constant per cell), H = h(|B|) B / |B| of the material,
the air side H_n,air = ν0 B_n, and distributes f_s × its measure to its nodes as consistent nodal forces (equal
shares; with 2π r in axisymmetry: node i of an edge gets 2π L (2 r_i + r_j) / 6). Faces on the mesh's boundary
(the axis, a symmetry plane, the outer boundary) are not a surface of the body and carry nothing.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .bh_curve import MU0, BHCurve
from .mesh import EMMesh

__all__ = ["material_laws", "body_surface", "surface_forces", "magnetisation_forces", "no_surface",
           "model_magnetisation_forces"]


def material_laws(mu_r: float = 1.0, curve: BHCurve | None = None) -> tuple[Callable, Callable]:
    """(h(b), w(b)): the field (A/m) and the energy density ∫_0^b H dB' (J/m³) at flux densities ``b`` >= 0 (T)
    of a material with relative permeability ``mu_r`` or the B–H curve ``curve``."""
    if curve is not None:
        return curve.h_of_b, curve.energy_density
    nu = 1.0 / (MU0 * float(mu_r))
    return (lambda b: nu * np.asarray(b, float)), (lambda b: 0.5 * nu * np.asarray(b, float) ** 2)


#: the faces of a simplex (triangle: edges, tetrahedron: triangles) and the vertex opposite each
_FACES = {3: ([[0, 1], [1, 2], [2, 0]], [2, 0, 1]), 4: ([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]], [0, 1, 2, 3])}


def body_surface(points: np.ndarray, cells: np.ndarray, exclude: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The boundary of a body of simplices ``cells`` (triangles (m, 3) in 2D, tetrahedra (m, 4) in 3D; node rows
    of ``points`` (N, dim)): its faces (k, dim) (edges in 2D, triangles in 3D), the index in ``cells`` of each
    face's own cell (k,), the outward unit normals (k, dim) and the faces' measures (k,) (m, m²). Faces listed in
    ``exclude`` (node rows, any order: the mesh's boundary lines or symmetry planes) are left out."""
    cells = np.asarray(cells, np.int64)
    local, opp = _FACES[cells.shape[1]]
    faces = np.concatenate([cells[:, f] for f in local])
    opposite = np.concatenate([cells[:, o] for o in opp])
    owner = np.tile(np.arange(len(cells)), len(local))
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    single = counts[inverse.ravel()] == 1
    if exclude is not None and len(exclude):
        skip = {tuple(e) for e in np.sort(np.asarray(exclude, np.int64), axis=1).tolist()}
        single &= np.array([tuple(k) not in skip for k in key.tolist()])
    faces, opposite, owner = faces[single], opposite[single], owner[single]
    x = np.asarray(points, float)
    d1 = x[faces[:, 1]] - x[faces[:, 0]]
    if faces.shape[1] == 2:
        measure = np.hypot(d1[:, 0], d1[:, 1])
        n = np.column_stack([d1[:, 1], -d1[:, 0]]) / measure[:, None]
    else:
        c = np.cross(d1, x[faces[:, 2]] - x[faces[:, 0]])
        measure = 0.5 * np.linalg.norm(c, axis=1)
        n = c / (2 * measure[:, None])
    n[np.einsum("ij,ij->i", n, x[opposite] - x[faces[:, 0]]) > 0] *= -1.0   # away from the opposite vertex
    return faces, owner, n, measure


def surface_forces(points: np.ndarray, cells: np.ndarray, b: np.ndarray, *, mu_r: float = 1.0,
                   curve: BHCurve | None = None, axisymmetric: bool = False,
                   exclude: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The magnetisation force of a body of simplices ``cells`` (module docstring) as nodal forces on its boundary
    nodes: ``b`` (len(cells), dim) B (T) in each cell, the material ``mu_r`` or ``curve``, ``exclude`` faces that
    are no surface (:func:`body_surface`). Returns (node rows (k,), forces (k, dim) N: per metre of depth in
    planar 2D, the whole ring in axisymmetry, the modelled part in 3D)."""
    faces, owner, n, measure = body_surface(points, cells, exclude)
    nodes, where = np.unique(faces, return_inverse=True)
    forces = np.zeros((len(nodes), n.shape[1]))
    if curve is None and mu_r == 1.0:   # vacuum: no magnetisation (exactly, not to round-off)
        return nodes, forces
    h_of_b, w_of_b = material_laws(mu_r, curve)
    bb = np.asarray(b, float)[owner]
    bmag = np.linalg.norm(bb, axis=1)
    hmag = h_of_b(bmag)
    hh = np.divide(hmag, bmag, out=np.zeros_like(bmag), where=bmag > 0)[:, None] * bb
    b_n, h_n = np.einsum("ij,ij->i", bb, n), np.einsum("ij,ij->i", hh, n)
    h_t2 = np.einsum("ij,ij->i", hh, hh) - h_n ** 2
    co_mat = hmag * bmag - w_of_b(bmag)
    co_air = 0.5 * MU0 * h_t2 + 0.5 * b_n ** 2 / MU0
    f_s = ((b_n / MU0 - h_n) * b_n - co_air + co_mat)[:, None] * n   # N/m^2
    x = np.asarray(points, float)
    if axisymmetric:   # node i of an edge: ∫ N_i 2π r dl
        r0, r1 = x[faces[:, 0], 0], x[faces[:, 1], 0]
        weights = np.column_stack([2 * np.pi * measure * (2 * r0 + r1) / 6, 2 * np.pi * measure * (r0 + 2 * r1) / 6])
    else:
        weights = np.repeat(measure[:, None] / faces.shape[1], faces.shape[1], axis=1)
    where = where.reshape(faces.shape)
    for j in range(faces.shape[1]):
        np.add.at(forces, where[:, j], f_s * weights[:, j:j + 1])
    return nodes, forces


def magnetisation_forces(mesh: EMMesh, rows: np.ndarray, b: np.ndarray, *, mu_r: float = 1.0,
                         curve: BHCurve | None = None, axisymmetric: bool) -> tuple[np.ndarray, np.ndarray]:
    """:func:`surface_forces` of a 2D body: the triangles ``rows`` of ``mesh`` with B ``b`` (len(rows), 2) (T,
    GetDP frame); the mesh's boundary lines (axis, symmetry, outer) are no surface."""
    return surface_forces(mesh.points, mesh.triangles[np.asarray(rows, np.int64)], b, mu_r=mu_r, curve=curve,
                          axisymmetric=axisymmetric, exclude=mesh.lines)


def no_surface(mesh) -> np.ndarray:
    """The faces of an EM mesh that are no surface of a body (node rows): a 2D mesh's boundary lines (axis,
    symmetry, outer), a 3D mesh's triangles on the outer boundary and the symmetry planes (physical 12, 14, 15)."""
    if not hasattr(mesh, "tets"):
        return mesh.lines
    from .mesh import OUTER
    from .mesh3d import SYM_A, SYM_H, read_surface_triangles

    return np.concatenate([read_surface_triangles(mesh.path, tag)[0] for tag in (OUTER, SYM_A, SYM_H)]
                          ).reshape(-1, 3)


def model_magnetisation_forces(model, points: np.ndarray, cells: np.ndarray, result,
                               exclude: np.ndarray | None = None) -> np.ndarray | None:
    """The magnetisation nodal forces (N; (len(points), dim)) of every magnetised conductor of an EM model (2D
    :class:`~.model.EMModel`: triangles, or :class:`~.solver3d.EM3DModel`: tetrahedra) at the end of a step:
    ``points`` the nodes where the step ran, ``cells`` every cell of its mesh, ``result`` the step's result with
    the conductors' element tables (``elements``, ``element_tags``, ``flux_density``), ``exclude``
    (:func:`no_surface`). None when no conductor is magnetic, so that a model in vacuum keeps its Lorentz forces
    untouched."""
    from .mesh import conductor_tag

    magnetic = [(k, c) for k, c in enumerate(model.conductors, start=1) if c.mu_r != 1.0 or c.bh_curve is not None]
    if not magnetic:
        return None
    out = np.zeros((len(points), np.asarray(points).shape[1]))
    for k, c in magnetic:
        sel = np.asarray(result.element_tags) == conductor_tag(k)
        b = np.asarray(result.flux_density[-1])[sel][:, :out.shape[1]]
        nodes, f = surface_forces(points, np.asarray(cells)[np.asarray(result.elements)[sel]], b, mu_r=c.mu_r,
                                  curve=c.bh_curve, axisymmetric=bool(getattr(model, "axisymmetric", False)),
                                  exclude=exclude)
        out[nodes] += f
    return out
