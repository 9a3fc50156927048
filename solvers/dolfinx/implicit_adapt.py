"""The adaptive step of the implicit integrator (a part of :class:`~.implicit.ImplicitSteps`): a local error
estimate of each Newmark / HHT-alpha step and the step-size controller.

The estimate (Zienkiewicz & Xie, Earthquake Eng. Struct. Dyn. 20 (1991) 871): the Newmark update of the
displacement is exact for a cubic motion up to the term dt^3 (beta - 1/6) da/dt, so the local error of a step is

    e = dt^2 (beta - 1/6) (a^{n+1} - a^n)          (m, per free component)

which falls as dt^3 (the trapezoidal rule: beta = 1/4, e = dt^2 (a^{n+1} - a^n) / 12). Its root mean square over
the free components of every body, |e|, is measured against the mixed tolerance

    eta = |e| / (error_tol * s + error_atol),   s = max(|u^{n+1}|, the largest |u| of the accepted steps)

(u = x - X0, root mean squares over the same components; m): a step with eta <= 1 is accepted. For a free
vibration of amplitude U and frequency omega, |e| / U ~ (omega dt)^3 / 12, the trapezoidal rule's phase error per
step; ``error_atol`` (m) keeps a start from rest (s -> 0) from taking ever shorter steps.

The controller: a step with eta <= 1 (or at ``dt_min``) is accepted and the next is
dt * min(2, max(0.2, 0.9 eta^(-1/3))), within [dt_min, dt_max]; a step with eta > 1 is rejected (the state is left
as it was: the loop evaluates the load again for the shorter step, :class:`StepRejected`) and retried with the
same formula's (shorter) step. A step whose Newton iterations fail is rejected with half the step while that is at
least dt_min; below, the fixed-step cuts of :meth:`~.implicit.ImplicitSteps.advance` take over. The step proposed
for the next call is :meth:`stable_time_step`'s answer (and in the checkpoint).
"""
from __future__ import annotations

import logging
import math
from typing import Dict, Tuple

import numpy as np
from mpi4py import MPI

from .implicit_options import NotConverged

__all__ = ["StepRejected", "local_error", "next_step", "AdaptiveSteps", "SAFETY", "GROWTH", "SHRINK"]

log = logging.getLogger(__name__)

#: the controller's safety factor, largest growth and largest shrink per step
SAFETY, GROWTH, SHRINK = 0.9, 2.0, 0.2


class StepRejected(RuntimeError):
    """An adaptive implicit step was rejected; the solver's state is unchanged. Retry from the same state with
    a step of ``dt`` (s) and the load of that step."""

    def __init__(self, dt: float, why: str):
        self.dt = float(dt)
        self.why = why
        super().__init__(f"step rejected ({why}); retry with dt = {dt:.6g} s")


def local_error(beta: float, dt: float, a_new: np.ndarray, a_old: np.ndarray) -> np.ndarray:
    """Zienkiewicz and Xie's local error estimate of a Newmark step.

    Parameters
    ----------
    beta : float
        Newmark's beta (dimensionless).
    dt : float
        The step, s.
    a_new, a_old : ndarray
        Accelerations at the end and the start of the step, m/s^2.

    Returns
    -------
    ndarray
        dt^2 (beta - 1/6) (a_new - a_old), m.
    """
    return dt * dt * (beta - 1.0 / 6.0) * (np.asarray(a_new) - np.asarray(a_old))


def next_step(dt: float, eta: float, dt_min: float, dt_max: float) -> float:
    """The controller's next step (s) after a step of ``dt`` (s) whose error estimate is ``eta`` times the accepted
    one: dt times min(GROWTH, max(SHRINK, SAFETY eta^(-1/3))) (the estimate is third order), within
    [dt_min, dt_max]."""
    factor = GROWTH if eta <= 0.0 else min(GROWTH, max(SHRINK, SAFETY * eta ** (-1.0 / 3.0)))
    return min(dt_max, max(dt_min, dt * factor))


