"""Rigid bodies in implicit runs: the translation of :class:`~.rigid.RigidBody` integrated exactly over each step
under the force held over it, with the end stops' impacts at their instants.

The implicit step (:mod:`.implicit`) holds the load over [t, t + dt] (the loop evaluates it at the window's centre
t + dt/2). A rigid body has no internal force, so every Newmark / HHT-alpha scheme reduces for it to

    u^{n+1} = u^n + dt v^n + dt^2 / 2 a,     v^{n+1} = v^n + dt a,     a = F / m + g   (free components)

(with a^{n+1} = a^n = a under the held force: beta and gamma drop out), the exact motion under a constant force:
:class:`HeldRigidBody` steps it so, with full-step velocities (the kinetic energy 1/2 m v^2 at the step's end, no
switch term: the work of the held force F.(u^{n+1} - u^n) equals the change of kinetic energy exactly). An end stop
reached within a step is met at its instant (the root of the parabola of the gap), the normal velocity reversed
times the restitution (the energy lost counted in ``stop_dissipated_J``) and the motion continued for the rest of
the step; a body on a stop that the forces push into it rests there (the stop's reaction takes the push).

Units: m, m/s, m/s^2, kg, N, s, J.
"""
from __future__ import annotations

import math

import numpy as np

from .rigid import EndStop, RigidBody

__all__ = ["HeldRigidBody", "first_contact"]

#: most stop impacts in one step (a bouncing body with restitution > 0 taking ever shorter hops): then it rests
_MAX_IMPACTS = 64


def first_contact(gap: float, rate: float, acc: float, span: float) -> float | None:
    """The first instant tau in [0, span] (s) at which the gap g(tau) = gap + rate tau + acc tau^2 / 2 (m, m/s,
    m/s^2) closes while closing (g = 0, g' <= 0); None if it stays open over the span. A gap already closed with
    the body moving in closes at 0; one just closed with the body leaving (after a rebound) at its return."""
    if gap <= 0.0 and (rate < 0.0 or (rate == 0.0 and acc < 0.0)):
        return 0.0
    g = max(gap, 0.0)
    if acc == 0.0:
        tau = -g / rate if rate < 0.0 else math.inf
    else:
        disc = rate * rate - 2.0 * acc * g
        if disc < 0.0:
            return None
        q = -0.5 * (rate + math.copysign(math.sqrt(disc), rate))  # the stable pair of roots of acc/2 t^2 + rate t + g
        roots = (q / (0.5 * acc), g / q if q != 0.0 else math.inf)
        tau = min((t for t in roots if t > 0.0 and rate + acc * t <= 0.0), default=math.inf)
    return tau if tau <= span else None


class HeldRigidBody(RigidBody):
    """A :class:`~.rigid.RigidBody` stepped exactly under the force held over each step (implicit runs); the same
    parameters, outputs and checkpoint. ``v`` is the velocity at the present time."""

    def advance(self, dt: float, n_steps: int, force: np.ndarray | None = None) -> None:
        """``n_steps`` steps of ``dt`` (s) under the resultant ``force`` (N, shape (dim,); None: none) held over
        them, plus gravity; the stops met at their instants."""
        self.force = np.zeros(self.dim) if force is None else np.asarray(force, float).reshape(self.dim).copy()
        f_total = (self.force + self.mass * np.asarray(self.gravity, float)) * self._mask
        for _ in range(int(n_steps)):
            u_start = self.u.copy()
            left = float(dt)
            for _impact in range(_MAX_IMPACTS + 1):
                a = self._acceleration()
                hit, tau = None, left
                for s in self.stops:
                    t = first_contact(s.gap(self.u), s.side * self.v[s.axis], s.side * a[s.axis], left)
                    if t is not None and (hit is None or t < tau):
                        hit, tau = s, t
                self.u = self.u + tau * self.v + 0.5 * tau * tau * a
                self.v = self.v + tau * a
                left -= tau
                if hit is None:
                    break
                self._impact(hit, _impact == _MAX_IMPACTS)
                if left <= 0.0:
                    break
            self.work_J += float(np.dot(f_total, self.u - u_start))
            self.a = self._acceleration()
            self._dt_prev = dt
            self.time += dt
            self.step_count += 1

    def _impact(self, s: EndStop, last: bool) -> None:
        """The body on stop ``s``: put on it, its normal velocity reversed times the restitution (zero on the
        ``last`` impact a step allows), the kinetic energy lost counted."""
        i = s.axis
        self.u[i] = s.position
        vn = self.v[i]
        if s.side * vn < 0.0:
            e = 0.0 if last else s.restitution
            self.v[i] = -e * vn
            self.stop_dissipated_J += 0.5 * self.mass * vn * vn * (1.0 - e * e)

    def velocity_now(self) -> np.ndarray:
        """Velocity at the present time (m/s): the full-step velocity."""
        return self.v.copy()
