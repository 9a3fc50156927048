"""Springback with contact kept (solvers/dolfinx/springback.py, issue 34 item 3): a press fit's residual contact
pressure against the Lame shrink-fit pressure of the interference measured on the released parts.

Two coaxial tubes (axisymmetric, uz = 0 on both faces: plane strain along the axis) in the paper's sec. 6
geometry: the inner tube's bore is pushed out past yield (a prescribed radial motion, static steps) into the outer
tube through the soft-contact layer of eq. (5); springback with contact kept releases the bore and leaves the
residual contact pressure p. A second springback from that state with contact removed gives each tube's free
radii; the two elastic rings pressed together by the interference of those radii are Lame's shrink fit (plane
strain) with the contact layer's law in series (tests/shrink_fit.py). The release between the two states is
elastic (checked: no plastic strain added), so superposition holds and the estimate is independent of the residual
stresses the forming left.
"""
import math

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, ContactPairSpec, Material
from pulseform.solvers.dolfinx.implicit import ImplicitOptions, ImplicitSolver
from pulseform.solvers.dolfinx.springback import springback
from shrink_fit import lame_shrink_fit_pressure, released_interference_check, surface_radius

STEEL = Material(7800.0, 76.923e9, 166.667e9, 300e6, 0.0)     # paper sec. 6: E = 200 GPa, nu = 0.3, 300 MPa
R0, R1, ROUT, H0, K = 0.0105, 0.0125, 0.025, 5.0e-5, 2.0e6     # cases/tube_press_fit: radii, contact layer (m, Pa m)


def _tubes(clearance: float, push: float, n_inner: int = 8, cell: float = 5e-4):
    """The two tubes (static implicit solver), the bore pushed out radially by ``push`` (m) over the steps, the
    outer tube's inner radius R1 + clearance + H0."""
    r2 = R1 + clearance + H0
    h = 1e-3
    mi = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([R0, 0.0]), np.array([R1, h])], [n_inner, 2])
    mo = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([r2, 0.0]), np.array([ROUT, h])],
                                [max(int(round((ROUT - r2) / cell)), 1), 2])
    ends = ((lambda x: np.isclose(x[1], 0.0) | np.isclose(x[1], h), (1,)),)
    bore = lambda x: np.isclose(x[0], R0)  # noqa: E731

    def expand(X, t):
        out = X.copy()
        out[:, 0] += push * min(t, 1.0)
        return out

    specs = [BodySpec("inner", mi, STEEL, fixed=ends, motion=((bore, expand),)),
             BodySpec("outer", mo, STEEL, fixed=ends)]
    return ImplicitSolver(specs, ImplicitOptions(dt=0.1, scheme="static"), formulation="axisymmetric",
                          contact_pairs=[ContactPairSpec("inner", "outer", K, H0)], comm=MPI.COMM_SELF)


def test_press_fit_residual_pressure_matches_lame_shrink_fit():
    """Inner tube pushed out by 0.2 mm past a clearance of 0.5 % R0 (10 static steps), released with contact
    kept: a residual contact pressure on every node of the contact surface, within 1 % of the Lame shrink-fit
    pressure of the free radii after a second release with contact removed (measured: see the print)."""
    s = _tubes(0.005 * R0, 2.0e-4)
    s.advance(0.1, 10)
    assert s.bodies["inner"].eps_p.min() > 0                       # the inner wall yielded through
    _, _, p_loaded, _ = s.contact_pressure(0)
    sb = springback(s, supports="kept", contact="kept", steps=2)
    assert sb.source_pairs == [0]
    p, lame, added, closed = released_interference_check(sb, R0, R1, ROUT, STEEL, K, H0)
    print(f"loaded contact pressure {p_loaded.mean() / 1e6:.2f} MPa; residual after springback {p / 1e6:.4f} MPa "
          f"on {closed} nodes; Lame shrink fit of the free radii {lame / 1e6:.4f} MPa ({100 * (p / lame - 1):+.3f} %); "
          f"plastic strain added by the release {added:.2e}")
    assert closed == int(np.isclose(sb.bodies["inner"].X0[:, 0], R1).sum())   # the whole surface stays closed
    assert p > 1e6                                                 # Pa: a tight joint
    assert p < p_loaded.mean()                                     # the release unloads the joint
    assert added < 1e-9                                            # the second release is elastic: Lame applies
    assert p == pytest.approx(lame, rel=0.01)


