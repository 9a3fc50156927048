"""Regression: a slave corner node beside the end of a master segment.

With 0.5 m elements the tolerance xi_tol·L (1 cm) equals the initial gap h0, so the left bar's
corner (4, 2) lies within the overshoot of the right bar's top segment, on its extended line
(h = 0 there). The segment the node projects onto (the right bar's face, h = 1 cm) must win;
before the fix the run stopped at t = 0 with a false penetration.
"""

from pulseform.solvers.dolfinx.verification import bar_impact


def test_corner_beside_segment_end_is_not_a_penetration():
    out = bar_impact(nx=8, ny=4, t_end=2e-4)
    stress = out["stress"]
    assert out["t"][-1] >= 2e-4 * (1 - 1e-9)
    # contact at the middle of the face has started (stress > 0) and stays physical (< 5 × 70 MPa)
    assert max(stress) > 0 and max(stress) < 350e6
