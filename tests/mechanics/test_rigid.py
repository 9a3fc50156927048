"""Rigid bodies (solvers/dolfinx/rigid.py) against closed-form motion: a constant force with gravity
gives u = u0 + v0 t + a t^2 / 2 exactly (central differences are exact for quadratic trajectories;
1e-12), also with steps of varying size; a body resting on an end stop under gravity stays there
(no drift, no penetration); a falling body hits a stop and rebounds with the coefficient of
restitution (bounce height e^2 h); a restart continues bit for bit; bad input is refused."""
from __future__ import annotations

import numpy as np
import pytest

from pulseform.solvers.dolfinx.rigid import EndStop, RigidBody

NODES = np.array([[0.02, 0.0], [0.03, 0.0], [0.03, 0.002], [0.02, 0.002]])


def test_constant_force_and_gravity_exact():
    m, f, g = 0.05, np.array([0.3, 2.0]), np.array([0.0, -9.81])
    b = RigidBody("disk", NODES, m, free=(True, True), gravity=tuple(g), offset=(1e-3, 0.0), velocity=(0.5, -1.0))
    a = f / m + g
    t = 0.0
    for dt, n in ((1e-4, 37), (3e-5, 11), (2.2e-4, 5), (1e-4, 20)):
        b.advance(dt, n, f)
        t += dt * n
        want = np.array([1e-3, 0.0]) + np.array([0.5, -1.0]) * t + 0.5 * a * t ** 2
        assert np.allclose(b.u, want, rtol=0, atol=1e-12 * max(1.0, np.abs(want).max()))
        assert np.allclose(b.velocity_now(), np.array([0.5, -1.0]) + a * t, rtol=0, atol=1e-12)
    assert b.time == pytest.approx(t, rel=1e-14)
    assert np.allclose(b.positions(), NODES + b.u)
    # work of force and gravity = change of kinetic energy (exact motion)
    ke0 = 0.5 * m * (0.5 ** 2 + 1.0 ** 2)
    assert b.kinetic_energy() - ke0 == pytest.approx(b.work_J, rel=1e-10)


def test_axisymmetric_body_moves_along_the_axis_only():
    b = RigidBody("ring", NODES, 0.01, gravity=(0.0, -9.81))
    b.advance(1e-4, 100, np.array([5.0, 0.3]))
    assert b.u[0] == 0.0 and b.u[1] == pytest.approx(0.5 * (0.3 / 0.01 - 9.81) * 0.01 ** 2, rel=1e-12)
    assert set(b.history()) == {"ring_position_y_m", "ring_travel_y_m", "ring_velocity_y_m_s", "ring_acceleration_y_m_s2", "ring_force_y_N"}


@pytest.mark.parametrize("e", [0.0, 0.6])
def test_resting_on_a_stop_under_gravity_stays_put(e):
    b = RigidBody("disk", NODES, 0.02, gravity=(0.0, -9.81), stops=(EndStop(1, 0.0, 1, e),))
    b.advance(1e-5, 5000)
    assert b.u[1] == 0.0 and b.v[1] == 0.0
    assert b.history()["disk_acceleration_y_m_s2"] == 0.0
    # a small upward force below the weight: still at rest; above it: lifts off
    b.advance(1e-5, 100, np.array([0.0, 0.9 * 0.02 * 9.81]))
    assert b.u[1] == 0.0
    b.advance(1e-5, 100, np.array([0.0, 1.1 * 0.02 * 9.81]))
    assert b.u[1] > 0.0


@pytest.mark.parametrize("e", [0.0, 0.5])
def test_drop_onto_a_stop_rebounds_with_restitution(e):
    h, g, dt = 0.01, 9.81, 1e-6
    b = RigidBody("disk", NODES, 0.02, gravity=(0.0, -g), offset=(0.0, h), stops=(EndStop(1, 0.0, 1, e),))
    t_fall = np.sqrt(2 * h / g)
    b.advance(dt, int(1.2 * t_fall / dt))  # one impact, at t_fall
    assert b.u[1] >= 0.0
    ke = 0.5 * 0.02 * 2 * g * h
    assert b.stop_dissipated_J == pytest.approx(ke * (1 - e * e), rel=2e-3)
    top = 0.0
    for _ in range(int(0.7 * t_fall / dt / 1000)):  # the rebound's top at (1 + e) t_fall, before the next impact
        b.advance(dt, 1000)
        assert b.u[1] >= 0.0  # never below the stop
        top = max(top, b.u[1])
    assert top == pytest.approx(e * e * h, rel=2e-3, abs=1e-8)


def test_restart_continues_bit_for_bit():
    kw = dict(free=(True, True), gravity=(0.0, -9.81), velocity=(1.0, 2.0), stops=(EndStop(1, -0.01, 1, 0.3),))
    a, b = RigidBody("p", NODES, 0.1, **kw), RigidBody("p", NODES, 0.1, **kw)
    f = np.array([0.1, -0.5])
    a.advance(1e-4, 300, f)
    b.advance(1e-4, 150, f)
    c = RigidBody("p", NODES, 0.1, **kw)
    c.load_state_dict({k: v.copy() for k, v in b.state_dict().items()})
    c.advance(1e-4, 150, f)
    for k in ("u", "v", "a"):
        assert np.array_equal(getattr(a, k), getattr(c, k)), k
    assert a.stop_dissipated_J == c.stop_dissipated_J and a.time == c.time


def test_bad_input():
    with pytest.raises(ValueError, match="mass must be > 0"):
        RigidBody("p", NODES, -1.0)
    with pytest.raises(ValueError, match="restitution must be in"):
        EndStop(1, 0.0, 1, 1.5)
    with pytest.raises(ValueError, match="beyond an end stop"):
        RigidBody("p", NODES, 1.0, offset=(0.0, -0.1), stops=(EndStop(1, 0.0),))
