"""Implicit dynamics of the explicit solver's bodies: Newmark / HHT-alpha time stepping (or static
equilibrium steps) with Newton iterations on the exact tangent (issue 34, item 1).

For slow devices, whose motion lasts milliseconds to seconds while the explicit stable step of a
deformable part is ~1e-7 s. The bodies, lumped mass, constraints, stress update, energy ledger,
output and restart are those of :class:`~.solver.ExplicitSolver` (2D: plane stress, plane strain,
axisymmetric) and :class:`~.solver3d.ExplicitSolver3D` (tetrahedra); what differs is the step.

The step (HHT-alpha in the form of Hilber, Hughes and Taylor 1977, with alpha in [-1/3, 0]; alpha = 0
is Newmark's average acceleration, the trapezoidal rule)::

    M a^{n+1} + (1 + alpha) f_int(u^{n+1}) - alpha f_int(u^n) = F          (free components)
    u^{n+1} = u^n + dt v^n + dt^2 ((1/2 - beta) a^n + beta a^{n+1})
    v^{n+1} = v^n + dt ((1 - gamma) a^n + gamma a^{n+1})
    beta = (1 - alpha)^2 / 4,  gamma = 1/2 - alpha

with M the row-sum lumped mass and F the external forces held over the step (the loop's
zero-order hold: the force passed to :meth:`advance` acts over [t, t + dt], so the acceleration
a^n is shifted by M^-1 (F_new - F_old) when it changes, as the explicit solver does). The
unknown is the displacement increment du = u^{n+1} - u^n; f_int(du) is
:func:`.implicit_element.cell_update` (the explicit kernels' updated-Lagrangian, Hughes-Winget,
J2 radial-return update with du in place of dt v^{n+1/2}) and its tangent the exact one of
:func:`.implicit_element.cell_tangent`. Newton: K_eff = M / (beta dt^2) + (1 + alpha) K_T, a sparse
LU (MUMPS) from du = 0, converged when the residual of the free components is below ``newton_tol``
times the largest of the norms of the inertia, the internal forces (reactions included), the external
forces and the start-of-step internal forces. A step that does not converge in
``newton_max`` iterations (or inverts a cell) is retried as two half steps, down to
2^-max_cuts of the step; beyond that :class:`ImplicitConvergenceError` stops the run in one line.
The static scheme drops the inertia (f_int(u^{n+1}) = F: quasi-static equilibrium steps, velocity
and acceleration zero); a body that its supports leave free to move rigidly makes its system
singular: :class:`~.implicit_linear.SingularSystemError`, naming the body and the free motion.

Accuracy: second order in dt for the trapezoidal rule (no amplitude error, period elongation
(omega dt)^2 / 12) and for HHT-alpha; HHT damps the modes with omega dt >> 1 (spectral radius at
infinity (1 + alpha) / (1 - alpha)). The energy ledger adds ``internal_work_J`` (the trapezoidal
work of the internal forces) and ``algorithmic_dissipation_J`` = external work - change of kinetic
energy - internal work: zero to the Newton tolerance for the trapezoidal rule, the energy HHT removes.
``options.adaptive``: each step chosen from a local error estimate, :mod:`.implicit_adapt`.

Contact pairs (eq. (5), elastic law) join the residual with their tangent (:mod:`.implicit_contact`);
rigid walls are exact constraints on an active set (:mod:`.implicit_walls`).

MPI (linear elements on a partitioned mesh, as the explicit solvers): each rank updates its owned cells, the
nodal forces are summed into their owners and copied to the ghosts (:meth:`~.body.Body.complete_nodal`), the
norms, sums of the ledger and every decision (convergence, cuts, walls, a singular system) are collective, and
the Newton system is a distributed PETSc matrix solved by MUMPS (:mod:`.implicit_dist`). Contact pairs: every rank
evaluates them on the gathered surfaces (the same forces, active pairs and stored energy on every rank; a crossed
layer's backtracking decided alike) and each pair's tangent is assembled once, by the rank owning its slave node,
in the global numbering (:func:`.implicit_contact.evaluate_contact`). Not done yet (the solver refuses them in
one line): contact friction and viscosity, soft planes, oblique sliding planes, bulk viscosity (not needed: HHT
damps the high modes).
"""
from __future__ import annotations

