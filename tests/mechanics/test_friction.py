"""Coulomb friction: a block pressed on a fixed base by a constant force N and sliding at v0
decelerates at mu N / m (rigid-body mechanics; the regularisation velocity 1e-3 m/s is far below
the sliding speed)."""
import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, ContactPairSpec, ExplicitSolver, Material

STEEL = Material(7800.0, 80e9, 170e9, 1e12, 0.0)


@pytest.mark.parametrize("mu", [0.1, 0.3])
def test_sliding_block_deceleration(mu):
    comm = MPI.COMM_SELF
    k, h0 = 1e5, 1e-3
    L, H = 0.1, 0.02
    pres = 2e6                                   # Pa, pressing the block on the base
    h_eq = 1.0 / (pres / k + 1.0 / h0)           # gap where k (1/h - 1/h0) = pres
    base = dmesh.create_rectangle(comm, [np.array([-0.2, -0.02]), np.array([0.4, 0.0])], [60, 2])
    block = dmesh.create_rectangle(comm, [np.array([0.0, h_eq]), np.array([L, h_eq + H])],
                                   [10, 2])
    allnodes = lambda x: np.full(x.shape[1], True)  # noqa: E731
    v0 = 1.0
    s = ExplicitSolver([BodySpec("block", block, STEEL, initial_velocity=(v0, 0.0)),
                        BodySpec("base", base, STEEL, fixed=((allnodes, (0, 1)),))],
                       formulation="plane_strain", comm=comm,
                       contact_pairs=(ContactPairSpec("block", "base", k, h0, friction=mu),))
    b = s.bodies["block"]
    top = lambda x: x[1] > h_eq + H - 1e-4  # noqa: E731 (current coordinates)
    m = b.total_mass()
    N = pres * L                                  # per unit thickness
    dt = s.stable_time_step()
    ts, vs = [], []
    expected = -mu * pres * L / (STEEL.density * L * H)
    t_stop = v0 / -expected
    while s.time < 0.7 * t_stop:
        f = s.pressure_nodal_forces("block", top, pres)
        s.advance(dt, 10, external_forces={"block": f})
        ts.append(s.time)
        vs.append(float((b.mass * b.v[:, 0]).sum() / b.mass.sum()))
    t, v = np.array(ts), np.array(vs)
    slope = np.polyfit(t, v, 1)[0]
    assert expected == pytest.approx(-mu * N / m, rel=1e-12)
    print(f"\nmu={mu}: deceleration {slope:.2f} m/s^2 vs {expected:.2f} ({slope / expected - 1:+.2%})"
          f", v({t[-1] * 1e3:.3f} ms) = {v[-1]:.4f} m/s")
    assert slope == pytest.approx(expected, rel=0.03)
    assert v[-1] > 0                              # still sliding
