"""Input checks of the 3D solver (issue 20): each wrong input is refused with a message naming it."""
import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import (BodySpec, ContactPairSpec, ExplicitSolver, ExplicitSolver3D,
                                       Material, RigidWallSpec, SoftPlaneSpec)

MAT = Material(7800.0, 80e9, 170e9, 300e6, 1e9)


def _cube():
    return dmesh.create_box(MPI.COMM_SELF, [np.zeros(3), np.ones(3)], [2, 2, 2],
                            dmesh.CellType.tetrahedron)


def test_meshes_and_dimensions():
    square = dmesh.create_unit_square(MPI.COMM_SELF, 2, 2)
    with pytest.raises(ValueError, match="3D tetrahedral mesh"):
        ExplicitSolver3D([BodySpec("b", square, MAT, initial_velocity=(0, 0, 0))], comm=MPI.COMM_SELF)
    with pytest.raises(ValueError, match="2D triangle mesh"):
        ExplicitSolver([BodySpec("b", _cube(), MAT)], comm=MPI.COMM_SELF)
    with pytest.raises(ValueError, match="initial_velocity needs 3 components"):
        ExplicitSolver3D([BodySpec("b", _cube(), MAT)], comm=MPI.COMM_SELF)   # default (0, 0)
    with pytest.raises(ValueError, match="initial_stress needs 6 components"):
        ExplicitSolver3D([BodySpec("b", _cube(), MAT, initial_velocity=(0, 0, 0),
                                   initial_stress=(1.0, 2.0, 3.0, 4.0))], comm=MPI.COMM_SELF)
    with pytest.raises(ValueError, match="fixed components must be in 0..2"):
        ExplicitSolver3D([BodySpec("b", _cube(), MAT, initial_velocity=(0, 0, 0),
                                   fixed=((lambda x: x[0] < 0.1, (3,)),))], comm=MPI.COMM_SELF)


def test_walls_planes_pairs_and_forces():
    body = BodySpec("b", _cube(), MAT, initial_velocity=(0, 0, 0))
    with pytest.raises(ValueError, match="3-component point and normal"):
        ExplicitSolver3D([body], rigid_walls=(RigidWallSpec((0, 0), (1, 0)),), comm=MPI.COMM_SELF)
    with pytest.raises(ValueError, match="3-component point and normal"):
        SoftPlaneSpec((0, 0), (1, 0), stiffness=1e8, h0=0.01)
    with pytest.raises(ValueError, match="stiffness > 0 and h0 > 0"):
        SoftPlaneSpec((0, 0, 0), (1, 0, 0), stiffness=1e8, h0=0.0)
    with pytest.raises(ValueError, match="unknown body 'x'"):
        ExplicitSolver3D([body], contact_pairs=(ContactPairSpec("b", "x", 1e8, 0.01),),
                         comm=MPI.COMM_SELF)
    s = ExplicitSolver3D([body], comm=MPI.COMM_SELF)
    n = s.bodies["b"].n_local
    with pytest.raises(ValueError, match=r"must have shape \(27, 3\)"):
        s.advance(s.stable_time_step(), 1, external_forces={"b": np.zeros((n, 2))})
    with pytest.raises(RuntimeError, match="exceeds the critical step"):
        s.advance(3.0 * s.stable_time_step(), 1)
