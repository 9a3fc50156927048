"""Pressure loads on ten-node tetrahedra (solvers/dolfinx/tet10.py ``face_pressure_forces``, Body3D.pressure_forces):
the six-node face's consistent load vector (Zienkiewicz & Taylor, The Finite Element Method, vol. 1: a uniform
pressure on a straight six-node triangle loads its corners with 0 and each edge node with p A / 3), and the patch
test it passes: a block on three sliding symmetry planes under a uniform pressure on its top carries the uniform
uniaxial stress sigma_zz = -p A0 / A at every Gauss point (the quarter-triangle split of the faces, p A / 12 at a
corner and p A / 4 at an edge node, does not: measured, sigma_zz from -1.39 p to -0.56 p at the Gauss points)."""
import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, Material
from pulseform.solvers.dolfinx.body3d import Body3D
from pulseform.solvers.dolfinx.implicit import ImplicitOptions, ImplicitSolver3D
from pulseform.solvers.dolfinx.tet10 import face_pressure_forces

ELASTIC = Material(2700.0, 26.9e9, 58.3e9, 1e12, 0.0)
P = 1e6


def _box(hi=(1.0, 1.5, 0.7), n=(2, 3, 2), skew=True):
    msh = dmesh.create_box(MPI.COMM_SELF, [np.zeros(3), np.array(hi, float)], list(n))
    if skew:
        msh.geometry.x[:, 1] += 0.3 * msh.geometry.x[:, 0] ** 2       # unequal faces on x = 1
    return msh


def test_straight_and_curved_six_node_faces():
    """Straight faces (x = 1 of a skewed box): 0 at the corners and -p A n / 3 at the edge nodes, to 1e-12. Curved
    faces (the edge nodes pushed off the face's plane): the forces sum to -p times the faces' vector area
    int n dA = 1/2 closed-integral of x cross dx along each face's boundary (Stokes), its three parabolic edges
    integrated by Simpson's rule (exact: the integrand is cubic), to 1e-12."""
    b = Body3D(BodySpec("b", _box(), ELASTIC, initial_velocity=(0.0, 0.0, 0.0), element="tet10"))
    faces = b.faces6[np.all(np.isclose(b.X0[b.faces6, 0], 1.0), axis=1)]
    x = b.x.copy()
    f = face_pressure_forces(faces, x, P)
    a, c, d = (x[faces[:, k]] for k in range(3))
    av = 0.5 * np.cross(c - a, d - a)
    corners, edges = np.unique(faces[:, :3]), np.unique(faces[:, 3:])
    assert np.abs(f[corners]).max() <= 1e-12 * P * np.abs(av).max()
    expect = np.zeros_like(f)
    for k in range(3, 6):
        np.add.at(expect, faces[:, k], -P * av / 3.0)
    assert np.abs(f[edges] - expect[edges]).max() <= 1e-12 * np.abs(expect).max()
    rng = np.random.default_rng(3)
    x[edges] += 0.05 * rng.standard_normal((len(edges), 3))       # curved faces
    f = face_pressure_forces(faces, x, P)
    vec_area = np.zeros(3)
    for a0, a1, m in ((0, 1, 3), (1, 2, 4), (2, 0, 5)):                # a -> b over ab, b -> c over bc, c -> a over ca
        p0, pm, p1 = x[faces[:, a0]], x[faces[:, m]], x[faces[:, a1]]
        ends = (np.cross(p0, -3 * p0 + 4 * pm - p1) + 4 * np.cross(pm, p1 - p0) + np.cross(p1, p0 - 4 * pm + 3 * p1))
        vec_area += 0.5 * ends.sum(axis=0) / 6.0
    assert np.abs(f.sum(axis=0) + P * vec_area).max() <= 1e-12 * P * np.abs(vec_area).max()


def test_block_under_pressure_passes_the_patch_test():
    """Static implicit: a ten-node block 1 x 1.5 x 0.7 m on the sliding planes x = 0, y = 0, z = 0, pressure p on
    its top (z = 0.7, the body's own pressure forces): sigma_zz uniform at every Gauss point to 1e-9 of p, equal to
    -p A0 / A (a dead load of the reference area on the current section), the other components below 1e-9 p."""
    msh = _box(skew=False)
    fixed = ((lambda X: np.isclose(X[0], 0.0), (0,)), (lambda X: np.isclose(X[1], 0.0), (1,)),
             (lambda X: np.isclose(X[2], 0.0), (2,)))
    s = ImplicitSolver3D([BodySpec("block", msh, ELASTIC, initial_velocity=(0.0, 0.0, 0.0), element="tet10",
                                   fixed=fixed)], ImplicitOptions(dt=1.0, scheme="static"), comm=MPI.COMM_SELF)
    b = s.bodies["block"]
    f = b.pressure_forces(lambda X: np.isclose(X[2], 0.7), P)
    assert f[:, 2].sum() == pytest.approx(-P * 1.5, rel=1e-12)
    s.advance(1.0, 1, {"block": f})
    sz = b.cell_stress[:, 2]
    top = b.x[np.isclose(b.X0[:, 2], 0.7)]
    area = np.ptp(top[:, 0]) * np.ptp(top[:, 1])
    assert np.ptp(sz) <= 1e-9 * P
    assert sz.mean() == pytest.approx(-P * 1.5 / area, rel=1e-9)
    assert np.abs(b.cell_stress[:, [0, 1, 3, 4, 5]]).max() <= 1e-9 * P
