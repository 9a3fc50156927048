"""Fake participants that test the coupling loop in seconds: a rigid body translating along the axis
(a :class:`~.interfaces.Mechanics`), an analytic force (a :class:`~.interfaces.LoadProvider`) and, for the 3D
loop, an analytic Lorentz force density on the conductor bodies of a 3D EM mesh that follows them
(:class:`AnalyticLorentz3D`: the GetDP load's mesh motion and force transfer without getdp)."""

from __future__ import annotations

from typing import Callable

import numpy as np

from .interfaces import LoadCapabilities, LoadStep, Mechanics, plain_total
from .transfer3d import body_forces, tet_force_integral


class RigidAxialBody:
    """A rigid body translating along the axis (y, or z in axisymmetry), with mass and gravity.

    For slow EM actuators and levitation, where explicit elasticity would need millions of steps.
    Variable-step central differences with the same force convention as the explicit solver: the
    forces given to :meth:`advance` act from the current time on (the first velocity update
    already uses them), so a constant force is integrated exactly.

    Parameters
    ----------
    name : str
        Body name (the key of its forces).
    nodes : ndarray (N, 2)
        Initial node coordinates (m); they all move with the body.
    mass : float
        kg (for an axisymmetric body, the whole ring's mass).
    gravity : float
        m/s², acting along −y.
    velocity : float
        Initial axial velocity (m/s).
    dt : float
        Time step (s) the loop asks for (the body itself has no stability limit).
    """

    def __init__(self, name: str, nodes: np.ndarray, mass: float, *, gravity: float = 0.0,
                 velocity: float = 0.0, dt: float = 1e-5) -> None:
        if mass <= 0.0:
            raise ValueError(f"mass must be > 0 kg, got {mass}")
        self.name, self.mass, self.gravity, self.dt = name, mass, gravity, dt
        self.x0 = np.asarray(nodes, dtype=float)[:, :2].copy()
        self.time, self.step_count = 0.0, 0
        self.y, self.v = 0.0, velocity  # v: velocity at the last half step (v^0 before any step)
        self.a = -gravity
        self._dt_prev = 0.0

    def stable_time_step(self) -> float:
        """The configured step (s)."""
        return self.dt

    def advance(self, dt: float, n_steps: int, forces: dict[str, np.ndarray] | None) -> None:
        """Central-difference steps with the axial resultant of ``forces`` acting from now on."""
        fy = float(forces[self.name][:, 1].sum()) if forces and self.name in forces else 0.0
        self.a = fy / self.mass - self.gravity
        for _ in range(n_steps):
            self.v += 0.5 * (self._dt_prev + dt) * self.a  # v^{n+1/2} = v^{n-1/2} + a_n (dt_{n-1}+dt_n)/2
            self.y += dt * self.v
            self._dt_prev = dt
            self.time += dt
            self.step_count += 1

    def positions(self) -> dict[str, np.ndarray]:
        """Node coordinates per body (m)."""
        return {self.name: self.x0 + np.array([0.0, self.y])}

    def total_force(self, forces: dict[str, np.ndarray]) -> np.ndarray:
        """Resultant (N) of the given nodal forces."""
        return plain_total(forces)

    def state_dict(self) -> dict[str, np.ndarray]:
        """Time, counters, position, velocity, acceleration, last step."""
        return {"scalars": np.array([self.time, self.step_count, self.y, self.v, self.a, self._dt_prev])}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        t, k, y, v, a, dtp = state["scalars"]
        self.time, self.step_count, self.y, self.v, self.a, self._dt_prev = \
            float(t), int(k), float(y), float(v), float(a), float(dtp)


