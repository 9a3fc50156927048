"""Soft contact, eq. (5), between 3D bodies: node to triangle face (issue 20, deliverable 2), in
numpy — the 3D counterpart of :func:`.contact.soft_contact_pass`, with the same rules:

* candidates: the ``_N_CANDIDATES`` master faces whose centroids are nearest to a slave node (k-d
  tree), for slave nodes inside the master surface's bounding box grown by the search radius;
* a candidate is valid if the node's projection on the face's plane lies inside the triangle
  (barycentric coordinates >= -``xi_tol``) and -h0 < h < h0, h = (x - p0) . n along the face's
  outward normal; per node the valid candidate with the least overshoot beyond the triangle, then
  the smallest |h|, then a partition-independent face key wins;
* h <= 0 on the chosen face, or a node that was in contact and now lies behind its previous face,
  is a penetration (reported, not handled);
* p = k (1/h - 1/h0) - nu |v_n| v_n on the pair's relative normal velocity, F = p A n with A the
  node's slave-boundary area projected on the face plane (sum A_f/3 max(0, -n_f . n)); the
  reaction -F goes to the master face's three nodes by the (clipped) barycentric weights;
  regularised Coulomb friction mu p A v_t / sqrt(v_t^2 + eps^2), capped at the force that halves
  the relative sliding velocity in one step (as in 2D).
"""
from __future__ import annotations

from typing import Optional

import numpy as np
from scipy.spatial import cKDTree

from .contact import ContactPairSpec, ContactResult, choose_faces, libm_log

__all__ = ["soft_contact_pass_3d", "triangle_contact_areas"]

_N_CANDIDATES = 8


def _barycentric(d: np.ndarray, e1: np.ndarray, e2: np.ndarray, n: np.ndarray):
    """Distance h along n and barycentric coordinates (xi0, xi1, xi2) of the projection of the
    points p0 + d on the triangles' planes (p0, p0 + e1, p0 + e2)."""
    h = np.einsum("ij,ij->i", d, n)
    q = d - h[:, None] * n
    a = np.einsum("ij,ij->i", e1, e1)
    b = np.einsum("ij,ij->i", e1, e2)
    c = np.einsum("ij,ij->i", e2, e2)
    d1 = np.einsum("ij,ij->i", q, e1)
    d2 = np.einsum("ij,ij->i", q, e2)
    det = a * c - b * b
    x1 = (c * d1 - b * d2) / det
    x2 = (a * d2 - b * d1) / det
    return h, np.stack([1.0 - x1 - x2, x1, x2], axis=1)


def triangle_contact_areas(tris: np.ndarray, X: np.ndarray, nodes: np.ndarray,
                           normals: np.ndarray) -> np.ndarray:
    """Contact area (m^2) of each of ``nodes`` whose contact normal is ``normals``: a third of each
    adjacent slave triangle's area projected on the contact plane, sum A/3 max(0, -n_f . n)."""
    n_nodes = X.shape[0]
    nm = np.zeros((n_nodes, 3))
    nm[nodes] = normals
    # only the triangles that touch one of the nodes (the per-node sums keep their order: same bits)
    touched = np.zeros(n_nodes, dtype=bool)
    touched[nodes] = True
    tris = tris[touched[tris].any(axis=1)]
    av = 0.5 * np.cross(X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 0]])
    A = np.zeros(n_nodes)
    for k in range(3):
        w = np.maximum(0.0, -np.einsum("ij,ij->i", av, nm[tris[:, k]])) / 3.0
        A += np.bincount(tris[:, k], weights=w, minlength=n_nodes)
    return A[nodes]


def _tunnelled(Xs, Xm, trim, previous, xi_tol):
    """(slave index, h) of a previously contacting node now behind its previous face."""
    if previous is None or len(previous[0]) == 0:
        return None
    si, mj = previous
    p0 = Xm[trim[mj, 0]]
    e1, e2 = Xm[trim[mj, 1]] - p0, Xm[trim[mj, 2]] - p0
    nv = np.cross(e1, e2)
    n = nv / np.linalg.norm(nv, axis=1)[:, None]
    h, xi = _barycentric(Xs[si] - p0, e1, e2, n)
    bad = (h <= 0.0) & np.all(xi >= -xi_tol, axis=1)
    if not bad.any():
        return None
    k = int(np.flatnonzero(bad)[np.argmin(h[bad])])
    return int(si[k]), float(h[k])


