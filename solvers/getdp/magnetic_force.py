"""The magnetisation force on a magnetised body in 2D (issue 35, item 3): a surface force on its boundary.

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

Discrete: each boundary edge of the body's triangles takes B of its own triangle (first-order elements: B is
constant per triangle), H = h(|B|) B / |B| of the material, the air side H_n,air = ν0 B_n, and distributes
f_s × its length to its two nodes as consistent nodal forces (with 2π r in axisymmetry: node i of an edge gets
2π L (2 r_i + r_j) / 6). Edges on the mesh's boundary lines (the axis, a symmetry plane, the outer boundary)
are not a surface of the body and carry nothing.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .bh_curve import MU0, BHCurve
from .mesh import EMMesh

__all__ = ["material_laws", "body_surface", "magnetisation_forces", "model_magnetisation_forces"]


def material_laws(mu_r: float = 1.0, curve: BHCurve | None = None) -> tuple[Callable, Callable]:
    """(h(b), w(b)): the field (A/m) and the energy density ∫_0^b H dB' (J/m³) at flux densities ``b`` >= 0 (T)
    of a material with relative permeability ``mu_r`` or the B–H curve ``curve``."""
    if curve is not None:
        return curve.h_of_b, curve.energy_density
    nu = 1.0 / (MU0 * float(mu_r))
    return (lambda b: nu * np.asarray(b, float)), (lambda b: 0.5 * nu * np.asarray(b, float) ** 2)


def body_surface(mesh: EMMesh, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The boundary of the triangles ``rows`` of ``mesh``: edges (m, 2) node ids, the row (index into ``rows``)
    of the triangle each edge belongs to (m,), the outward unit normals (m, 2) and the lengths (m,) (m). Edges on
    the mesh's boundary lines (``mesh.lines``) are left out."""
    rows = np.asarray(rows, np.int64)
    tri = mesh.triangles[rows]
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    opposite = np.concatenate([tri[:, 2], tri[:, 0], tri[:, 1]])
    owner = np.tile(np.arange(len(rows)), 3)
    key = np.sort(edges, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    single = counts[inverse.ravel()] == 1
    if len(mesh.lines):
        on_line = {tuple(e) for e in np.sort(mesh.lines, axis=1).tolist()}
        single &= np.array([tuple(k) not in on_line for k in key.tolist()])
    edges, opposite, owner = edges[single], opposite[single], owner[single]
    p0, p1, pc = mesh.points[edges[:, 0]], mesh.points[edges[:, 1]], mesh.points[opposite]
    d = p1 - p0
    length = np.hypot(d[:, 0], d[:, 1])
    n = np.column_stack([d[:, 1], -d[:, 0]]) / length[:, None]
    n[np.einsum("ij,ij->i", n, pc - p0) > 0] *= -1.0   # away from the triangle's third node
    return edges, owner, n, length


def magnetisation_forces(mesh: EMMesh, rows: np.ndarray, b: np.ndarray, *, mu_r: float = 1.0,
                         curve: BHCurve | None = None, axisymmetric: bool) -> tuple[np.ndarray, np.ndarray]:
    """The magnetisation force of a body (module docstring) as nodal forces on its boundary nodes.

    ``rows``: the body's triangles (rows of ``mesh.triangles``), ``b`` (len(rows), 2): B (T) in each of them
    (GetDP frame); its material: ``mu_r`` or ``curve``. Returns (node ids (k,), forces (k, 2) N; in planar N per
    metre of depth, in axisymmetry the whole ring's, i.e. only the axial component has a total)."""
    edges, owner, n, length = body_surface(mesh, rows)
    if curve is None and mu_r == 1.0:   # vacuum: no magnetisation (exactly, not to round-off)
        return np.unique(edges), np.zeros((len(np.unique(edges)), 2))
    h_of_b, w_of_b = material_laws(mu_r, curve)
    bb = np.asarray(b, float)[owner]
    bmag = np.hypot(bb[:, 0], bb[:, 1])
    hmag = h_of_b(bmag)
    hh = np.divide(hmag, bmag, out=np.zeros_like(bmag), where=bmag > 0)[:, None] * bb
    b_n, h_n = np.einsum("ij,ij->i", bb, n), np.einsum("ij,ij->i", hh, n)
    h_t2 = np.einsum("ij,ij->i", hh, hh) - h_n ** 2
    co_mat = hmag * bmag - w_of_b(bmag)
    co_air = 0.5 * MU0 * h_t2 + 0.5 * b_n ** 2 / MU0
    f_s = ((b_n / MU0 - h_n) * b_n - co_air + co_mat)[:, None] * n   # N/m^2
    if axisymmetric:
        r0, r1 = mesh.points[edges[:, 0], 0], mesh.points[edges[:, 1], 0]
        w0, w1 = 2 * np.pi * length * (2 * r0 + r1) / 6, 2 * np.pi * length * (r0 + 2 * r1) / 6
    else:
        w0 = w1 = 0.5 * length
    nodes, where = np.unique(edges, return_inverse=True)
    where = where.reshape(edges.shape)
    forces = np.zeros((len(nodes), 2))
    np.add.at(forces, where[:, 0], f_s * w0[:, None])
    np.add.at(forces, where[:, 1], f_s * w1[:, None])
    return nodes, forces


def model_magnetisation_forces(model, mesh: EMMesh, result) -> np.ndarray | None:
    """The magnetisation nodal forces (N; (n_nodes, 2) on ``mesh``'s nodes) of every magnetised conductor of a 2D
    :class:`~.model.EMModel` at the end of a step (``result``: its :class:`~.model.EMStepResult`, with the
    conductors' element tables: ``elements``, ``element_tags``, ``flux_density``); None when no conductor is
    magnetic, so that a model in vacuum keeps its Lorentz forces untouched."""
    from .mesh import conductor_tag

    magnetic = [(k, c) for k, c in enumerate(model.conductors, start=1) if c.mu_r != 1.0 or c.bh_curve is not None]
    if not magnetic:
        return None
    out = np.zeros((mesh.n_nodes, 2))
    for k, c in magnetic:
        sel = np.asarray(result.element_tags) == conductor_tag(k)
        nodes, f = magnetisation_forces(mesh, np.asarray(result.elements)[sel], result.flux_density[-1][sel],
                                        mu_r=c.mu_r, curve=c.bh_curve, axisymmetric=model.axisymmetric)
        out[nodes] += f
    return out
