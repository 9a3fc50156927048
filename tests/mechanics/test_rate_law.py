"""Rate-dependent yield (Cowper-Symonds, Johnson-Cook) behind the same Material interface: under
an isochoric plane-strain stretch at constant log rate r (equivalent strain rate 2 r / sqrt(3)),
the von Mises stress after yield equals (sigma_0 + A eps_p) x rate factor (radial return)."""
import math

import numpy as np
import pytest

from pulseform.solvers.dolfinx import (BodySpec, CowperSymonds, ExplicitSolver, JohnsonCook,
                                       Material)

from mech_helpers import distorted_square

ALL = lambda x: np.full(x.shape[1], True)  # noqa: E731
R = 200.0   # 1/s


@pytest.mark.parametrize("law,factor", [
    (None, lambda rate: 1.0),
    (CowperSymonds(D=6500.0, p=4.0), lambda rate: 1 + (rate / 6500.0) ** 0.25),
    (JohnsonCook(C=0.02, eps_rate0=1.0), lambda rate: 1 + 0.02 * math.log(rate)),
])
def test_flow_stress_with_rate_factor(law, factor):
    mat = Material(2700.0, 26e9, 70e9, 100e6, 500e6, rate_law=law)

    def motion(X, t):
        lam = math.exp(R * t)
        return X * np.array([lam, 1.0 / lam])

    msh = distorted_square(n=3)
    s = ExplicitSolver([BodySpec("b", msh, mat, motion=((ALL, motion),))],
                       formulation="plane_strain", comm=msh.comm, bulk_viscosity=False)
    b = s.bodies["b"]
    dt = 0.5 * s.stable_time_step()
    s.advance(dt, 400)
    ep = b.eps_p
    assert ep.min() > 1e-3
    # the discrete rate on the mid-step configuration: (2 / dt) tanh(R dt / 2)
    rate = 2.0 / math.sqrt(3.0) * (2.0 / dt) * math.tanh(R * dt / 2.0)
    expected = (100e6 + 500e6 * ep) * factor(rate)
    assert np.allclose(b.von_mises, expected, rtol=1e-9)
