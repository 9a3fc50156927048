"""Explicit central-difference solver: updated Lagrangian, lumped mass, soft contact, rigid walls."""
from __future__ import annotations

import logging
from typing import Dict, Mapping, Optional, Sequence

import numba
import numpy as np
from mpi4py import MPI

from .body import QUADRATIC, Body, BodySpec
from .contact import ContactPairSpec, ContactPenetrationError, RigidWallSpec, Surface
from .kernels import (MODE_AXISYMMETRIC, MODE_PLANE_STRAIN, MODE_PLANE_STRESS,
                      WORK_SIZE, element_critical_dt, element_step, pack_parameters)
from . import restart
from .cell_fields import kinetic_sum
from .block import EV_DT, EV_INVERTED, run_steps
from .kernel_threads import run_steps_threaded
from .block_data import BlockData, block_supported
from .python_steps import PythonSteps
from .reference_kernel import element_step_numpy
from .tri6 import critical_step_factor as tri6_step_factor
from .tri6_kernel import Tri6Kernel

__all__ = ["ExplicitSolver"]

log = logging.getLogger(__name__)

_MODES = {"plane_stress": MODE_PLANE_STRESS, "plane_strain": MODE_PLANE_STRAIN,
          "axisymmetric": MODE_AXISYMMETRIC}
_ACC_KEYS = restart._ACC_KEYS