class AdaptiveSteps:
    """The adaptive step of :class:`~.implicit.ImplicitSteps` (its ``options``, ``bodies``, ``_newton``,
    ``_commit``, ``_step_with_cuts`` and held forces)."""

    def _adapt_init(self) -> None:
        """The controller's state: the next step, the displacement scale, counts and the last estimate."""
        self._dt_next = self.options.dt
        self._u_peak = 0.0
        self.rejected_steps = 0
        self.last_error = 0.0      # eta of the last step: its error over the accepted one (dimensionless)
        self.last_error_m = 0.0    # |e| of the last step, m

    def _held_forces(self) -> Dict[str, Tuple[np.ndarray, np.ndarray, bool]]:
        """What :meth:`advance` changes before the step (accelerations, held forces), to undo on a rejection."""
        return {n: (b.a.copy(), self._fext[n].copy(), self._fext_nonzero[n]) for n, b in self.bodies.items()}

    def _reject(self, held, dt_new: float, why: str) -> None:
        """Leave the state as it was before :meth:`advance` and raise :class:`StepRejected`."""
        for n, (a, f, nz) in held.items():
            self.bodies[n].a[...] = a
            self._fext[n][...] = f
            self._fext_nonzero[n] = nz
        self.rejected_steps += 1
        log.debug("t=%.6e s: %s; retry with %.4e s", self.time, why, dt_new)
        raise StepRejected(dt_new, why)

    def error_estimate(self, du: Dict[str, np.ndarray], dt: float) -> Tuple[float, float, float]:
        """(eta, |e| in m, the displacement scale s in m) of a step of ``dt`` (s) with the increments ``du``
        (body -> (N, gdim), m) from the present state: the module's estimate over the free components."""
        o = self.options
        beta = o.beta
        e2 = u2 = 0.0
        count = 0
        for n, b in self.bodies.items():
            no = b.n_owned                    # owned rows: each node counted once over the ranks
            free = ~self._mask[n][:no]
            a_new = (du[n][:no] - dt * b.v[:no] - dt * dt * (0.5 - beta) * b.a[:no]) / (beta * dt * dt)
            e2 += float(np.sum(local_error(beta, dt, a_new, b.a[:no])[free] ** 2))
            u2 += float(np.sum((b.x[:no] + du[n][:no] - b.X0[:no])[free] ** 2))
            count += int(np.count_nonzero(free))
        if self.comm.size > 1:                # every rank takes the same decision
            e2, u2, count = (float(v) for v in self.comm.allreduce(np.array([e2, u2, count], float), op=MPI.SUM))
        e = math.sqrt(e2 / max(count, 1))
        s = max(math.sqrt(u2 / max(count, 1)), self._u_peak)
        accepted = o.error_tol * s + o.error_atol
        eta = e / accepted if accepted > 0.0 else (0.0 if e == 0.0 else math.inf)
        return eta, e, s

    def _adaptive_step(self, dt: float, n_steps: int, held) -> None:
        """One adaptive step of ``dt`` (s) under the held forces: accepted (committed, the next step proposed) or
        rejected (:class:`StepRejected`, nothing changed)."""
        o = self.options
        if n_steps != 1:
            raise ValueError(f"adaptive implicit steps go one per call (n_steps = 1), got {n_steps}")
        dt_min = o.step_min
        try:
            trial = self._newton(dt, 1.0)
        except NotConverged as exc:
            if 0.5 * dt >= dt_min:
                self._reject(held, 0.5 * dt, exc.why)
            self._step_with_cuts(dt, 0, 0.0, 1.0)   # at the smallest step: the fixed-step cuts
            self._dt_next = dt
            return
        eta, e, s = self.error_estimate(trial.du, dt)
        if eta > 1.0 and dt > dt_min * (1.0 + 1e-9):
            self._reject(held, next_step(dt, eta, dt_min, o.dt_max),
                         f"error estimate {eta:.3g} times the accepted one on a step of {dt:.4g} s")
        self._commit(trial, dt, 0.0, 1.0)
        self.last_error, self.last_error_m = eta, e
        self._u_peak = s
        self._dt_next = next_step(dt, eta, dt_min, o.dt_max)

    def adapt_state(self) -> np.ndarray:
        """The controller's state for a checkpoint: next step (s), displacement scale (m), rejected steps, last
        estimate (dimensionless and m)."""
        return np.array([self._dt_next, self._u_peak, self.rejected_steps, self.last_error, self.last_error_m])

    def load_adapt_state(self, a: np.ndarray) -> None:
        """Restore :meth:`adapt_state`."""
        dt_next, u_peak, rejected, eta, e = (float(v) for v in np.asarray(a, dtype=float))
        self._dt_next, self._u_peak, self.rejected_steps = dt_next, u_peak, int(rejected)
        self.last_error, self.last_error_m = eta, e
