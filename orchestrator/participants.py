"""The two participants of the staggered loop, as small interfaces, plus simple implementations.

The loop (:mod:`.loop`) only sees these protocols, so a fake load (an analytic force), a
pressure pulse, a GetDP eddy-current load, the explicit DOLFINx mechanics, a rigid body or a
prescribed motion all plug in without touching it.

Conventions: nodal forces are dicts ``body name -> (N, 2) array`` in N (planar: for the case's
thickness; axisymmetric: over the full 2π ring); positions likewise in m.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np


@dataclass
class LoadStep:
    """What a load provider hands the loop for one EM step [t0, t1].

    Attributes
    ----------
    forces : dict
        Nodal forces per body (N), held constant over the step.
    reference_integral : ndarray (2,)
        The provider's own ∫ f dV (N) for the conservation ledger (None when not applicable).
    values : dict
        Scalars for history.csv (SI units in the names), e.g. coil current.
    """

    forces: dict[str, np.ndarray]
    reference_integral: np.ndarray | None = None
    values: dict[str, float] = field(default_factory=dict)


class Mechanics(Protocol):
    """A mechanical participant."""

    time: float
    step_count: int

    def stable_time_step(self) -> float:
        """Largest stable step (s), safety factor included."""

    def advance(self, dt: float, n_steps: int, forces: dict[str, np.ndarray] | None) -> None:
        """``n_steps`` steps of ``dt`` (s) with nodal forces held constant."""

    def positions(self) -> dict[str, np.ndarray]:
        """Current node coordinates per body (m)."""

    def total_force(self, forces: dict[str, np.ndarray]) -> np.ndarray:
        """Resultant (N), shape (2,), of nodal forces: each node counted once over all ranks."""

    def state_dict(self) -> dict[str, np.ndarray]:
        """Everything needed to continue exactly."""

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""


def plain_total(forces: dict[str, np.ndarray]) -> np.ndarray:
    """Resultant (N) of nodal forces held entirely on this process."""
    total = np.zeros(2)
    for f in forces.values():
        total += np.asarray(f)[:, :2].sum(axis=0)
    return total


class LoadProvider(Protocol):
    """A load participant."""

    def load(self, t0: float, t1: float, t_mid: float, mechanics: Mechanics) -> LoadStep:
        """Nodal forces for the EM step [t0, t1] (s) on the mechanics' current geometry.

        ``t_mid`` is the centre of the window over which central differences deliver the held
        force's impulse, t0 + (n − 1)·dt/2; providers with an explicit time law evaluate there
        (second order); GetDP returns its implicit-Euler value at t1.
        """

    def state_dict(self) -> dict[str, np.ndarray]:
        """Everything needed to continue exactly."""

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""


class RigidAxialBody:
    """A rigid body translating along the axis (y, or z in axisymmetry), with mass and gravity.

    For slow EM actuators and levitation, where explicit elasticity would need millions of steps.
    Central difference with a consistent half-step start, so a constant force is integrated
    exactly. ``nodes`` are the body's nodes (m); they all move with the body.

    Parameters
    ----------
    name : str
        Body name (the key of its forces).
    nodes : ndarray (N, 2)
        Initial node coordinates (m).
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
        self.y, self.v, self._v_half, self._dt_prev = 0.0, velocity, None, 0.0
        self.work = 0.0

    def stable_time_step(self) -> float:
        """The configured step (s)."""
        return self.dt

    def _accel(self, forces: dict[str, np.ndarray] | None) -> float:
        fy = float(forces[self.name][:, 1].sum()) if forces and self.name in forces else 0.0
        return fy / self.mass - self.gravity

    def advance(self, dt: float, n_steps: int, forces: dict[str, np.ndarray] | None) -> None:
        """Central-difference steps with the axial resultant of ``forces`` held constant."""
        a = self._accel(forces)
        fy = a * self.mass + self.gravity * self.mass
        for _ in range(n_steps):
            # variable-step central difference: v^{n+1/2} = v^{n-1/2} + a (dt_{n-1} + dt_n) / 2
            v_half = (self.v + 0.5 * dt * a) if self._v_half is None else \
                self._v_half + 0.5 * (self._dt_prev + dt) * a
            self.y += dt * v_half
            self.work += fy * dt * v_half
            self._v_half, self._dt_prev = v_half, dt
            self.v = v_half + 0.5 * dt * a  # synchronised velocity at the step end (same a)
            self.time += dt
            self.step_count += 1

    def positions(self) -> dict[str, np.ndarray]:
        """Node coordinates per body (m)."""
        return {self.name: self.x0 + np.array([0.0, self.y])}

    def total_force(self, forces: dict[str, np.ndarray]) -> np.ndarray:
        """Resultant (N) of the given nodal forces."""
        return plain_total(forces)

    def state_dict(self) -> dict[str, np.ndarray]:
        """Time, counters, position, velocities."""
        vh = np.nan if self._v_half is None else self._v_half
        return {"scalars": np.array([self.time, self.step_count, self.y, self.v, vh, self.work, self._dt_prev])}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        t, k, y, v, vh, w, self._dt_prev = state["scalars"]
        self.time, self.step_count, self.y, self.v, self.work = float(t), int(k), float(y), float(v), float(w)
        self._v_half = None if np.isnan(vh) else float(vh)


class AnalyticForce:
    """A load provider with an analytic resultant F(t) (N) along y, spread evenly over a body's nodes.

    The force is evaluated at ``t_mid``, the centre of its impulse window (second-order hold).
    """

    def __init__(self, body: str, n_nodes: int, force: Callable[[float], float]) -> None:
        self.body, self.n_nodes, self.force = body, n_nodes, force

    def load(self, t0: float, t1: float, t_mid: float, mechanics: Mechanics) -> LoadStep:
        """Nodal forces at ``t_mid``."""
        fy = self.force(t_mid)
        f = np.zeros((self.n_nodes, 2))
        f[:, 1] = fy / self.n_nodes
        return LoadStep({self.body: f}, np.array([0.0, fy]), {"force_y_N": fy})

    def state_dict(self) -> dict[str, np.ndarray]:
        """Stateless."""
        return {}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Stateless."""