def soft_contact_pass_3d(Xs: np.ndarray, Vs: np.ndarray, slave_tris: np.ndarray, Xm: np.ndarray,
                         Vm: np.ndarray, trim: np.ndarray, spec: ContactPairSpec,
                         weight: float = 1.0, xi_tol: float = 0.02,
                         Ms: Optional[np.ndarray] = None, Mm: Optional[np.ndarray] = None,
                         dt: float = 0.0, previous: Optional[tuple] = None,
                         tri_key: Optional[np.ndarray] = None,
                         prefer: Optional[tuple] = None) -> ContactResult:
    """Node-to-face soft contact of slave surface nodes against master triangles.

    Parameters
    ----------
    Xs, Vs : (Ns, 3) arrays
        Slave surface node positions (m) and velocities (m/s).
    slave_tris : (Ts, 3) int array
        Slave boundary triangles (indices into Xs), outward oriented: for the contact areas.
    Xm, Vm : (Nm, 3) arrays
        Master surface node positions and velocities.
    trim : (Tm, 3) int array
        Master triangles, outward oriented ((x1 - x0) x (x2 - x0) points out of the master).
    spec : ContactPairSpec
        Law parameters (stiffness Pa m, h0 m, friction, friction_velocity m/s, viscosity kg/m^3).
    weight, xi_tol, Ms, Mm, dt, previous
        As in :func:`.contact.soft_contact_pass` (``xi_tol``: accepted barycentric undershoot).
    tri_key : (Tm,) int array, optional
        Canonical order of the master faces for ties (equal |h| to 1e-9 h0).
    prefer : (slave indices, face indices), optional
        Pairs of a previous evaluation, kept near shared edges (:func:`.contact.choose_faces`).

    Returns
    -------
    ContactResult
        Forces on slave and master surface nodes (N), normal contact stress (Pa) and gap (m) per
        slave node (NaN out of contact), stored layer energy (J), dissipation power (W), the worst
        penetration or None, and the active (slave node, master face) pairs.
    """
    ns = Xs.shape[0]
    tunnel = _tunnelled(Xs, Xm, trim, previous, xi_tol)
    Fs = np.zeros((ns, 3))
    Fm = np.zeros((Xm.shape[0], 3))
    pres = np.full(ns, np.nan)
    gap = np.full(ns, np.nan)
    empty = ContactResult(Fs, Fm, pres, gap, 0.0, 0.0, tunnel)
    if ns == 0 or trim.shape[0] == 0 or tunnel is not None:
        return empty
    h0 = spec.h0
    p0, p1, p2 = Xm[trim[:, 0]], Xm[trim[:, 1]], Xm[trim[:, 2]]
    cen = (p0 + p1 + p2) / 3.0
    rad = np.sqrt(np.max([np.einsum("ij,ij->i", p - cen, p - cen) for p in (p0, p1, p2)], axis=0))
    radius = rad.max() * (1 + 2 * xi_tol) + h0
    lo = np.minimum(np.minimum(p0, p1), p2).min(axis=0) - radius
    hi = np.maximum(np.maximum(p0, p1), p2).max(axis=0) + radius
    near = np.flatnonzero(np.all((Xs >= lo) & (Xs <= hi), axis=1))
    if near.size == 0:
        return empty
    # the tree holds only faces whose centroid can be within the radius of a candidate slave node
    # (the others are never returned by the bounded query: same candidates, a smaller tree)
    slo = Xs[near].min(axis=0) - radius
    shi = Xs[near].max(axis=0) + radius
    keep = np.flatnonzero(np.all((cen >= slo) & (cen <= shi), axis=1))
    nt = keep.size
    if nt == 0:
        return empty
    kq = min(_N_CANDIDATES, trim.shape[0])
    _, idx = cKDTree(cen[keep]).query(Xs[near], k=kq, distance_upper_bound=radius)
    idx = np.asarray(idx).reshape(near.size, kq)
    found = idx < nt
    if not found.any():
        return empty
    si = np.repeat(near, kq).reshape(near.size, kq)[found]
    mj = keep[idx[found]].astype(np.int64)
    e1, e2 = p1[mj] - p0[mj], p2[mj] - p0[mj]
    nv = np.cross(e1, e2)
    two_area = np.linalg.norm(nv, axis=1)
    nrm = nv / two_area[:, None]
    h, xi = _barycentric(Xs[si] - p0[mj], e1, e2, nrm)
    ok = np.all(xi >= -xi_tol, axis=1) & (h < h0) & (h > -h0)
    if not ok.any():
        return empty
    si, mj, xi, nrm, h = si[ok], mj[ok], xi[ok], nrm[ok], h[ok]
    size = np.sqrt(two_area[ok])
    over = np.maximum(-xi.min(axis=1), 0.0) * size
    key = tri_key[mj] if tri_key is not None else mj
    first = choose_faces(si, mj, h, over, size, h0, key, prefer)
    si, mj, xi, nrm, h = si[first], mj[first], xi[first], nrm[first], h[first]
    if np.any(h <= 0.0):
        k = int(np.argmin(h))
        return ContactResult(Fs, Fm, pres, gap, 0.0, 0.0, (int(si[k]), float(h[k])))
    w = np.clip(xi, 0.0, None)
    w /= w.sum(axis=1)[:, None]
    corners = trim[mj]                                             # (n, 3) master nodes
    vm = np.einsum("ik,ikj->ij", w, Vm[corners])
    vrel = Vs[si] - vm
    vn = np.einsum("ij,ij->i", vrel, nrm)
    p_el = spec.stiffness * (1.0 / h - 1.0 / h0)
    p_v = -spec.viscosity * np.abs(vn) * vn
    p = p_el + p_v
    A = triangle_contact_areas(slave_tris, Xs, si, nrm)
    F = (weight * p * A)[:, None] * nrm
    diss = -np.sum(weight * p_v * A * vn)
    if spec.friction > 0:
        vt = vrel - vn[:, None] * nrm
        vtn = np.sqrt(np.einsum("ij,ij->i", vt, vt) + spec.friction_velocity ** 2)
        mag = weight * spec.friction * np.maximum(p, 0.0) * A / vtn
        if dt > 0 and Ms is not None and Mm is not None:
            mm = np.einsum("ik,ik->i", w, Mm[corners])
            meff = Ms[si] * mm / (Ms[si] + mm)
            mag = np.minimum(mag, 0.5 * meff / dt)
        Ft = -mag[:, None] * vt
        F += Ft
        diss -= np.sum(np.einsum("ij,ij->i", Ft, vt))
    Fs[si] = F
    nm = Xm.shape[0]
    for c in range(3):
        for k in range(3):
            Fm[:, c] -= np.bincount(corners[:, k], weights=w[:, k] * F[:, c], minlength=nm)
    pres[si] = p
    gap[si] = h
    stored = float(np.sum(weight * A * spec.stiffness * (libm_log(h0 / h) - (h0 - h) / h0)))
    return ContactResult(Fs, Fm, pres, gap, stored, float(diss), None, (si, mj))
