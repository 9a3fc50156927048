"""Participants built on the explicit DOLFINx solver: the mechanics adapter and pressure pulses.

The pressure pulses drive a :class:`PressureMechanics`: the mechanics participant owns its solver
(bodies, follower pressure, damping switches, compiled steps); the pulses decide only what acts
when, through that small interface.
"""

from __future__ import annotations

import logging
from typing import Protocol

import numpy as np
from mpi4py import MPI

from pulseform.solvers.dolfinx.implicit_adapt import StepRejected

from ..case.model import Load
from ..coupling.interfaces import LoadCapabilities, LoadStep, Mechanics, RetryStep, StepBlock
from .pulse_block import PulseBlock, PulseProgram, block_plan, run_pulse_block
from ..mesh.markers import box_marker
from .pulses import pulse_pressure, pulse_table

log = logging.getLogger(__name__)



class PressureMechanics(Mechanics, Protocol):
    """A mechanics the pressure pulses can load: follower pressures on marked boundary facets,
    mass-proportional and kinetic damping, and (optionally) whole blocks of pulse steps in
    compiled code. Bodies are named as in :meth:`Mechanics.positions`."""

    def reference_positions(self) -> dict[str, np.ndarray]:
        """Node coordinates per body in the initial configuration (m), this rank's nodes."""

    def max_speed(self, body: str) -> float:
        """Largest nodal speed (m/s) of a body's last half-step velocity over all ranks (0 without nodes)."""

    def pressure_forces(self, body: str, nodes: np.ndarray, pressure: float) -> np.ndarray:
        """Consistent nodal forces (N) of a uniform follower pressure (Pa, positive pushes into
        the body) on the boundary facets of ``body`` whose two nodes are marked in ``nodes`` (bool
        per local node), on the current configuration."""

    def mass_damping_forces(self, alpha: float) -> dict[str, np.ndarray]:
        """Mass-proportional damping forces −α m v (N) per body, α in 1/s, v the last half-step velocity."""

    def set_kinetic_damping(self, on: bool) -> None:
        """Kinetic damping (velocities zeroed at each peak of a body's kinetic energy) on or off
        from the next step on."""

    def advance_pulses(self, program: PulseProgram, shifts: np.ndarray, t_stop: float, n_max: int,
                       dt_max: float | None) -> PulseBlock | None:
        """Up to ``n_max`` EM steps of one mechanical step each with the pulses of ``program``
        (:mod:`.pulse_block`), stopping before the step that lands on ``t_stop`` (s); ``shifts``
        (s per pulse, nan: waiting for rest) updated in place. None: no compiled path, nothing done."""


