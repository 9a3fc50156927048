"""Explicit central-difference solver for 3D bodies on linear tetrahedra (issue 20, first slice).

The step, the energy ledger, restart, the rigid walls and the MPI ghost exchange are the 2D
solver's (:class:`~.solver.ExplicitSolver`, :class:`~.python_steps.PythonSteps`,
:mod:`.restart`): they work on (N, gdim) nodal arrays. What is 3D: the bodies
(:class:`~.body3d.Body3D`) and the element kernel (:func:`.tet_kernel.tet_step`). Soft contact
between bodies is not available in 3D yet (rigid walls are).
"""
from __future__ import annotations

import logging
from typing import Sequence

import numpy as np
from mpi4py import MPI

from . import restart
from .body import BodySpec
from .body3d import Body3D
from .contact import RigidWallSpec
from .kernels import pack_parameters
from .solver import ExplicitSolver
from .tet_kernel import MODE_SOLID, tet_critical_dt, tet_step

__all__ = ["ExplicitSolver3D"]

log = logging.getLogger(__name__)


class ExplicitSolver3D(ExplicitSolver):
    """Explicit elastic-plastic dynamics of 3D bodies (P1 tetrahedra) with rigid walls.

    Central differences with velocities at half steps, row-sum lumped mass, updated Lagrangian
    with a Jaumann (Hughes-Winget) objective stress update, J2 radial return with linear
    hardening and the optional rate laws of :class:`~.material.Material`, bulk viscosity, the
    stable step from the deformed mesh at every step. ``advance``, ``stable_time_step``,
    ``energies``, ``wall_pressure``, ``pressure_nodal_forces``, ``state_dict`` /
    ``load_state_dict`` and ``kinetic_damping`` are those of :class:`~.solver.ExplicitSolver`, with
    (N, 3) nodal arrays (forces in N, positions in m, velocities in m/s) and stresses
    [xx, yy, zz, xy, yz, xz] in Pa. The steps run in the Python step loop around the compiled
    element kernel (serial and MPI alike).

    Parameters
    ----------
    bodies : sequence of BodySpec
        The bodies (unique names), each on a 3D tetrahedral mesh.
    rigid_walls : sequence of RigidWallSpec
        Rigid half-space walls (3-component ``point`` and ``normal``).
    cfl : float
        Safety factor on the critical time step (0 < cfl <= 1).
    bulk_viscosity : bool
        Linear + quadratic bulk viscosity on/off.
    bulk_linear, bulk_quadratic : float
        Its coefficients (defaults 0.06 and 1.2).
    comm : MPI communicator
        The communicator of every body's mesh.
    """

    def __init__(self, bodies: Sequence[BodySpec], rigid_walls: Sequence[RigidWallSpec] = (),
                 cfl: float = 0.5, bulk_viscosity: bool = True, bulk_linear: float = 0.06,
                 bulk_quadratic: float = 1.2, comm=MPI.COMM_WORLD):
        if not 0 < cfl <= 1:
            raise ValueError(f"cfl must be in (0, 1], got {cfl}")
        if bulk_linear < 0 or bulk_quadratic < 0:
            raise ValueError("bulk viscosity coefficients must be >= 0")
        if not bodies:
            raise ValueError("need at least one body")
        self.threads = 1
        self.formulation = "3d"
        self.mode = MODE_SOLID
        self.cfl = float(cfl)
        self.comm = comm
        self._kernel = tet_step
        self._work = np.zeros(0)
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
        self._cidx = {n: np.flatnonzero(b.constrained_mask().ravel())
                      for n, b in self.bodies.items()}
        self.contact_pairs = ()
        self.rigid_walls = tuple(rigid_walls)
        for w in self.rigid_walls:
            if np.asarray(w.point).shape != (3,) or np.asarray(w.normal).shape != (3,):
                raise ValueError("a 3D rigid wall needs a 3-component point and normal")
            w.unit_normal()
            for nm in (w.bodies or ()):
                if nm not in self.bodies:
                    raise ValueError(f"rigid wall names unknown body {nm!r}")
        self._surf = {}
        ext = max(float(np.abs(b.X0).max()) if b.X0.size else 0.0 for b in self.bodies.values())
        self._wall_tol = 1e-12 * max(self.comm.allreduce(ext, op=MPI.MAX), 1e-300)
        self.time = 0.0
        self.step_count = 0
        self._dt_prev = 0.0
        self._acc = {k: 0.0 for k in restart._ACC_KEYS}
        self._contact_stored = 0.0
        self._fext = {n: np.zeros_like(b.x) for n, b in self.bodies.items()}
        self._fext_nonzero = {n: False for n in self.bodies}
        self.kinetic_damping = False
        self._ke_half = {n: 0.0 for n in self.bodies}
        self._contact_out = []
        self._fsurf_prev = {}
        self._contact_work = 0.0
        self._active = {}
        self._wall_out = [dict() for _ in self.rigid_walls]
        self._dt_crit = self._initial_dt_crit()
        self._compute_forces(0.0, update_state=False)
        self._E0 = self._stored_energy()
        self._contact_stored0 = self._contact_stored
        self._block = None
        log.info("ExplicitSolver3D: %d bodies, %d cells, %d walls, stable dt %.4g s",
                 len(self.bodies), self.comm.allreduce(sum(len(b.cells) for b in self.bodies.values())),
                 len(self.rigid_walls), self.stable_time_step())

    def _initial_dt_crit(self) -> float:
        dmin = np.inf
        for n, b in self.bodies.items():
            d = tet_critical_dt(b.cells, b.x, self._prm[n])
            if d < 0:
                raise ValueError(f"body {n!r}: inverted cell in the initial mesh")
            dmin = min(dmin, d)
        return self.comm.allreduce(dmin, op=MPI.MIN)

    def stable_time_step(self) -> float:
        """Stable step of the current configuration: cfl x smallest element critical step, s.

        The critical step of a tetrahedron is its smallest altitude (3 V / largest face area) over
        the dilatational wave speed, reduced for bulk viscosity as sqrt(1 + xi^2) - xi; it is
        refreshed by every step from the deformed mesh.
        """
        return self.cfl * self._dt_crit

    def contact_pressure(self, pair_index: int):
        """Not available: no soft contact between 3D bodies yet."""
        raise NotImplementedError("soft contact between 3D bodies is not implemented (rigid walls are)")

    contact_pressure_at = contact_pressure
