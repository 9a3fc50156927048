"""Rigid bodies in implicit runs (solvers/dolfinx/rigid_held.py): the motion under a held force and gravity is the
exact parabola at any step, the end stops are met at their instants (a ball dropped on a stop with restitution:
the analytic bouncing-ball trajectory, its energy loss), and the ledger (kinetic energy + stop losses = work)
closes to round-off. References: u = u0 + v0 t + a t^2 / 2; a drop from h hits at sqrt(2 h / g) with speed
sqrt(2 g h), each rebound e times slower, hops of 2 v / g, all energy m g h lost after the infinite series of hops
(time sqrt(2h/g) (1 + e) / (1 - e))."""
import math

import numpy as np
import pytest

from pulseform.solvers.dolfinx.rigid import EndStop
from pulseform.solvers.dolfinx.rigid_held import HeldRigidBody, first_contact

NODES = np.zeros((3, 2))


@pytest.mark.parametrize("dt", [1e-3, 3.7e-4])
def test_constant_force_is_exact_at_any_step(dt):
    """A 2 kg body at 1 m/s under -6 N (a = -3 m/s^2) and gravity along x, 7 steps: position and velocity equal
    the parabola to round-off (1e-15 relative), the kinetic energy change equals the work."""
    b = HeldRigidBody("r", NODES, 2.0, free=(True, True), gravity=(0.5, 0.0), velocity=(0.0, 1.0))
    ke0 = b.kinetic_energy()
    b.advance(dt, 7, np.array([0.0, -6.0]))
    t = 7 * dt
    assert b.u == pytest.approx([0.25 * t * t, t - 1.5 * t * t], rel=1e-15, abs=1e-18)
    assert b.velocity_now() == pytest.approx([0.5 * t, 1.0 - 3.0 * t], rel=1e-15)
    assert b.kinetic_energy() - ke0 == pytest.approx(b.work_J, rel=1e-12)
    assert b.time == pytest.approx(t, rel=1e-15) and b.step_count == 7


def _bouncing(t: float, h: float, g: float, e: float) -> float:
    """Height (m) at time t (s) of a ball dropped from h onto a floor with restitution e."""
    t1 = math.sqrt(2.0 * h / g)
    if t < t1:
        return h - 0.5 * g * t * t
    tt, v = t - t1, e * g * t1
    while v > 1e-14:
        hop = 2.0 * v / g
        if tt < hop:
            return v * tt - 0.5 * g * tt * tt
        tt, v = tt - hop, e * v
    return 0.0


@pytest.mark.parametrize("e", [0.0, 0.5])
def test_drop_on_a_stop_follows_the_bouncing_ball(e):
    """A 1 kg body dropped from 0.1 m on a stop at 0 (g = 9.81) in steps of 13 ms (the fall takes 143 ms: impacts
    inside steps): its height at every step equals the analytic bouncing ball to 1e-15 m; after the series of hops
    it rests on the stop, having lost m g h = 0.981 J to it, and the ledger closes."""
    g, h = 9.81, 0.1
    b = HeldRigidBody("r", NODES, 1.0, free=(False, True), gravity=(0.0, -g), offset=(0.0, h),
                      stops=(EndStop(1, 0.0, 1, e),))
    worst = 0.0
    for _ in range(60):
        b.advance(0.013, 1)
        worst = max(worst, abs(b.u[1] - _bouncing(b.time, h, g, e)))
    print(f"restitution {e}: largest deviation from the bouncing ball {worst:.2e} m")
    assert worst < 1e-15
    assert b.time > math.sqrt(2 * h / g) * (1 + e) / (1 - e)
    assert b.u[1] == 0.0 and b.velocity_now()[1] == 0.0
    assert b.stop_dissipated_J == pytest.approx(g * h, rel=1e-12)
    assert b.kinetic_energy() + b.stop_dissipated_J == pytest.approx(b.work_J, rel=1e-12)


def test_a_body_pushed_into_its_stop_stays_and_leaves_when_pulled():
    """On its stop, a push into it leaves it at rest (no work, no drift); a pull of 2 N on 1 kg then moves it off
    by t^2 (exact)."""
    b = HeldRigidBody("r", NODES, 1.0, free=(False, True), stops=(EndStop(1, 0.0, 1, 0.0),))
    b.advance(1e-3, 10, np.array([0.0, -50.0]))
    assert b.u[1] == 0.0 and b.v[1] == 0.0 and b.work_J == 0.0
    b.advance(1e-3, 10, np.array([0.0, 2.0]))
    assert b.u[1] == pytest.approx(1e-4, rel=1e-12)


def test_first_contact():
    """The instant the gap closes: a fall from 1 m at g = 2 closes at 1 s; a body moving away never (or at its
    return: 1 m/s up under -2 m/s^2 from the stop returns at 1 s); already closing: 0; beyond the span: None."""
    assert first_contact(1.0, 0.0, -2.0, 5.0) == pytest.approx(1.0, rel=1e-15)
    assert first_contact(1.0, 0.0, -2.0, 0.5) is None
    assert first_contact(0.0, 1.0, -2.0, 5.0) == pytest.approx(1.0, rel=1e-15)
    assert first_contact(0.0, -1.0, 0.0, 5.0) == 0.0
    assert first_contact(1.0, 1.0, 0.0, 5.0) is None
    assert first_contact(2.0, -1.0, 0.0, 5.0) == pytest.approx(2.0)
