"""The forming-limit check (issue 33, item 5): the sheet strain measure on prescribed homogeneous deformations
against analytic true strains, the margin below a curve against hand-computed values, and the monitor's
worst-cell bookkeeping. Pure numpy: no solver, milliseconds.

References: for x = R F0 X with F0 = diag(λ1, λ2, λ3) (principal axes along the reference axes) and any
rotation R, the principal true strains are ln λ_i exactly; in axisymmetry the hoop stretch of a cell is
r_c / r0_c (its centroid's radii) by definition (docs/mechanics.md, "Forming limit check").
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from pulseform.orchestrator.case.forming_limit import FormingLimitTable
from pulseform.orchestrator.mech.forming_limit import FormingLimitCurve, FormingLimitMonitor
from pulseform.orchestrator.mech.sheet_strain import deformation_gradients, sheet_normal, sheet_strains

TOL = 1e-12


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues: rotation by ``angle`` (rad) about the unit ``axis`` (3,)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def _plate_tets(nx=4, ny=3, L=(0.1, 0.06, 0.002)):
    """A flat plate (normal z, thickness L[2]) cut into tetrahedra (6 per box, one layer)."""
    xs, ys, zs = np.linspace(0, L[0], nx + 1), np.linspace(0, L[1], ny + 1), np.array([0.0, L[2]])
    X = np.array([[x, y, z] for z in zs for y in ys for x in xs])
    idx = lambda i, j, k: k * (nx + 1) * (ny + 1) + j * (nx + 1) + i  # noqa: E731
    tets = []
    for i in range(nx):
        for j in range(ny):
            v = [idx(i + a, j + b, c) for c in (0, 1) for b in (0, 1) for a in (0, 1)]
            # Kuhn's 6 tetrahedra of a cube (vertices v0..v7 in binary order x, y, z)
            for p in ((0, 1, 3, 7), (0, 1, 5, 7), (0, 2, 3, 7), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 6, 7)):
                tets.append([v[q] for q in p])
    return X, np.array(tets)


def _section_tris(r0=0.01, r1=0.06, z0=0.0, z1=0.001, nx=10, ny=2):
    """A rectangle [r0, r1] x [z0, z1] (a sheet's section: normal along the short side) cut into triangles."""
    xs, ys = np.linspace(r0, r1, nx + 1), np.linspace(z0, z1, ny + 1)
    X = np.array([[x, y] for y in ys for x in xs])
    tris = []
    for j in range(ny):
        for i in range(nx):
            a, b = j * (nx + 1) + i, j * (nx + 1) + i + 1
            c, d = a + nx + 1, b + nx + 1
            tris += [[a, b, d], [a, d, c]]
    return X, np.array(tris)


# ------------------------------------------------------------------------------------------ 3D solids
#: (name, λ1 along x, λ2 along y, λ3 through the thickness z): volume-preserving paths of sheet forming
PATHS_3D = [("uniaxial", 1.25, 1 / math.sqrt(1.25), 1 / math.sqrt(1.25)),
            ("plane_strain", 1.2, 1.0, 1 / 1.2),
            ("equibiaxial", 1.15, 1.15, 1 / 1.15 ** 2),
            # left of uniaxial (a deep-drawing flange): the sheet thickens, the most negative principal strain is
            # in the plane; the thickness is still found (closest to the normal)
            ("drawing", 1.3, 0.7, 1 / (1.3 * 0.7))]


@pytest.mark.parametrize("name,l1,l2,l3", PATHS_3D)
def test_3d_log_strains_of_homogeneous_deformations(name, l1, l2, l3):
    X, tets = _plate_tets()
    R = _rotation([0.3, -0.5, 0.8], 0.7)   # a rigid rotation changes no strain
    x = (X @ (R @ np.diag([l1, l2, l3])).T) + np.array([0.01, -0.02, 0.03])
    minor, major = sheet_strains(X, x, tets, "3d")
    e = sorted([math.log(l1), math.log(l2)])
    assert np.abs(minor - e[0]).max() < TOL and np.abs(major - e[1]).max() < TOL, name
    F = deformation_gradients(X, x, tets)
    assert np.abs(F - R @ np.diag([l1, l2, l3])).max() < 1e-12


def test_3d_sheet_normal_of_a_tilted_plate():
    """The normal is the axis the nodes spread least along: the plate's z, rotated with it."""
    X, _ = _plate_tets()
    R = _rotation([1.0, 2.0, 0.5], 0.9)
    n = sheet_normal(X @ R.T)
    assert abs(abs(n @ (R @ [0, 0, 1.0])) - 1.0) < 1e-12


# ------------------------------------------------------------------------------------------ 2D models
@pytest.mark.parametrize("lam,mu", [(1.2, 1 / 1.2), (0.8, 1.1), (1.05, 1.05)])
def test_plane_strain_section(lam, mu):
    """A sheet section along x (normal y): stretch λ along the sheet, μ through the thickness, and a rotation;
    the third (z) stretch is 1: (ε2, ε1) = sorted(ln λ, 0)."""
    X, tris = _section_tris()
    c, s = math.cos(0.3), math.sin(0.3)
    x = X @ (np.array([[c, -s], [s, c]]) @ np.diag([lam, mu])).T
    minor, major = sheet_strains(X, x, tris, "plane_strain")
    e = sorted([math.log(lam), 0.0])
    assert np.abs(minor - e[0]).max() < TOL and np.abs(major - e[1]).max() < TOL


@pytest.mark.parametrize("l1,l2", [(1.25, 1 / math.sqrt(1.25)), (1.2, 1.0), (1.15, 1.15), (0.9, 1.3)])
def test_plane_stress_is_the_sheet_itself(l1, l2):
    """Plane stress: the model plane is the sheet; its two principal strains are (ε2, ε1)."""
    X, tris = _section_tris(0.0, 0.05, 0.0, 0.04, 5, 4)
    c, s = math.cos(-1.1), math.sin(-1.1)
    x = X @ (np.array([[c, -s], [s, c]]) @ np.diag([l1, l2])).T
    minor, major = sheet_strains(X, x, tris, "plane_stress")
    e = sorted([math.log(l1), math.log(l2)])
    assert np.abs(minor - e[0]).max() < TOL and np.abs(major - e[1]).max() < TOL


@pytest.mark.parametrize("lam,mu", [(1.2, 1 / 1.2 ** 2), (1.05, 0.95)])
def test_axisymmetric_disk_equibiaxial(lam, mu):
    """A flat disk (normal z): r = λ R, z = μ Z is equibiaxial stretching: meridional = hoop = ln λ."""
    X, tris = _section_tris(0.0, 0.06, 0.0, 0.001, 12, 2)
    x = X * [lam, mu]
    minor, major = sheet_strains(X, x, tris, "axisymmetric")
    assert np.abs(minor - math.log(lam)).max() < TOL and np.abs(major - math.log(lam)).max() < TOL


def test_axisymmetric_tube_hoop_is_the_centroid_radius_ratio():
    """A tube wall (normal r: the section is thin in r): r = R + c, z = μ Z. The wall keeps its thickness,
    the axial strain is ln μ and each cell's hoop strain ln(r_c / r0_c); (ε2, ε1) = sorted(both)."""
    X, tris = _section_tris(0.020, 0.0215, -0.03, 0.03, 2, 24)
    c, mu = 0.004, 0.97
    x = np.column_stack([X[:, 0] + c, mu * X[:, 1]])
    minor, major = sheet_strains(X, x, tris, "axisymmetric")
    r0 = X[tris, 0].mean(axis=1)
    hoop = np.log((r0 + c) / r0)
    both = np.sort(np.column_stack([hoop, np.full(len(hoop), math.log(mu))]), axis=1)
    assert np.abs(minor - both[:, 0]).max() < TOL and np.abs(major - both[:, 1]).max() < TOL
    assert abs(abs(sheet_normal(X)[0]) - 1.0) < 1e-12


def test_unknown_formulation_refused():
    X, tris = _section_tris()
    with pytest.raises(ValueError, match="formulation"):
        sheet_strains(X, X, tris, "shell")


# ------------------------------------------------------------------------------------------ the margin
CURVE = FormingLimitCurve(np.array([-0.2, 0.0, 0.2]), np.array([0.35, 0.22, 0.30]), 0.1)


@pytest.mark.parametrize("e2,e1,margin,zone", [
    (-0.1, 0.20, 0.085, 1),     # FLC(-0.1) = (0.35 + 0.22) / 2 = 0.285: 0.085 below, within the 0.1 margin
    (0.1, 0.10, 0.16, 0),       # FLC(0.1) = 0.26: safe
    (0.0, 0.25, -0.03, 2),      # FLC0 = 0.22: above the curve, failed
    (0.4, 0.25, 0.05, 1),       # beyond the last point: flat at 0.30
    (-0.5, 0.10, 0.25, 0),      # before the first point: flat at 0.35
    (0.05, 0.15, 0.09, 1)])     # FLC(0.05) = 0.22 + 0.25 * 0.08 = 0.24
def test_margin_of_known_points(e2, e1, margin, zone):
    m = CURVE.margin(np.array([e2]), np.array([e1]))
    assert m[0] == pytest.approx(margin, abs=1e-15)
    assert CURVE.zone(m)[0] == zone


def test_curve_of_a_table():
    c = FormingLimitCurve.of(FormingLimitTable(minor_strain=(-0.2, 0.0, 0.2), major_strain=(0.35, 0.22, 0.3)))
    assert c.safety_margin == 0.1 and np.array_equal(c.limit(c.minor), c.major)
    assert c.outside(-0.21) and c.outside(0.2001) and not c.outside(0.0)


# ------------------------------------------------------------------------------------------ the monitor
class _Comm:
    size, rank = 1, 0


def _solver(X, cells, formulation):
    body = SimpleNamespace(X0=X, x=X.copy(), cells=cells, n_owned=len(X))
    return SimpleNamespace(bodies={"sheet": body}, formulation=formulation, comm=_Comm(), step_count=0, time=0.0)


def test_monitor_keeps_the_worst_cell_over_time():
    """A plate stretched in plane strain (ε1 = ln 1.3 on the cells of x < 0.05, ε1 = ln 1.1 beyond), then
    relaxed: the history column follows the state, the worst cell stays the one of the largest stretch at
    its time; the state survives a checkpoint round trip."""
    X, tets = _plate_tets()
    s = _solver(X, tets, "3d")
    mon = FormingLimitMonitor({"sheet": CURVE}, s)
    assert mon.record()["sheet_flc_margin_min"] == pytest.approx(0.22, abs=1e-15)   # undeformed: FLC0
    b = s.bodies["sheet"]
    left = X[:, 0] < 0.05 + 1e-12
    b.x = X * [1.0, 1.0, 1 / 1.3]
    b.x[:, 0] = np.where(left, 1.3 * X[:, 0], 1.3 * 0.05 + 1.1 * (X[:, 0] - 0.05))
    s.step_count, s.time = 10, 2e-5
    row = mon.record()
    assert row["sheet_flc_margin_min"] == pytest.approx(0.22 - math.log(1.3), abs=1e-12)
    fields = mon.cell_fields("sheet")
    assert set(fields) == {"minor_strain", "major_strain", "flc_margin", "flc_zone"}
    assert np.all(fields["flc_zone"][fields["flc_margin"] < 0] == 2.0)
    b.x = X.copy()
    s.step_count, s.time = 20, 4e-5
    assert mon.record()["sheet_flc_margin_min"] == pytest.approx(0.22, abs=1e-15)
    m = mon.metrics()
    assert m["sheet_flc_margin_min"] == pytest.approx(0.22 - math.log(1.3), abs=1e-12)
    assert m["sheet_flc_worst_time_s"] == 2e-5 and m["sheet_flc_worst_zone"] == 2.0
    assert m["sheet_flc_worst_minor_strain"] == pytest.approx(0.0, abs=1e-12)
    assert m["sheet_flc_worst_x_m"] < 1.3 * 0.05    # a cell of the more stretched half
    again = FormingLimitMonitor({"sheet": CURVE}, s)
    again.load_state_dict(mon.state_dict())
    assert again.metrics() == m


def test_a_bar_is_no_sheet(caplog):
    """A body as thick as it is wide has no sheet normal: the check says so (the demo's sheet does not)."""
    X, tets = _plate_tets(2, 2, (0.01, 0.01, 0.01))
    with caplog.at_level("WARNING"):
        FormingLimitMonitor({"sheet": CURVE}, _solver(X, tets, "3d"))
    assert "not thin along any axis" in caplog.text
    caplog.clear()
    X, tets = _plate_tets()
    with caplog.at_level("WARNING"):
        FormingLimitMonitor({"sheet": CURVE}, _solver(X, tets, "3d"))
    assert "not thin" not in caplog.text
