"""Explicit central-difference solver for 3D bodies on linear tetrahedra (issue 20, first slice).

The step, the energy ledger, restart, the rigid walls and the MPI ghost exchange are the 2D
solver's (:class:`~.solver.ExplicitSolver`, :class:`~.python_steps.PythonSteps`,
:mod:`.restart`): they work on (N, gdim) nodal arrays. What is 3D: the bodies
(:class:`~.body3d.Body3D`), the element kernels (:mod:`.tet_kernel`, :mod:`.tet_batch`) and the
contact passes: node to triangle face between bodies (:mod:`.contact3d`) and soft rigid planes
(:mod:`.soft_plane`); rigid walls are the 2D code's.
"""
from __future__ import annotations

import logging
from typing import Callable, Sequence

import numba
import numpy as np
from mpi4py import MPI

from .body import BodySpec
from .body3d import Body3D
from .contact import ContactPairSpec, ContactPenetrationError, RigidWallSpec
from .contact3d import soft_contact_pass_3d
from .kernels import pack_parameters
from .mass_scaling import scaled_body_mass, selective_scale
from .soft_plane import SoftPlaneSpec, soft_plane_forces
from .solver import ExplicitSolver
from .tet10 import QP_DERIVATIVES, QP_WEIGHTS, critical_step_factor
from .tet10_kernel import tet10_critical_dt, tet10_step
from .tet10_steps import Tet10Steps, steps_supported
from .tet_batch import TET_WORK_SIZE, batched_material, tet_step_batched
from .tet_kernel import MODE_SOLID, tet_chunk_size, tet_critical_dt, tet_step
from .tet_threads import TetThreadArrays, tet_step_threaded, tet_thread_arrays

__all__ = ["ExplicitSolver3D"]

log = logging.getLogger(__name__)

_NO_TEMP = np.empty(0)  # no temperature per cell (a material without a specific heat)


def _tet_kernel(cells, x, v, dt, prm, stress, eps_p, f_int, acc, work, temp=None):
    """The 3D element kernel of a body: the vectorised batches for a rate-independent material
    or a general one (a flow curve, a temperature per cell ``temp``, K: screened), else the scalar
    kernel (the linear law with a rate law); both give the same bits where both apply."""
    temp = _NO_TEMP if temp is None else temp  # an array always: one compiled variant of each kernel
    if batched_material(prm):
        return tet_step_batched(cells, x, v, dt, prm, stress, eps_p, f_int, acc, work, temp)
    return tet_step(cells, x, v, dt, prm, stress, eps_p, f_int, acc, work, temp)


class _ThreadedKernel:
    """The 3D element kernel of one body on ``threads`` threads (:mod:`.tet_threads`): the
    serial kernel's signature, the serial bits."""

    def __init__(self, arrays: TetThreadArrays, threads: int):
        self.arrays = arrays
        self.threads = threads

    def __call__(self, cells, x, v, dt, prm, stress, eps_p, f_int, acc, work=None, temp=None) -> float:
        numba.set_num_threads(self.threads)
        return tet_step_threaded(cells, x, v, dt, prm, stress, eps_p, f_int, acc, self.arrays, temp)


class _QuadraticKernel:
    """The element kernel of a ten-node body (:mod:`.tet10_kernel`, serial): the linear kernel's signature, with
    the body's critical-step factor (:func:`.tet10.critical_step_factor`) and its cells' density factors
    ``rho_scale`` (selective mass scaling, :mod:`.mass_scaling`; empty: none)."""

    def __init__(self, factor: float):
        self.factor = float(factor)
        self.rho_scale = np.empty(0)

    def __call__(self, cells, x, v, dt, prm, stress, eps_p, f_int, acc, work=None, temp=None) -> float:
        temp = _NO_TEMP if temp is None else temp
        return tet10_step(cells, x, v, dt, prm, stress, eps_p, f_int, acc, temp, QP_DERIVATIVES, QP_WEIGHTS,
                          self.factor, self.rho_scale)

    def critical_dt(self, cells, x, prm) -> float:
        """The cells' smallest critical step at rest (CFL 1), s; -1 if one is inverted."""
        return tet10_critical_dt(cells, x, prm, self.factor, self.rho_scale)


