"""The element update of the implicit solver and its exact tangent, on numpy arrays over the cells
(P1 triangles in plane stress / plane strain / axisymmetry, P1 tetrahedra in 3D; ten-node tetrahedra
(:mod:`.tet10`) and six-node triangles (:mod:`.tri6`) with the same update at each of their Gauss points, their
stress rows ``4 c + q`` and ``3 c + q``).

The update is the explicit kernels' finite-strain treatment written for a displacement increment
``du`` over a step instead of ``dt * v^{n+1/2}`` (:mod:`.element_math`, :mod:`.tet_kernel`):

* updated Lagrangian: the increment's gradient ``H = d du / d x`` on the mid-step configuration
  ``x^n + du / 2``; strain increment ``sym H``, spin increment ``skew H`` (axisymmetry: hoop strain
  increment = mean radial increment / mid-step centroid radius; plane strain: 0; plane stress:
  the value that makes sigma_zz = 0 after the return, by a secant iteration);
* the old stress rotated by the Hughes-Winget (Cayley) rotation ``Q = (I - W/2)^-1 (I + W/2)``
  (the Jaumann objective rate, exact for a rigid rotation increment);
* hypo-elastic predictor ``Q sigma Q^T + lambda tr(de) I + 2 G de``, J2 radial return on the yield
  stress of :func:`.implicit_flow.flow_stress` (a local Newton iteration: one step for the linear law);
* internal nodal forces with sigma^{n+1} on x^{n+1} (one-point rule, exact for P1).

So an implicit step of size dt and an explicit step with ``v^{n+1/2} = du / dt`` give the same
stress: the two solvers share one constitutive update.

The tangent ``d f_int / d du`` of every cell is the exact derivative of this update — the
consistent (algorithmic) tangent of the return mapping with the geometric terms of the updated
Lagrangian kinematics — computed by complex-step differentiation: ``K[:, j] = Im f(du + i h e_j) / h``
is exact to rounding for any h small enough (no subtraction; h = 1e-20 of the cell size here),
because every operation of the update is analytic in ``du`` (the only branch, elastic or plastic,
follows the real part). Newton on it converges quadratically (tests/solvers/test_implicit.py).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from .implicit_flow import flow_stress, is_linear, needs_rate
from .kernels import MODE_AXISYMMETRIC, MODE_PLANE_STRESS
from .material import Material
from . import tet10, tri6
from .tet_kernel import MODE_SOLID

__all__ = ["CellState", "CellResult", "cell_update", "cell_tangent", "voigt_to_tensor", "tensor_to_voigt"]

#: (row, column) of each Voigt component: 2D [xx, yy, zz, xy], 3D [xx, yy, zz, xy, yz, xz]
_VOIGT = {4: ((0, 0), (1, 1), (2, 2), (0, 1)), 6: ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))}
#: relative step of the complex-step derivative (times the cell size, m)
_H_REL = 1e-20


def voigt_to_tensor(s: np.ndarray) -> np.ndarray:
    """Voigt stresses (n, 4) [xx, yy, zz, xy] or (n, 6) [xx, yy, zz, xy, yz, xz] -> symmetric (n, 3, 3), Pa."""
    t = np.zeros((s.shape[0], 3, 3), dtype=s.dtype)
    for k, (i, j) in enumerate(_VOIGT[s.shape[1]]):
        t[:, i, j] = s[:, k]
        t[:, j, i] = s[:, k]
    return t


def tensor_to_voigt(t: np.ndarray, n: int) -> np.ndarray:
    """Symmetric (m, 3, 3) -> Voigt (m, n), n = 4 (2D) or 6 (3D)."""
    return np.stack([t[:, i, j] for i, j in _VOIGT[n]], axis=1)


@dataclass(frozen=True)
class CellState:
    """What the update of a set of cells needs besides the increment.

    Attributes
    ----------
    x : ndarray (nc, nn, dim)
        Node positions of each cell at the start of the step, m.
    stress : ndarray (nc, 4) or (nc, 6)
        Cauchy stress at the start of the step (Voigt), Pa.
    eps_p : ndarray (nc,)
        Equivalent plastic strain at the start of the step.
    material : Material
        The cells' material.
    mode : int
        ``MODE_PLANE_STRESS``, ``MODE_PLANE_STRAIN``, ``MODE_AXISYMMETRIC`` or ``MODE_SOLID``.
    thickness : float
        Out-of-plane thickness (planar modes), m.
    dt : float
        The step, s (for the strain rate of a rate law).
    """

    x: np.ndarray
    stress: np.ndarray
    eps_p: np.ndarray
    material: Material
    mode: int
    thickness: float
    dt: float

    def take(self, idx: np.ndarray) -> "CellState":
        """The state of the cells ``idx``."""
        return CellState(self.x[idx], self.stress[idx], self.eps_p[idx], self.material, self.mode,
                         self.thickness, self.dt)


@dataclass
class CellResult:
    """The update's result per cell.

    Attributes
    ----------
    force : ndarray (nc, nn, dim)
        Internal nodal forces, N (planar: for the thickness; axisymmetric: the full 2 pi ring).
    stress : ndarray (nc, 4) or (nc, 6)
        Cauchy stress at the end of the step, Pa.
    deps_p : ndarray (nc,)
        Plastic strain increment.
    plastic_work : ndarray (nc,)
        Plastic dissipation of the step, sigma_s^{n+1} deps_p V^{n+1/2}, J.
    inverted : ndarray (nc,) bool
        Cells whose mid-step or end configuration is inverted (their force is not meaningful).
    """

    force: np.ndarray
    stress: np.ndarray
    deps_p: np.ndarray
    plastic_work: np.ndarray
    inverted: np.ndarray


def _gradients(x: np.ndarray):
    """Shape-function gradients (nc, nn, dim) and the Jacobian determinant (2 area or 6 volume) of
    the P1 cells ``x`` (nc, nn, dim)."""
    J = np.swapaxes(x[:, 1:, :] - x[:, :1, :], 1, 2)        # J[c, i, j] = x_{j+1, i} - x_{0, i}
    adj, det = _adjugate(J)
    bad = np.real(det) <= 0.0
    inv = adj / np.where(bad, 1.0, det)[:, None, None]     # rows: gradients of N_1 .. N_dim
    g = np.concatenate([-inv.sum(axis=1, keepdims=True), inv], axis=1)
    return g, det, bad


def _adjugate(J: np.ndarray):
    """Adjugate and determinant of 2x2 or 3x3 matrices (n, d, d), in closed form (cofactors: analytic
    for complex entries, and faster than batched LAPACK calls on tiny matrices)."""
    if J.shape[1] == 2:
        a, b, c, d = J[:, 0, 0], J[:, 0, 1], J[:, 1, 0], J[:, 1, 1]
        adj = np.stack([np.stack([d, -b], axis=1), np.stack([-c, a], axis=1)], axis=1)
        return adj, a * d - b * c
    c0 = np.cross(J[:, :, 1], J[:, :, 2])                 # rows of the inverse: (col_j x col_k) / det
    c1 = np.cross(J[:, :, 2], J[:, :, 0])
    c2 = np.cross(J[:, :, 0], J[:, :, 1])
    det = np.einsum("ni,ni->n", J[:, :, 0], c0)
    return np.stack([c0, c1, c2], axis=1), det


def _measure(x: np.ndarray, det: np.ndarray, st: CellState) -> np.ndarray:
    """Cell volumes (m^3) from the Jacobian determinant: 3D det/6; planar thickness x area;
    axisymmetric 2 pi r_centroid x area."""
    if st.mode == MODE_SOLID:
        return det / 6.0
    area = 0.5 * det
    if st.mode == MODE_AXISYMMETRIC:
        return 2.0 * np.pi * x[:, :, 0].mean(axis=1) * area
    return st.thickness * area


def _radial_return(T: np.ndarray, st: CellState, rate: Optional[np.ndarray]):
    """J2 radial return of the trial stresses ``T`` (n, 3, 3), Pa: the stress, plastic strain increment
    and the yield stress after it. A local Newton iteration on the plastic multiplier for a
    nonlinear flow law (one step for the linear one)."""
    G = st.material.shear_modulus
    p = (T[:, 0, 0] + T[:, 1, 1] + T[:, 2, 2]) / 3.0
    dev = T.copy()
    for i in range(3):
        dev[:, i, i] -= p
    q = np.sqrt(1.5 * np.einsum("nij,nij->n", dev, dev))   # analytic in the entries (no abs)
    sy, slope = flow_stress(st.material, st.eps_p, rate)
    f = q - sy
    # plastic beyond rounding only: a cell left on the yield surface by the last step (q = sy to rounding) starts
    # the next one with the elastic tangent — an unloading step's tangent, and loading is found at the next iterate
    plastic = np.real(f) > 1e-12 * np.real(sy)
    if plastic.any() and not is_linear(st.material):
        dep = _nonlinear_return(q, G, st, rate, plastic)
    else:
        dep = np.where(plastic, f / (3.0 * G + slope), 0.0)
    sy_new, _ = flow_stress(st.material, st.eps_p + dep, rate)
    qs = np.where(plastic, q, 1.0)
    fac = np.where(plastic, 1.0 - 3.0 * G * dep / qs, 1.0)
    out = dev * fac[:, None, None]
    for i in range(3):
        out[:, i, i] += p
    return out, dep, sy_new


def _nonlinear_return(q: np.ndarray, G: float, st: CellState, rate: Optional[np.ndarray],
                      plastic: np.ndarray) -> np.ndarray:
    """The plastic strain increment of a nonlinear flow law: the root of q - 3 G d - sigma_s(eps_p + d) on the
    real parts, by Newton's method kept inside the bracket [0, q / 3G] (bisection where a step leaves it or the
    slope is not finite: a power law starting vertically), to round-off (as the compiled
    :func:`.flow_curves.plastic_return`); then one Newton step in the complex arguments from that root, which
    carries a complex step's derivative exactly (the root's sensitivity d = -f_x / f_d)."""
    ep = np.real(st.eps_p)
    qr = np.real(q)
    rr = None if rate is None else np.real(rate)
    g3 = 3.0 * G
    lo, hi = np.zeros_like(qr), np.where(plastic, qr / g3, 0.0)
    sy, h = flow_stress(st.material, ep, rr)
    den = g3 + h
    d = np.where(plastic & np.isfinite(den), (qr - sy) / np.where(np.isfinite(den), den, 1.0), 0.5 * hi)
    d = np.where((d > lo) & (d < hi), d, 0.5 * (lo + hi))
    for _ in range(200):
        sy, h = flow_stress(st.material, ep + d, rr)
        f = np.where(plastic, qr - g3 * d - sy, 0.0)
        lo = np.where(f > 0.0, d, lo)
        hi = np.where(f < 0.0, d, hi)
        den = g3 + h
        dn = d + f / np.where(np.isfinite(den), den, 1.0)
        dn = np.where(np.isfinite(den) & (dn > lo) & (dn < hi), dn, 0.5 * (lo + hi))
        dn = np.where(plastic & (f != 0.0), dn, d)
        done = (np.abs(dn - d) <= 4e-16 * np.abs(dn) + 1e-300) | (hi - lo <= 4e-16 * hi)
        d = dn
        if np.all(done | ~plastic):
            break
    sy, h = flow_stress(st.material, ep + d, rate) if np.iscomplexobj(q) or np.iscomplexobj(rate) else (None, None)
    if sy is None:
        return np.where(plastic, d, 0.0)
    r = np.where(plastic, q - g3 * d - sy, 0.0)
    return np.where(plastic, d + r / np.where(plastic, g3 + h, 1.0), 0.0)


def _update_stress(Sr: np.ndarray, E: np.ndarray, st: CellState):
    """Hypo-elastic predictor on the rotated stress ``Sr`` with the strain increment ``E`` (n, 3, 3),
    then the radial return."""
    G, K = st.material.shear_modulus, st.material.bulk_modulus
    lam = K - 2.0 * G / 3.0
    tr = E[:, 0, 0] + E[:, 1, 1] + E[:, 2, 2]
    T = Sr + 2.0 * G * E
    for i in range(3):
        T[:, i, i] += lam * tr
    rate = None
    if needs_rate(st.material):
        e = E.copy()
        for i in range(3):
            e[:, i, i] -= tr / 3.0
        rate = np.sqrt(2.0 / 3.0 * np.einsum("nij,nij->n", e, e)) / st.dt
    return _radial_return(T, st, rate)


def cell_update(st: CellState, du: np.ndarray) -> CellResult:
    """Stress, plastic strain and internal forces of the cells at the end of a step with the nodal
    displacement increments ``du`` (nc, nn, dim), m (real, or complex for :func:`cell_tangent`).

    Parameters
    ----------
    st : CellState
        The cells at the start of the step.
    du : ndarray (nc, nn, dim)
        Displacement increment of each cell's nodes over the step, m.

    Returns
    -------
    CellResult
    """
    nc, nn, dim = du.shape
    if (nn, dim) in _QUADRATIC:
        return _quadratic_update(st, du, _QUADRATIC[nn, dim])
    xm = st.x + 0.5 * du
    x1 = st.x + du
    gm, detm, badm = _gradients(xm)
    g1, det1, bad1 = _gradients(x1)
    H = np.einsum("cai,caj->cij", du, gm)                  # d du_i / d x_j on the mid-step configuration
    dtype = np.result_type(du, st.stress)
    E = np.zeros((nc, 3, 3), dtype=dtype)
    W = np.zeros((nc, 3, 3), dtype=dtype)
    E[:, :dim, :dim] = 0.5 * (H + np.swapaxes(H, 1, 2))
    W[:, :dim, :dim] = 0.5 * (H - np.swapaxes(H, 1, 2))
    if st.mode == MODE_AXISYMMETRIC:
        E[:, 2, 2] = du[:, :, 0].mean(axis=1) / xm[:, :, 0].mean(axis=1)
    # Hughes-Winget: Q = (I - A)^-1 (I + A) = I + 2 (A + A^2) / (1 + a.a), A = W/2 with axial vector a
    A = 0.5 * W
    aa = A[:, 0, 1] ** 2 + A[:, 0, 2] ** 2 + A[:, 1, 2] ** 2
    Q = np.eye(3) + (2.0 / (1.0 + aa))[:, None, None] * (A + A @ A)
    S0 = voigt_to_tensor(st.stress)
    Sr = Q @ S0 @ np.swapaxes(Q, 1, 2)
    if st.mode == MODE_PLANE_STRESS:
        S, dep, sy = _plane_stress(Sr, E, st)
    else:
        S, dep, sy = _update_stress(Sr, E, st)
    vol1 = _measure(x1, det1, st)
    f = vol1[:, None, None] * np.einsum("cij,caj->cai", S[:, :dim, :dim], g1)
    if st.mode == MODE_AXISYMMETRIC:
        f[:, :, 0] += (2.0 * np.pi * 0.5 * det1 * S[:, 2, 2] / 3.0)[:, None]
    volm = _measure(xm, detm, st)
    bad = badm | bad1
    return CellResult(f, tensor_to_voigt(S, st.stress.shape[1]), dep, sy * dep * volm, bad)


#: the quadratic elements by (nodes, dimension): their Gauss rules (N_QP, QP_WEIGHTS, QP_DERIVATIVES, QP_VALUES)
_QUADRATIC = {(10, 3): tet10, (6, 2): tri6}


def _qp_gradients(x: np.ndarray, el):
    """Shape-function gradients g[c, q, a, i] = d N_a / d x_i (nc, nq, nn, dim) of quadratic cells ``x``
    (nc, nn, dim) at the Gauss points of the element module ``el``, the Jacobian determinants (nc, nq) and the cells
    with one not positive."""
    nc, _, dim = x.shape
    J = np.einsum("cai,qaj->cqij", x, el.QP_DERIVATIVES).reshape(-1, dim, dim)
    adj, det = _adjugate(J)
    bad = (np.real(det) <= 0.0).reshape(nc, el.N_QP)
    inv = (adj / np.where(np.real(det) <= 0.0, 1.0, det)[:, None, None]).reshape(nc, el.N_QP, dim, dim)
    g = np.einsum("qaj,cqji->cqai", el.QP_DERIVATIVES, inv)
    return g, det.reshape(nc, el.N_QP), bad.any(axis=1)


def _qp_measure(x: np.ndarray, det: np.ndarray, st: CellState, el) -> np.ndarray:
    """The volume of each Gauss point (nc, nq), m^3: w_q det J_q, times the thickness (planar) or 2 pi r_q
    (axisymmetric, r at the Gauss point of the cells ``x``)."""
    w = el.QP_WEIGHTS * det
    if st.mode == MODE_SOLID:
        return w
    if st.mode == MODE_AXISYMMETRIC:
        return w * (2.0 * np.pi) * np.einsum("qa,ca->cq", el.QP_VALUES, x[:, :, 0])
    return w * st.thickness


def _quadratic_update(st: CellState, du: np.ndarray, el) -> CellResult:
    """:func:`cell_update` of quadratic cells (ten-node tetrahedra :mod:`.tet10`, six-node triangles :mod:`.tri6`,
    the module ``el``): the same kinematics and stress update at each Gauss point (state rows ``nq c + q``; the
    hoop strain increment of axisymmetry du_r / r at the Gauss point of the mid-step configuration), the forces by
    the Gauss rule on x^{n+1} (axisymmetry: with 2 pi r_q, and the hoop term 2 pi sigma_zz N_a)."""
    nc, nn, dim = du.shape
    nq = el.N_QP
    xm, x1 = st.x + 0.5 * du, st.x + du
    gm, detm, badm = _qp_gradients(xm, el)
    g1, det1, bad1 = _qp_gradients(x1, el)
    H = np.einsum("cai,cqaj->cqij", du, gm).reshape(-1, dim, dim)     # per Gauss point, cell-major
    dtype = np.result_type(du, st.stress)
    E = np.zeros((nc * nq, 3, 3), dtype=dtype)
    A = np.zeros((nc * nq, 3, 3), dtype=dtype)
    E[:, :dim, :dim] = 0.5 * (H + np.swapaxes(H, 1, 2))
    A[:, :dim, :dim] = 0.25 * (H - np.swapaxes(H, 1, 2))              # A = W / 2
    if st.mode == MODE_AXISYMMETRIC:
        N = el.QP_VALUES
        E[:, 2, 2] = (np.einsum("qa,ca->cq", N, du[:, :, 0]) / np.einsum("qa,ca->cq", N, xm[:, :, 0])).ravel()
    aa = A[:, 0, 1] ** 2 + A[:, 0, 2] ** 2 + A[:, 1, 2] ** 2
    Q = np.eye(3) + (2.0 / (1.0 + aa))[:, None, None] * (A + A @ A)
    S0 = voigt_to_tensor(st.stress)
    Sr = Q @ S0 @ np.swapaxes(Q, 1, 2)
    pts = CellState(np.zeros((len(st.eps_p), 0)), st.stress, st.eps_p, st.material, st.mode, st.thickness, st.dt)
    if st.mode == MODE_PLANE_STRESS:                                   # the Gauss points' state (rows)
        S, dep, sy = _plane_stress(Sr, E, pts)
    else:
        S, dep, sy = _update_stress(Sr, E, pts)
    vol1 = _qp_measure(x1, det1, st, el)                                # (nc, nq)
    Sq = S.reshape(nc, nq, 3, 3)
    f = np.einsum("cq,cqij,cqaj->cai", vol1, Sq[:, :, :dim, :dim], g1)
    if st.mode == MODE_AXISYMMETRIC:
        f[:, :, 0] += 2.0 * np.pi * np.einsum("cq,cq,qa->ca", el.QP_WEIGHTS * det1, Sq[:, :, 2, 2], el.QP_VALUES)
    volm = _qp_measure(xm, detm, st, el).ravel()
    return CellResult(f, tensor_to_voigt(S, st.stress.shape[1]), dep, sy * dep * volm, badm | bad1)


def _plane_stress(Sr: np.ndarray, E: np.ndarray, st: CellState):
    """Plane stress: the out-of-plane strain increment that makes sigma_zz = 0 after the
    return (elastic: closed form; plastic: a secant iteration, as the explicit kernel does)."""
    G, K = st.material.shear_modulus, st.material.bulk_modulus
    lam = K - 2.0 * G / 3.0
    E = E.copy()
    E[:, 2, 2] = -(lam * (E[:, 0, 0] + E[:, 1, 1]) + Sr[:, 2, 2]) / (lam + 2.0 * G)
    S, dep, sy = _update_stress(Sr, E, st)
    tol = 1e-12 * (np.abs(sy) + np.abs(S[:, 0, 0]) + np.abs(S[:, 1, 1]))
    idx = np.flatnonzero((np.real(dep) > 0.0) & (np.abs(S[:, 2, 2]) > tol))
    if idx.size:
        sub = st.take(idx)
        Ei, Si = E[idx].copy(), Sr[idx]
        z0 = Ei[:, 2, 2].copy()
        r0 = S[idx, 2, 2].copy()
        z1 = z0 - r0 / (lam + 2.0 * G)
        for _ in range(60):
            Ei[:, 2, 2] = z1
            s_i, d_i, y_i = _update_stress(Si, Ei, sub)
            r1 = s_i[:, 2, 2]
            done = np.abs(r1) <= tol[idx]
            same = r1 == r0
            step = np.where(same | done, 0.0, r1 * (z1 - z0) / np.where(same, 1.0, r1 - r0))
            z0, r0, z1 = z1, r1, z1 - step
            if np.all(done | same):
                break
        if np.iscomplexobj(z0):
            z0 = _exact_derivative(Si, Ei, sub, z0)
        Ei[:, 2, 2] = z0
        s_i, d_i, y_i = _update_stress(Si, Ei, sub)
        S[idx], dep[idx], sy[idx] = s_i, d_i, y_i
    S[:, 2, 2] = 0.0
    return S, dep, sy


def _exact_derivative(Sr: np.ndarray, E: np.ndarray, st: CellState, z: np.ndarray) -> np.ndarray:
    """Plane stress under a complex step: the secant iteration converges the real part of the out-of-plane strain
    increment z but not its imaginary part (the derivative). Two Newton corrections z - sigma_zz(z) / s with the
    slope s = d sigma_zz / dz at the solution (a real one-sided difference) make Im z the implicit function's
    derivative, -(d sigma_zz / d du) / s, to the slope's accuracy (1e-7)."""
    E = E.copy()
    for _ in range(2):
        E[:, 2, 2] = z
        r = _update_stress(Sr, E, st)[0][:, 2, 2]
        dz = 1e-7 * np.maximum(np.abs(np.real(z)), 1e-9)
        E[:, 2, 2] = z + dz
        slope = np.real(_update_stress(Sr, E, st)[0][:, 2, 2] - r) / dz
        z = z - r / np.where(slope != 0.0, slope, 1.0)
    return z


def cell_tangent(st: CellState, du: np.ndarray) -> np.ndarray:
    """The exact tangent d f_int / d du of every cell by complex steps, (nc, nn*dim, nn*dim), N/m.

    Row and column ``a * dim + i`` are node ``a``'s component ``i``.
    """
    nc, nn, dim = du.shape
    nd = nn * dim
    size = np.abs(st.x - st.x.mean(axis=1, keepdims=True)).max(axis=(1, 2))
    h = _H_REL * np.where(size > 0, size, 1.0)            # (nc,)
    pert = np.zeros((nd, nc, nn, dim), dtype=complex)
    pert[...] = du[None]
    for j in range(nd):
        pert[j, :, j // dim, j % dim] += 1j * h
    big = CellState(np.tile(st.x, (nd, 1, 1)), np.tile(st.stress, (nd, 1)), np.tile(st.eps_p, nd),
                    st.material, st.mode, st.thickness, st.dt)
    res = cell_update(big, pert.reshape(nd * nc, nn, dim))
    f = np.imag(res.force).reshape(nd, nc, nd) / h[None, :, None]   # [j, c, row]
    return np.ascontiguousarray(np.transpose(f, (1, 2, 0)))