import logging
import math
from typing import Dict, List, Mapping, Optional, Sequence

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

from .body import BodySpec
from .contact import ContactPairSpec, RigidWallSpec
from .implicit_contact import ContactCrossed, check_pairs, evaluate_contact
from .implicit_element import CellState, cell_tangent, cell_update
from .implicit_flow import unsupported_material
from .implicit_ledger import ImplicitLedger
from .implicit_adapt import AdaptiveSteps, StepRejected
from .implicit_dist import DistributedSystem
from .implicit_linear import SerialSystem, SingularSystemError
from .implicit_options import SCHEMES, ImplicitConvergenceError, ImplicitOptions
from .implicit_options import NotConverged as _NotConverged
from .implicit_walls import WallSet, check_static_supports, reduced_basis
from .solver import ExplicitSolver
from .solver3d import ExplicitSolver3D

__all__ = ["ImplicitOptions", "ImplicitSolver", "ImplicitSolver3D", "ImplicitConvergenceError",
           "SingularSystemError", "SCHEMES", "StepRejected"]

log = logging.getLogger(__name__)

#: halvings of a Newton update that crossed a contact layer before the step is cut
_BACKTRACKS = 8


class _Trial:
    """One Newton iterate: the unknowns, cell results, contact, residual (N) and its scale, the held walls."""

    def __init__(self, du: Dict[str, np.ndarray]):
        self.du = du
        self.results = {}
        self.reaction: Dict[str, np.ndarray] = {}
        self.contact = None
        self.walls = None
        self.R = np.zeros(0)
        self.scale = 0.0


