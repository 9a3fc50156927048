"""Robustness of the full contact path on the paper's section-5 materials: a 1 mm aluminium
blank at 100 m/s onto a steel die face tilted by 20 deg (two-pass soft contact with friction,
plasticity, k / h0^2 = 1e14 Pa/m below E / dx). Checks: the run completes without penetration,
the blank yields, the energy ledger closes to 1 % of the initial kinetic energy, and a first-step
overlap is reported as a penetration at t = 0."""
import math

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import (BodySpec, ContactPairSpec, ContactPenetrationError,
                                       ExplicitSolver, Material)

BLANK = Material(2735.0, 26.5e9, 65.1e9, 195e6, 520e6)
DIE = Material(7800.0, 76.9e9, 166e9, 620e6, 1020e6)


def _solver(y0):
    comm = MPI.COMM_SELF
    blank = dmesh.create_rectangle(comm, [np.array([-0.025, y0]), np.array([0.025, y0 + 0.001])],
                                   [100, 2])
    die = dmesh.create_rectangle(comm, [np.array([-0.04, -0.02]), np.array([0.04, 0.0])],
                                 [40, 10])
    th = math.radians(20.0)
    R = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    die.geometry.x[:, :2] = die.geometry.x[:, :2] @ R.T
    bottom = lambda x: x[1] < -0.015  # noqa: E731
    return ExplicitSolver(
        [BodySpec("blank", blank, BLANK, initial_velocity=(0.0, -100.0)),
         BodySpec("die", die, DIE, fixed=((bottom, (0, 1)),))],
        formulation="plane_strain",
        contact_pairs=(ContactPairSpec("blank", "die", 1e6, 1e-4, friction=0.2, two_pass=True),),
        comm=comm)


def test_blank_on_tilted_die():
    s = _solver(0.0100)
    ke0 = s.energies()["kinetic_J"]
    while s.time < 40e-6:
        s.advance(s.stable_time_step(), 10)
    e = s.energies()
    print(f"\nblank on die: {s.step_count} steps, plastic {e['plastic_J'] / ke0:.3f} KE0, contact "
          f"dissipated {e['contact_dissipated_J'] / ke0:.4f} KE0, balance "
          f"{e['balance_error_J'] / ke0:.2e} KE0, max eps_p {s.bodies['blank'].eps_p.max():.3f}")
    assert s.bodies["blank"].eps_p.max() > 0.05
    assert e["plastic_J"] > 0.02 * ke0 and e["contact_dissipated_J"] > 0
    assert abs(e["balance_error_J"]) < 0.01 * ke0


def test_initial_overlap_is_reported():
    with pytest.raises(ContactPenetrationError, match="t=0.000000e"):
        _solver(0.0005)
