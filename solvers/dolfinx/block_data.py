"""Pack an :class:`~.solver.ExplicitSolver` into the arrays of the compiled block path
(:mod:`.block`) and copy the Python-side state in and out at block boundaries.

The bodies' nodal and cell arrays (``x, v, a, cell_stress, eps_p``), the held external forces and
the previous contact forces *are* views into the concatenated arrays, so nothing is copied per
block but a few scalars, the active contact sets and the contact / wall outputs.
"""
from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Dict, List, Sequence, Tuple

import numpy as np

from .block import N_SC, SC, BodyArrays, WallArrays
from .cell_list import new_grid
from .contact_kernel import ContactArrays
from .kernel_threads import thread_arrays
from .kernels import WORK_SIZE

if TYPE_CHECKING:
    from .solver import ExplicitSolver

__all__ = ["BlockData", "block_supported"]

log = logging.getLogger(__name__)


def block_supported(solver: "ExplicitSolver") -> str:
    """Why the compiled block path cannot run this solver ('' if it can)."""
    if solver.comm.size > 1:
        return "MPI (ghost exchange per step)"
    for b in solver.bodies.values():
        if getattr(b, "element", "tet4") == "tri6":
            return f"body {b.name!r}: six-node triangles (their kernel runs in the Python step loop)"
        if b.spec.motion:
            return f"body {b.name!r}: prescribed motions (Python callables)"
        for kind, _, _, val in b._constraints:
            if kind == "fix" and callable(val):
                return f"body {b.name!r}: time-dependent prescribed velocity (Python callable)"
    return ""


def _concat_views(arrays: Sequence[np.ndarray], shape_tail: Tuple[int, ...],
                  dtype=float) -> Tuple[np.ndarray, List[np.ndarray]]:
    """One array holding ``arrays`` back to back, and views of it in their place."""
    n = sum(len(a) for a in arrays)
    out = np.zeros((n,) + shape_tail, dtype=dtype)
    views, o = [], 0
    for a in arrays:
        out[o:o + len(a)] = a
        views.append(out[o:o + len(a)])
        o += len(a)
    return out, views