def test_springback_contact_removed_separates_the_parts():
    """The same press fit released with contact removed (the default): the tubes are free, and the outer tube,
    pushed past yield only near its bore, springs back inwards less than the inner one's permanent expansion
    allows: the released radii overlap (the interference the kept contact carries)."""
    s = _tubes(0.005 * R0, 2.0e-4)
    s.advance(0.1, 10)
    sb = springback(s, supports="kept")
    assert sb.source_pairs == [] and not sb.contact_pairs
    fi, fo = sb.bodies["inner"], sb.bodies["outer"]
    r2 = float(fo.X0[:, 0].min())
    assert surface_radius(fo, r2) - surface_radius(fi, R1) < H0   # interference: the layer would push
    with pytest.raises(ValueError, match="contact must be one of"):
        springback(s, contact="yes")
    with pytest.raises(ValueError, match="walls must be one of"):
        springback(s, walls="")


def test_lame_shrink_fit_pressure_limits():
    """The estimate itself: no pressure for a free gap of h0 or more; for an interference much larger than the
    layer's compression, Lame's rigid-layer value delta / (C_i + (b_i / b_o) C_o) with delta = h0 - (b_o - b_i),
    less the layer's own compression (here h0 - h = 15 nm of delta = 5 um: 0.29 %)."""
    E, nu = STEEL.youngs_modulus, STEEL.poisson_ratio
    assert lame_shrink_fit_pressure(R0, R1, R1 + H0 + 1e-7, ROUT, E, nu, K, H0) == 0.0
    b_o = R1 + H0 - 5e-6
    p = lame_shrink_fit_pressure(R0, R1, b_o, ROUT, E, nu, K, H0)
    ci = R1 * (1 + nu) * ((1 - 2 * nu) * R1 ** 2 + R0 ** 2) / (E * (R1 ** 2 - R0 ** 2))
    co = b_o * (1 + nu) * ((1 - 2 * nu) * b_o ** 2 + ROUT ** 2) / (E * (ROUT ** 2 - b_o ** 2))
    rigid = 5e-6 / (ci + R1 / b_o * co)
    assert p < rigid
    assert p == pytest.approx(rigid, rel=5e-3)
    assert math.isfinite(p)


def test_springback_walls_kept_hold_the_part():
    """A bar (plane stress, 20 x 2 cells) on a sliding rigid wall y = 0, held in x at x = 0, stretched past yield by
    its end face (static steps), released with ``walls="kept"``: the wall is then its only support across the bar,
    and it springs back by sigma (L + d) / E (as a bar released onto minimal supports, test_springback.py) within
    2 % (measured 0.55 %), resting on the wall (the stretch narrowed the bar and lifted parts of its
    bottom off the wall, which cannot pull); with the walls removed the same release has no support in y and
    stops in one line naming the free motion."""
    from dolfinx import mesh as dmesh_

    from pulseform.solvers.dolfinx import RigidWallSpec
    from pulseform.solvers.dolfinx.implicit import SingularSystemError

    L, H, d = 0.1, 0.01, 2e-3
    msh = dmesh_.create_rectangle(MPI.COMM_SELF, [np.array([0.0, 0.0]), np.array([L, H])], [20, 2])
    mat = Material(2700.0, 26.9e9, 58.3e9, 100e6, 500e6)

    def pull(X, t):
        out = X.copy()
        out[:, 0] += d * min(t, 1.0)
        return out

    spec = BodySpec("bar", msh, mat, fixed=((lambda x: np.isclose(x[0], 0.0), (0,)),),
                    motion=((lambda x: np.isclose(x[0], L), pull),))
    s = ImplicitSolver([spec], ImplicitOptions(dt=0.1, scheme="static"), formulation="plane_stress", thickness=0.01,
                       rigid_walls=[RigidWallSpec((0.0, 0.0), (0.0, 1.0), sliding=True)], comm=MPI.COMM_SELF)
    s.advance(0.1, 10)
    bar = s.bodies["bar"]
    sxx = float(bar.cell_stress[:, 0].mean())
    assert bar.eps_p.min() > 0
    sb = springback(s, walls="kept")
    assert len(sb.rigid_walls) == 1 and sb.rigid_walls[0].bodies == ("bar",)
    moved = sb.springback_displacement["bar"]
    tip = np.isclose(bar.X0[:, 0], L)
    print(f"sxx {sxx / 1e6:.2f} MPa, springback {moved[tip, 0].mean() * 1e3:.5f} mm, sigma (L + d) / E "
          f"{-sxx * (L + d) / mat.youngs_modulus * 1e3:.5f} mm")
    assert moved[tip, 0].mean() == pytest.approx(-sxx * (L + d) / mat.youngs_modulus, rel=0.02)
    y = sb.bodies["bar"].x[:, 1]
    assert y.min() > -1e-12 and abs(y.min()) < 1e-12        # resting on the wall, nowhere behind it
    with pytest.raises(SingularSystemError, match="translation y"):
        springback(s, walls="removed")