class DolfinxMechanics:
    """The :class:`PressureMechanics` protocol (so also the loop's
    :class:`~pulseform.orchestrator.coupling.interfaces.Mechanics`) over
    ``pulseform.solvers.dolfinx.ExplicitSolver``; the only holder of the solver among the participants."""

    def __init__(self, solver) -> None:
        self.solver = solver
        self._pulse_plan = None  # the compiled pulse block's data, built on its first use

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

    @property
    def retries_steps(self) -> bool:
        """Whether :meth:`advance` may reject its step (the adaptive implicit step: :class:`RetryStep`)."""
        return bool(getattr(getattr(self.solver, "options", None), "adaptive", False))

    def advance(self, dt: float, n_steps: int, forces: dict[str, np.ndarray] | None) -> None:
        """``n_steps`` steps (central differences, or implicit) with held nodal forces (N).

        Raises
        ------
        RetryStep
            The adaptive implicit step rejected the step (the solver's state unchanged): the step it asks for.
        """
        try:
            self.solver.advance(dt, n_steps, forces)
        except StepRejected as exc:
            raise RetryStep(exc.dt, exc.why) from None

    def positions(self) -> dict[str, np.ndarray]:
        """Current node coordinates per body (m), this rank's nodes (ghosts included)."""
        return {n: b.x for n, b in self.solver.bodies.items()}

    def heated_cells(self) -> dict[str, np.ndarray]:
        """The cells (vertex rows, (nc, 3) or (nc, 4): a six- or ten-node cell's corners) of every body that carries
        a temperature, by name."""
        return {n: b.cells[:, :b.gdim + 1] for n, b in self.solver.bodies.items() if b.material.thermal}

    def cell_temperatures(self) -> dict[str, np.ndarray]:
        """The temperature per cell (K) of every body that carries one, by name (its cells in the order of
        :meth:`heated_cells`; a six- or ten-node cell's: the mean of its Gauss points')."""
        return {n: _cell_values(b, b.temperature) for n, b in self.solver.bodies.items() if b.material.thermal}

    def add_heat(self, heat: dict[str, np.ndarray]) -> None:
        """Heat the cells of bodies adiabatically: body name -> J/m^3 per cell (``ExplicitSolver.add_heat``; a
        six- or ten-node cell's heat goes to each of its Gauss points)."""
        for name, e in heat.items():
            b = self.solver.bodies[name]
            e = np.asarray(e, dtype=float)
            if getattr(b, "element", "tet4") in ("tet10", "tri6"):
                e = np.repeat(e, len(b.temperature) // max(len(b.cells), 1))
            self.solver.add_heat(name, e)

    def impulse_window(self, t0: float, dt: float, k: int) -> float:
        """Where the loop evaluates the load of ``k`` steps of ``dt`` from ``t0`` (s): the solver's own (the implicit
        one's t0 + k·dt/2, t0 + k·dt for static steps), else central differences' t0 + (k − 1)·dt/2."""
        window = getattr(self.solver, "impulse_window", None)
        return window(t0, dt, k) if window is not None else t0 + 0.5 * (k - 1) * dt

    def total_force(self, forces: dict[str, np.ndarray]) -> np.ndarray:
        """Resultant (N) over owned nodes of every rank (ghost rows are complete copies)."""
        local = np.zeros(next(iter(self.solver.bodies.values())).gdim)   # 2 components, or 3 in 3D
        for name, f in forces.items():
            local += np.asarray(f)[: self.solver.bodies[name].n_owned].sum(axis=0)
        return self.solver.comm.allreduce(local)

    def state_dict(self) -> dict[str, np.ndarray]:
        """The solver's exact-restart state."""
        return self.solver.state_dict()

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        self.solver.load_state_dict(state)

    # ----------------------------------------------------------------- for the pressure pulses
    def reference_positions(self) -> dict[str, np.ndarray]:
        """Node coordinates per body in the initial configuration (m), this rank's nodes."""
        return {n: b.X0 for n, b in self.solver.bodies.items()}

    def max_speed(self, body: str) -> float:
        """Largest nodal speed (m/s) of the body's owned nodes over all ranks (0 without nodes)."""
        b = self.solver.bodies[body]
        local = float(np.sqrt((b.v[: b.n_owned] ** 2).sum(axis=1)).max()) if b.n_owned else 0.0
        return self.solver.comm.allreduce(local, op=MPI.MAX)

    def pressure_forces(self, body: str, nodes: np.ndarray, pressure: float) -> np.ndarray:
        """Consistent nodal forces (N) of a uniform follower pressure (Pa) on the body's boundary
        facets whose two nodes are marked (``nodes``: bool per local node); every row complete."""
        return self.solver.pressure_nodal_forces(body, lambda x: nodes, pressure)

    def mass_damping_forces(self, alpha: float) -> dict[str, np.ndarray]:
        """−α m v (N) per body (α in 1/s; m the lumped mass, v the last half-step velocity)."""
        return {name: -alpha * b.mass[:, None] * b.v for name, b in self.solver.bodies.items()}

    def set_kinetic_damping(self, on: bool) -> None:
        """The solver's kinetic damping on or off from the next step on."""
        self.solver.kinetic_damping = on

    def advance_pulses(self, program: PulseProgram, shifts: np.ndarray, t_stop: float, n_max: int,
                       dt_max: float | None) -> PulseBlock | None:
        """Pulse steps in the solver's compiled path (:func:`.pulse_block.run_pulse_block`); None
        where a step needs Python (MPI, callables: no compiled path)."""
        if getattr(self.solver, "compiled", None) is None:
            return None
        self._pulse_plan = block_plan(self.solver, program, self._pulse_plan)
        return run_pulse_block(self.solver, self._pulse_plan, shifts, t_stop, n_max, dt_max)


class PressurePulses(LoadCapabilities):
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
        self._prog: PulseProgram | None = None  # the pulses as the compiled block takes them

    def _shift(self, i: int, t0: float, mechanics: PressureMechanics) -> float:
        """Time shift of pulse i; fixes it when a rest-triggered pulse fires."""
        if not np.isnan(self.offsets[i]):
            return float(self.offsets[i])
        prev = self.loads[i - 1]
        prev_shift = self.offsets[i - 1]
        if np.isnan(prev_shift) or t0 < prev.t_end + prev_shift:
            return np.nan
        if mechanics.max_speed(self.loads[i].body) < self.loads[i].rest_speed:
            self.offsets[i] = t0 - self.loads[i].t_start
        return float(self.offsets[i])

    def load(self, t0: float, t1: float, t_mid: float, mechanics: PressureMechanics) -> LoadStep:
        """Nodal forces (N) per body for the step [t0, t1] (s); switches the mechanics' kinetic
        damping for the step."""
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
            f = mechanics.pressure_forces(ld.body, self._loaded_nodes(i, mechanics), p)
            forces[ld.body] = forces[ld.body] + f if ld.body in forces else f
        mechanics.set_kinetic_damping(t_mid < self.kinetic_until)
        alpha = relax + (self.damping if self.damping_from <= t_mid < self.damping_until else 0.0)
        if alpha > 0.0:
            _add(forces, mechanics.mass_damping_forces(alpha))
        return LoadStep(forces, None, values)

    def initial(self, mechanics: PressureMechanics) -> LoadStep:
        """Pressures and nodal forces (N) at t = 0, for the history's first row: each started
        pulse at t = 0 (eq. 8 starts at p0, eq. 7 at 0; a pulse waiting for rest at 0) plus the
        mass damping if it acts at t = 0. Changes no state (the mechanics' kinetic damping is
        left to :meth:`load`)."""
        forces: dict[str, np.ndarray] = {}
        values: dict[str, float] = {}
        for i, ld in enumerate(self.loads):
            shift = self.offsets[i]
            p = 0.0 if np.isnan(shift) else pulse_pressure(ld, 0.0 - float(shift))
            values[f"load{i}_pressure_Pa"] = p
            if p != 0.0:
                f = mechanics.pressure_forces(ld.body, self._loaded_nodes(i, mechanics), p)
                forces[ld.body] = forces[ld.body] + f if ld.body in forces else f
        if self.damping > 0.0 and self.damping_from <= 0.0 < self.damping_until:
            _add(forces, mechanics.mass_damping_forces(self.damping))
        return LoadStep(forces, None, values)

    def _waiting(self, i: int, t0: float) -> bool:
        """Pulse i waits for rest: the previous pulse has started and its window is over."""
        prev_shift = self.offsets[i - 1] if i > 0 else np.nan
        return not np.isnan(prev_shift) and t0 >= self.loads[i - 1].t_end + prev_shift

    def _loaded_nodes(self, i: int, mechanics: PressureMechanics) -> np.ndarray:
        """Nodes of pulse i's box on the body's *initial* configuration (bool per local node:
        the material surface): the box picks the same facets however far the body has moved
        (e.g. a blank's upper face drawn into a die). Cached per pulse."""
        if i not in self._masks:
            ld = self.loads[i]
            X0 = mechanics.reference_positions()[ld.body]
            x3 = np.zeros((3, X0.shape[0]))
            x3[:2] = X0.T
            self._masks[i] = np.asarray(box_marker(ld.surface)(x3), dtype=bool)
        return self._masks[i]

    # ----------------------------------------------------------------- compiled blocks
    def advance_block(self, mechanics: PressureMechanics, t_stop: float, n_max: int,
                      dt_max: float | None) -> StepBlock | None:
        """Up to ``n_max`` EM steps of one mechanical step each (the mechanics-only loop:
        ``n = 1``, ``landing = "last"``) in compiled code, load evaluation included: per step the
        stable step, the pulses at ``t_mid = t0``, their follower-pressure nodal forces on the
        current configuration, the force switch and the explicit step — what :meth:`load` and
        ``mechanics.advance`` do per step, with the same bits (:mod:`.pulse_block`, run by the
        mechanics: :meth:`PressureMechanics.advance_pulses`). Stops before the step that lands on
        ``t_stop`` (left to the loop's own step) and at the first event. Mass damping (−α m v)
        is applied as in :meth:`load`.

        Rest-triggered pulses too: a pulse waiting for rest (its predecessor's window over) checks
        the loaded body's largest nodal speed each step, fires below ``rest_speed``, and applies
        its ``rest_damping`` while it waits, as :meth:`load` does.

        Returns None (nothing done) where a step needs Python: no compiled solver path (MPI,
        callables), or the first pulse waits.
        """
        if n_max < 1 or (len(self.offsets) and np.isnan(self.offsets[0])):
            return None
        offsets = self.offsets.copy()
        blk = mechanics.advance_pulses(self._program(mechanics), offsets, t_stop, n_max, dt_max)
        if blk is None:
            return None
        self.offsets = offsets
        values = {f"load{i}_pressure_Pa": blk.pressure[:, i] for i in range(len(self.loads))}
        return StepBlock(blk.t0, blk.dt, blk.resultant, values, blk.error)

    def _program(self, mechanics: PressureMechanics) -> PulseProgram:
        """The pulses as the compiled block takes them, built once."""
        if self._prog is None:
            rest = np.array([[ld.rest_speed, ld.rest_damping] for ld in self.loads]).reshape(-1, 2)
            self._prog = PulseProgram(pulse_table(self.loads), rest, tuple(ld.body for ld in self.loads),
                                      tuple(self._loaded_nodes(i, mechanics) for i in range(len(self.loads))),
                                      float(self.damping), float(self.damping_from), float(self.damping_until),
                                      float(self.kinetic_until))
        return self._prog

    @property
    def columns(self) -> tuple[str, ...]:
        """The resultant and each pulse's pressure."""
        return ("force_x_N", "force_y_N") + tuple(f"load{i}_pressure_Pa" for i in range(len(self.loads)))

    def run_metrics(self, history, counters) -> dict[str, float]:
        """The actual start time of each pulse (s)."""
        return {f"load{i}_start_time_s": float(t) for i, t in enumerate(self.start_times())}

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


def _add(forces: dict[str, np.ndarray], more: dict[str, np.ndarray]) -> None:
    """Add nodal forces (N) per body into ``forces``, in ``more``'s body order."""
    for name, f in more.items():
        forces[name] = forces[name] + f if name in forces else f


def _cell_values(b, arr: np.ndarray) -> np.ndarray:
    """Per cell the values of a per-row array of body ``b`` (a ten-node body's rows are its Gauss points)."""
    means = getattr(b, "cell_means", None)
    return means(arr) if means is not None else arr
