"""Rigid walls in the implicit solver's Newton iterations: an active set of exact constraints (issue 34, item 1).

The explicit solver's wall (:class:`~.contact.RigidWallSpec`) puts a node found behind it back on it and
stops it (``sliding``: stops its normal motion only). Here the same rule is a constraint of the Newton
solve: a node on the wall (distance <= the solver's wall tolerance) at the start of a step, or found behind
it by an iterate, is held — on the spot where the iterate's normal projection puts it (sticking) or on the
wall's plane (sliding) — and released when the force the wall would have to give it pulls (its normal part
is below −``newton_tol`` × the residual's scale) once the other equations have converged. No penalty: the
held components are exact, so a bar pressed on a wall carries σ = E ε to the Newton tolerance.

A held node's constrained directions (its supports' components, the wall's normal, or all of them on a
sticking wall) are removed from the unknowns by a basis of their complement (:func:`reduced_basis`: the
identity's columns for the free components, the null space of the constraints for a node on a wall);
the increments that bring held nodes onto their targets enter the Newton update as a correction.
"""
from __future__ import annotations

from typing import Dict, List, Mapping, Tuple

import numpy as np
import scipy.sparse as sp

from .implicit_linear import SingularSystemError, free_rigid_modes

__all__ = ["WallSet", "reduced_basis", "check_static_supports"]


class WallSet:
    """The held nodes of one step's Newton solve: per body, row -> {wall index: target}, the target being the
    row's displacement increment (m, sticking walls) or None (sliding walls: on the plane)."""

    def __init__(self, solver):
        self.solver = solver
        self.held: Dict[str, Dict[int, Dict[int, object]]] = {n: {} for n in solver.bodies}
        for iw, w, n, b in self._walls():
            d = (b.x - np.asarray(w.point, float)) @ w.unit_normal()
            for r in np.flatnonzero(d <= solver._wall_tol):
                self.held[n].setdefault(int(r), {})[iw] = None if w.sliding else np.zeros(b.gdim)

    def _walls(self):
        s = self.solver
        for iw, w in enumerate(s.rigid_walls):
            for n in (w.bodies or s.bodies):
                yield iw, w, n, s.bodies[n]

    def activate(self, du: Mapping[str, np.ndarray]) -> bool:
        """Hold the nodes the iterate ``du`` put behind a wall; True if any."""
        changed = False
        for iw, w, n, b in self._walls():
            nrm = w.unit_normal()
            d = (b.x + du[n] - np.asarray(w.point, float)) @ nrm
            for r in np.flatnonzero(d < -self.solver._wall_tol):
                h = self.held[n].setdefault(int(r), {})
                if iw not in h:
                    h[iw] = None if w.sliding else du[n][r] - d[r] * nrm
                    changed = True
        return changed

    def release(self, reaction: Mapping[str, np.ndarray], tol: float) -> bool:
        """Let go of the held nodes whose wall force (``reaction[body][row]`` · normal, N) is below ``-tol``;
        True if any."""
        changed = False
        for iw, w, n, b in self._walls():
            nrm = w.unit_normal()
            for r in list(self.held[n]):
                if iw in self.held[n][r] and float(reaction[n][r] @ nrm) < -tol:
                    del self.held[n][r][iw]
                    if not self.held[n][r]:
                        del self.held[n][r]
                    changed = True
        return changed

    def pressures(self, reaction: Mapping[str, np.ndarray], x: Mapping[str, np.ndarray]) -> List[dict]:
        """Per wall, body -> (rows, wall pressure Pa) of its held nodes (as the explicit solver's
        ``_wall_out[iw]["p"]``; a ten-node body: every node of its loaded faces, :meth:`~.body.Body.wall_pressures`)."""
        out: List[dict] = [dict() for _ in self.solver.rigid_walls]
        for iw, w, n, b in self._walls():
            nrm = w.unit_normal()
            rows = np.array(sorted(r for r, h in self.held[n].items() if iw in h), dtype=np.int64)
            if rows.size == 0 and self.solver.comm.size == 1:   # MPI: a collective (the areas' ghost exchange)
                continue
            out[iw].setdefault("p", {})[n] = b.wall_pressures(rows, reaction[n][rows] @ nrm, x[n], nrm)
        return out

    def wall_force(self, reaction: Mapping[str, np.ndarray]) -> Dict[str, np.ndarray]:
        """The walls' forces (N) on the held nodes: the reaction's constrained part (all of it on a sticking
        wall, its normal part on a sliding one); zero elsewhere."""
        out = {}
        for n, b in self.solver.bodies.items():
            f = np.zeros_like(b.x)
            for r, h in self.held[n].items():
                walls = [self.solver.rigid_walls[iw] for iw in h]
                if any(not w.sliding for w in walls):
                    f[r] = reaction[n][r]
                else:
                    for w in walls:
                        nrm = w.unit_normal()
                        f[r] += (reaction[n][r] @ nrm) * nrm
            out[n] = f
        return out

    def stop(self, n: str, v: np.ndarray, a: np.ndarray) -> None:
        """The explicit wall's rule on the held nodes of body ``n``: no velocity or acceleration (sticking), none
        along the normal (sliding); ``v`` and ``a`` (N, gdim) are changed in place. Without it the Newmark update
        of a held node (du = 0) flips its velocity every step."""
        for r, h in self.held[n].items():
            for iw in h:
                w = self.solver.rigid_walls[iw]
                if not w.sliding:
                    v[r] = 0.0
                    a[r] = 0.0
                else:
                    nrm = w.unit_normal()
                    v[r] -= (v[r] @ nrm) * nrm
                    a[r] -= (a[r] @ nrm) * nrm

    def held_mask(self, n: str) -> np.ndarray:
        """(N, gdim) bool: the components of body ``n`` a sticking wall holds, and the normal component of
        nodes on a sliding wall whose normal is a coordinate axis (for the static step's rigid-motion check)."""
        b = self.solver.bodies[n]
        m = np.zeros(b.x.shape, dtype=bool)
        for r, h in self.held[n].items():
            for iw in h:
                w = self.solver.rigid_walls[iw]
                nrm = w.unit_normal()
                if not w.sliding:
                    m[r] = True
                elif np.max(np.abs(nrm)) > 1 - 1e-12:
                    m[r, int(np.argmax(np.abs(nrm)))] = True
        return m


