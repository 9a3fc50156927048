"""Compiled explicit steps of a ten-node body (:mod:`.tet10_kernel`): n central-difference steps of
:class:`~.solver3d.ExplicitSolver3D` in one numba call, for the quasi-static runs that need 1e5 steps and more
(dynamic relaxation of a bent strip).

Every operation repeats the Python step loop (:meth:`.python_steps.PythonSteps._step`) in the same order and with
the same rounding (numpy's sums by :func:`.reductions.np_sum`), so that the two give the same bits: the half-step
velocity, the constant prescribed velocities in their order, kinetic damping, the external work, the positions,
the element kernel (:func:`.tet10_kernel.tet10_step`), the ledger's plastic and viscous work, f = f_ext - f_int,
a = f / m with the prescribed components zeroed. What it runs (:func:`steps_supported`): one process, one body,
ten-node, constant prescribed velocities, no rigid walls, soft planes, contact pairs, sliding planes or prescribed
motions; anything else runs the Python loop. A step above the critical one and an inverted cell stop the block
with the Python loop's state and message.
"""
from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numba
import numpy as np

from .reductions import np_sum
from .tet10 import QP_DERIVATIVES, QP_WEIGHTS
from .tet10_kernel import tet10_step

if TYPE_CHECKING:
    from .solver3d import ExplicitSolver3D

__all__ = ["Tet10Steps", "steps_supported", "run_tet10_steps"]

log = logging.getLogger(__name__)

EV_NONE, EV_DT, EV_INVERTED = 0, 1, 2
# the scalar state ``sc``: time (s), steps, previous and critical step (s), plastic, viscous, external, kinetic
# damping and wall ledger entries (J), the half-step kinetic energy of the last peak (J), kinetic damping on (1/0),
# external forces nonzero (1/0)
_T, _NSTEP, _DTP, _DTC, _PL, _VI, _EXT, _KD, _WALL, _KEH, _KDON, _FON = range(12)
_N_SC = 12


@numba.njit(cache=True)
def _constrain(v, con_idx, con_val):
    """The prescribed velocity components (flat indices into ``v``, constant values, m/s), in order."""
    vf = v.reshape(-1)
    for j in range(con_idx.shape[0]):
        vf[con_idx[j]] = con_val[j]


@numba.njit(cache=True)
def _half_ke(v, m, tmp):
    """sum m v^2 (kg m^2/s^2), rounded as np.sum(m[:, None] * v ** 2)."""
    k = 0
    for i in range(v.shape[0]):
        for c in range(3):
            tmp[k] = m[i] * (v[i, c] * v[i, c])
            k += 1
    return np_sum(tmp, k)


@numba.njit(cache=True)
def _kinetic_peak(v, m, con_idx, con_val, tmp, sc):
    """Kinetic damping (as ``PythonSteps._kinetic_peak``): once the half-step kinetic energy has passed a peak,
    zero the velocities (prescribed ones re-applied); returns the kinetic energy removed, J."""
    ke = 0.5 * _half_ke(v, m, tmp)
    if ke >= sc[_KEH]:
        sc[_KEH] = ke
        return 0.0
    v[:] = 0.0
    _constrain(v, con_idx, con_val)
    sc[_KEH] = 0.0
    return ke - 0.5 * _half_ke(v, m, tmp)


@numba.njit(cache=True)
def run_tet10_steps(cells, x, v, a, m, fext, stress, eps_p, temp, prm, dN, wq, factor, rho_scale, con_idx, con_val,
                    cidx, sc, f, acc, tmp, dt, n_steps, ev):
    """``n_steps`` explicit steps of size ``dt`` (s) of one ten-node body (the arrays of
    :class:`~.body3d.Body3D` and of :func:`.tet10_kernel.tet10_step`, ``rho_scale`` its density factors;
    ``con_idx`` / ``con_val`` the prescribed velocity components as flat indices into ``v`` and values (m/s),
    ``cidx`` the flat indices of every prescribed component, ``sc`` the scalar state, ``f`` (N, 3), ``acc`` (3,),
    ``tmp`` (3 N,) scratch). Stops at the first event (``ev[0]``: 1 a step above the critical one, before anything is
    done; 2 an inverted cell, ``ev[1]`` its index, after the kernel). Returns the steps done."""
    n = x.shape[0]
    for k in range(n_steps):
        if dt > sc[_DTC] * (1 + 1e-12):
            ev[0] = EV_DT
            return k
        dt_avg = 0.5 * (sc[_DTP] + dt)
        t_new = sc[_T] + dt
        wext = 0.0
        for i in range(n):
            for c in range(3):
                v[i, c] += dt_avg * a[i, c]
        _constrain(v, con_idx, con_val)
        if sc[_KDON] > 0.0:
            sc[_KD] += _kinetic_peak(v, m, con_idx, con_val, tmp, sc)
        if sc[_FON] > 0.0:
            j = 0
            for i in range(n):
                for c in range(3):
                    tmp[j] = v[i, c] * fext[i, c]
                    j += 1
            wext += dt * np_sum(tmp, j)
        for i in range(n):
            for c in range(3):
                x[i, c] += dt * v[i, c]
        sc[_WALL] += 0.0                      # no walls: the Python loop adds their 0.0
        sc[_EXT] += wext
        sc[_T] = t_new
        f[:] = 0.0
        acc[:] = 0.0
        d = tet10_step(cells, x, v, dt, prm, stress, eps_p, f, acc, temp, dN, wq, factor, rho_scale)
        if acc[2] >= 0:
            ev[0] = EV_INVERTED
            ev[1] = int(acc[2])
            return k
        sc[_PL] += acc[0]
        sc[_VI] += acc[1]
        for i in range(n):
            for c in range(3):
                f[i, c] = -f[i, c]
        if sc[_FON] > 0.0:
            for i in range(n):
                for c in range(3):
                    f[i, c] += fext[i, c]
        sc[_DTC] = d if d < np.inf else np.inf       # Python's min(inf, d)
        for i in range(n):
            for c in range(3):
                a[i, c] = f[i, c] / m[i]
        af = a.reshape(-1)
        for j in range(cidx.shape[0]):
            af[cidx[j]] = 0.0
        sc[_DTP] = dt
        sc[_NSTEP] += 1
    return n_steps


