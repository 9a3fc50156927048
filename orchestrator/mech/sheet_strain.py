"""In-plane principal true strains of a sheet, per element, from reference and current node positions.

Post-processing only (numpy, vectorised over the cells; the explicit kernels are not involved). For
P1 triangles and tetrahedra the deformation gradient F is constant in a cell:
F = [x1 − x0, x2 − x0, ...] [X1 − X0, X2 − X0, ...]⁻¹. The principal stretches λ_i and their
reference (material) directions N_i are the eigenpairs of C = Fᵀ F (C N_i = λ_i² N_i); the principal
true (logarithmic, Hencky) strains are ε_i = ln λ_i = ½ ln(λ_i²).

Which of the three principal strains is the through-thickness one depends on the model:

* ``plane_stress``: the model plane is the sheet; its two principal strains are the in-plane ones
  (the thickness strain is not needed).
* ``plane_strain``, ``axisymmetric``: the model plane is a section through the thickness. The third
  principal direction is the out-of-plane one: a stretch of 1 (ε = 0) in plane strain, the hoop
  stretch r/r0 (at the cell's centroid: ln(r_c / r0_c)) in axisymmetry, and it always lies in the
  sheet. Of the two principal directions in the section, the one whose reference direction N_i is
  closer to the reference sheet normal n0 (larger |N_i · n0|) is the thickness; the other is the
  meridional (in-section) strain.
* ``3d``: the principal direction closest to n0 is the thickness; the other two are in-plane.

The reference sheet normal of a body is :func:`sheet_normal`: the axis along which its reference
nodes spread least (the smallest principal axis of their covariance), in the model plane (plane
strain, axisymmetry) or in space (3D). It is exact for flat sheets and straight tube walls; for a
sheet curved by much before forming (a preformed dome, a whole tube in 3D) one normal does not fit
every element and the thickness choice may be wrong where the sheet turns away from it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["deformation_gradients", "sheet_normal", "sheet_strains", "FORMULATIONS"]

#: the kinematics :func:`sheet_strains` knows (the mechanics' ``formulation`` values)
FORMULATIONS = ("plane_stress", "plane_strain", "axisymmetric", "3d")


def deformation_gradients(X: np.ndarray, x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Deformation gradient of every P1 cell.

    Parameters
    ----------
    X, x : (N, d) ndarray
        Reference and current node positions, m (d = 2 for triangles, 3 for tetrahedra).
    cells : (C, d + 1) int ndarray
        Node indices of each cell.

    Returns
    -------
    (C, d, d) ndarray
        F = dx/dX of each cell (-).
    """
    Xe, xe = X[cells], x[cells]
    DX = np.swapaxes(Xe[:, 1:] - Xe[:, :1], 1, 2)   # columns: reference edge vectors from vertex 0
    Dx = np.swapaxes(xe[:, 1:] - xe[:, :1], 1, 2)
    return Dx @ np.linalg.inv(DX)


def sheet_normal(X: np.ndarray) -> np.ndarray:
    """The reference sheet normal of a body: the unit axis along which its nodes ``X`` ((N, d), m) spread
    least (eigenvector of the smallest eigenvalue of their covariance), sign chosen with a positive
    largest component. Exact for a flat sheet (the thickness direction) and a straight tube wall in a
    section (the radius)."""
    X = np.asarray(X, dtype=float)
    return normal_of_moments(len(X), X.sum(axis=0), X.T @ X)[0]


def normal_of_moments(n: float, first: np.ndarray, second: np.ndarray) -> tuple[np.ndarray, float]:
    """:func:`sheet_normal` from the node count ``n``, the sum of positions ``first`` (d,) (m) and the sum of
    their outer products ``second`` (d, d) (m²): moments that ranks of a parallel run add up. Also returns
    how thin the body is along it: the RMS spread along the normal over the next smallest spread (-; a
    sheet's is small, a bar's near 1, where the normal is ill-defined)."""
    mean = first / n
    cov = second / n - np.outer(mean, mean)
    vals, vecs = np.linalg.eigh(cov)
    nrm = vecs[:, 0]
    thin = float(np.sqrt(max(vals[0], 0.0) / vals[1])) if vals[1] > 0 else 1.0
    return (nrm if nrm[np.argmax(np.abs(nrm))] > 0 else -nrm), thin


def sheet_strains(X: np.ndarray, x: np.ndarray, cells: np.ndarray, formulation: str,
                  normal: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Minor and major in-plane principal true strains of every cell of a sheet (module docstring).

    Parameters
    ----------
    X, x : (N, d) ndarray
        Reference and current node positions, m ((r, z) in axisymmetry).
    cells : (C, d + 1) int ndarray
        P1 triangles (d = 2) or tetrahedra (d = 3).
    formulation : {"plane_stress", "plane_strain", "axisymmetric", "3d"}
        The model's kinematics.
    normal : (d,) ndarray, optional
        Reference sheet normal (unit; plane strain, axisymmetry, 3D); default :func:`sheet_normal` of ``X``.

    Returns
    -------
    minor, major : (C,) ndarray
        ε2 <= ε1, true strains (-).
    """
    if formulation not in FORMULATIONS:
        raise ValueError(f"formulation must be one of {FORMULATIONS}, got {formulation!r}")
    F = deformation_gradients(X, x, cells)
    stretch2, N = np.linalg.eigh(np.swapaxes(F, 1, 2) @ F)   # λ² ascending, columns N_i (reference)
    eps = 0.5 * np.log(stretch2)
    if formulation == "plane_stress":
        return eps[:, 0], eps[:, 1]
    n0 = sheet_normal(X) if normal is None else np.asarray(normal, dtype=float)
    thick = np.argmax(np.abs(np.einsum("cij,i->cj", N, n0)), axis=1)   # the direction closest to n0
    keep = np.ones(eps.shape, dtype=bool)
    keep[np.arange(len(eps)), thick] = False
    in_plane = eps[keep].reshape(len(eps), -1)
    if formulation == "3d":
        return in_plane.min(axis=1), in_plane.max(axis=1)
    if formulation == "axisymmetric":
        out = np.log(x[cells, 0].sum(axis=1) / X[cells, 0].sum(axis=1))   # hoop: ln(r_c / r0_c)
    else:
        out = np.zeros(len(eps))                                             # plane strain: ε_zz = 0
    both = np.column_stack([in_plane[:, 0], out])
    return both.min(axis=1), both.max(axis=1)