class ExplicitSolver3D(ExplicitSolver):
    """Explicit elastic-plastic dynamics of 3D bodies (P1 tetrahedra, or ten-node ones per body:
    ``BodySpec.element = "tet10"``, :mod:`.tet10_kernel`, serial) with rigid walls.

    Central differences with velocities at half steps, row-sum lumped mass, updated Lagrangian
    with a Jaumann (Hughes-Winget) objective stress update, J2 radial return with linear
    hardening and the optional rate laws of :class:`~.material.Material`, bulk viscosity, the
    stable step from the deformed mesh at every step. ``advance``, ``stable_time_step``,
    ``energies``, ``wall_pressure``, ``pressure_nodal_forces``, ``state_dict`` /
    ``load_state_dict`` and ``kinetic_damping`` are those of :class:`~.solver.ExplicitSolver`, with
    (N, 3) nodal arrays (forces in N, positions in m, velocities in m/s) and stresses
    [xx, yy, zz, xy, yz, xz] in Pa. The steps run in the Python step loop around the compiled
    element kernel (serial and MPI alike); the kernel may run on several threads (``threads``). A single
    ten-node body runs its steps in one compiled call (``compiled_steps``), with the same bits.

    Parameters
    ----------
    bodies : sequence of BodySpec
        The bodies (unique names), each on a 3D tetrahedral mesh.
    rigid_walls : sequence of RigidWallSpec
        Rigid half-space walls (3-component ``point`` and ``normal``).
    soft_planes : sequence of SoftPlaneSpec
        Rigid planes with the soft contact layer of eq. (5) (:mod:`.soft_plane`).
    contact_pairs : sequence of ContactPairSpec
        Soft contact between bodies, node to triangle face (:mod:`.contact3d`).
    cfl : float
        Safety factor on the critical time step (0 < cfl <= 1).
    bulk_viscosity : bool
        Linear + quadratic bulk viscosity on/off.
    bulk_linear, bulk_quadratic : float
        Its coefficients (defaults 0.06 and 1.2).
    comm : MPI communicator
        The communicator of every body's mesh.
    threads : int
        Threads of the element kernel (default 1; at most the cores numba sees): each body's cells
        in fixed chunks, a chunk per task (:mod:`.tet_threads`; a body of one chunk, at most
        :data:`.tet_kernel.TET_CHUNK` cells, runs on one). The results do not depend on it: they
        are the one-thread results bit for bit. Under MPI each rank uses that many.
    compiled_steps : bool
        Run the steps of :meth:`advance` of a single ten-node body in one compiled call (:mod:`.tet10_steps`: one
        process, constant prescribed velocities, no walls, soft planes, contact or sliding planes) instead of
        the Python step loop; both give the same bits. Default on; other solvers run the Python loop.
    mass_scaling_dt : float, optional
        Selective mass scaling of the ten-node bodies (:mod:`.mass_scaling`), for quasi-static runs (dynamic
        relaxation) only: every cell whose critical step (CFL 1, at rest, on the reference mesh) is below this
        target, s, has its density multiplied by (target / its step)^2, so that its step is the target; the mass
        added is logged and kept in :attr:`mass_scaling` (per body: cells scaled, kg added, fraction of the body's
        mass). The lumped mass, hence the ledger's kinetic energy, the critical step and the bulk viscosity use the
        scaled density. Default None: no scaling. Bodies of linear tetrahedra are refused (not done).
    """

    def __init__(self, bodies: Sequence[BodySpec], rigid_walls: Sequence[RigidWallSpec] = (),
                 soft_planes: Sequence[SoftPlaneSpec] = (),
                 contact_pairs: Sequence[ContactPairSpec] = (), cfl: float = 0.5,
                 bulk_viscosity: bool = True, bulk_linear: float = 0.06,
                 bulk_quadratic: float = 1.2, comm=MPI.COMM_WORLD, threads: int = 1,
                 compiled_steps: bool = True, mass_scaling_dt: float | None = None):
        if not 0 < cfl <= 1:
            raise ValueError(f"cfl must be in (0, 1], got {cfl}")
        if bulk_linear < 0 or bulk_quadratic < 0:
            raise ValueError("bulk viscosity coefficients must be >= 0")
        if not bodies:
            raise ValueError("need at least one body")
        if int(threads) != threads or not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
            raise ValueError(f"threads must be an integer from 1 to {numba.config.NUMBA_NUM_THREADS} "
                             f"(the cores numba sees), got {threads}")
        self.threads = int(threads)
        self.formulation = "3d"
        self.mode = MODE_SOLID
        self.cfl = float(cfl)
        self.comm = comm
        self._kernel = _tet_kernel
        self._work = np.zeros(TET_WORK_SIZE)
        self.bodies = {}
        for spec in bodies:
            if spec.name in self.bodies:
                raise ValueError(f"duplicate body name {spec.name!r}")
            if spec.mesh.comm.size != comm.size:
                raise ValueError("mesh communicator size differs from the solver's")
            self.bodies[spec.name] = Body3D(spec)
        self._prm = {n: pack_parameters(b.material, MODE_SOLID, 1.0, bulk_linear, bulk_quadratic,
                                        bulk_viscosity)
                     for n, b in self.bodies.items()}
        # a body of one chunk (tet_chunk_size) keeps the serial kernel: the same bits, no threads; a ten-node
        # body its serial kernel
        self._kernels: dict[str, Callable] = {
            n: _QuadraticKernel(critical_step_factor(b.cells, b.X0, b.material.shear_modulus,
                                                     b.material.bulk_modulus)) if b.element == "tet10"
            else _ThreadedKernel(tet_thread_arrays(b.cells, len(b.x)), self.threads)
            if self.threads > 1 and tet_chunk_size(len(b.cells)) < len(b.cells) else _tet_kernel
            for n, b in self.bodies.items()}
        self.mass_scaling: dict[str, dict[str, float]] = {}
        if mass_scaling_dt is not None:
            self._scale_masses(float(mass_scaling_dt))
        self._cidx = {n: np.flatnonzero(b.constrained_mask().ravel())
                      for n, b in self.bodies.items()}
        self.contact_pairs = tuple(contact_pairs)
        for cp in self.contact_pairs:
            for nm in (cp.slave, cp.master):
                if nm not in self.bodies:
                    raise ValueError(f"contact pair names unknown body {nm!r}")
        self.rigid_walls = tuple(rigid_walls)
        for w in self.rigid_walls:
            if np.asarray(w.point).shape != (3,) or np.asarray(w.normal).shape != (3,):
                raise ValueError("a 3D rigid wall needs a 3-component point and normal")
            w.unit_normal()
            for nm in (w.bodies or ()):
                if nm not in self.bodies:
                    raise ValueError(f"rigid wall names unknown body {nm!r}")
        self.soft_planes = tuple(soft_planes)
        for sp in self.soft_planes:
            if not isinstance(sp, SoftPlaneSpec):
                raise TypeError("soft_planes takes SoftPlaneSpec entries")
            for nm in (sp.bodies or ()):
                if nm not in self.bodies:
                    raise ValueError(f"soft plane names unknown body {nm!r}")
        self._soft_out = [dict() for _ in self.soft_planes]
        self._init_run_state()
        # contact forces of the previous step per body, on local rows (trapezoidal work; restart)
        self._fsurf_prev = ({n: np.zeros_like(b.x) for n, b in self.bodies.items()}
                            if self.soft_planes or self.contact_pairs else {})
        self._init_start()
        self._block = None
        why = steps_supported(self) if compiled_steps else "compiled_steps=False"
        self._steps = None if why else Tet10Steps(self)
        if compiled_steps and why and any(b.element == "tet10" for b in self.bodies.values()):
            log.info("ExplicitSolver3D: ten-node steps in the Python step loop (%s)", why)
        log.info("ExplicitSolver3D: %d bodies, %d cells, %d walls, %d soft planes, %d contact "
                 "pairs, %d thread(s), stable dt %.4g s",
                 len(self.bodies), self.comm.allreduce(sum(len(b.cells) for b in self.bodies.values())),
                 len(self.rigid_walls), len(self.soft_planes), len(self.contact_pairs),
                 self.threads, self.stable_time_step())

    _element_dt = staticmethod(tet_critical_dt)

    def _scale_masses(self, target_dt: float) -> None:
        """Selective mass scaling of every ten-node body to the critical step ``target_dt`` (s,
        :mod:`.mass_scaling`): the density factors into its kernel, the scaled HRZ mass into the body."""
        linear = [n for n, b in self.bodies.items() if b.element != "tet10"]
        if linear:
            raise ValueError(f"mass_scaling_dt: bodies {linear} of linear tetrahedra (selective mass scaling is "
                             "done for ten-node bodies only)")
        for n, b in self.bodies.items():
            k = self._kernels[n]
            scale = selective_scale(b.cells, b.X0, self._prm[n], k.factor, target_dt)
            added, frac = 0.0, 0.0
            if np.any(scale > 1.0):
                k.rho_scale = scale
                b.mass, added, frac = scaled_body_mass(n, b.cells, b.X0, b.material.density, scale, b.n_local)
            self.mass_scaling[n] = {"cells": int(np.count_nonzero(scale > 1.0)), "added_kg": added,
                                    "added_fraction": frac}

    def _body_dt(self, name: str) -> float:
        """The smallest critical step of body ``name``'s cells at rest (CFL 1), s; -1 if one is inverted."""
        b = self.bodies[name]
        k = self._kernels[name]
        if isinstance(k, _QuadraticKernel):
            return k.critical_dt(b.cells, b.x, self._prm[name])
        return self._element_dt(b.cells, b.x, self._prm[name])

    def _body_kernel(self, name: str) -> Callable:
        """The element kernel of body ``name``: the serial one, or on ``threads`` threads."""
        return self._kernels[name]

    def stable_time_step(self) -> float:
        """Stable step of the current configuration: cfl x smallest element critical step, s.

        The critical step of a tetrahedron is its smallest altitude (3 V / largest face area) over
        the dilatational wave speed, reduced for bulk viscosity as sqrt(1 + xi^2) - xi; it is
        refreshed by every step from the deformed mesh.
        """
        return self.cfl * self._dt_crit

    def _contact(self, ftot, dt: float) -> None:
        """Soft contact, eq. (5): pairs of bodies (global surfaces on every rank, as in 2D) and
        soft planes (owned and ghost rows alike, from completed areas, so that ghosts move with
        their owners); the work of all contact forces by the trapezoidal rule and the stored layer
        energy feed the ledger as in 2D."""
        if not (self.soft_planes or self.contact_pairs):
            return
        stored = 0.0
        work = 0.0
        fcs = {n: np.zeros_like(b.x) for n, b in self.bodies.items()}
        stored_pairs, bad = self._pair_forces(fcs, dt)
        for n, b in self.bodies.items():
            fc = fcs[n]
            for i, sp in enumerate(self.soft_planes):
                if sp.bodies is not None and n not in sp.bodies:
                    continue
                area = b.wall_tributary_areas(b.x, sp.unit_normal())
                area = b.complete_nodal(np.repeat(area[:, None], 3, axis=1))[:, 0]
                rows, h, p, force, e = soft_plane_forces(sp, b.x, area)
                if np.any(h <= 0.0) and bad is None:
                    j = rows[np.argmin(h)]
                    bad = (f"t={self.time:.6e} s: node {int(b.global_ids[j])} of body {n!r} at "
                           f"({b.x[j, 0]:.6g}, {b.x[j, 1]:.6g}, {b.x[j, 2]:.6g}) m reached "
                           f"h={h.min():.3e} m <= 0 against soft plane {i}")
                fc[rows] += force
                own = rows < b.n_owned
                stored += float(np.sum(e[own]))
                self._soft_out[i][n] = (rows, p)
            ftot[n] += fc
            no = b.n_owned
            if dt > 0:
                work += dt * float(np.sum(b.v[:no] * 0.5 * (self._fsurf_prev[n][:no] + fc[:no])))
            self._fsurf_prev[n][...] = fc
        if self.comm.allreduce(bad is not None, op=MPI.LOR):
            raise ContactPenetrationError(bad or "penetration of a soft plane on another rank")
        self._contact_work += self._sum(work)
        self._contact_stored = self._sum(stored) + stored_pairs

    def _pair_forces(self, fcs, dt: float):
        """Node-to-face contact of every pair on the gathered (global) surfaces, added to the
        local rows of ``fcs``; returns (stored layer energy J, penetration message or None)."""
        if not self.contact_pairs:
            return 0.0, None
        data = {}
        fsurf = {}
        for n, sf in self._surf.items():
            data[n] = (sf.gather(self.bodies[n].x), sf.gather(self.bodies[n].v))
            fsurf[n] = np.zeros_like(data[n][0])
        stored = 0.0
        for ip, cp in enumerate(self.contact_pairs):
            passes = [(cp.slave, cp.master)] + ([(cp.master, cp.slave)] if cp.two_pass else [])
            wgt = 0.5 if cp.two_pass else 1.0
            for k, (sn, mn) in enumerate(passes):
                (Xs, Vs), (Xm, Vm) = data[sn], data[mn]
                ss, ms = self._surf[sn], self._surf[mn]
                res = soft_contact_pass_3d(Xs, Vs, ss.seg, Xm, Vm, ms.seg, cp, wgt, Ms=ss.M,
                                           Mm=ms.M, dt=dt, previous=self._active.get((ip, k)),
                                           tri_key=ms.seg_key)
                if res.penetration is not None:
                    i, h = res.penetration
                    return 0.0, (f"t={self.time:.6e} s: node {int(ss.gids[i])} of body {sn!r} at "
                                 f"({Xs[i, 0]:.6g}, {Xs[i, 1]:.6g}, {Xs[i, 2]:.6g}) m reached "
                                 f"h={h:.3e} m <= 0 against body {mn!r} (contact pair {ip})")
                self._active[(ip, k)] = res.active
                fsurf[sn] += res.F_slave
                fsurf[mn] += res.F_master
                stored += res.stored
                if k == 0:
                    self._contact_out[ip] = (res.pressure, res.gap, Xs)
        for n, sf in self._surf.items():
            sf.scatter_add(fsurf[n], fcs[n])
        return stored, None

    def soft_plane_pressure(self, plane_index: int, body: str):
        """Contact stress of eq. (5) on the body's nodes inside the layer of a soft plane at the
        current time: (local node rows, reference coords (M, 3), pressure Pa) on this rank (a ten-node
        body: at every node of its loaded faces, :meth:`~.body3d.Body3D.contact_pressures`)."""
        rows, p = self._soft_out[plane_index].get(body, (np.zeros(0, int), np.zeros(0)))
        b = self.bodies[body]
        rows, p = b.contact_pressures(rows, p, b.x)
        return rows, b.X0[rows], p