def reduced_basis(solver, walls: WallSet, du: Mapping[str, np.ndarray], mask: Mapping[str, np.ndarray],
                  target: Mapping[str, np.ndarray], offsets: Mapping[str, int],
                  ndof: int) -> Tuple[sp.csr_matrix, np.ndarray]:
    """The basis T (ndof x n_free) of the unknowns left free by the supports (``mask``, their increments
    ``target``) and the held wall nodes, and the correction (ndof,) that brings the constrained components
    of ``du`` onto their targets (m)."""
    rows: List[np.ndarray] = []
    vals: List[np.ndarray] = []
    cols: List[np.ndarray] = []
    corr = np.zeros(ndof)
    ncol = 0
    for n, b in solver.bodies.items():
        d = b.gdim
        o = offsets[n]
        m = mask[n].copy()
        held = walls.held[n]
        if held:
            m[list(held)] = True
        c = np.where(mask[n], target[n] - du[n], 0.0)
        c[list(held)] = 0.0
        corr[o:o + b.x.size] = c.ravel()
        free = np.flatnonzero(~m.ravel())
        rows.append(o + free)
        cols.append(ncol + np.arange(free.size))
        vals.append(np.ones(free.size))
        ncol += free.size
        for r, h in held.items():
            C, g = [], []
            for comp in np.flatnonzero(mask[n][r]):
                C.append(np.eye(d)[comp])
                g.append(target[n][r, comp])
            for iw, tgt in h.items():
                w = solver.rigid_walls[iw]
                if tgt is not None:    # sticking: every component on its target
                    for comp in range(d):
                        C.append(np.eye(d)[comp])
                        g.append(tgt[comp])
                else:                  # sliding: the normal component on the plane
                    nrm = w.unit_normal()
                    C.append(nrm)
                    g.append(float(nrm @ (np.asarray(w.point, float) - b.x[r])))
            C = np.array(C)
            delta = np.linalg.lstsq(C, np.array(g) - C @ du[n][r], rcond=None)[0]
            corr[o + r * d:o + r * d + d] = delta
            _, s, vt = np.linalg.svd(C)
            rank = int(np.sum(s > 1e-10 * s.max()))
            for v in vt[rank:]:
                rows.append(o + r * d + np.arange(d))
                cols.append(np.full(d, ncol))
                vals.append(v)
                ncol += 1
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(ndof, ncol))
    return T, corr


def check_static_supports(solver) -> bool:
    """A static step needs every body held against rigid motion (else its tangent is singular): by its
    supports or the walls it rests on. Bodies in a contact pair are left to the solve (a zero pivot raises
    :class:`~.implicit_linear.SingularSystemError` there). Returns whether the answer holds for later steps
    (not with walls: what they hold changes).

    Raises
    ------
    SingularSystemError
        A body free to move rigidly, named with its free motions.
    """
    walls = WallSet(solver)
    touching = {cp.slave for cp in solver.contact_pairs} | {cp.master for cp in solver.contact_pairs}
    comm = solver.comm
    for n, b in solver.bodies.items():
        if n in touching:
            continue
        x, held = b.x, solver._mask[n] | walls.held_mask(n)
        if comm.size > 1:   # the whole body's owned rows on every rank: every rank takes the same decision
            x = np.concatenate(comm.allgather(x[:b.n_owned]))
            held = np.concatenate(comm.allgather(held[:b.n_owned]))
        free = free_rigid_modes(x, held, bool(b.axisymmetric))
        if free:
            raise SingularSystemError(
                f"t={solver.time:.6g} s: body {n!r} can move rigidly ({', '.join(free)}) in a static step: singular "
                "stiffness; add [[bodies.fixed]] or use scheme 'trapezoidal'")
    return not solver.rigid_walls
