"""Soft contact, eq. (5), with its tangent, in the implicit solver's Newton iterations (issue 34, item 1).

The contact forces of an iterate are those of the explicit solver's passes
(:func:`.contact.soft_contact_pass` in 2D, :func:`.contact3d.soft_contact_pass_3d` in 3D: the same
search, areas and law p = k (1/h - 1/h0)), evaluated at the iterate's positions. Their tangent is
that of each active pair (a slave node against a master segment or triangle) differentiated by the
complex step in every coordinate of the pair's nodes, with the pair, the clipped weights of a projection
beyond the master's edges and the node's contact area held at their values of the iterate. The area's
change with the lengths of the slave node's own segments (a motion across the contact normal) is left out
of the tangent: relative size h / (segment length), 5e-3 in the tests; the residual stays exact and Newton
converges linearly in that share. The barrier 1/h makes the contact smooth for
Newton; an iterate that crosses it (h <= 0) is reported as :class:`ContactCrossed`, and the Newton loop
halves its update (and, failing that, cuts the step).

Under MPI (linear elements) every rank evaluates every pass on the gathered surfaces and keeps the forces of its
local rows; the tangent's triplets are given by the rank owning each pair's slave node, in the global numbering of
:class:`~.implicit_dist.DistributedSystem` (:func:`evaluate_contact`).

Only the elastic law: the velocity-dependent friction and viscosity of :class:`~.contact.ContactPairSpec`
are refused by the implicit solver (a static springback has no velocity).
"""
from __future__ import annotations

from typing import Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .contact import ContactPairSpec, soft_contact_pass
from .contact3d import _barycentric, soft_contact_pass_3d, triangle_contact_areas

__all__ = ["ContactCrossed", "check_pairs", "pair_force", "ContactEval", "surface_dofs", "evaluate_contact"]

_CS = 1e-30   # complex-step size (relative to the coordinates' scale: exact to round-off for any size)


class ContactCrossed(Exception):
    """An iterate put a contact node at h <= 0 (through the soft-contact layer)."""


def check_pairs(pairs: Sequence[ContactPairSpec]) -> None:
    """Refuse the velocity-dependent parts of the contact law (``ValueError``, one line)."""
    for i, cp in enumerate(pairs):
        if cp.friction > 0 or cp.viscosity > 0:
            raise ValueError(f"contact pair {i} ({cp.slave} -> {cp.master}): the implicit integrator has the elastic "
                             "law of eq. (5) only; set friction = 0 and viscosity = 0, or use mechanics.integrator = "
                             "'explicit'")


def pair_force(xs: np.ndarray, xm: np.ndarray, area: np.ndarray, k: float, h0: float, weight: float,
               fixed_w: np.ndarray, free_w: np.ndarray) -> np.ndarray:
    """Contact forces (N) of eq. (5) on a batch of pairs, complex-step safe.

    Parameters
    ----------
    xs : (P, d) array
        Slave node positions, m (d = 2: master segments; d = 3: master triangles).
    xm : (P, d, d) array
        The master nodes of each pair's segment (2D, oriented so that (t_y, -t_x) points out) or triangle
        (3D, outward by the right-hand rule), m.
    area : (P,) array
        Contact areas, m^2 (held).
    k, h0, weight : float
        The law's stiffness (Pa m), layer (m) and the pass's weight.
    fixed_w : (P, d) array
        Master weights where the projection lies beyond the master's edges (held), else ignored.
    free_w : (P,) bool array
        True where the projection lies on the master: its weights follow the positions.

    Returns
    -------
    (P, d + 1, d) array
        Forces on the slave node and on the master nodes (the reaction, split by the weights).
    """
    d = xs.shape[1]
    if d == 2:
        xa, xb = xm[:, 0], xm[:, 1]
        t = xb - xa
        L = np.sqrt(t[:, 0] * t[:, 0] + t[:, 1] * t[:, 1])
        nrm = np.stack([t[:, 1], -t[:, 0]], axis=1) / L[:, None]
        rel = xs - xa
        xi = (rel[:, 0] * t[:, 0] + rel[:, 1] * t[:, 1]) / (L * L)
        w = np.stack([1.0 - xi, xi], axis=1)
    else:
        e1, e2 = xm[:, 1] - xm[:, 0], xm[:, 2] - xm[:, 0]
        nv = np.stack([e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1], e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2],
                       e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]], axis=1)
        nrm = nv / np.sqrt(np.sum(nv * nv, axis=1))[:, None]
        rel = xs - xm[:, 0]
        h = np.sum(rel * nrm, axis=1)
        q = rel - h[:, None] * nrm
        a, b, c = np.sum(e1 * e1, axis=1), np.sum(e1 * e2, axis=1), np.sum(e2 * e2, axis=1)
        d1, d2 = np.sum(q * e1, axis=1), np.sum(q * e2, axis=1)
        det = a * c - b * b
        x1, x2 = (c * d1 - b * d2) / det, (a * d2 - b * d1) / det
        w = np.stack([1.0 - x1 - x2, x1, x2], axis=1)
    h = np.sum(rel * nrm, axis=1)
    w = np.where(free_w[:, None], w, fixed_w)
    F = (weight * k * (1.0 / h - 1.0 / h0) * area)[:, None] * nrm
    out = np.empty((xs.shape[0], d + 1, d), dtype=F.dtype)
    out[:, 0] = F
    out[:, 1:] = -w[:, :, None] * F[:, None, :]
    return out