class ImplicitSteps(AdaptiveSteps, ImplicitLedger):
    """The implicit step, a part of :class:`ImplicitSolver` and :class:`ImplicitSolver3D` (the bodies,
    mass, constraints, ledger and restart are those of the explicit solver they extend)."""

    options: ImplicitOptions

    def _implicit_init(self, options: ImplicitOptions) -> None:
        if getattr(self, "soft_planes", ()):
            raise ValueError("the implicit integrator has no soft planes yet: use a contact pair with a body, "
                             "a rigid wall, or mechanics.integrator = 'explicit'")
        for n, b in self.bodies.items():
            if b.sliding is not None:
                raise ValueError(f"body {n!r}: oblique sliding planes are not in the implicit integrator yet")
            unsupported = unsupported_material(b.material)
            if unsupported:
                raise ValueError(f"body {n!r}: the implicit integrator's return mapping has no {unsupported} yet "
                                 "(implicit_flow.flow_stress): use mechanics.integrator = 'explicit'")
        self.options = options
        self._dt_prev = 0.0     # velocities are full-step values: the kinetic energy is 1/2 m v^2
        self.last_residuals: List[float] = []
        self.newton_iterations = 0
        self.step_cuts = 0
        self._offsets = {}
        off = 0
        for n, b in self.bodies.items():
            self._offsets[n] = off
            off += b.x.size
        self._ndof = off
        self._linear = DistributedSystem(self) if self.comm.size > 1 else SerialSystem(self)
        self._mask = {n: b.constrained_mask() for n, b in self.bodies.items()}
        self._fint: Dict[str, np.ndarray] = {}
        self._fcon: Dict[str, np.ndarray] = {}
        self._fwall = {n: np.zeros_like(b.x) for n, b in self.bodies.items()}
        self._f_from = {n: np.zeros_like(b.x) for n, b in self.bodies.items()}
        self._iacc = {"internal_work_J": 0.0, "support_work_J": 0.0, "contact_work_J": 0.0, "wall_work_J": 0.0}
        self._restart_from_state()
        self._supported: Optional[bool] = None
        self._adapt_init()
        log.info("implicit integrator: %s (alpha %g), dt %.4g s, Newton tol %.1e, at most %d iterations, "
                 "%d cuts", options.scheme, options.alpha, options.dt, options.newton_tol, options.newton_max,
                 options.max_cuts)

    def _restart_from_state(self) -> None:
        """Start stepping from the bodies' present positions, stress and plastic strain (after construction, or
        after they were copied from another solver: :mod:`.springback`): the internal forces, the acceleration
        (dynamic: M a = -f_int on the free components; static: zero, and zero velocity), the ledger's start."""
        self._active = {}
        ev = evaluate_contact(self, {n: b.x for n, b in self.bodies.items()})
        self._active, self._contact_out = ev.active, ev.out
        self._contact_stored = self._contact_stored0 = ev.stored
        self._contact_work = 0.0
        for n, b in self.bodies.items():
            zero = np.zeros(b.cells.shape + (b.gdim,))
            self._fint[n] = self._cells(n, b, zero, self.options.dt).force_nodal
            self._fcon[n] = ev.force[n]
            self._fwall[n][...] = 0.0
            if self.options.scheme == "static":
                b.v[...] = 0.0
                b.a[...] = 0.0
            else:
                a = (self._fext[n] - self._fint[n] + self._fcon[n]) / b.mass[:, None]
                a[self._mask[n]] = 0.0
                b.a[...] = a
        for k in self._acc:
            self._acc[k] = 0.0
        for k in self._iacc:
            self._iacc[k] = 0.0
        self._KE0 = self._kinetic()
        self._E0 = self._stored_energy()

    # ------------------------------------------------------------------ the loop's view
    def stable_time_step(self) -> float:
        """The implicit step (s): ``options.dt``, or the adaptive step's proposal (no stability limit)."""
        return getattr(self, "_dt_next", self.options.dt) if self.options.adaptive else self.options.dt

    def impulse_window(self, t0: float, dt: float, k: int) -> float:
        """Where the loop evaluates the load of ``k`` steps of ``dt`` from ``t0`` (s): dynamic schemes hold the
        force over [t0, t0 + k dt], the centre of that window is t0 + k dt / 2; static steps reach equilibrium
        with it at the end, t0 + k dt."""
        return t0 + (1.0 if self.options.scheme == "static" else 0.5) * k * dt

    @property
    def compiled(self):
        """None: no compiled explicit block path (the pulse blocks run the Python loop)."""
        return None

    def advance(self, dt: float, n_steps: int = 1,
                external_forces: Optional[Mapping[str, np.ndarray]] = None) -> None:
        """Advance ``n_steps`` implicit steps of size ``dt`` with external forces held over them.

        Parameters
        ----------
        dt : float
            Time step, s (any size: the scheme is unconditionally stable; accuracy decides).
        n_steps : int
            Number of steps.
        external_forces : dict, optional
            Body name -> nodal forces (n_local_nodes, gdim), N (planar: for the thickness;
            axisymmetric: the full ring), held constant over the steps; absent bodies: zero. Each
            row is the complete force on its node; rows of ghost nodes (MPI) are ignored.

        Raises
        ------
        ImplicitConvergenceError
            Newton did not converge on the smallest step allowed (``max_cuts`` halvings).
        SingularSystemError
            A static step of a body its supports leave free to move rigidly, or a zero pivot.
        StepRejected
            ``options.adaptive``: the step's error is above ``error_tol`` (nothing changed; retry with its ``dt``).
        """
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number, got {dt!r}")
        if int(n_steps) != n_steps or n_steps < 1:
            raise ValueError(f"n_steps must be a positive integer, got {n_steps!r}")
        if external_forces is not None:
            unknown = set(external_forces) - set(self.bodies)
            if unknown:
                raise ValueError(f"external_forces for unknown bodies {sorted(unknown)}")
        held = self._held_forces() if self.options.adaptive else None
        for n, b in self.bodies.items():
            f = np.zeros_like(b.x)
            if external_forces is not None and n in external_forces:
                arr = np.asarray(external_forces[n], dtype=float)
                if arr.shape != b.x.shape:
                    raise ValueError(f"external_forces[{n!r}] must have shape {b.x.shape}")
                f[:b.n_owned] = arr[:b.n_owned]   # each owned row is the complete force
            b.complete_nodal(f)                       # MPI: the ghosts' rows from their owners
            if self.options.scheme != "static":   # the held force acts from now on: shift a^n
                delta = (f - self._fext[n]) / b.mass[:, None]
                delta[self._mask[n]] = 0.0
                b.a += delta
            self._fext[n][...] = f
            self._fext_nonzero[n] = bool(np.any(f))
        if self.options.scheme == "static" and not self._supported:
            self._supported = check_static_supports(self)
        if held is not None:
            return self._adaptive_step(dt, n_steps, held)
        for _ in range(int(n_steps)):
            self._step_with_cuts(dt, 0, 0.0, 1.0)
            for n in self.bodies:   # static: the state is now in equilibrium with the held force
                self._f_from[n][...] = self._fext[n]

    # ------------------------------------------------------------------ one step
    def _load(self, n: str, s: float) -> np.ndarray:
        """The external force (N) on body ``n`` at the fraction ``s`` in [0, 1] of the present call's steps: the
        held force (dynamic schemes: zero-order hold); static steps ramp it from the force of the last
        equilibrium, so that a cut step also cuts the load increment."""
        if self.options.scheme != "static":
            return self._fext[n]
        return self._f_from[n] + s * (self._fext[n] - self._f_from[n])

    def _step_with_cuts(self, dt: float, depth: int, s0: float, s1: float) -> None:
        """One step of ``dt`` taking the load fraction from ``s0`` to ``s1`` (:meth:`_load`); on failure two of
        dt / 2 (each may be cut again), down to ``max_cuts``."""
        try:
            trial = self._newton(dt, s1)
        except _NotConverged as exc:
            if depth >= self.options.max_cuts:
                raise ImplicitConvergenceError(
                    f"t={self.time:.6g} s: Newton did not converge on a step of {dt:.4g} s after {depth} cuts "
                    f"({exc.why}): the load is too abrupt for the step, or the structure lost stability") from None
            log.info("t=%.6e s: %s on a step of %.4e s; two half steps", self.time, exc.why, dt)
            self.step_cuts += 1
            mid = 0.5 * (s0 + s1)
            self._step_with_cuts(0.5 * dt, depth + 1, s0, mid)
            self._step_with_cuts(0.5 * dt, depth + 1, mid, s1)
            return
        self._commit(trial, dt, s0, s1)

    def _prescribed(self, n: str, b, dt: float) -> np.ndarray:
        """Displacement increments (N, gdim), m, of the constrained components over [t, t + dt]
        (fixed components: the trapezoidal integral of their prescribed velocity; motions: their
        target minus the current position; the axis: 0). Free components: 0."""
        du = np.zeros_like(b.x)
        t0, t1 = self.time, self.time + dt
        for kind, nodes, a, val in b._constraints:
            if nodes.size == 0:
                continue
            if kind == "fix":
                v = 0.5 * (val(t0) + val(t1)) if callable(val) else val
                for c in a:
                    du[nodes, c] = dt * v
            else:
                du[nodes] = np.asarray(a(b.X0[nodes], t1), dtype=float) - b.x[nodes]
        if b.axis_nodes.size:
            du[b.axis_nodes, 0] = 0.0
        return du

    def _cells(self, n: str, b, du_cells: np.ndarray, dt: float):
        """The cell update of body ``n`` for cell increments ``du_cells`` (nc, nn, gdim); adds the
        assembled nodal internal force as ``force_nodal`` (complete on every local row) and ``tangent()``, which
        computes the cell tangents."""
        st = CellState(b.x[b.cells], b.cell_stress, b.eps_p, b.material, self.mode,
                       float(getattr(b, "thickness", 1.0)), dt)
        res = cell_update(st, du_cells)
        f = np.zeros_like(b.x)
        for c in range(b.gdim):
            f[:, c] = np.bincount(b.cells.ravel(), weights=res.force[:, :, c].ravel(), minlength=len(b.x))
        res.force_nodal = b.complete_nodal(f)      # MPI: the ghosts' shares summed into their owners
        res.tangent = lambda: cell_tangent(st, du_cells)
        return res

    def _evaluate(self, du: Dict[str, np.ndarray], dt: float, c_m: float, c_k: float, s1: float) -> _Trial:
        """The cells, contact and residual R = M a + (1 + alpha)(f_int - f_c) - alpha (f_int^n - f_c^n) - F of the
        iterate ``du`` (all components; the wall and support reactions are R at their components)."""
        o = self.options
        trial = _Trial(du)
        try:   # every rank evaluates the same passes on the gathered surfaces; the decision is made collective
            trial.contact, crossed = evaluate_contact(self, {n: b.x + du[n] for n, b in self.bodies.items()},
                                                      getattr(self, "_last_pairs", None)), None
        except ContactCrossed as exc:
            crossed = str(exc)
        if self.contact_pairs:
            crossed = self._linear.first(crossed)
        if crossed is not None:
            raise ContactCrossed(crossed)
        self._last_pairs = trial.contact.active
        R_parts, scale_parts, inverted = [], [0.0, 0.0, 0.0, 0.0], None
        for n, b in self.bodies.items():
            res = self._cells(n, b, du[n][b.cells], dt)
            if res.inverted.any() and inverted is None:
                inverted = f"cell {int(np.flatnonzero(res.inverted)[0])} of body {n!r} inverted"
                if self.comm.size > 1:
                    inverted += f" (rank {self.comm.rank})"
            inert = np.zeros_like(b.x)
            if c_m:
                inert = b.mass[:, None] * c_m * (du[n] - dt * b.v - dt * dt * (0.5 - o.beta) * b.a)
            F = self._load(n, s1)
            fc = trial.contact.force[n]
            R = inert + c_k * (res.force_nodal - fc) - o.alpha * (self._fint[n] - self._fcon[n]) - F
            trial.reaction[n] = R
            R_parts.append(R.ravel())
            no = b.n_owned   # MPI: the owned rows (summed over the ranks below)
            free = ~self._mask[n][:no]
            scale_parts[0] += float(np.sum(inert[:no][free] ** 2))
            scale_parts[1] += float(np.sum(res.force_nodal[:no] ** 2))   # all components: the reactions too
            scale_parts[2] += float(np.sum(F[:no][free] ** 2))
            # the force scale must not vanish with the solution (a static step back to zero load)
            scale_parts[3] += float(np.sum(self._fint[n][:no][free] ** 2))
            trial.results[n] = res
        inverted = self._linear.first(inverted)
        if inverted is not None:
            raise _NotConverged(inverted, self.last_residuals)
        trial.R = np.concatenate(R_parts)
        trial.scale = self._linear.agree(math.sqrt(max(self._linear.sums(scale_parts))))
        return trial

    def _newton(self, dt: float, s1: float) -> _Trial:
        """Newton iterations of one step from the current state to the load fraction ``s1``; returns the
        converged iterate (the state is not changed) or raises :class:`_NotConverged`.

        The predictor is no motion: extrapolations invert cells on large steps (the constant-acceleration one
        carries the lumped mass's response to a just-applied load, the constant-velocity one the velocity of
        modes the step does not resolve). The prescribed components (supports, walls) join through the
        correction of the first solve on the start-of-step tangent, which spreads them over the body (set at
        once, they strain only the cells at the boundary: yield there). An update that crosses a contact
        layer is halved (up to ``_BACKTRACKS`` times)."""
        o = self.options
        c_m = 0.0 if o.scheme == "static" else 1.0 / (o.beta * dt * dt)
        c_k = 1.0 + o.alpha
        du = {n: np.zeros_like(b.x) for n, b in self.bodies.items()}
        target = {n: np.where(self._mask[n], self._prescribed(n, b, dt), 0.0) for n, b in self.bodies.items()}
        walls = WallSet(self)
        residuals: List[float] = []
        self.last_residuals, self._last_pairs = residuals, None
        last, halvings = None, 0
        for it in range(o.newton_max + 1):
            try:
                trial = self._evaluate(du, dt, c_m, c_k, s1)
            except ContactCrossed as exc:
                if last is None or halvings >= _BACKTRACKS:
                    raise _NotConverged(str(exc), residuals) from None
                halvings += 1
                for n in du:
                    last[n] *= 0.5
                    du[n] -= last[n]
                continue
            lin = self._linear   # one process, or the ranks' distributed system (every decision collective)
            if lin.any(not np.all(np.isfinite(trial.R))):
                raise _NotConverged("non-finite residual", residuals)
            T, corr = reduced_basis(self, walls, du, self._mask, target, self._offsets, self._ndof)
            rn = lin.reduce(T, corr, trial.R)
            rel = rn / trial.scale if trial.scale > 0 else (0.0 if rn == 0 else math.inf)
            residuals.append(rel)
            if rel <= o.newton_tol and not lin.any(np.any(corr)) and not lin.any(
                    walls.release(trial.reaction, o.newton_tol * trial.scale)):
                self.newton_iterations += it
                trial.walls = walls
                return trial
            if it == o.newton_max:
                break
            K = self._assemble([(n, b, trial.results[n]) for n, b in self.bodies.items()], 0.0, c_k)
            r, c, v = trial.contact.tangent()   # this rank's pairs, in the system's numbering
            delta = lin.solve(K, c_m, f"t = {self.time:.6e} s, Newton iteration {it + 1}", (r, c, c_k * v))
            last = {}
            for n, b in self.bodies.items():
                o0 = self._offsets[n]
                last[n] = delta[o0:o0 + b.x.size].reshape(b.x.shape)
                du[n] = du[n] + last[n]
            walls.activate(du)
        raise _NotConverged(f"relative residual {residuals[-1]:.2g} > {o.newton_tol:.2g} after {o.newton_max} "
                            "iterations", residuals)

    def _assemble(self, blocks, c_m: float, c_k: float) -> sp.csr_matrix:
        """The effective tangent c_m M + c_k K_T over all bodies' components on the local layout (sparse, N/m) from
        the ``(name, body, cell results)`` of ``blocks`` (the contact's, c_k K_c, joins in the linear system's
        ``solve``: :meth:`.implicit_contact.ContactEval.tangent`)."""
        rows, cols, vals, diag = [], [], [], []
        for n, b, res in blocks:
            d = b.gdim
            dofs = (self._offsets[n] + b.cells[:, :, None] * d + np.arange(d)).reshape(len(b.cells), -1)
            nd = dofs.shape[1]
            rows.append(np.repeat(dofs, nd, axis=1).ravel())
            cols.append(np.tile(dofs, (1, nd)).ravel())
            vals.append((c_k * res.tangent()).ravel())
            diag.append(np.repeat(c_m * b.mass, d))
        K = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(self._ndof, self._ndof)).tocsr()
        if c_m:
            K = K + sp.diags(np.concatenate(diag))
        return K.tocsr()


