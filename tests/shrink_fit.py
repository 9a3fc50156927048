"""The independent estimate of a press fit's residual contact pressure (tests/mechanics/test_springback_contact.py,
tests/cases/test_tube_press_fit.py): Lame's plane-strain shrink fit of two elastic tubes with the soft-contact
layer's law in series, for the interference measured on the parts released from each other.

    inner tube a < r < b_i under external pressure p:     u(b_i) = -p C_i,
        C_i = b_i (1 + nu) ((1 - 2 nu) b_i^2 + a^2) / (E (b_i^2 - a^2))
    outer tube b_o < r < c under internal pressure p b_i / b_o (the same force per unit length):
        u(b_o) = p (b_i / b_o) C_o,   C_o = b_o (1 + nu) ((1 - 2 nu) b_o^2 + c^2) / (E (c^2 - b_o^2))
    gap h = (b_o + p (b_i / b_o) C_o) - (b_i - p C_i),   p = k (1 / h - 1 / h0).

(Timoshenko & Goodier, Theory of Elasticity, sec. 28, with E -> E / (1 - nu^2), nu -> nu / (1 - nu) for plane
strain.)
"""
import numpy as np
from scipy.optimize import brentq

from pulseform.solvers.dolfinx.springback import springback


def lame_shrink_fit_pressure(a: float, b_i: float, b_o: float, c: float, E: float, nu: float, k: float,
                             h0: float) -> float:
    """Residual contact pressure (Pa, on the inner tube's outer surface) of an inner tube a < r < b_i and an outer
    tube b_o < r < c (free radii, m) pressed together through the soft-contact layer (k, Pa m; h0, m); plane
    strain (module docstring). 0 if the free gap b_o - b_i is at least h0."""
    ci = b_i * (1 + nu) * ((1 - 2 * nu) * b_i ** 2 + a ** 2) / (E * (b_i ** 2 - a ** 2))
    co = b_o * (1 + nu) * ((1 - 2 * nu) * b_o ** 2 + c ** 2) / (E * (c ** 2 - b_o ** 2))
    if b_o - b_i >= h0:
        return 0.0

    def f(p):
        h = (b_o + p * b_i / b_o * co) - (b_i - p * ci)
        return p - k * (1.0 / h - 1.0 / h0)

    hi = (h0 - (b_o - b_i)) / (ci + b_i / b_o * co)     # the pressure that closes the interference: h = h0 there
    return brentq(f, 0.0, hi, xtol=1e-6, rtol=1e-12)


def surface_radius(body, r_ref: float) -> float:
    """Mean current radius (m) of the nodes at reference radius ``r_ref``."""
    return float(body.x[np.isclose(body.X0[:, 0], r_ref), 0].mean())


def released_interference_check(sb, r_in: float, r_out: float, r_outer_out: float, material, k: float, h0: float):
    """Release ``sb`` (a springback of bodies ``inner`` and ``outer`` with their contact pair kept) once more with
    contact removed; return the kept mean contact pressure (Pa), the Lame estimate from the free radii (Pa), the
    plastic strain the release added and the number of slave nodes in contact. ``r_in``, ``r_out``: the inner
    tube's reference bore and outer radius; ``r_outer_out``: the outer tube's reference outer radius (m)."""
    _, _, p, _ = sb.contact_pressure(0)
    free = springback(sb, supports="kept", contact="removed")
    fi, fo = free.bodies["inner"], free.bodies["outer"]
    r2 = float(fo.X0[:, 0].min())
    a, b_i = surface_radius(fi, r_in), surface_radius(fi, r_out)
    b_o, c = surface_radius(fo, r2), surface_radius(fo, r_outer_out)
    lame = lame_shrink_fit_pressure(a, b_i, b_o, c, material.youngs_modulus, material.poisson_ratio, k, h0)
    added = max(float(np.abs(free.bodies[n].eps_p - sb.bodies[n].eps_p).max()) for n in ("inner", "outer"))
    return float(p.mean()), lame, added, len(p)
