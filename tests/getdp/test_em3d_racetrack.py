"""3D deck on a coil that is not axisymmetric: a racetrack, its direction from the electrokinetic pre-solve.

Two racetrack turns (sections 4 mm x 3 mm at 12-16 mm and 18-22 mm from the centre line, z -4..-1 mm,
straight sides 40 mm long along y, semicircular ends about (0, +-20 mm)), 10 kA per turn, direct
current; the quarter x, y >= 0 with the planes x = 0 and y = 0 as n x a = 0 symmetry planes (the
current crosses them at right angles), air sphere 100 mm, shell to 125 mm. The current direction
in the coil is -grad v / |grad v| of the electrokinetic pre-solve (v = 1 on the turns' faces on
y = 0, 0 on those on x = 0); the section is the electrode area.

Reference: Biot-Savart of the racetrack's current (uniform density over each turn's section: 6 x 6
Gauss filaments per turn, each filament a closed racetrack path of 2 straight sides and 2 half
circles polygonised in 2 x 2000 chords; exact field of each straight segment), B_z at the
centre (0, 0, -2.5 mm). The filament sum is checked against the elliptic-integral ring formula
with straight sides of zero length. The 3D value is the mean of B_z over the current-free 4 mm
ball about the centre (quarter of it): B_z is harmonic and even in x and y, so this mean is the
centre value (see test_em3d_static).

Observed (coil element size, tetrahedra: error): 3 mm, 6.6k: -0.74 %; 2 mm, 12.1k: -0.81 %;
1.5 mm, 18.0k: -0.51 % (this test); 1.2 mm, 29.3k: -0.61 % -- the level of the ring coil's
(-0.4 to -0.8 %); the issue's bar is 1 %.
"""
import numpy as np
import pytest

from pulseform.solvers.getdp import DampedSine, Rect
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel, ball_average, solve_transient3d

from getdp_testlib import needs_getdp
from test_coil_field import loop_field

MU0 = 4e-7 * np.pi
I_TURN, HALF_STRAIGHT, Z_CENTRE = 1e4, 0.02, -0.0025
TURNS = [Rect(0.012 + i * 0.006, -0.004, 0.016 + i * 0.006, -0.001) for i in range(2)]


def racetrack_path(rho: float, half: float, z: float, n_arc: int = 2000) -> np.ndarray:
    """Closed polyline (counter-clockwise seen from +z) of a racetrack filament at distance rho from
    its centre line, straight sides x = +-rho for |y| <= half, half circles about (0, +-half)."""
    th = np.linspace(0.0, np.pi, n_arc + 1)
    top = np.stack([rho * np.cos(th), half + rho * np.sin(th)], 1)          # (rho, half) -> (-rho, half)
    bottom = np.stack([-rho * np.cos(th), -half - rho * np.sin(th)], 1)     # (-rho, -half) -> (rho, -half)
    xy = np.concatenate([top, bottom, top[:1]])
    return np.column_stack([xy, np.full(len(xy), z)])


def segments_field(path: np.ndarray, current: float, p: np.ndarray) -> np.ndarray:
    """B (T) at p of a current (A) along the straight segments of a polyline (exact per segment)."""
    a, b = path[:-1], path[1:]
    d, r1, r2 = b - a, p - a, p - b
    c = np.cross(d, r1)
    f = (np.einsum("ij,ij->i", d, r1 / np.linalg.norm(r1, axis=1)[:, None] - r2 / np.linalg.norm(r2, axis=1)[:, None])
         / np.einsum("ij,ij->i", c, c))
    return MU0 * current / (4 * np.pi) * (c * f[:, None]).sum(0)


def racetrack_field(turns, half: float, current: float, p, n_gauss: int = 6) -> np.ndarray:
    g, w = np.polynomial.legendre.leggauss(n_gauss)
    b = np.zeros(3)
    for t in turns:
        for gi, wi in zip(g, w):
            rho = 0.5 * (t.x0 + t.x1) + 0.5 * (t.x1 - t.x0) * gi
            for gj, wj in zip(g, w):
                z = 0.5 * (t.y0 + t.y1) + 0.5 * (t.y1 - t.y0) * gj
                b += wi * wj / 4 * segments_field(racetrack_path(rho, half, z), current, np.asarray(p, float))
    return b


def test_filament_sum_matches_ring_formula():
    """Zero-length straight sides: the polygonised filament is a ring; compare with the elliptic formula."""
    p = np.array([0.004, 0.0, 0.003])
    b = segments_field(racetrack_path(0.02, 0.0, 0.0, n_arc=4000), 1.0, p)
    br, bz = loop_field(0.02, 0.0, p[0], p[2])
    np.testing.assert_allclose([b[0], b[2]], [br, bz], rtol=1e-6)


@pytest.mark.getdp
@needs_getdp
def test_racetrack_centre_field_vs_biot_savart(work):
    mesh = ring_sector_mesh(work / "racetrack.msh", TURNS, [], sector_deg=90.0, racetrack=HALF_STRAIGHT,
                            r_air=0.1, r_shell=0.125, h_coil=1.5e-3, h_air=0.015, h_centre=0.7e-3)
    assert mesh.electrode_area[1] == pytest.approx(2 * 12e-6, rel=1e-12)
    model = EM3DModel(coils=[Coil3D(2, waveform=DampedSine(I_TURN, 0.0, 0.0, np.pi / 2), direction="electrokinetic")],
                      shell=(0.1, 0.125), sector_deg=90.0)
    res = solve_transient3d(model, mesh, 1e-6, 1, work / "run", field_output=True)
    b, n = ball_average(mesh, res.b_cells, (0.0, 0.0, Z_CENTRE), 4e-3)
    ref = racetrack_field(TURNS, HALF_STRAIGHT, I_TURN, (0.0, 0.0, Z_CENTRE))
    err = b[2] / ref[2] - 1
    print(f"\nracetrack quarter, {mesh.n_tets} tets, {res.n_dofs} dofs: B_z centre {b[2]:.6f} T (mean of {n} tets), "
          f"Biot-Savart {ref[2]:.6f} T, rel. error {err:+.3%}")
    assert abs(err) < 0.01
