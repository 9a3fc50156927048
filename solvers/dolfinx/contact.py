"""Soft contact (paper eq. 5) node-to-segment between deformable bodies, and rigid walls.

Contact surfaces are gathered on every rank (they are 1D and small), so that each rank evaluates
the same global contact forces and adds those of its local nodes; serial and parallel runs then
differ only by summation order.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numba
import numpy as np
from scipy.spatial import cKDTree

__all__ = ["ContactPairSpec", "RigidWallSpec", "ContactPenetrationError", "Surface",
           "SlaveGeometry", "soft_contact_pass", "ContactResult", "choose_faces", "PREFER_OVERSHOOT"]

log = logging.getLogger(__name__)

#: candidate master segments examined per slave node (nearest midpoints within the search radius)
_N_CANDIDATES = 8


class ContactPenetrationError(RuntimeError):
    """A contact node reached h <= 0 (the soft-contact layer was crossed)."""


@dataclass(frozen=True)
class ContactPairSpec:
    """Soft-contact pair, eq. (5): p = k (1/h - 1/h0) for h < h0.

    Parameters
    ----------
    slave, master : str
        Body names; slave nodes are pushed off master segments.
    stiffness : float
        k, per unit area, Pa m (the paper's bar test: 1e8).
    h0 : float
        Width of the force layer, m.
    friction : float
        Coulomb coefficient mu on the tangential relative velocity (regularised).
    viscosity : float
        Paper's artificial viscosity nu, kg/m^3: contact stress -nu |v_n| v_n on the pair's
        relative normal velocity v_n.
    two_pass : bool
        Also treat master nodes against slave segments; each pass then carries half the force.
    friction_velocity : float
        Regularisation velocity of the friction law, m/s.
    """

    slave: str
    master: str
    stiffness: float
    h0: float
    friction: float = 0.0
    viscosity: float = 0.0
    two_pass: bool = False
    friction_velocity: float = 1e-3

    def __post_init__(self) -> None:
        if not (self.stiffness > 0 and self.h0 > 0):
            raise ValueError("ContactPairSpec needs stiffness > 0 and h0 > 0")
        if self.friction < 0 or self.viscosity < 0 or self.friction_velocity <= 0:
            raise ValueError("friction, viscosity must be >= 0, friction_velocity > 0")
        if self.slave == self.master:
            raise ValueError("self-contact is not supported")


@dataclass(frozen=True)
class RigidWallSpec:
    """Rigid half-space wall {(x - point) . normal >= 0}.

    The paper's rule "if x < x0 then x = x0, v = 0", generalised: a node found behind the wall is
    put back on it and its velocity is zeroed (``sliding=True`` zeroes only the normal component).

    Parameters
    ----------
    point : (float, float)
        A point of the wall, m.
    normal : (float, float)
        Normal pointing into the allowed half-space (normalised internally).
    bodies : sequence of str, optional
        Bodies it acts on (default: all).
    sliding : bool
        Keep the tangential velocity (frictionless wall) instead of the paper's v = 0.
    """

    point: tuple
    normal: tuple
    bodies: Optional[Sequence[str]] = None
    sliding: bool = False

    def unit_normal(self) -> np.ndarray:
        n = np.asarray(self.normal, dtype=float)
        nn = np.linalg.norm(n)
        if not nn > 0:
            raise ValueError("RigidWallSpec.normal must be non-zero")
        return n / nn


class Surface:
    """Global boundary of a body (all ranks): node global ids, segments (triangles of a 3D body),
    gathered positions."""

    def __init__(self, body):
        self.body = body
        comm = body.comm
        seg_g = body.global_ids[body.segments]
        all_segs = comm.allgather(seg_g)
        segs_g = np.concatenate(all_segs) if all_segs else np.zeros((0, 2), np.int64)
        self.gids = np.unique(segs_g)
        self.seg = np.searchsorted(self.gids, segs_g).astype(np.int64)
        lg = body.global_ids
        in_surf = np.isin(lg, self.gids)
        self.loc_rows = np.flatnonzero(in_surf)                       # local rows (owned + ghost)
        self.loc_pos = np.searchsorted(self.gids, lg[self.loc_rows])
        own = self.loc_rows < body.n_owned
        self.own_rows = self.loc_rows[own]
        self.own_pos = self.loc_pos[own]
        self.X0 = self.gather(body.X0)
        self.M = self.gather(body.mass[:, None])[:, 0]
        # partition-independent rank of each segment (by its reference midpoint), used to break
        # ties between equally distant candidate segments identically in serial and parallel
        if self.seg.shape[1] == 2:
            mid = 0.5 * (self.X0[self.seg[:, 0]] + self.X0[self.seg[:, 1]])
            order = np.lexsort((mid[:, 1], mid[:, 0]))
        else:    # triangles of a 3D body: by centroid
            mid = self.X0[self.seg].mean(axis=1)
            order = np.lexsort((mid[:, 2], mid[:, 1], mid[:, 0]))
        self.seg_key = np.empty(len(order), dtype=np.int64)
        self.seg_key[order] = np.arange(len(order))

    def gather(self, arr: np.ndarray) -> np.ndarray:
        """Global (Ns, k) array of a nodal (N, k) array, from the owners."""
        comm = self.body.comm
        if comm.size == 1:
            out = np.empty((len(self.gids),) + arr.shape[1:])
            out[self.loc_pos] = arr[self.loc_rows]
            return out
        parts = comm.allgather((self.own_pos, arr[self.own_rows]))
        out = np.empty((len(self.gids),) + arr.shape[1:])
        for pos, val in parts:
            out[pos] = val
        return out

    def scatter_add(self, F: np.ndarray, f_local: np.ndarray) -> None:
        """Add global surface forces F (Ns, 2) to the local nodal array (owned and ghost rows)."""
        f_local[self.loc_rows] += F[self.loc_pos]

    def areas(self, X: np.ndarray) -> np.ndarray:
        """Tributary areas of the surface nodes at positions X (Ns, 2), m^2."""
        return self.body.tributary_areas(self.seg, X)

    def geometry(self, X: np.ndarray) -> "SlaveGeometry":
        """Segment data for contact areas at positions X (see :class:`SlaveGeometry`)."""
        wa, wb, nrm = self.body.segment_weights(self.seg, X)
        return SlaveGeometry(self.seg, wa, wb, nrm)


@dataclass
class SlaveGeometry:
    """Slave-surface segments (S, 2), their end-node areas wa, wb (m^2) and outward normals."""

    seg: np.ndarray
    wa: np.ndarray
    wb: np.ndarray
    nrm: np.ndarray

    def contact_areas(self, nodes: np.ndarray, normals: np.ndarray, n_nodes: int) -> np.ndarray:
        """Contact area of each of ``nodes`` whose master normal is ``normals``: the adjacent
        segment areas projected on the contact plane, sum of w max(0, -n_seg . n_master), m^2.
        A corner node thus gets no area from a side segment perpendicular to the contact."""
        nm = np.zeros((n_nodes, 2))
        nm[nodes] = normals
        ca = np.maximum(0.0, -np.einsum("ij,ij->i", self.nrm, nm[self.seg[:, 0]])) * self.wa
        cb = np.maximum(0.0, -np.einsum("ij,ij->i", self.nrm, nm[self.seg[:, 1]])) * self.wb
        A = (np.bincount(self.seg[:, 0], weights=ca, minlength=n_nodes)
             + np.bincount(self.seg[:, 1], weights=cb, minlength=n_nodes))
        return A[nodes]


@dataclass
class ContactResult:
    """Outcome of one contact pass (arrays over slave-surface nodes; NaN where not in contact)."""

    F_slave: np.ndarray
    F_master: np.ndarray
    pressure: np.ndarray
    gap: np.ndarray
    stored: float
    dissipation_power: float
    penetration: Optional[tuple]
    active: tuple = (np.zeros(0, np.int64), np.zeros(0, np.int64))


def soft_contact_pass(Xs, Vs, geo: SlaveGeometry, Xm, Vm, segm, spec: ContactPairSpec,
                      weight: float = 1.0,
                      xi_tol: float = 0.02, Ms=None, Mm=None, dt: float = 0.0,
                      previous: Optional[tuple] = None,
                      seg_key: Optional[np.ndarray] = None,
                      prefer: Optional[tuple] = None) -> ContactResult:
    """Node-to-segment soft contact of slave nodes against master segments.

    Parameters
    ----------
    Xs, Vs : (Ns, 2) arrays
        Slave node positions (m) and velocities (m/s).
    geo : SlaveGeometry
        Slave segments, areas and normals; a node's contact area is its adjacent segment areas
        projected on the contact plane (:meth:`SlaveGeometry.contact_areas`).
    Xm, Vm : (Nm, 2) arrays
        Master surface node positions and velocities.
    segm : (S, 2) int array
        Master segments, oriented so that (t_y, -t_x) is the outward normal.
    spec : ContactPairSpec
        Law parameters.
    weight : float
        Scale of the forces (0.5 per pass for two-pass contact).
    xi_tol : float
        Accepted projection overshoot beyond a segment's ends, in segment lengths.
    Ms, Mm : (Ns,), (Nm,) arrays, optional
        Lumped masses of slave and master surface nodes, kg; with ``dt`` > 0 they cap the friction
        force at what stops the relative sliding within half a step (explicit stability of the
        regularised law: its viscous slope mu p A / eps would otherwise exceed 2 m / dt).
    dt : float
        Time step, s (0: no cap).
    previous : (slave indices, segment indices), optional
        Contacts of the previous step (``ContactResult.active``): a node that was in contact and
        now lies behind the same segment (it crossed the whole layer within one step) is reported
        as a penetration too.
    seg_key : (S,) int array, optional
        Canonical order of the master segments: among candidates whose |h| agree to 1e-9 h0
        (a node facing a shared vertex), the lowest key wins, whatever the storage order.

    prefer : (slave indices, segment indices), optional
        Pairs of a previous evaluation (the implicit solver's last Newton iterate): a node keeps that
        segment while it lies within :data:`PREFER_OVERSHOOT` of the segment's length beyond its ends
        (:func:`choose_faces`); None (the explicit solver): the rule alone.
    Returns
    -------
    ContactResult
        Forces on slave and master surface nodes (N), normal contact stress (Pa) and gap h (m)
        per slave node, stored layer energy (J), dissipation power of viscosity + friction (W), and
        ``(slave index, h)`` of the worst penetrating node or None.
    """
    ns = Xs.shape[0]
    tunnel = _tunnelled(Xs, Xm, segm, previous, xi_tol)
    Fs = np.zeros((ns, 2))
    Fm = np.zeros((Xm.shape[0], 2))
    pres = np.full(ns, np.nan)
    gap = np.full(ns, np.nan)
    empty = ContactResult(Fs, Fm, pres, gap, 0.0, 0.0, tunnel)
    if ns == 0 or segm.shape[0] == 0 or tunnel is not None:
        return empty
    h0 = spec.h0
    pa = Xm[segm[:, 0]]
    pb = Xm[segm[:, 1]]
    t = pb - pa
    ln = np.linalg.norm(t, axis=1)
    radius = 0.5 * ln.max() * (1 + xi_tol) + h0
    # slave nodes near the master surface's bounding box, then the nearest segment midpoints
    lo = np.minimum(pa, pb).min(axis=0) - radius
    hi = np.maximum(pa, pb).max(axis=0) + radius
    near = np.flatnonzero(np.all((Xs >= lo) & (Xs <= hi), axis=1))
    if near.size == 0:
        return empty
    nseg = segm.shape[0]
    kq = min(_N_CANDIDATES, nseg)
    tree = cKDTree(0.5 * (pa + pb))
    dist, idx = tree.query(Xs[near], k=kq, distance_upper_bound=radius)
    idx = np.asarray(idx).reshape(near.size, kq)
    found = idx < nseg
    if not found.any():
        return empty
    si = np.repeat(near, kq).reshape(near.size, kq)[found]
    mj = idx[found].astype(np.int64)
    d = Xs[si] - pa[mj]
    tt = t[mj]
    L = ln[mj]
    xi = np.einsum("ij,ij->i", d, tt) / (L * L)
    nrm = np.stack([tt[:, 1], -tt[:, 0]], axis=1) / L[:, None]
    h = np.einsum("ij,ij->i", d, nrm)
    ok = (xi >= -xi_tol) & (xi <= 1 + xi_tol) & (h < h0) & (h > -h0)
    if not ok.any():
        return empty
    si, mj, xi, nrm, h = si[ok], mj[ok], xi[ok], nrm[ok], h[ok]
    key = seg_key[mj] if seg_key is not None else mj
    # the segment the node projects onto (least overshoot beyond the segment's ends, in m) wins over
    # one it only reaches through the xi_tol tolerance: a corner node beside the end of a master
    # segment lies on that segment's extended line (h = 0 there) although its true distance is the
    # gap to the neighbouring segment
    over = np.maximum(np.maximum(-xi, xi - 1.0), 0.0) * L[ok]
    first = choose_faces(si, mj, h, over, L[ok], h0, key, prefer)
    si, mj, xi, nrm, h = si[first], mj[first], xi[first], nrm[first], h[first]
    bad = h <= 0.0
    if bad.any():
        k = int(np.argmin(h))
        return ContactResult(Fs, Fm, pres, gap, 0.0, 0.0, (int(si[k]), float(h[k])))
    xc = np.clip(xi, 0.0, 1.0)
    ia, ib = segm[mj, 0], segm[mj, 1]
    vm = (1 - xc)[:, None] * Vm[ia] + xc[:, None] * Vm[ib]
    vrel = Vs[si] - vm
    vn = np.einsum("ij,ij->i", vrel, nrm)
    p_el = spec.stiffness * (1.0 / h - 1.0 / h0)
    p_v = -spec.viscosity * np.abs(vn) * vn
    p = p_el + p_v
    A = geo.contact_areas(si, nrm, ns)
    F = (weight * p * A)[:, None] * nrm
    diss = -np.sum(weight * p_v * A * vn)
    if spec.friction > 0:
        vt = vrel - vn[:, None] * nrm
        vtn = np.sqrt(np.einsum("ij,ij->i", vt, vt) + spec.friction_velocity ** 2)
        mag = weight * spec.friction * np.maximum(p, 0.0) * A / vtn
        if dt > 0 and Ms is not None and Mm is not None:
            mm = (1 - xc) * Mm[ia] + xc * Mm[ib]
            meff = Ms[si] * mm / (Ms[si] + mm)
            mag = np.minimum(mag, 0.5 * meff / dt)
        Ft = -mag[:, None] * vt
        F += Ft
        diss -= np.sum(np.einsum("ij,ij->i", Ft, vt))
    Fs[si] = F
    nm = Xm.shape[0]
    for c in range(2):
        Fm[:, c] = -(np.bincount(ia, weights=(1 - xc) * F[:, c], minlength=nm)
                     + np.bincount(ib, weights=xc * F[:, c], minlength=nm))
    pres[si] = p
    gap[si] = h
    stored = float(np.sum(weight * A * spec.stiffness * (libm_log(h0 / h) - (h0 - h) / h0)))
    return ContactResult(Fs, Fm, pres, gap, stored, float(diss), None, (si, mj))


#: how far (relative to the face's size) beyond a preferred master face a slave node may lie and keep it
PREFER_OVERSHOOT = 1e-3


def choose_faces(si: np.ndarray, mj: np.ndarray, h: np.ndarray, over: np.ndarray, size: np.ndarray, h0: float,
                 key: np.ndarray, prefer: Optional[tuple] = None) -> np.ndarray:
    """The master face (segment or triangle) each slave node is paired with, among its candidates.

    The rule (both dimensions): the least overshoot beyond the face's edges (m; a face the node projects
    onto wins over one it only reaches through the tolerance), then the least |h| (m), then the face's
    canonical ``key``; overshoots and gaps are compared in units of 1e-9 ``h0`` (ties to round-off go to the
    key, not to the last bits of the positions). With ``prefer`` (the (slave, face) pairs of a previous
    evaluation), a node keeps its preferred face while its overshoot there is below :data:`PREFER_OVERSHOOT`
    times the face's ``size`` (m): a node on or near an edge shared by two faces that tilt by a little stays
    with one of them through Newton's iterations instead of alternating between them, which leaves the
    residual in a two-cycle (measured: two 3D blocks pressed through the layer, residual stuck at 2.5e-6).

    Parameters
    ----------
    si, mj : (P,) int arrays
        Candidate pairs: slave node and master face indices.
    h, over, size : (P,) arrays
        Signed gap (m), overshoot beyond the face's edges (m), the face's size (m: length of a segment,
        square root of twice a triangle's area).
    h0 : float
        The contact layer (m).
    key : (P,) int array
        The faces' canonical order.
    prefer : (slave indices, face indices), optional
        Previously chosen pairs.

    Returns
    -------
    (n,) int array
        Index into the candidates of each slave node's chosen pair (one per node, in node order).
    """
    hq = np.round(np.abs(h) / (1e-9 * h0))
    oq = np.round(over / (1e-9 * h0))
    if prefer is not None and len(prefer[0]):
        face = np.full(int(max(si.max(), np.max(prefer[0]))) + 1, -1, dtype=np.int64)
        face[np.asarray(prefer[0], np.int64)] = prefer[1]
        kept = (face[si] == mj) & (over <= PREFER_OVERSHOOT * size)
        oq = np.where(kept, 0.0, oq)
        order = np.lexsort((key, hq, ~kept, oq, si))
    else:
        order = np.lexsort((key, hq, oq, si))
    return order[np.unique(si[order], return_index=True)[1]]


@numba.njit(cache=True)
def libm_log(x: np.ndarray) -> np.ndarray:
    """Natural log of each element by the C library's ``log``, as the compiled contact pass
    (:mod:`.contact_kernel`) takes it: numpy's vectorised ``np.log`` (AVX-512) differs from it in
    the last bit for about a quarter of the arguments, which made the stored layer energy of the
    two step paths differ by ~1e-15 relative."""
    out = np.empty_like(x)
    for i in range(x.shape[0]):
        out[i] = math.log(x[i])
    return out


def _tunnelled(Xs, Xm, segm, previous, xi_tol):
    """(slave index, h) of a previously contacting node now behind its previous segment."""
    if previous is None or len(previous[0]) == 0:
        return None
    si, mj = previous
    pa = Xm[segm[mj, 0]]
    t = Xm[segm[mj, 1]] - pa
    L2 = np.einsum("ij,ij->i", t, t)
    d = Xs[si] - pa
    xi = np.einsum("ij,ij->i", d, t) / L2
    h = (d[:, 0] * t[:, 1] - d[:, 1] * t[:, 0]) / np.sqrt(L2)
    bad = (h <= 0.0) & (xi >= -xi_tol) & (xi <= 1 + xi_tol)
    if not bad.any():
        return None
    k = int(np.flatnonzero(bad)[np.argmin(h[bad])])
    return int(si[k]), float(h[k])
