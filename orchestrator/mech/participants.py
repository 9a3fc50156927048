"""Participants built on the explicit DOLFINx solver: the mechanics adapter and pressure pulses."""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numba
import numpy as np
from mpi4py import MPI

from pulseform.solvers.dolfinx.block import EV_NONE, SC, follower_pressure, step, switch_forces

from ..case.model import Load
from ..coupling.interfaces import LoadCapabilities, LoadStep
from .pulses import T_END, T_START, box_marker, pulse_pressure, pulse_table, pulse_value

log = logging.getLogger(__name__)

_T, _DTC, _CFL, _KDON = SC["time"], SC["dt_crit"], SC["cfl"], SC["kinetic_damping"]

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

    # ----------------------------------------------------------------- compiled blocks
    def advance_block(self, mechanics: DolfinxMechanics, t_stop: float, n_max: int,
                      dt_max: float | None) -> "PulseBlock | None":
        """Up to ``n_max`` EM steps of one mechanical step each (the mechanics-only loop:
        ``n = 1``, ``landing = "last"``) in compiled code, load evaluation included: per step the
        stable step, the pulses at ``t_mid = t0``, their follower-pressure nodal forces on the
        current configuration, the force switch and the explicit step — what :meth:`load` and
        ``mechanics.advance`` do per step, with the same bits. Stops before the step that lands on
        ``t_stop`` (left to the loop's own step) and at the first event. Mass damping (−α m v)
        is applied as in :meth:`load`.

        Rest-triggered pulses too: a pulse waiting for rest (its predecessor's window over) checks
        the loaded body's largest nodal speed each step, fires below ``rest_speed``, and applies
        its ``rest_damping`` while it waits, as :meth:`load` does.

        Returns None (nothing done) where a step needs Python: no compiled solver path (MPI,
        callables).
        """
        solver = mechanics.solver
        bd = getattr(solver, "compiled", None)
        if bd is None or n_max < 1 or (len(self.offsets) and np.isnan(self.offsets[0])):
            return None
        plan = self._block_plan(mechanics)
        out = PulseBlock(np.zeros(n_max), np.zeros(n_max), np.zeros((n_max, 2)),
                         np.zeros((n_max, len(self.loads))), None)
        bd.load()
        offsets = self.offsets.copy()
        done = _pulse_steps(bd.B, bd.W, bd.C, bd.sc, bd.ev, bd.evf, plan.table, offsets, plan.rest,
                            plan.body, plan.seg_off, plan.segs, bd.node_off, plan.order,
                            float(self.kinetic_until), float(self.damping), float(self.damping_from),
                            float(self.damping_until), float(t_stop), int(n_max),
                            math.inf if dt_max is None else float(dt_max),
                            solver.mode == 2, plan.thickness, plan.new, plan.acc0, plan.acc1,
                            plan.has, out.t0, out.dt, out.resultant, out.pressure)
        bd.store()
        self.offsets = offsets
        last = done if bd.ev[0] != EV_NONE else done - 1
        if last >= 0:
            solver.kinetic_damping = bool(out.t0[last] + 0.0 * out.dt[last] < self.kinetic_until)
        if bd.ev[0] != EV_NONE:
            try:
                solver.raise_event(float(out.dt[done]))
            except Exception as exc:  # noqa: BLE001 - handed to the loop, raised after the rows
                out.error = exc
        return out.trimmed(done)

    def _block_plan(self, mechanics: DolfinxMechanics) -> "_Plan":
        """The pulses' loaded segments (solver-wide node rows) and scratch, built once."""
        solver = mechanics.solver
        plan = getattr(self, "_plan", None)
        if plan is not None and plan.solver is solver:
            return plan
        bd = solver.compiled
        names = list(solver.bodies)
        segs, seg_off, body = [], [0], []
        for i, ld in enumerate(self.loads):
            b = solver.bodies[ld.body]
            ib = names.index(ld.body)
            mask = self._material_marker(i, mechanics)(None)
            sg = b.segments[mask[b.segments[:, 0]] & mask[b.segments[:, 1]]] if len(b.segments) \
                else np.zeros((0, 2), np.int64)
            segs.append(sg.astype(np.int64) + bd.node_off[ib])
            seg_off.append(seg_off[-1] + len(sg))
            body.append(ib)
        ntot = int(bd.node_off[-1])
        rest = np.array([[ld.rest_speed, ld.rest_damping] for ld in self.loads]).reshape(-1, 2)
        self._plan = _Plan(solver, pulse_table(self.loads), rest,
                           np.concatenate(segs).reshape(-1, 2) if segs else np.zeros((0, 2), np.int64),
                           np.array(seg_off, np.int64), np.array(body, np.int64),
                           np.zeros(len(names), np.int64), float(next(iter(solver.bodies.values())).thickness),
                           np.zeros((ntot, 2)), np.zeros((ntot, 2)), np.zeros((ntot, 2)),
                           np.zeros(len(names), np.uint8))
        return self._plan

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