def steps_supported(solver: "ExplicitSolver3D") -> str:
    """Why the compiled steps cannot run ``solver`` ('' if they can)."""
    if solver.comm.size > 1:
        return "MPI (ghost exchange per step)"
    if len(solver.bodies) != 1:
        return f"{len(solver.bodies)} bodies (the compiled steps take one)"
    b = next(iter(solver.bodies.values()))
    if b.element != "tet10":
        return f"body {b.name!r}: element {b.element!r} (the compiled steps are the ten-node kernel's)"
    if solver.rigid_walls or solver.soft_planes or solver.contact_pairs:
        return "rigid walls, soft planes or contact pairs"
    if b.sliding is not None or b.spec.motion:
        return f"body {b.name!r}: sliding planes or prescribed motions"
    for kind, _, _, val in b._constraints:
        if kind != "fix" or callable(val):
            return f"body {b.name!r}: time-dependent prescribed velocity (Python callable)"
        if np.ndim(val) != 0:
            return f"body {b.name!r}: a prescribed velocity that is not one number"
    return ""


class Tet10Steps:
    """The compiled steps of one solver (:func:`steps_supported` must hold): the body's prescribed components and
    scratch arrays, built once; :meth:`run` copies the scalar state in and out around :func:`run_tet10_steps`.

    Parameters
    ----------
    solver : ExplicitSolver3D
        The solver; its body's arrays are used in place.
    """

    def __init__(self, solver: "ExplicitSolver3D") -> None:
        self.solver = solver
        self.name, b = next(iter(solver.bodies.items()))
        idx, val = [], []
        for _, nodes, comps, value in b._constraints:
            for c in comps:
                idx.append(3 * np.asarray(nodes, np.int64) + c)
                val.append(np.full(len(nodes), float(value)))
        self.con_idx = np.concatenate(idx) if idx else np.zeros(0, np.int64)
        self.con_val = np.concatenate(val) if val else np.zeros(0)
        self.cidx = np.asarray(solver._cidx[self.name], np.int64)
        self.factor = float(solver._kernels[self.name].factor)
        self.rho_scale = solver._kernels[self.name].rho_scale
        self.f = np.zeros_like(b.x)
        self.acc = np.zeros(3)
        self.tmp = np.zeros(b.x.size)
        self.sc = np.zeros(_N_SC)
        self.ev = np.zeros(2, np.int64)

    def run(self, dt: float, n_steps: int) -> None:
        """``n_steps`` steps of size ``dt`` (s) with the solver's held external forces.

        Raises
        ------
        RuntimeError
            ``dt`` exceeds the critical step, or a cell inverted (the Python loop's messages and state).
        """
        s, n = self.solver, self.name
        b = s.bodies[n]
        sc, acc = self.sc, s._acc
        sc[:] = (s.time, s.step_count, s._dt_prev, s._dt_crit, acc["plastic_J"], acc["viscous_J"],
                 acc["external_work_J"], acc["kinetic_damping_J"], acc["wall_dissipated_J"], s._ke_half[n],
                 1.0 if s.kinetic_damping else 0.0, 1.0 if s._fext_nonzero[n] else 0.0)
        self.ev[:] = 0
        run_tet10_steps(b.cells, b.x, b.v, b.a, b.mass, s._fext[n], b.cell_stress, b.eps_p, b.temperature,
                        s._prm[n], QP_DERIVATIVES, QP_WEIGHTS, self.factor, self.rho_scale, self.con_idx, self.con_val,
                        self.cidx, sc, self.f, self.acc, self.tmp, float(dt), int(n_steps), self.ev)
        s.time, s.step_count, s._dt_prev, s._dt_crit = float(sc[_T]), int(sc[_NSTEP]), float(sc[_DTP]), float(sc[_DTC])
        for key, i in (("plastic_J", _PL), ("viscous_J", _VI), ("external_work_J", _EXT),
                       ("kinetic_damping_J", _KD), ("wall_dissipated_J", _WALL)):
            acc[key] = float(sc[i])
        s._ke_half[n] = float(sc[_KEH])
        if self.ev[0] == EV_DT:
            raise RuntimeError(f"t={s.time:.6e} s: dt={dt:.4e} s exceeds the critical step "
                               f"{s._dt_crit:.4e} s of the deformed mesh")
        if self.ev[0] == EV_INVERTED:
            e = int(self.ev[1])
            raise RuntimeError(f"t={s.time:.6e} s: cell {e} of body {n!r} inverted "
                               f"(centroid {b.x[b.cells[e]].mean(axis=0)})")
