"""Participants built on the explicit DOLFINx solver: the mechanics adapter and pressure pulses."""

from __future__ import annotations

import numpy as np

from .case import Load
from .loads import box_marker, pulse_pressure
from .participants import LoadStep


class DolfinxMechanics:
    """The :class:`~.participants.Mechanics` protocol over ``pulseform.solvers.dolfinx.ExplicitSolver``."""

    def __init__(self, solver) -> None:
        self.solver = solver

    @property
    def time(self) -> float:
        """Current time (s)."""
        return self.solver.time

    @property
    def step_count(self) -> int:
        """Mechanical steps taken."""
        return self.solver.step_count

    def stable_time_step(self) -> float:
        """Stable step (s), cfl included, from the current mesh."""
        return self.solver.stable_time_step()

    def advance(self, dt: float, n_steps: int, forces: dict[str, np.ndarray] | None) -> None:
        """``n_steps`` central-difference steps with held nodal forces (N)."""
        self.solver.advance(dt, n_steps, forces)

    def positions(self) -> dict[str, np.ndarray]:
        """Current node coordinates per body (m), this rank's nodes (ghosts included)."""
        return {n: b.x for n, b in self.solver.bodies.items()}

    def total_force(self, forces: dict[str, np.ndarray]) -> np.ndarray:
        """Resultant (N) over owned nodes of every rank (ghost rows are complete copies)."""
        local = np.zeros(2)
        for name, f in forces.items():
            local += np.asarray(f)[: self.solver.bodies[name].n_owned].sum(axis=0)
        return self.solver.comm.allreduce(local)

    def state_dict(self) -> dict[str, np.ndarray]:
        """The solver's exact-restart state."""
        return self.solver.state_dict()

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        self.solver.load_state_dict(state)


class PressurePulses:
    """Load provider of the paper's pressure pulses (eq. 7, 8) as follower surface tractions.

    Each pulse is evaluated at ``t_mid`` (the centre of the held force's impulse window) and turned
    into consistent nodal forces on the loaded facets of the current configuration.
    """

    def __init__(self, loads: tuple[Load, ...]) -> None:
        self.loads = loads

    def load(self, t0: float, t1: float, t_mid: float, mechanics: DolfinxMechanics) -> LoadStep:
        """Nodal forces (N) per body for the step [t0, t1] (s)."""
        forces: dict[str, np.ndarray] = {}
        values: dict[str, float] = {}
        for i, ld in enumerate(self.loads):
            p = pulse_pressure(ld, t_mid)
            values[f"load{i}_pressure_Pa"] = p
            if p == 0.0:
                continue
            f = mechanics.solver.pressure_nodal_forces(ld.body, box_marker(ld.surface), p)
            forces[ld.body] = forces[ld.body] + f if ld.body in forces else f
        return LoadStep(forces, None, values)

    def state_dict(self) -> dict[str, np.ndarray]:
        """Stateless (time laws only)."""
        return {}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Stateless."""