class AnalyticForce(LoadCapabilities):
    """A load provider with an analytic resultant F(t) (N) along y, spread evenly over a body's nodes.

    The force is evaluated at ``t_mid``, the centre of its impulse window (second-order hold).
    """

    columns = ("force_y_N",)

    def __init__(self, body: str, n_nodes: int, force: Callable[[float], float]) -> None:
        self.body, self.n_nodes, self.force = body, n_nodes, force

    def load(self, t0: float, t1: float, t_mid: float, mechanics: Mechanics) -> LoadStep:
        """Nodal forces at ``t_mid``."""
        fy = self.force(t_mid)
        f = np.zeros((self.n_nodes, 2))
        f[:, 1] = fy / self.n_nodes
        return LoadStep({self.body: f}, np.array([0.0, fy]), {"force_y_N": fy})

    def initial(self, mechanics: Mechanics) -> LoadStep:
        """Nodal forces at t = 0."""
        return self.load(0.0, 0.0, 0.0, mechanics)

    def state_dict(self) -> dict[str, np.ndarray]:
        """Stateless."""
        return {}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Stateless."""


class AnalyticLorentz3D(LoadCapabilities):
    """A 3D load provider without getdp: an analytic force density f(x, t) (N/m^3) on the tetrahedra of the
    conductor bodies of a 3D EM mesh, the mesh following the bodies as the GetDP load's does.

    :meth:`follow` moves the EM mesh (the bodies' nodes where the mechanics has them, the air by ``mover``:
    :class:`~pulseform.orchestrator.mesh.motion3d.MeshMover3D`); :meth:`load` evaluates ``density`` at the
    centroids of the bodies' moved tetrahedra at ``t_mid`` (the loop's hold point) and spreads it on their
    nodes as the GetDP load does (:func:`~.transfer3d.body_forces`: f V / 4 per node, a ten-node body's HRZ
    shares), the reference integral Σ f V for the loop's ledger. Keeps ``last_forces`` (per body, N) and ``x_em`` (the moved EM nodes, m).

    Parameters
    ----------
    mesh : Mesh3D
        The EM mesh in its reference configuration (``points``, ``tets``).
    bodies : list of ConductorBody3D
        The bodies (``name``, ``sub.rows``: their rows of ``mesh.tets``, ``body_to_em``: their nodes in it).
    mover : MeshMover3D
        The air motion on ``mesh``.
    density : callable (centroids (m, 3) m, t s) -> (m, 3) N/m^3
        The force density.
    """

    columns = ("force_density_max_N_m3", "em_mesh_min_quality")

    def __init__(self, mesh, bodies, mover, density: Callable[[np.ndarray, float], np.ndarray]) -> None:
        self.mesh, self.bodies, self.mover, self.density = mesh, list(bodies), mover, density
        self.x_em = np.array(mesh.points, dtype=float)
        self.last_forces: dict[str, np.ndarray] = {}
        self._moved_at: float | None = None

    def follow(self, t0: float, mechanics) -> None:
        """The EM mesh follows the bodies for the step starting at ``t0`` (s)."""
        positions = mechanics.positions()
        u = np.zeros_like(self.mesh.points)
        for b in self.bodies:
            u[b.body_to_em] = b.vertices(positions[b.name]) - self.mesh.points[b.body_to_em]
        self.x_em = self.mover.moved(u)
        self._moved_at = t0

    def load(self, t0: float, t1: float, t_mid: float, mechanics) -> LoadStep:
        """Nodal forces (N) on the bodies of the density at ``t_mid`` on the moved mesh."""
        if self._moved_at != t0:
            self.follow(t0, mechanics)
        x = self.x_em
        rows = np.concatenate([b.sub.rows for b in self.bodies])
        tets = self.mesh.tets[rows]
        f = np.asarray(self.density(x[tets].mean(axis=1), t_mid), dtype=float)
        forces = body_forces(self.bodies, x, self.mesh.tets, rows, f)
        self.last_forces = forces
        values = {"force_density_max_N_m3": float(np.abs(f).max()),
                  "em_mesh_min_quality": float(self.mover.last_min_quality)}
        return LoadStep(forces, tet_force_integral(x, tets, f), values)

    def initial(self, mechanics) -> LoadStep:
        """No force at t = 0."""
        return LoadStep({}, None, {})

    def state_dict(self) -> dict[str, np.ndarray]:
        """Stateless: the mesh follows the mechanics' positions, the density is a function of time."""
        return {}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Stateless."""
