"""The mechanics participant of rigid bodies (``pulseform.solvers.dolfinx.rigid.RigidBody``): the
conductors of actuators, jumping rings and levitated plates, which move without deforming.

It implements the loop's ``Mechanics`` protocol: the nodal forces a load hands over are summed into
each body's resultant, the bodies' nodes (the EM mesh's nodes of those conductors) follow their
translations. Rigid bodies have no stability limit: the mechanical step is the one given (the EM
step divided by the subcycling), e.g. a number of steps per period of an AC source.
"""

from __future__ import annotations

import math

import numpy as np

from pulseform.solvers.dolfinx.rigid import RigidBody
from pulseform.solvers.dolfinx.rigid_held import HeldRigidBody

from ..coupling.interfaces import plain_total

__all__ = ["RigidMechanics"]


class RigidMechanics:
    """Rigid bodies stepped together (serial: every node of a rigid body is on this process).

    Parameters
    ----------
    bodies : list of RigidBody
        The bodies, by unique name.
    dt : float
        The mechanical step (s) :meth:`stable_time_step` reports (the loop caps it further with its
        ``dt_max``).
    """

    def __init__(self, bodies: list[RigidBody], dt: float) -> None:
        names = [b.name for b in bodies]
        if len(set(names)) != len(names):
            raise ValueError(f"rigid body names must be unique, got {names}")
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"the rigid bodies' step must be a finite time > 0 s, got {dt}")
        self.bodies = {b.name: b for b in bodies}
        self.dt = float(dt)
        self.time = 0.0
        self.step_count = 0

    @property
    def dim(self) -> int:
        """The bodies' dimension (2, or 3 in 3D)."""
        return max((b.dim for b in self.bodies.values()), default=2)

    def stable_time_step(self) -> float:
        """The configured step (s): rigid bodies have no stability limit."""
        return self.dt

    def impulse_window(self, t0: float, dt: float, k: int) -> float:
        """Where the loop evaluates the load of ``k`` steps of ``dt`` from ``t0`` (s): the centre of the window over
        which the bodies take a held force's impulse: t0 + k·dt/2 when they hold it over each step (implicit runs,
        :class:`~pulseform.solvers.dolfinx.rigid_held.HeldRigidBody`), central differences' t0 + (k − 1)·dt/2."""
        held = any(isinstance(b, HeldRigidBody) for b in self.bodies.values())
        return t0 + 0.5 * (k if held else k - 1) * dt

    def advance(self, dt: float, n_steps: int, forces: dict[str, np.ndarray] | None) -> None:
        """``n_steps`` steps of ``dt`` (s); each body under the resultant (N) of its nodal forces."""
        for name, b in self.bodies.items():
            f = None if not forces or name not in forces else np.asarray(forces[name])[:, :b.dim].sum(axis=0)
            b.advance(dt, n_steps, f)
        self.time += dt * n_steps
        self.step_count += int(n_steps)

    def rest(self) -> None:
        """Every body at rest where it is (:meth:`RigidBody.rest`)."""
        for b in self.bodies.values():
            b.rest()

    def use_scheme(self, held: bool) -> None:
        """Step every body exactly under the force held over each step (``held``: implicit runs,
        :class:`HeldRigidBody`) or by central differences (:class:`RigidBody`), from its present state: position,
        force, totals and clock kept, the velocity at the present time kept (central differences keep the last
        half step's, v − dt/2 a of it)."""
        kind = HeldRigidBody if held else RigidBody
        for name, b in list(self.bodies.items()):
            if type(b) is not kind:
                self.bodies[name] = b.recast(kind)

    def positions(self) -> dict[str, np.ndarray]:
        """Node coordinates per body (m)."""
        return {n: b.positions() for n, b in self.bodies.items()}

    def total_force(self, forces: dict[str, np.ndarray]) -> np.ndarray:
        """Resultant (N) of the nodal forces."""
        return plain_total(forces, self.dim)

    def history(self) -> dict[str, float]:
        """Position, velocity, acceleration and applied force of every body (SI units in the names)."""
        out: dict[str, float] = {}
        for b in self.bodies.values():
            out.update(b.history())
        return out

    def energies(self) -> dict[str, float]:
        """Kinetic energy, work of the applied forces and gravity, energy taken by the stops (J)."""
        return {"kinetic_J": sum(b.kinetic_energy() for b in self.bodies.values()),
                "external_work_J": sum(b.work_J for b in self.bodies.values()),
                "stop_dissipated_J": sum(b.stop_dissipated_J for b in self.bodies.values())}

    def state_dict(self) -> dict[str, np.ndarray]:
        """Every body's state, the time and the step count."""
        d = {"clock": np.array([self.time, self.step_count, self.dt])}
        for n, b in self.bodies.items():
            d.update({f"{n}/{k}": v for k, v in b.state_dict().items()})
        return d

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        self.time, self.step_count, self.dt = float(state["clock"][0]), int(state["clock"][1]), float(state["clock"][2])
        for n, b in self.bodies.items():
            b.load_state_dict({k[len(n) + 1:]: v for k, v in state.items() if k.startswith(f"{n}/")})
