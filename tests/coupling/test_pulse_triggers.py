"""Pressure pulses that wait for rest, mass-proportional damping forces and the kinetic damping
window (the mechanics participant over a fake solver)."""

from types import SimpleNamespace

import numpy as np
import pytest
from mpi4py import MPI

from pulseform.orchestrator.case.model import Box, PulseSin2
from pulseform.orchestrator.mech.participants import DolfinxMechanics, PressurePulses


def _fake(speed):
    """The mechanics participant over a fake solver."""
    body = SimpleNamespace(v=np.array([[0.0, speed], [0.0, 0.0]]), n_owned=2, mass=np.array([2.0, 3.0]),
                           X0=np.zeros((2, 2)))
    solver = SimpleNamespace(bodies={"blank": body}, comm=MPI.COMM_WORLD,
                             pressure_nodal_forces=lambda name, marker, p: np.full((2, 2), p))
    return DolfinxMechanics(solver)


def _pulse(t_start, t_end, trigger="time"):
    return PulseSin2(type="pulse_sin2", body="blank", surface=Box(), amplitude=1e6, beta=0.0, omega=1e5,
                     t_start=t_start, t_end=t_end, trigger=trigger, rest_speed=0.5)


def test_second_pulse_waits_for_rest():
    loads = (_pulse(0.0, 1e-4), _pulse(0.0, 1e-4, "rest"))
    pp = PressurePulses(loads)
    moving, still = _fake(3.0), _fake(0.1)
    assert np.isnan(pp._shift(1, 0.5e-4, still))        # first pulse not over yet
    assert np.isnan(pp._shift(1, 2e-4, moving))         # over, but the blank still moves
    assert pp._shift(1, 3e-4, still) == pytest.approx(3e-4)  # fires now, window kept
    step = pp.load(3e-4, 3.2e-4, 3e-4 + 2.5e-5, still)
    assert step.values["load1_pressure_Pa"] == pytest.approx(1e6 * np.sin(1e5 * 2.5e-5) ** 2)
    assert pp.start_times() == pytest.approx([0.0, 3e-4])
    saved = pp.state_dict()
    fresh = PressurePulses(loads)
    fresh.load_state_dict(saved)
    assert fresh.start_times() == pytest.approx([0.0, 3e-4])


def test_mass_damping_force_until_time():
    pp = PressurePulses((), damping=50.0, damping_until=1e-3)
    mech = _fake(2.0)
    f = pp.load(0.0, 1e-6, 0.5e-6, mech).forces["blank"]
    assert f[0, 1] == pytest.approx(-50.0 * 2.0 * 2.0) and f[1, 1] == 0.0
    assert pp.load(2e-3, 2.1e-3, 2.05e-3, mech).forces == {}


def test_kinetic_damping_switched_on_until_time():
    pp = PressurePulses((), kinetic_until=1e-3)
    mech = _fake(2.0)
    assert pp.load(0.0, 1e-6, 0.5e-6, mech).forces == {} and mech.solver.kinetic_damping is True
    pp.load(2e-3, 2.1e-3, 2.05e-3, mech)
    assert mech.solver.kinetic_damping is False
