"""The pressure pulses in compiled blocks: EM steps of one mechanical step each, pulse evaluation,
follower-pressure forces, mass damping and the explicit step in numba (the mechanics-only loop).

The mechanics participant runs them (:meth:`.participants.DolfinxMechanics.advance_pulses`) on its
solver's compiled path; the pressure pulses (:class:`.participants.PressurePulses`) hand it their
program (:class:`PulseProgram`) and never see the solver.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np

from pulseform.solvers.dolfinx.block import EV_NONE, SC, follower_pressure, step, switch_forces

from .pulses import T_END, T_START, pulse_value

if TYPE_CHECKING:
    from pulseform.solvers.dolfinx import ExplicitSolver

_T, _DTC, _CFL, _KDON = SC["time"], SC["dt_crit"], SC["cfl"], SC["kinetic_damping"]


@dataclass(frozen=True, eq=False)
class PulseProgram:
    """What the pressure pulses ask of the compiled block; built once per run by the pulses.

    Attributes
    ----------
    table : ndarray (P, 8)
        :func:`.pulses.pulse_table` rows of the P pulses (Pa, 1/s, rad/s, s).
    rest : ndarray (P, 2)
        Per pulse: ``rest_speed`` (m/s) and ``rest_damping`` (1/s).
    bodies : tuple of str
        The loaded body of each pulse.
    nodes : tuple of ndarray
        Per pulse: the body's loaded nodes (bool per local node); a boundary facet is loaded when
        both its nodes are.
    damping, damping_from, damping_until : float
        Mass-proportional damping α (1/s), acting for ``damping_from`` <= t < ``damping_until`` (s).
    kinetic_until : float
        Kinetic damping on for t < this time (s).
    """

    table: np.ndarray
    rest: np.ndarray
    bodies: tuple[str, ...]
    nodes: tuple[np.ndarray, ...]
    damping: float
    damping_from: float
    damping_until: float
    kinetic_until: float


@dataclass
class PulseBlock:
    """What a compiled block did, per EM step: start time t0 (s), step dt (s), force resultant (N),
    pressure of each pulse (Pa); ``error`` the event that stopped it."""

    t0: np.ndarray
    dt: np.ndarray
    resultant: np.ndarray
    pressure: np.ndarray
    error: Exception | None

    def trimmed(self, n: int) -> "PulseBlock":
        """The first ``n`` steps."""
        return PulseBlock(self.t0[:n], self.dt[:n], self.resultant[:n], self.pressure[:n], self.error)


@dataclass
class _Plan:
    """Compiled-block data of a pulse program for one solver (see :func:`run_pulse_block`)."""

    solver: object
    program: PulseProgram
    segs: np.ndarray       # (S, 2) loaded segments of every pulse, solver-wide node rows
    seg_off: np.ndarray    # pulse i's segments: segs[seg_off[i]:seg_off[i + 1]]
    body: np.ndarray       # body index per pulse
    order: np.ndarray      # scratch: loaded bodies in the order the forces dict gets them
    thickness: float
    new: np.ndarray        # (N, 2) held forces of the step
    acc0: np.ndarray
    acc1: np.ndarray
    has: np.ndarray


def block_plan(solver: ExplicitSolver, program: PulseProgram, plan: _Plan | None = None) -> _Plan:
    """The program's loaded segments (solver-wide node rows) and scratch; ``plan`` is reused when
    it was built for the same solver and program."""
    if plan is not None and plan.solver is solver and plan.program is program:
        return plan
    bd = solver.compiled
    names = list(solver.bodies)
    segs, seg_off, body = [], [0], []
    for name, mask in zip(program.bodies, program.nodes):
        b = solver.bodies[name]
        ib = names.index(name)
        sg = b.segments[mask[b.segments[:, 0]] & mask[b.segments[:, 1]]] if len(b.segments) \
            else np.zeros((0, 2), np.int64)
        segs.append(sg.astype(np.int64) + bd.node_off[ib])
        seg_off.append(seg_off[-1] + len(sg))
        body.append(ib)
    ntot = int(bd.node_off[-1])
    return _Plan(solver, program,
                 np.concatenate(segs).reshape(-1, 2) if segs else np.zeros((0, 2), np.int64),
                 np.array(seg_off, np.int64), np.array(body, np.int64),
                 np.zeros(len(names), np.int64), float(next(iter(solver.bodies.values())).thickness),
                 np.zeros((ntot, 2)), np.zeros((ntot, 2)), np.zeros((ntot, 2)),
                 np.zeros(len(names), np.uint8))


def run_pulse_block(solver: ExplicitSolver, plan: _Plan, shifts: np.ndarray, t_stop: float, n_max: int,
                    dt_max: float | None) -> PulseBlock:
    """Up to ``n_max`` EM steps of one mechanical step each on the solver's compiled path (which
    must exist: ``solver.compiled``), as the loop, :meth:`.participants.PressurePulses.load` and the
    solver's ``advance`` do them per step, with the same bits; stops before the step that lands on
    ``t_stop`` (s) and at the first event (raised into ``PulseBlock.error``).

    ``shifts`` (s, one per pulse, nan: waiting for rest) is updated in place when a pulse fires.
    The solver's kinetic-damping switch is left as the last step had it.
    """
    bd, pg = solver.compiled, plan.program
    out = PulseBlock(np.zeros(n_max), np.zeros(n_max), np.zeros((n_max, 2)),
                     np.zeros((n_max, len(pg.table))), None)
    bd.load()
    done = _pulse_steps(bd.B, bd.W, bd.C, bd.sc, bd.ev, bd.evf, pg.table, shifts, pg.rest,
                        plan.body, plan.seg_off, plan.segs, bd.node_off, plan.order,
                        float(pg.kinetic_until), float(pg.damping), float(pg.damping_from),
                        float(pg.damping_until), float(t_stop), int(n_max),
                        math.inf if dt_max is None else float(dt_max),
                        solver.mode == 2, plan.thickness, plan.new, plan.acc0, plan.acc1,
                        plan.has, out.t0, out.dt, out.resultant, out.pressure)
    bd.store()
    last = done if bd.ev[0] != EV_NONE else done - 1
    if last >= 0:
        solver.kinetic_damping = bool(out.t0[last] + 0.0 * out.dt[last] < pg.kinetic_until)
    if bd.ev[0] != EV_NONE:
        try:
            solver.raise_event(float(out.dt[done]))
        except Exception as exc:  # noqa: BLE001 - handed to the loop, raised after the rows
            out.error = exc
    return out.trimmed(done)


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
