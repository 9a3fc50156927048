"""Participants built on the explicit DOLFINx solver: the mechanics adapter and pressure pulses."""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from .case import Load
from .loads import box_marker, pulse_pressure
from .participants import LoadStep

ANALYSIS_PREFIX = "analysis/"  # checkpoint keys of the analyses' restart state


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
        """The solver's exact-restart state, plus the analyses' restart state: arrays the case
        analyses keep in ``solver.analysis_state`` (name -> array, e.g. the corner fill's "touched
        so far" record), stored under ``analysis/<name>``."""
        state = self.solver.state_dict()
        for name, arr in getattr(self.solver, "analysis_state", {}).items():
            state[f"{ANALYSIS_PREFIX}{name}"] = np.asarray(arr).copy()
        return state

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict` (the analyses find theirs in ``solver.analysis_state``)."""
        n = len(ANALYSIS_PREFIX)
        self.solver.load_state_dict({k: v for k, v in state.items() if not k.startswith(ANALYSIS_PREFIX)})
        self.solver.analysis_state = {k[n:]: np.asarray(v) for k, v in state.items() if k.startswith(ANALYSIS_PREFIX)}


class PressurePulses:
    """Load provider of the paper's pressure pulses (eq. 7, 8) as follower surface tractions, plus
    optional mass-proportional damping.

    Each pulse is evaluated at ``t_mid`` (the centre of the held force's impulse window) and turned
    into consistent nodal forces on the loaded facets of the current configuration. A pulse with
    ``trigger = "rest"`` keeps its window length but starts at the first EM step after the
    previous pulse's end at which the loaded body's largest nodal speed is below ``rest_speed``.
    Damping adds −α m v (v: the solver's last half-step velocity) while
    ``damping_from`` <= t < ``damping_until``, plus a pulse's ``rest_damping`` while that pulse waits
    for rest (dynamic relaxation between discharges). For t < ``kinetic_until`` the solver's
    kinetic damping is on (velocities zeroed at each peak of a body's kinetic energy).
    """

    def __init__(self, loads: tuple[Load, ...], damping: float = 0.0, damping_until: float = float("inf"),
                 damping_from: float = 0.0, kinetic_until: float = 0.0) -> None:
        self.loads = loads
        self.damping, self.damping_until, self.damping_from = damping, damping_until, damping_from
        self.kinetic_until = kinetic_until
        self.offsets = np.array([0.0 if ld.trigger == "time" else np.nan for ld in loads])
        self._masks: dict[int, np.ndarray] = {}

    def _shift(self, i: int, t0: float, mechanics: DolfinxMechanics) -> float:
        """Time shift of pulse i; fixes it when a rest-triggered pulse fires."""
        if not np.isnan(self.offsets[i]):
            return float(self.offsets[i])
        prev = self.loads[i - 1]
        prev_shift = self.offsets[i - 1]
        if np.isnan(prev_shift) or t0 < prev.t_end + prev_shift:
            return np.nan
        body = mechanics.solver.bodies[self.loads[i].body]
        local = float(np.sqrt((body.v[: body.n_owned] ** 2).sum(axis=1)).max()) if body.n_owned else 0.0
        speed = mechanics.solver.comm.allreduce(local, op=MPI.MAX)
        if speed < self.loads[i].rest_speed:
            self.offsets[i] = t0 - self.loads[i].t_start
        return float(self.offsets[i])

    def load(self, t0: float, t1: float, t_mid: float, mechanics: DolfinxMechanics) -> LoadStep:
        """Nodal forces (N) per body for the step [t0, t1] (s)."""
        forces: dict[str, np.ndarray] = {}
        values: dict[str, float] = {}
        relax = 0.0
        for i, ld in enumerate(self.loads):
            shift = self._shift(i, t0, mechanics)
            if np.isnan(shift) and ld.rest_damping > 0.0 and self._waiting(i, t0):
                relax = max(relax, ld.rest_damping)
            p = 0.0 if np.isnan(shift) else pulse_pressure(ld, t_mid - shift)
            values[f"load{i}_pressure_Pa"] = p
            if p == 0.0:
                continue
            f = mechanics.solver.pressure_nodal_forces(ld.body, self._material_marker(i, mechanics), p)
            forces[ld.body] = forces[ld.body] + f if ld.body in forces else f
        mechanics.solver.kinetic_damping = t_mid < self.kinetic_until
        alpha = relax + (self.damping if self.damping_from <= t_mid < self.damping_until else 0.0)
        if alpha > 0.0:
            for name, b in mechanics.solver.bodies.items():
                f = -alpha * b.mass[:, None] * b.v
                forces[name] = forces[name] + f if name in forces else f
        return LoadStep(forces, None, values)

    def initial(self, mechanics: DolfinxMechanics) -> LoadStep:
        """Pressures and nodal forces (N) at t = 0, for the history's first row: each started
        pulse at t = 0 (eq. 8 starts at p0, eq. 7 at 0; a pulse waiting for rest at 0) plus the
        mass damping if it acts at t = 0. Changes no state (the solver's kinetic damping flag is
        left to :meth:`load`)."""
        forces: dict[str, np.ndarray] = {}
        values: dict[str, float] = {}
        for i, ld in enumerate(self.loads):
            shift = self.offsets[i]
            p = 0.0 if np.isnan(shift) else pulse_pressure(ld, 0.0 - float(shift))
            values[f"load{i}_pressure_Pa"] = p
            if p != 0.0:
                f = mechanics.solver.pressure_nodal_forces(ld.body, self._material_marker(i, mechanics), p)
                forces[ld.body] = forces[ld.body] + f if ld.body in forces else f
        if self.damping > 0.0 and self.damping_from <= 0.0 < self.damping_until:
            for name, b in mechanics.solver.bodies.items():
                f = -self.damping * b.mass[:, None] * b.v
                forces[name] = forces[name] + f if name in forces else f
        return LoadStep(forces, None, values)

    def _waiting(self, i: int, t0: float) -> bool:
        """Pulse i waits for rest: the previous pulse has started and its window is over."""
        prev_shift = self.offsets[i - 1] if i > 0 else np.nan
        return not np.isnan(prev_shift) and t0 >= self.loads[i - 1].t_end + prev_shift

    def _material_marker(self, i: int, mechanics: DolfinxMechanics):
        """Facet marker of pulse i on the body's *initial* configuration (material surface): the
        box picks the same facets however far the body has moved (e.g. a blank's upper face drawn
        into a die). Cached per pulse; falls back to current coordinates for bodies without X0."""
        if i not in self._masks:
            ld = self.loads[i]
            body = mechanics.solver.bodies[ld.body]
            X0 = getattr(body, "X0", None)
            if X0 is None:
                return box_marker(ld.surface)
            x3 = np.zeros((3, X0.shape[0]))
            x3[:2] = X0.T
            self._masks[i] = np.asarray(box_marker(ld.surface)(x3), dtype=bool)
        mask = self._masks[i]
        return lambda x: mask

    def start_times(self) -> list[float]:
        """Actual start time (s) of each pulse (nan: not started)."""
        return [ld.t_start + off for ld, off in zip(self.loads, self.offsets)]

    def state_dict(self) -> dict[str, np.ndarray]:
        """The trigger shifts of the pulses."""
        return {"offsets": self.offsets.copy()}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        if "offsets" in state:
            self.offsets = np.array(state["offsets"], dtype=float)