class ContactEval:
    """The contact of one iterate: nodal forces per body (N), stored layer energy (J), the active pairs,
    the slave pressures (per pair: pressure, gap, positions of the slave surface) and, on demand, the
    tangent's triplets."""

    def __init__(self):
        self.force: Dict[str, np.ndarray] = {}
        self.stored = 0.0
        self.active: Dict[tuple, tuple] = {}
        self.out: List[tuple] = []
        self._pairs: List[tuple] = []

    def tangent(self) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rows, cols, values) of -dF/dx, the contact's part of the tangent (N/m), in the Newton system's numbering
        (:func:`surface_dofs`; one process: ``offsets[body] + row * gdim + component``): the pairs whose slave node
        this rank owns."""
        R, C, V = [], [], []
        for xs, xm, area, spec, weight, fixed_w, free_w, dofs in self._pairs:
            P, d = xs.shape
            nn = d + 1
            x = np.concatenate([xs[:, None, :], xm], axis=1)    # (P, nn, d)
            J = np.empty((P, nn * d, nn * d))
            for j in range(nn * d):
                xc = x.astype(complex)
                xc[:, j // d, j % d] += 1j * _CS
                f = pair_force(xc[:, 0], xc[:, 1:], area, spec.stiffness, spec.h0, weight, fixed_w, free_w)
                J[:, :, j] = -f.imag.reshape(P, nn * d) / _CS
            R.append(np.repeat(dofs, nn * d, axis=1).ravel())
            C.append(np.tile(dofs, (1, nn * d)).ravel())
            V.append(J.ravel())
        if not R:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        return np.concatenate(R), np.concatenate(C), np.concatenate(V)



def surface_dofs(solver) -> Dict[str, Tuple[np.ndarray, np.ndarray]]:
    """Per contact surface (body name), the Newton system's numbers of its nodes' unknowns, (Ns, gdim) int in the
    order of the gathered surface (:class:`~.contact.Surface`, every surface node on every rank: ``node_dofs`` of
    ``solver._linear``, the global numbering under MPI), and (Ns,) bool: the nodes this rank owns (each node is owned
    by one rank). Computed once (collective under MPI) and kept on the solver."""
    cached = getattr(solver, "_surf_dofs", None)
    if cached is not None:
        return cached
    out = {}
    for n, s in solver._surf.items():
        g = s.gather(np.asarray(solver._linear.node_dofs(n), dtype=float))   # < 2^53: exact in a float
        mine = np.zeros(len(s.gids), dtype=bool)
        mine[s.own_pos] = True
        out[n] = (np.rint(g).astype(np.int64), mine)
    solver._surf_dofs = out
    return out


def evaluate_contact(solver, x: Mapping[str, np.ndarray],
                     prefer: Optional[Mapping[tuple, tuple]] = None) -> ContactEval:
    """The contact forces of ``solver``'s pairs with the bodies at positions ``x`` (name -> (N, d), m);
    ``prefer``: the active pairs of the previous Newton iterate (:attr:`ContactEval.active`), kept by a node
    near an edge between two master faces (:func:`.contact.choose_faces`).

    Every rank evaluates every pass on the gathered surfaces (the same arrays, hence the same active pairs, stored
    energy and pressures on every rank, as the explicit solver's contact) and adds each surface node's force to
    its local row, owned or ghost (complete rows: no further exchange). The tangent's triplets
    (:meth:`ContactEval.tangent`) are those of the pairs whose slave node this rank owns, in the Newton system's
    numbering (:func:`surface_dofs`): over the ranks, each pair once.

    Raises
    ------
    ContactCrossed
        A slave node at h <= 0, or behind the master face it touched at the start of the step (on every rank).
    """
    ev = ContactEval()
    for n, b in solver.bodies.items():
        ev.force[n] = np.zeros_like(b.x)
    if not solver.contact_pairs:
        return ev
    sdofs = surface_dofs(solver)
    X = {n: s.gather(x[n]) for n, s in solver._surf.items()}
    fsurf = {n: np.zeros_like(Xn) for n, Xn in X.items()}
    for ip, cp in enumerate(solver.contact_pairs):
        passes = [(cp.slave, cp.master)] + ([(cp.master, cp.slave)] if cp.two_pass else [])
        wgt = 0.5 if cp.two_pass else 1.0
        for kp, (sn, mn) in enumerate(passes):
            Xs, Xm = X[sn], X[mn]
            ss, ms = solver._surf[sn], solver._surf[mn]
            zs, zm = np.zeros_like(Xs), np.zeros_like(Xm)
            prev = solver._active.get((ip, kp))
            pref = prefer.get((ip, kp)) if prefer is not None else prev
            if Xs.shape[1] == 2:
                geo = ss.geometry(Xs)
                res = soft_contact_pass(Xs, zs, geo, Xm, zm, ms.seg, cp, wgt, previous=prev, seg_key=ms.seg_key,
                                        prefer=pref)
            else:
                res = soft_contact_pass_3d(Xs, zs, ss.seg, Xm, zm, ms.seg, cp, wgt, previous=prev, tri_key=ms.seg_key,
                                           prefer=pref)
            if res.penetration is not None:
                i, h = res.penetration
                raise ContactCrossed(f"node {int(ss.gids[i])} of body {sn!r} reached h={h:.3e} m <= 0 against body "
                                     f"{mn!r} (contact pair {ip})")
            ev.active[(ip, kp)] = res.active
            fsurf[sn] += res.F_slave
            fsurf[mn] += res.F_master
            ev.stored += res.stored
            if kp == 0:
                ev.out.append((res.pressure, res.gap, Xs))
            si, mj = res.active
            if si.size == 0:
                continue
            d = Xs.shape[1]
            corners = ms.seg[mj]
            xs, xm = Xs[si], Xm[corners]
            nrm = _normals(xm)
            if d == 2:
                area = geo.contact_areas(si, nrm, Xs.shape[0])
                t = xm[:, 1] - xm[:, 0]
                xi = np.einsum("ij,ij->i", xs - xm[:, 0], t) / np.einsum("ij,ij->i", t, t)
                inside = (xi >= 0.0) & (xi <= 1.0)
                xc = np.clip(xi, 0.0, 1.0)
                fixed_w = np.stack([1.0 - xc, xc], axis=1)
            else:
                area = triangle_contact_areas(ss.seg, Xs, si, nrm)
                _, wts = _barycentric(xs - xm[:, 0], xm[:, 1] - xm[:, 0], xm[:, 2] - xm[:, 0], nrm)
                inside = np.all(wts >= 0.0, axis=1)
                fixed_w = np.clip(wts, 0.0, None)
                fixed_w /= fixed_w.sum(axis=1)[:, None]
            mine = sdofs[sn][1][si]          # the pairs of the slave nodes this rank owns
            if not mine.any():
                continue
            dofs = np.concatenate([sdofs[sn][0][si]] + [sdofs[mn][0][corners[:, j]] for j in range(corners.shape[1])],
                                  axis=1)
            ev._pairs.append((xs[mine], xm[mine], area[mine], cp, wgt, fixed_w[mine], inside[mine], dofs[mine]))
    for n, s in solver._surf.items():
        s.scatter_add(fsurf[n], ev.force[n])
    return ev


def _normals(xm: np.ndarray) -> np.ndarray:
    """Unit outward normals of master segments (P, 2, 2) or triangles (P, 3, 3)."""
    if xm.shape[1] == 2:
        t = xm[:, 1] - xm[:, 0]
        return np.stack([t[:, 1], -t[:, 0]], axis=1) / np.linalg.norm(t, axis=1)[:, None]
    nv = np.cross(xm[:, 1] - xm[:, 0], xm[:, 2] - xm[:, 0])
    return nv / np.linalg.norm(nv, axis=1)[:, None]