class ExplicitSolver(PythonSteps):
    """Explicit elastic-plastic dynamics of several 2D bodies with soft contact (paper eq. 4-5).

    Central differences with velocities at half steps, row-sum lumped mass, updated Lagrangian with
    a Jaumann (Hughes-Winget) objective stress update, J2 radial return, bulk viscosity.

    Parameters
    ----------
    bodies : sequence of BodySpec
        The bodies (unique names).
    formulation : {"plane_stress", "plane_strain", "axisymmetric"}
        2D model; axisymmetric uses x = r, y = z, and nodes on r = 0 get u_r = 0.
    contact_pairs : sequence of ContactPairSpec
        Soft-contact pairs.
    rigid_walls : sequence of RigidWallSpec
        Rigid half-space walls.
    cfl : float
        Safety factor on the critical time step (0 < cfl <= 1).
    bulk_viscosity : bool
        Linear + quadratic bulk viscosity on/off.
    bulk_linear, bulk_quadratic : float
        Its coefficients (defaults 0.06 and 1.2).
    thickness : float
        Out-of-plane thickness for planar formulations, m.
    comm : MPI communicator
        Must be the communicator of every body's mesh.
    kernel : {"numba", "numpy"}
        Element kernel: the compiled one, or the vectorised-numpy reference.
    compiled_steps : bool
        Run the steps of :meth:`advance` in the compiled block path (:mod:`.block`; serial runs
        with constant prescribed velocities and the numba kernel) instead of the Python step
        loop. Both give the same bits; the Python loop is kept for MPI and as the reference.
    threads : int
        Threads of the compiled explicit steps (block path only; default 1). The results do not
        depend on it (:mod:`.kernel_threads`); at most the cores numba sees.

    Attributes
    ----------
    kinetic_damping : bool
        Kinetic damping (dynamic relaxation) on/off, default off; may be switched between steps.
        When on, a body's velocities are set to zero at each peak of its kinetic energy; the
        removed energy is ``energies()["kinetic_damping_J"]``.
    """

    def __init__(self, bodies: Sequence[BodySpec], formulation: str = "plane_stress",
                 contact_pairs: Sequence[ContactPairSpec] = (),
                 rigid_walls: Sequence[RigidWallSpec] = (), cfl: float = 0.5,
                 bulk_viscosity: bool = True, bulk_linear: float = 0.06,
                 bulk_quadratic: float = 1.2, thickness: float = 1.0, comm=MPI.COMM_WORLD,
                 kernel: str = "numba", compiled_steps: bool = True, threads: int = 1):
        if formulation not in _MODES:
            raise ValueError(f"formulation must be one of {sorted(_MODES)}, got {formulation!r}")
        if not 0 < cfl <= 1:
            raise ValueError(f"cfl must be in (0, 1], got {cfl}")
        if not thickness > 0:
            raise ValueError("thickness must be > 0")
        if bulk_linear < 0 or bulk_quadratic < 0:
            raise ValueError("bulk viscosity coefficients must be >= 0")
        if kernel not in ("numba", "numpy"):
            raise ValueError("kernel must be 'numba' or 'numpy'")
        if not bodies:
            raise ValueError("need at least one body")
        if int(threads) != threads or not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
            raise ValueError(f"threads must be an integer from 1 to {numba.config.NUMBA_NUM_THREADS} "
                             f"(the cores numba sees), got {threads}")
        self.threads = int(threads)
        self.formulation = formulation
        self.mode = _MODES[formulation]
        self.cfl = float(cfl)
        self.comm = comm
        self._kernel = element_step if kernel == "numba" else element_step_numpy
        self._work = np.zeros(WORK_SIZE)  # the element kernel's scratch
        axi = self.mode == MODE_AXISYMMETRIC
        self.bodies: Dict[str, Body] = {}
        for spec in bodies:
            if spec.name in self.bodies:
                raise ValueError(f"duplicate body name {spec.name!r}")
            if spec.mesh.comm.size != comm.size:
                raise ValueError("mesh communicator size differs from the solver's")
            self.bodies[spec.name] = Body(spec, axi, thickness)
        self._prm = {n: pack_parameters(b.material, self.mode, thickness, bulk_linear,
                                        bulk_quadratic, bulk_viscosity)
                     for n, b in self.bodies.items()}
        # six-node bodies: their own kernel (serial, the Python step loop), with their critical-step factor
        self._kernels = {n: Tri6Kernel(tri6_step_factor(b.cells, b.X0, b.material.shear_modulus,
                                                        b.material.bulk_modulus))
                         for n, b in self.bodies.items() if b.element == "tri6"}
        # flat indices of the constrained velocity components (a = 0 there)
        self._cidx = {n: np.flatnonzero(b.constrained_mask().ravel())
                      for n, b in self.bodies.items()}
        self.contact_pairs = tuple(contact_pairs)
        self.rigid_walls = tuple(rigid_walls)
        for cp in self.contact_pairs:
            for nm in (cp.slave, cp.master):
                if nm not in self.bodies:
                    raise ValueError(f"contact pair names unknown body {nm!r}")
        for w in self.rigid_walls:
            w.unit_normal()
            for nm in (w.bodies or ()):
                if nm not in self.bodies:
                    raise ValueError(f"rigid wall names unknown body {nm!r}")
        self._init_run_state()
        self._fsurf_prev = {n: np.zeros((len(sf.gids), 2)) for n, sf in self._surf.items()}
        self._init_start()
        why = block_supported(self) if kernel == "numba" else "the numpy kernel"
        if self.threads > 1 and (why or not compiled_steps):
            raise ValueError(f"threads = {self.threads} needs the compiled block path, not available here "
                             f"({why or 'compiled_steps=False'})")
        if compiled_steps and not why:
            self._block = BlockData(self)
        else:
            self._block = None
            if compiled_steps:
                log.info("ExplicitSolver: Python step loop (%s)", why)
        log.info("ExplicitSolver: %s, %d bodies, %d contact pairs, %d walls, stable dt %.4g s",
                 formulation, len(self.bodies), len(self.contact_pairs), len(self.rigid_walls),
                 self.stable_time_step())

    def _init_run_state(self) -> None:
        """The run's state before its first step (2D and 3D): contact surfaces, the walls' tolerance (m),
        time, counters, energy accumulators, external forces, kinetic damping off."""
        names = {cp.slave for cp in self.contact_pairs} | {cp.master for cp in self.contact_pairs}
        self._surf = {n: Surface(self.bodies[n]) for n in sorted(names)}
        ext = max(float(np.abs(b.X0).max()) if b.X0.size else 0.0 for b in self.bodies.values())
        self._wall_tol = 1e-12 * max(self.comm.allreduce(ext, op=MPI.MAX), 1e-300)
        self.time = 0.0
        self.step_count = 0
        self._dt_prev = 0.0
        self._acc = {k: 0.0 for k in _ACC_KEYS}
        self._contact_stored = 0.0
        self._fext = {n: np.zeros_like(b.x) for n, b in self.bodies.items()}
        self._fext_nonzero = {n: False for n in self.bodies}
        self.kinetic_damping = False
        self._ke_half = {n: 0.0 for n in self.bodies}
        self._contact_out = [None] * len(self.contact_pairs)

    def _init_start(self) -> None:
        """The critical step and the forces and stored energy at t = 0 (initial stress, contact layers),
        without changing the state (2D and 3D)."""
        self._contact_work = 0.0
        self._active = {}
        self._wall_out = [dict() for _ in self.rigid_walls]
        self._dt_crit = self._initial_dt_crit()
        self._compute_forces(0.0, update_state=False)
        self._wall_pressures()
        self._E0 = self._stored_energy()
        self._contact_stored0 = self._contact_stored

    # ------------------------------------------------------------------ time step
    #: the compiled critical time step of one body's cells (s): triangles here, tetrahedra in 3D
    _element_dt = staticmethod(element_critical_dt)

    def _body_dt(self, name: str) -> float:
        """The smallest critical step of body ``name``'s cells at rest (CFL 1), s; -1 if one is inverted."""
        b = self.bodies[name]
        if name in self._kernels:
            return self._kernels[name].critical_dt(b.cells, b.x, self._prm[name])
        return self._element_dt(b.cells, b.x, self._prm[name])

    def _body_kernel(self, name: str):
        """The element kernel of body ``name``: the solver's, or a six-node body's own (:mod:`.tri6_kernel`)."""
        return self._kernels.get(name, self._kernel)

    def _initial_dt_crit(self) -> float:
        dmin = np.inf
        for n in self.bodies:
            d = self._body_dt(n)
            if d < 0:
                raise ValueError(f"body {n!r}: inverted cell in the initial mesh")
            dmin = min(dmin, d)
        return self.comm.allreduce(dmin, op=MPI.MIN)

    def stable_time_step(self) -> float:
        """Stable step of the current configuration: cfl x smallest element critical step, s.

        The critical step of a triangle is (2 area / longest edge) / c_d, reduced for bulk
        viscosity as sqrt(1 + xi^2) - xi; it is refreshed by every step as the mesh deforms.
        """
        return self.cfl * self._dt_crit

    # ------------------------------------------------------------------ stepping
    def advance(self, dt: float, n_steps: int = 1,
                external_forces: Optional[Mapping[str, np.ndarray]] = None) -> None:
        """Advance ``n_steps`` explicit steps of size ``dt``.

        Parameters
        ----------
        dt : float
            Time step, s. Must not exceed the critical step (CFL 1) of the current mesh.
        n_steps : int
            Number of steps.
        external_forces : dict, optional
            Body name -> nodal forces (n_local_nodes, 2) ((n_local_nodes, 3) for 3D bodies), N
            (planar: for the solver's thickness; axisymmetric: total over the 2 pi ring), held
            constant over the steps. Each row is the complete force on that node; rows of ghost
            nodes (MPI) are ignored.

        Raises
        ------
        ContactPenetrationError
            A contact node reached h <= 0.
        RuntimeError
            ``dt`` exceeds the critical step, or a cell inverted.
        """
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number, got {dt!r}")
        if int(n_steps) != n_steps or n_steps < 1:
            raise ValueError(f"n_steps must be a positive integer, got {n_steps!r}")
        fext = {}
        for n, b in self.bodies.items():
            f = np.zeros_like(b.x)
            if external_forces is not None and n in external_forces:
                arr = np.asarray(external_forces[n], dtype=float)
                if arr.shape != b.x.shape:
                    raise ValueError(f"external_forces[{n!r}] must have shape {b.x.shape}")
                f[: b.n_owned] = arr[: b.n_owned]
            fext[n] = f
        if external_forces is not None:
            unknown = set(external_forces) - set(self.bodies)
            if unknown:
                raise ValueError(f"external_forces for unknown bodies {sorted(unknown)}")
        # the forces act from the current time on: a^n must already include them. The estimate
        # v^n = v^{n-1/2} + dt/2 a^n then changes; its kinetic energy change is work of the switch.
        for n, b in self.bodies.items():
            delta = fext[n] - self._fext[n]
            if self.comm.allreduce(bool(np.any(delta)), op=MPI.LOR):
                delta = b.complete_nodal(delta)
                no = b.n_owned
                ke_old = np.sum(b.mass[:no, None] * (b.v[:no] + 0.5 * self._dt_prev * b.a[:no]) ** 2)
                b.a += delta / b.mass[:, None]
                b.a.ravel()[self._cidx[n]] = 0.0
                b.project_sliding(b.a)
                ke_new = np.sum(b.mass[:no, None] * (b.v[:no] + 0.5 * self._dt_prev * b.a[:no]) ** 2)
                self._acc["external_work_J"] += self._sum(0.5 * (ke_new - ke_old))
            self._fext[n][...] = fext[n]
            self._fext_nonzero[n] = bool(np.any(fext[n]))
        if self._block is not None:
            self._run_block(dt, int(n_steps))
            return
        if self._steps is not None:
            self._steps.run(dt, int(n_steps))
            return
        done = False
        try:
            for _ in range(int(n_steps)):
                self._step(dt, self._fext)
            done = True
        finally:
            if done or self.comm.size == 1:  # a collective under MPI (ghost exchange of areas)
                self._wall_pressures()

    #: the compiled steps of a 3D solver's ten-node body (:class:`~.tet10_steps.Tet10Steps`), or None
    _steps = None

    @property
    def compiled(self):
        """The compiled block path's arrays (:class:`~.block_data.BlockData`), or None when the
        Python step loop runs (MPI, callables in constraints, numpy kernel)."""
        return self._block

    def _run_block(self, dt: float, n_steps: int) -> None:
        """``n_steps`` steps of size ``dt`` in the compiled path; raises its events."""
        bd = self._block
        bd.load()
        if bd.threaded is None:
            run_steps(bd.B, bd.W, bd.C, bd.sc, dt, n_steps, bd.ev, bd.evf)
        else:
            numba.set_num_threads(self.threads)
            run_steps_threaded(bd.B, bd.W, bd.C, bd.sc, dt, n_steps, bd.ev, bd.evf, bd.threaded)
        bd.store()
        self.raise_event(dt)

    def raise_event(self, dt: float) -> None:
        """Raise what the compiled path reported in its event array (nothing if none)."""
        bd = self._block
        code = int(bd.ev[0])
        if code == 0:
            return
        if code == EV_DT:
            raise RuntimeError(f"t={self.time:.6e} s: dt={dt:.4e} s exceeds the critical step "
                               f"{self._dt_crit:.4e} s of the deformed mesh")
        if code == EV_INVERTED:
            n = bd.names[int(bd.ev[1])]
            b, e = self.bodies[n], int(bd.ev[2])
            raise RuntimeError(f"t={self.time:.6e} s: cell {e} of body {n!r} inverted "
                               f"(centroid {b.x[b.cells[e]].mean(axis=0)})")
        ip, _, si, mi, _, _ = bd.passes[int(bd.ev[1])]
        sn, mn = bd.surf_names[si], bd.surf_names[mi]
        i, h = int(bd.ev[2]), float(bd.evf[0])
        xs = self.bodies[sn].x[bd.C.rows[bd.C.node_off[si] + i] - bd.node_off[bd.names.index(sn)]]
        raise ContactPenetrationError(
            f"t={self.time:.6e} s: node {int(self._surf[sn].gids[i])} of body {sn!r} "
            f"at ({xs[0]:.6g}, {xs[1]:.6g}) m reached h={h:.3e} m <= 0 against "
            f"body {mn!r} (contact pair {ip})")

    def contact_pressure(self, pair_index: int):
        """Contact state of a pair's slave surface at the current time.

        Returns
        -------
        gids : (M,) int array
            Global node ids of the slave surface nodes in contact (h < h0).
        coords : (M, 2) array
            Their current positions, m.
        pressure : (M,) array
            Normal contact stress k (1/h - 1/h0) plus the viscous term, Pa.
        gap : (M,) array
            Distance h to the master surface, m (a ten-node slave: NaN at the nodes of its loaded faces that are
            outside the layer, which read the face's pressure field).
        """
        out = self._contact_out[pair_index]
        s = self._surf[self.contact_pairs[pair_index].slave]
        if out is None:
            return np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros(0), np.zeros(0)
        _, h, X = out
        p = self._slave_pressures(pair_index)
        m = np.isfinite(p)
        return s.gids[m], X[m], p[m], h[m]

    def contact_pressure_at(self, pair_index: int, point) -> float:
        """Contact stress (Pa, 0 if out of contact) at the slave surface node nearest ``point``
        in the *reference* configuration."""
        cp = self.contact_pairs[pair_index]
        s = self._surf[cp.slave]
        i = int(np.argmin(np.linalg.norm(s.X0 - np.asarray(point, float), axis=1)))
        p = self._slave_pressures(pair_index)
        if p is None or not np.isfinite(p[i]):
            return 0.0
        return float(p[i])

    def _slave_pressures(self, pair_index: int):
        """The contact stress (Pa) of every slave surface node of a pair (NaN out of contact), or None before
        the pair's first evaluation; a quadratic slave (serial: its rows are its global ids) reads them on its
        boundary faces (:meth:`~.body.Body.contact_pressures`), NaN off its loaded faces."""
        out = self._contact_out[pair_index]
        p = None if out is None else out[0]
        b = self.bodies[self.contact_pairs[pair_index].slave]
        if p is None or b.element not in QUADRATIC:
            return p
        s = self._surf[b.name]
        inside = np.flatnonzero(np.isfinite(p))
        nodes, pr = b.contact_pressures(s.gids[inside], p[inside], b.x)
        out = np.full_like(p, np.nan)
        out[np.searchsorted(s.gids, nodes)] = pr
        return out

    def wall_pressure(self, wall_index: int, body: str):
        """Wall reaction per unit area on the body's nodes pressed on the wall at the current time.

        Returns (local node rows, reference coords (M, 2), pressure Pa) on this rank.
        """
        hit, p = self._wall_out[wall_index].get("p", {}).get(body, (np.zeros(0, int), np.zeros(0)))
        return hit, self.bodies[body].X0[hit], p

    def _stored_energy(self) -> float:
        return self._kinetic() + self._elastic() + self._contact_stored

    def _kinetic(self) -> float:
        ke = 0.0
        for b in self.bodies.values():
            no = b.n_owned
            ke += 0.5 * float(kinetic_sum(b.mass, b.v, b.a, 0.5 * self._dt_prev, no, np.empty(no)))
        return self._sum(ke)

    def _elastic(self) -> float:
        return self._sum(sum(b.elastic_energy() for b in self.bodies.values()))

    def energies(self) -> Dict[str, float]:
        """Energy ledger, J: kinetic_J, elastic_J, plastic_J, contact_stored_J,
        contact_dissipated_J, viscous_J, wall_dissipated_J, kinetic_damping_J (removed by kinetic
        damping), external_work_J, balance_error_J
        (= all stored + dissipated - external work - initial stored energy)."""
        e = {"kinetic_J": self._kinetic(), "elastic_J": self._elastic(),
             "contact_stored_J": self._contact_stored}
        e.update(self._acc)
        e["contact_dissipated_J"] = (-self._contact_work
                                     - (self._contact_stored - self._contact_stored0))
        e["balance_error_J"] = (e["kinetic_J"] + e["elastic_J"] + e["contact_stored_J"]
                                + e["plastic_J"] + e["viscous_J"] + e["contact_dissipated_J"]
                                + e["wall_dissipated_J"] + e["kinetic_damping_J"] - e["external_work_J"]
                                - self._E0)
        return e

    def add_heat(self, body: str, energy_density: np.ndarray) -> None:
        """Heat the cells of ``body`` adiabatically by ``energy_density`` (J/m^3 per cell of this rank,
        e.g. the Joule heat of an EM step): T += e / (rho c_p). A body without a temperature
        (``Material.specific_heat`` unset) is left as it is.

        Parameters
        ----------
        body : str
            Body name.
        energy_density : (n_cells,) array
            Heat per unit volume, J/m^3 (>= 0 for Joule heat).
        """
        b = self.bodies[body]
        if not b.material.thermal:
            return
        e = np.asarray(energy_density, dtype=float)
        if e.shape != b.temperature.shape:
            raise ValueError(f"energy_density for {body!r} must have shape {b.temperature.shape}, got {e.shape}")
        b.temperature += e / (b.material.density * b.material.specific_heat)

    @property
    def initial_energy(self) -> float:
        """Stored energy (kinetic + elastic + contact layer) at t = 0, J."""
        return self._E0

    def pressure_nodal_forces(self, body: str, facet_marker, pressure: float) -> np.ndarray:
        """Consistent nodal forces of a uniform follower pressure on boundary facets.

        Parameters
        ----------
        body : str
            Body name.
        facet_marker : callable
            ``marker(x) -> bool array`` over coordinates (3, N) in the *current* configuration;
            a facet is loaded when both its vertices are marked.
        pressure : float
            Pressure, Pa (positive pushes into the body).

        Returns
        -------
        (n_local_nodes, 2) array ((n_local_nodes, 3) for 3D bodies)
            Nodal forces, N (planar: times thickness; axisymmetric: the full 2 pi ring); every row
            (ghosts too) holds the complete force of its node.
        """
        return self.bodies[body].pressure_forces(facet_marker, pressure)

    # ------------------------------------------------------------------ restart
    def state_dict(self) -> Dict[str, np.ndarray]:
        """Complete solver state as arrays (exact restart with :meth:`load_state_dict`)."""
        return restart.state_dict(self)

    def load_state_dict(self, d: Mapping[str, np.ndarray]) -> None:
        """Restore a state written by :meth:`state_dict` (same meshes and partitioning); the
        continuation is bitwise identical to an uninterrupted run."""
        restart.load_state_dict(self, d)