class ImplicitSolver(ImplicitSteps, ExplicitSolver):
    """Implicit dynamics of 2D bodies (plane stress, plane strain, axisymmetric; P1 triangles).

    Parameters
    ----------
    bodies : sequence of BodySpec
        The bodies (unique names).
    options : ImplicitOptions
        Scheme, step and Newton settings.
    formulation : {"plane_stress", "plane_strain", "axisymmetric"}
        2D model (axisymmetric: x = r, y = z; nodes on r = 0 get u_r = 0).
    thickness : float
        Out-of-plane thickness for planar formulations, m.
    comm : MPI communicator
        The bodies' meshes' (one process, or the ranks of a partitioned mesh: every method is collective).
    contact_pairs, rigid_walls : sequence
        Contact pairs (elastic law of eq. (5)) and rigid walls.
    """

    def __init__(self, bodies: Sequence[BodySpec], options: ImplicitOptions,
                 formulation: str = "plane_stress", thickness: float = 1.0, comm=MPI.COMM_WORLD,
                 contact_pairs: Sequence[ContactPairSpec] = (), rigid_walls: Sequence[RigidWallSpec] = ()):
        self.options = options   # the explicit constructor logs stable_time_step()
        check_pairs(contact_pairs)
        super().__init__(bodies, formulation=formulation, contact_pairs=contact_pairs, rigid_walls=rigid_walls,
                         bulk_viscosity=False, thickness=thickness, comm=comm, compiled_steps=False)
        self._implicit_init(options)


class ImplicitSolver3D(ImplicitSteps, ExplicitSolver3D):
    """Implicit dynamics of 3D bodies on linear or ten-node tetrahedra (``BodySpec.element``; the options of
    :class:`ImplicitSolver`)."""

    def __init__(self, bodies: Sequence[BodySpec], options: ImplicitOptions, comm=MPI.COMM_WORLD,
                 contact_pairs: Sequence[ContactPairSpec] = (), rigid_walls: Sequence[RigidWallSpec] = ()):
        self.options = options
        check_pairs(contact_pairs)
        super().__init__(bodies, rigid_walls=rigid_walls, contact_pairs=contact_pairs, bulk_viscosity=False,
                         comm=comm, compiled_steps=False)
        self._implicit_init(options)