@dataclass
class _Plan:
    """Compiled-block data of the pulses for one solver (see :meth:`PressurePulses.advance_block`)."""

    solver: object
    table: np.ndarray      # pulse_table rows
    rest: np.ndarray       # per pulse: rest_speed (m/s), rest_damping (1/s)
    segs: np.ndarray       # (S, 2) loaded segments of every pulse, solver-wide node rows
    seg_off: np.ndarray    # pulse i's segments: segs[seg_off[i]:seg_off[i + 1]]
    body: np.ndarray       # body index per pulse
    order: np.ndarray      # scratch: loaded bodies in the order the forces dict gets them
    thickness: float
    new: np.ndarray        # (N, 2) held forces of the step
    acc0: np.ndarray
    acc1: np.ndarray
    has: np.ndarray


@dataclass
class PulseBlock:
    """What :meth:`PressurePulses.advance_block` did, per EM step: start time t0 (s), step dt (s),
    force resultant (N), pressure of each pulse (Pa); ``error`` the event that stopped it."""

    t0: np.ndarray
    dt: np.ndarray
    resultant: np.ndarray
    pressure: np.ndarray
    error: Exception | None

    def trimmed(self, n: int) -> "PulseBlock":
        """The first ``n`` steps."""
        return PulseBlock(self.t0[:n], self.dt[:n], self.resultant[:n], self.pressure[:n], self.error)


@numba.njit(cache=True)
def _pulse_steps(B, W, C, sc, ev, evf, table, shifts, rest, lbody, seg_off, segs, node_off, order,
                 kin_until, damping, damping_from, damping_until, t_stop, n_max, dt_max, axisym, thickness, new, acc0, acc1, has,
                 out_t0, out_dt, out_res, out_p):
    """EM steps of one mechanical step each with the pulses' follower pressures, as
    ``StaggeredLoop.em_step`` + ``PressurePulses.load`` + ``ExplicitSolver.advance`` do them
    (same operations, same order). Returns the steps completed; on an event ``ev[0]`` is set and
    ``out_dt[returned]`` is the failed step's dt."""
    done = 0
    while done < n_max:
        dt = sc[_CFL] * sc[_DTC]
        dt = min(dt, dt_max)
        t0 = sc[_T]
        remaining = t_stop - t0
        if dt >= remaining * (1.0 - 1e-12):
            break                      # the landing step: the loop's own
        t_mid = t0 + 0.5 * 0 * dt
        new[:] = 0.0
        has[:] = 0
        nl = 0
        relax = 0.0
        for i in range(table.shape[0]):
            if math.isnan(shifts[i]):  # PressurePulses._shift: fire a waiting pulse at rest
                ps = shifts[i - 1]
                if not (math.isnan(ps) or t0 < table[i - 1, T_END] + ps):
                    ib = lbody[i]
                    speed = 0.0
                    if node_off[ib + 1] > node_off[ib]:
                        speed = -np.inf
                        for j in range(node_off[ib], node_off[ib + 1]):
                            sp = math.sqrt(B.v[j, 0] * B.v[j, 0] + B.v[j, 1] * B.v[j, 1])
                            if sp > speed or math.isnan(sp):
                                speed = sp
                    if speed < rest[i, 0]:
                        shifts[i] = t0 - table[i, T_START]
            if math.isnan(shifts[i]) and rest[i, 1] > 0.0 and i > 0 and \
                    not math.isnan(shifts[i - 1]) and t0 >= table[i - 1, T_END] + shifts[i - 1]:
                relax = max(relax, rest[i, 1])
            p = 0.0 if math.isnan(shifts[i]) else pulse_value(table[i], t_mid - shifts[i])
            out_p[done, i] = p
            if p == 0.0:
                continue
            ib = lbody[i]
            follower_pressure(B.x, segs, seg_off[i], seg_off[i + 1], node_off[ib], node_off[ib + 1],
                              p, axisym, thickness, acc0, acc1, new, has[ib] == 0)
            if has[ib] == 0:
                order[nl] = ib
                nl += 1
            has[ib] = 1
        alpha = relax + (damping if damping_from <= t_mid < damping_until else 0.0)
        if alpha > 0.0:                # mass damping on every body, after the pulses
            for ib in range(node_off.shape[0] - 1):
                for i in range(node_off[ib], node_off[ib + 1]):
                    for c in range(2):
                        f = -alpha * B.m[i] * B.v[i, c]
                        new[i, c] = new[i, c] + f if has[ib] else f
                if has[ib] == 0:
                    order[nl] = ib
                    nl += 1
                has[ib] = 1
        r0 = 0.0                       # DolfinxMechanics.total_force, bodies in the dict's order
        r1 = 0.0
        for k in range(nl):
            ib = order[k]
            if node_off[ib + 1] == node_off[ib]:
                continue
            n0 = node_off[ib]
            s0 = new[n0, 0]
            s1 = new[n0, 1]
            for i in range(n0 + 1, node_off[ib + 1]):
                s0 += new[i, 0]
                s1 += new[i, 1]
            r0 += s0
            r1 += s1
        sc[_KDON] = 1.0 if t_mid < kin_until else 0.0
        switch_forces(B, sc, new)
        out_t0[done] = t0
        out_dt[done] = dt
        step(B, W, C, sc, dt, ev, evf)
        if ev[0] != EV_NONE:
            return done
        out_res[done, 0] = r0
        out_res[done, 1] = r1
        done += 1
    return done