class BlockData:
    """The compiled path's arrays for one solver (serial); built once.

    Parameters
    ----------
    solver : ExplicitSolver
        Its bodies' arrays are replaced by views into the concatenated arrays.
    """

    def __init__(self, solver: "ExplicitSolver") -> None:
        self.solver = solver
        bodies = list(solver.bodies.values())
        names = list(solver.bodies)
        self.names = names
        node_off = np.cumsum([0] + [b.n_local for b in bodies]).astype(np.int64)
        cell_off = np.cumsum([0] + [len(b.cells) for b in bodies]).astype(np.int64)
        self.node_off = node_off
        x, xv = _concat_views([b.x for b in bodies], (2,))
        v, vv = _concat_views([b.v for b in bodies], (2,))
        a, av = _concat_views([b.a for b in bodies], (2,))
        st, sv = _concat_views([b.cell_stress for b in bodies], (4,))
        ep, ev = _concat_views([b.eps_p for b in bodies], ())
        tp, tv = _concat_views([b.temperature for b in bodies], ())
        fx, fv = _concat_views([solver._fext[n] for n in names], (2,))
        for b, x_, v_, a_, s_, e_, t_ in zip(bodies, xv, vv, av, sv, ev, tv):
            b.x, b.v, b.a, b.cell_stress, b.eps_p, b.temperature = x_, v_, a_, s_, e_, t_
        for n, f_ in zip(names, fv):
            solver._fext[n] = f_
        cells = np.concatenate([b.cells.astype(np.int32) + np.int32(o)
                                for b, o in zip(bodies, node_off[:-1])]).reshape(-1, 3)
        # one row per body, padded to the longest (a flow curve's parameters follow N_PRM)
        prm = np.zeros((len(names), max(len(solver._prm[n]) for n in names)))
        for ib, n in enumerate(names):
            prm[ib, :len(solver._prm[n])] = solver._prm[n]
        con_idx, con_val, con_off = [], [], [0]
        for b, o in zip(bodies, node_off[:-1]):
            for kind, nodes, comps, val in b._constraints:
                for c in comps:          # same order as Body.apply_velocity_constraints
                    con_idx.append(2 * (np.asarray(nodes, np.int64) + o) + c)
                    con_val.append(np.full(len(nodes), float(val)))
            if b.axis_nodes.size:
                con_idx.append(2 * (b.axis_nodes.astype(np.int64) + o))
                con_val.append(np.zeros(b.axis_nodes.size))
            con_off.append(sum(len(c) for c in con_idx))
        cidx = [solver._cidx[n].astype(np.int64) + 2 * o for n, o in zip(names, node_off[:-1])]
        ntot = int(node_off[-1])
        self.B = BodyArrays(
            node_off=node_off, cell_off=cell_off, cells=np.ascontiguousarray(cells), prm=prm,
            x=x, v=v, a=a, m=np.concatenate([b.mass for b in bodies]), f=np.zeros((ntot, 2)),
            fext=fx, fext_on=np.zeros(len(names), np.uint8), stress=st, eps_p=ep, temp=tp,
            con_off=np.array(con_off, np.int64),
            con_idx=np.concatenate(con_idx).astype(np.int64) if con_idx else np.zeros(0, np.int64),
            con_val=np.concatenate(con_val) if con_val else np.zeros(0),
            cidx_off=np.cumsum([0] + [len(c) for c in cidx]).astype(np.int64),
            cidx=np.concatenate(cidx) if cidx else np.zeros(0, np.int64),
            ke_half=np.zeros(len(names)), tmp=np.zeros(2 * max(ntot, 1)), acc=np.zeros(3),
            work=np.zeros(WORK_SIZE))
        self.W = self._walls(ntot)
        self.C = self._contact()
        self.sc = np.zeros(N_SC)
        self.sc[SC["wall_tol"]] = solver._wall_tol
        self.sc[SC["axisymmetric"]] = 1.0 if solver.mode == 2 else 0.0
        self.sc[SC["thickness"]] = next(iter(solver.bodies.values())).thickness
        self.sc[SC["cfl"]] = solver.cfl
        self.sc[SC["n_contact"]] = len(solver.contact_pairs)
        #: the threaded kernel's arrays (``solver.threads > 1``), else None
        self.threaded = thread_arrays(self.B) if solver.threads > 1 else None
        self.ev = np.zeros(4, np.int64)
        self.evf = np.zeros(2)

    def _walls(self, ntot: int) -> WallArrays:
        s = self.solver
        nw = len(s.rigid_walls)
        acts = np.zeros((nw, len(self.names)), np.uint8)
        order = np.full((nw, len(self.names)), -1, np.int64)
        for iw, w in enumerate(s.rigid_walls):
            for k, n in enumerate(w.bodies or self.names):
                acts[iw, self.names.index(n)] = 1
                order[iw, k] = self.names.index(n)
        return WallArrays(
            point=np.array([w.point for w in s.rigid_walls], float).reshape(nw, 2),
            normal=np.array([w.unit_normal() for w in s.rigid_walls], float).reshape(nw, 2),
            sliding=np.array([w.sliding for w in s.rigid_walls], np.uint8),
            acts=acts, order=order, on=np.zeros((nw, ntot), np.uint8), fn=np.zeros((nw, ntot)),
            push=np.zeros((nw, ntot), np.uint8), hits=np.zeros(max(ntot, 1), np.int64))

    def _contact(self) -> ContactArrays:
        s = self.solver
        snames = list(s._surf)
        self.surf_names = snames
        surfs = [s._surf[n] for n in snames]
        node_off = np.cumsum([0] + [len(sf.gids) for sf in surfs]).astype(np.int64)
        seg_off = np.cumsum([0] + [len(sf.seg) for sf in surfs]).astype(np.int64)
        rows = []
        for n, sf in zip(snames, surfs):
            r = np.empty(len(sf.gids), np.int64)
            r[sf.loc_pos] = sf.loc_rows
            rows.append(r + self.node_off[self.names.index(n)])
        nsn = int(node_off[-1])
        seg = _cat([sf.seg for sf in surfs], np.int64).reshape(-1, 2)
        gfirst = _cat([sf.seg[:, 0] + o for sf, o in zip(surfs, node_off[:-1])], np.int64)
        gsecond = _cat([sf.seg[:, 1] + o for sf, o in zip(surfs, node_off[:-1])], np.int64)
        f0_off, f0 = _csr(gfirst, nsn)
        f1_off, f1 = _csr(gsecond, nsn)
        fsp, fspv = _concat_views([s._fsurf_prev[n] for n in snames], (2,))
        for n, f_ in zip(snames, fspv):
            s._fsurf_prev[n] = f_
        passes = []
        for ip, cp in enumerate(s.contact_pairs):
            pp = [(cp.slave, cp.master)] + ([(cp.master, cp.slave)] if cp.two_pass else [])
            for k, (sn, mn) in enumerate(pp):
                passes.append((ip, k, snames.index(sn), snames.index(mn), 0.5 if cp.two_pass else 1.0,
                               cp))
        self.passes = passes
        nsl = [int(node_off[p[2] + 1] - node_off[p[2]]) for p in passes]
        prev_off = np.cumsum([0] + nsl).astype(np.int64)
        nseg_max = max([len(sf.seg) for sf in surfs] + [1])
        nnode_max = max([len(sf.gids) for sf in surfs] + [1])
        head, nxt, meta = new_grid(nseg_max)
        npr = int(prev_off[-1])
        return ContactArrays(
            node_off=node_off, rows=_cat(rows, np.int64),
            mass=_cat([sf.M for sf in surfs], float),
            seg_off=seg_off, seg=seg, key=_cat([sf.seg_key for sf in surfs], np.int64),
            f0_off=f0_off, f0=f0, f1_off=f1_off, f1=f1,
            xs=np.zeros((nsn, 2)), vs=np.zeros((nsn, 2)), wa=np.zeros(len(seg)), wb=np.zeros(len(seg)),
            snrm=np.zeros((len(seg), 2)), fs=np.zeros((nsn, 2)), fs_prev=fsp,
            midx=np.zeros(nseg_max), midy=np.zeros(nseg_max), ln=np.zeros(nseg_max),
            p_slave=np.array([p[2] for p in passes], np.int64),
            p_master=np.array([p[3] for p in passes], np.int64),
            p_weight=np.array([p[4] for p in passes], float),
            p_k=np.array([p[5].stiffness for p in passes], float),
            p_h0=np.array([p[5].h0 for p in passes], float),
            p_mu=np.array([p[5].friction for p in passes], float),
            p_nu=np.array([p[5].viscosity for p in passes], float),
            p_eps2=np.array([p[5].friction_velocity ** 2 for p in passes], float),
            prev_off=prev_off, prev=np.full(npr, -1, np.int64), pres=np.full(npr, np.nan),
            gap=np.full(npr, np.nan),
            c_si=np.zeros(nnode_max, np.int64), c_mj=np.zeros(nnode_max, np.int64),
            c_xi=np.zeros(nnode_max), c_n0=np.zeros(nnode_max), c_n1=np.zeros(nnode_max),
            c_h=np.zeros(nnode_max), c_term=np.zeros(nnode_max),
            acc_a=np.zeros((nnode_max, 2)), acc_b=np.zeros((nnode_max, 2)),
            g_head=head, g_next=nxt, g_meta=meta, q_idx=np.zeros(8, np.int64), q_d2=np.zeros(8),
            work=np.zeros(2 * max(nnode_max, 1)))

    # ------------------------------------------------------------------ state in / out
    def load(self) -> None:
        """Copy the solver's Python-side state (scalars, active contacts) into the arrays."""
        s, sc = self.solver, self.sc
        sc[SC["time"]] = s.time
        sc[SC["step_count"]] = s.step_count
        sc[SC["dt_prev"]] = s._dt_prev
        sc[SC["dt_crit"]] = s._dt_crit
        for k in ("plastic_J", "viscous_J", "external_work_J", "wall_dissipated_J",
                  "kinetic_damping_J"):
            sc[SC[k]] = s._acc[k]
        sc[SC["contact_work"]] = s._contact_work
        sc[SC["contact_stored"]] = s._contact_stored
        sc[SC["kinetic_damping"]] = 1.0 if s.kinetic_damping else 0.0
        B, C = self.B, self.C
        for ib, n in enumerate(self.names):
            B.fext_on[ib] = 1 if s._fext_nonzero[n] else 0
            B.ke_half[ib] = s._ke_half[n]
        C.prev[:] = -1
        for p, (ip, k, *_rest) in enumerate(self.passes):
            act = s._active.get((ip, k))
            if act is not None and len(act[0]):
                C.prev[C.prev_off[p] + act[0]] = act[1]
        self.ev[:] = 0

    def store(self) -> None:
        """Copy the arrays' scalars, active contacts, contact and wall outputs back."""
        s, sc, B, C, W = self.solver, self.sc, self.B, self.C, self.W
        s.time = float(sc[SC["time"]])
        s.step_count = int(sc[SC["step_count"]])
        s._dt_prev = float(sc[SC["dt_prev"]])
        s._dt_crit = float(sc[SC["dt_crit"]])
        for k in ("plastic_J", "viscous_J", "external_work_J", "wall_dissipated_J",
                  "kinetic_damping_J"):
            s._acc[k] = float(sc[SC[k]])
        s._contact_work = float(sc[SC["contact_work"]])
        s._contact_stored = float(sc[SC["contact_stored"]])
        for ib, n in enumerate(self.names):
            s._fext_nonzero[n] = bool(B.fext_on[ib])
            s._ke_half[n] = float(B.ke_half[ib])
        for p, (ip, k, si, *_rest) in enumerate(self.passes):
            prev = C.prev[C.prev_off[p]:C.prev_off[p + 1]]
            nodes = np.flatnonzero(prev >= 0)
            s._active[(ip, k)] = (nodes.astype(np.int64), prev[nodes].astype(np.int64))
            if k == 0:
                o0, o1 = C.node_off[si], C.node_off[si + 1]
                s._contact_out[ip] = (C.pres[C.prev_off[p]:C.prev_off[p + 1]].copy(),
                                      C.gap[C.prev_off[p]:C.prev_off[p + 1]].copy(),
                                      B.x[C.rows[o0:o1]].copy())
        self._store_walls()

    def _store_walls(self) -> None:
        s, W, B = self.solver, self.W, self.B
        for iw, w in enumerate(s.rigid_walls):
            out: Dict = {"on": {}}
            for ib, n in enumerate(self.names):
                if not W.acts[iw, ib]:
                    continue
                o0, o1 = self.node_off[ib], self.node_off[ib + 1]
                out["on"][n] = np.flatnonzero(W.on[iw, o0:o1])
            s._wall_out[iw] = out
        for ib, n in enumerate(self.names):
            o0, o1 = self.node_off[ib], self.node_off[ib + 1]
            area = None
            for iw, w in enumerate(s.rigid_walls):
                if not W.acts[iw, ib]:
                    continue
                rows = np.flatnonzero(W.push[iw, o0:o1])
                if area is None:
                    b = s.bodies[n]
                    area = b.tributary_areas(b.segments, b.x)
                s._wall_out[iw].setdefault("p", {})[n] = (rows, -W.fn[iw, o0 + rows] / area[rows])


def _cat(arrays: Sequence[np.ndarray], dtype) -> np.ndarray:
    """``np.concatenate`` of 1D or (n, 2) arrays as ``dtype``; empty (0,) for no arrays."""
    return np.concatenate(arrays).astype(dtype) if arrays else np.zeros(0, dtype)


def _csr(owner: np.ndarray, n: int) -> Tuple[np.ndarray, np.ndarray]:
    """Offsets (n + 1) and entries listing, per owner, the indices i with owner[i] == it,
    ascending."""
    order = np.argsort(owner, kind="stable").astype(np.int64)
    counts = np.bincount(owner, minlength=n) if len(owner) else np.zeros(n, np.int64)
    off = np.zeros(n + 1, np.int64)
    off[1:] = np.cumsum(counts)
    return off, order
