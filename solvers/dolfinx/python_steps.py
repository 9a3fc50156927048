"""The Python step loop of :class:`~.solver.ExplicitSolver`: one explicit central-difference step
with internal, contact and wall forces and kinetic damping, in numpy over each body's arrays.

It runs under MPI (ghost exchange in :meth:`~.body.Body.complete_nodal`), with callables in
constraints, with the numpy kernel, and as the reference of the compiled block path
(:mod:`.block`, which repeats these operations in the same order: the same bits). The solver's
construction evaluates the forces at t = 0 here too (:meth:`PythonSteps._compute_forces`).
"""
from __future__ import annotations

from typing import Dict, Mapping

import numpy as np
from mpi4py import MPI

from .body import Body
from .contact import ContactPenetrationError, soft_contact_pass

__all__ = ["PythonSteps"]


class PythonSteps:
    """The Python step loop, a part of :class:`~.solver.ExplicitSolver` (which holds the state:
    bodies, kernel parameters, contact surfaces, walls, energy accumulators)."""

    def _step(self, dt: float, fext: Mapping[str, np.ndarray]) -> None:
        if dt > self._dt_crit * (1 + 1e-12):
            raise RuntimeError(f"t={self.time:.6e} s: dt={dt:.4e} s exceeds the critical step "
                               f"{self._dt_crit:.4e} s of the deformed mesh")
        dt_avg = 0.5 * (self._dt_prev + dt)
        t_new = self.time + dt
        wext = 0.0
        for n, b in self.bodies.items():
            b.v += dt_avg * b.a
            b.apply_velocity_constraints(t_new, dt)
            if self.kinetic_damping:
                self._acc["kinetic_damping_J"] += self._kinetic_peak(n, b, t_new, dt)
            no = b.n_owned
            if self._fext_nonzero[n]:
                wext += dt * float(np.sum(b.v[:no] * fext[n][:no]))
            b.x += dt * b.v
        self._acc["wall_dissipated_J"] += self._apply_walls()
        self._acc["external_work_J"] += self.comm.allreduce(wext) if self.comm.size > 1 else wext
        self.time = t_new
        self._compute_forces(dt, update_state=True)
        self._dt_prev = dt
        self.step_count += 1

    def _kinetic_peak(self, n: str, b: Body, t_new: float, dt: float) -> float:
        """Kinetic damping (dynamic relaxation): once the body's half-step kinetic energy has
        passed a peak, set its velocities to zero (prescribed ones excepted); returns the kinetic
        energy removed (J)."""
        no = b.n_owned
        ke = self._sum(0.5 * float(np.sum(b.mass[:no, None] * b.v[:no] ** 2)))
        if ke >= self._ke_half[n]:
            self._ke_half[n] = ke
            return 0.0
        b.v[...] = 0.0
        b.apply_velocity_constraints(t_new, dt)
        self._ke_half[n] = 0.0
        return ke - self._sum(0.5 * float(np.sum(b.mass[:no, None] * b.v[:no] ** 2)))

    def _apply_walls(self) -> float:
        """Put nodes found behind a wall back on it and remove their (normal) velocity; returns the
        kinetic energy removed (J). Nodes on the wall are remembered for the reaction step."""
        removed = 0.0
        for iw, w in enumerate(self.rigid_walls):
            nrm = w.unit_normal()
            p = np.asarray(w.point, dtype=float)
            on = {}
            for n in (w.bodies or self.bodies):
                b = self.bodies[n]
                d = (b.x - p) @ nrm
                hit = np.flatnonzero(d < 0.0)
                if hit.size:
                    b.x[hit] -= d[hit, None] * nrm
                    own = hit[hit < b.n_owned]
                    ke0 = 0.5 * np.sum(b.mass[own] * np.sum(b.v[own] ** 2, axis=1))
                    if w.sliding:
                        b.v[hit] -= (b.v[hit] @ nrm)[:, None] * nrm
                    else:
                        b.v[hit] = 0.0
                    removed += ke0 - 0.5 * np.sum(b.mass[own] * np.sum(b.v[own] ** 2, axis=1))
                on[n] = np.flatnonzero(d <= self._wall_tol)
            self._wall_out[iw] = {"on": on}
        return self.comm.allreduce(removed) if self.comm.size > 1 else removed

    def _wall_reactions(self, n: str, b: Body, f: np.ndarray) -> None:
        """Cancel the force of wall nodes pushed into the wall (all of it for a sticking wall, the
        normal part for a sliding one) and record their normal forces (N) for
        :meth:`_wall_pressures`."""
        for iw, w in enumerate(self.rigid_walls):
            on = self._wall_out[iw].get("on", {}).get(n)
            if on is None:
                continue
            nrm = w.unit_normal()
            fn = f[on] @ nrm
            push = fn < 0.0
            rows = on[push]
            if w.sliding:
                f[rows] -= fn[push, None] * nrm
            else:
                f[rows] = 0.0
            self._wall_out[iw].setdefault("fn", {})[n] = (rows, fn[push])

    def _wall_pressures(self) -> None:
        """The wall reactions per unit area (Pa) of the nodes the last step found pushed into the
        walls (:meth:`~.body.Body.wall_pressures`: a ten-node body's at every node of its loaded faces), on the
        current positions (those of that step's forces). The steps do not need them:
        they are computed once, at the end of :meth:`advance` (the boundary areas cost as much as
        the rest of a 3D step's Python part); the same bits as at every step."""
        for iw, w in enumerate(self.rigid_walls):
            out = self._wall_out[iw]
            nrm = w.unit_normal()
            for n, (rows, fn) in out.pop("fn", {}).items():
                b = self.bodies[n]
                out.setdefault("p", {})[n] = b.wall_pressures(rows, -fn, b.x, nrm)

    def _body_kernel(self, name: str):
        """The element kernel of body ``name`` (the solver's ``_kernel``; the 3D solver's
        threaded kernel is one per body)."""
        return self._kernel

    def _compute_forces(self, dt: float, update_state: bool) -> None:
        dtc = np.inf
        ftot = {}
        for n, b in self.bodies.items():
            f = np.zeros_like(b.x)
            acc = np.zeros(3)
            kernel = self._body_kernel(n)
            if update_state:
                d = kernel(b.cells, b.x, b.v, dt, self._prm[n], b.cell_stress, b.eps_p, f, acc,
                           self._work, b.temperature)
            else:
                d = kernel(b.cells, b.x, np.zeros_like(b.v), 0.0, self._prm[n],
                           b.cell_stress.copy(), b.eps_p.copy(), f, acc, self._work, b.temperature.copy())
            if acc[2] >= 0:
                e = int(acc[2])
                raise RuntimeError(f"t={self.time:.6e} s: cell {e} of body {n!r} inverted "
                                   f"(centroid {b.x[b.cells[e]].mean(axis=0)})")
            if update_state:
                self._acc["plastic_J"] += self._sum(acc[0])
                self._acc["viscous_J"] += self._sum(acc[1])
            dtc = min(dtc, d)
            np.negative(f, out=f)
            if self._fext_nonzero[n]:
                f[: b.n_owned] += self._fext[n][: b.n_owned]
            ftot[n] = b.complete_nodal(f)
        if self.comm.size > 1:
            dtc = self.comm.allreduce(dtc, op=MPI.MIN)
        if update_state:
            self._dt_crit = dtc
        self._contact(ftot, dt if update_state else 0.0)
        for n, b in self.bodies.items():
            f = ftot[n]
            self._wall_reactions(n, b, f)
            np.divide(f, b.mass[:, None], out=b.a)
            b.a.ravel()[self._cidx[n]] = 0.0
            b.project_sliding(b.a)

    def _sum(self, val: float) -> float:
        return self.comm.allreduce(float(val)) if self.comm.size > 1 else float(val)

    def _contact(self, ftot: Dict[str, np.ndarray], dt: float) -> None:
        """Add soft-contact forces; the work of all contact forces is integrated with the
        trapezoidal rule dt v^{n+1/2} . (F^n + F^{n+1}) / 2 (consistent with central differences),
        and the contact dissipation is that work minus the change of the stored layer energy."""
        if not self.contact_pairs:
            return
        data = {}
        fsurf = {}
        for n, s in self._surf.items():
            X = s.gather(self.bodies[n].x)
            V = s.gather(self.bodies[n].v)
            data[n] = (X, V, s.geometry(X))
            fsurf[n] = np.zeros_like(X)
        stored = 0.0
        for ip, cp in enumerate(self.contact_pairs):
            passes = [(cp.slave, cp.master)]
            if cp.two_pass:
                passes.append((cp.master, cp.slave))
            wgt = 0.5 if cp.two_pass else 1.0
            for k, (sn, mn) in enumerate(passes):
                Xs, Vs, geo = data[sn]
                Xm, Vm, _ = data[mn]
                res = soft_contact_pass(Xs, Vs, geo, Xm, Vm, self._surf[mn].seg, cp, wgt,
                                        Ms=self._surf[sn].M, Mm=self._surf[mn].M, dt=dt,
                                        previous=self._active.get((ip, k)),
                                        seg_key=self._surf[mn].seg_key)
                if res.penetration is not None:
                    i, h = res.penetration
                    raise ContactPenetrationError(
                        f"t={self.time:.6e} s: node {int(self._surf[sn].gids[i])} of body {sn!r} "
                        f"at ({Xs[i, 0]:.6g}, {Xs[i, 1]:.6g}) m reached h={h:.3e} m <= 0 against "
                        f"body {mn!r} (contact pair {ip})")
                self._active[(ip, k)] = res.active
                fsurf[sn] += res.F_slave
                fsurf[mn] += res.F_master
                stored += res.stored
                if k == 0:
                    self._contact_out[ip] = (res.pressure, res.gap, Xs)
        work = 0.0
        for n, s in self._surf.items():
            s.scatter_add(fsurf[n], ftot[n])
            if dt > 0:
                work += dt * float(np.sum(data[n][1] * 0.5 * (self._fsurf_prev[n] + fsurf[n])))
            self._fsurf_prev[n][...] = fsurf[n]
        self._contact_work += work
        self._contact_stored = stored
