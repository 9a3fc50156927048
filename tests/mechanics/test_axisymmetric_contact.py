"""Axisymmetric soft contact: two solid cylinders (r in [0, 0.5] m, 1 m long) impacting along the
axis at 10 m/s. The ring forces are equal and opposite, so axial momentum is conserved to
round-off, the energy ledger closes (< 1 % of the initial kinetic energy) and the axis nodes stay
on the axis. (The contact stress at the axis is printed, not checked: no clean reference for
these proportions.)"""
import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, ContactPairSpec, ExplicitSolver
from pulseform.solvers.dolfinx.verification import PAPER_BAR_MATERIAL as MAT


def test_axial_impact_of_cylinders():
    comm = MPI.COMM_SELF
    h0 = 0.005
    a = dmesh.create_rectangle(comm, [np.array([0.0, 0.0]), np.array([0.5, 1.0])], [10, 20])
    b = dmesh.create_rectangle(comm, [np.array([0.0, 1.0 + h0]), np.array([0.5, 2.0 + h0])],
                               [10, 20])
    s = ExplicitSolver([BodySpec("a", a, MAT, initial_velocity=(0.0, 10.0)),
                        BodySpec("b", b, MAT)], formulation="axisymmetric", comm=comm,
                       contact_pairs=(ContactPairSpec("a", "b", 1e8, h0),))
    m = sum(bd.total_mass() for bd in s.bodies.values())
    assert m == pytest.approx(2 * MAT.density * np.pi * 0.25, rel=1e-12)
    p0 = s.bodies["a"].total_mass() * 10.0
    ke0 = s.energies()["kinetic_J"]
    dt = s.stable_time_step()
    t_first = 1.0 / MAT.dilatational_wave_speed     # before the release wave from the free end
    pres, worst = [], 0.0
    while s.time < 3e-4:
        s.advance(dt)
        if 0.3 * t_first < s.time < 0.9 * t_first:
            pres.append(s.contact_pressure_at(0, (0.0, 1.0)))
        worst = max(worst, abs(s.energies()["balance_error_J"]))
    pz = sum((bd.mass * (bd.v[:, 1] + 0.5 * dt * bd.a[:, 1])).sum() for bd in s.bodies.values())
    axis = [np.flatnonzero(bd.X0[:, 0] == 0.0) for bd in s.bodies.values()]
    print(f"\naxial momentum {pz:.6f} vs {p0:.6f}; energy error {worst / ke0:.2e}; axis contact "
          f"stress {np.mean(pres) / 1e6:.1f} MPa (bar 70.0, plane wave "
          f"{MAT.density * MAT.dilatational_wave_speed * 5 / 1e6:.1f})")
    assert pz == pytest.approx(p0, rel=1e-10)
    assert worst < 0.01 * ke0
    assert all(np.all(bd.x[ax, 0] == 0.0) for bd, ax in zip(s.bodies.values(), axis))
    assert min(pres) > 0.0                        # in contact over the whole window
