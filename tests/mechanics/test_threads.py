"""The element kernel on several threads (solvers/dolfinx/kernel_threads.py) gives the serial
results bit for bit: per-cell forces gathered per node in cell order and the dissipation summed per
fixed chunk in chunk order are the serial kernel's sums in the serial order. Reference: the serial
compiled path (itself bitwise equal to the Python step loop, test_compiled_steps.py)."""
import numba
import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, ContactPairSpec, ExplicitSolver, Material, RigidWallSpec
from pulseform.solvers.dolfinx.kernels import CHUNK

AL = Material(2735.0, 26.5e9, 65.1e9, 195e6, 520e6)
needs_two = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba sees one core")


def _solver(threads: int, formulation: str) -> ExplicitSolver:
    """A block (two chunks of cells and a partial one) thrown at 150 m/s onto a rigid wall and
    into a second body through soft contact: plastic, with contact and wall forces."""
    x0 = 0.05 if formulation == "axisymmetric" else 0.0
    a = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([x0, 0.0]), np.array([x0 + 0.02, 0.02])], [100, 100])
    b = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([x0, 0.0205]), np.array([x0 + 0.02, 0.03])], [20, 10])
    return ExplicitSolver([BodySpec("a", a, AL, initial_velocity=(0.0, -150.0)),
                           BodySpec("b", b, AL, initial_velocity=(0.0, -150.0))],
                          formulation=formulation,
                          contact_pairs=(ContactPairSpec(slave="b", master="a", stiffness=1e12, h0=2e-4),),
                          rigid_walls=(RigidWallSpec((0.0, 0.0), (0.0, 1.0)),), comm=MPI.COMM_SELF,
                          threads=threads)


@needs_two
@pytest.mark.parametrize("formulation", ["plane_strain", "axisymmetric", "plane_stress"])
def test_two_threads_give_the_serial_bits(formulation):
    one, two = _solver(1, formulation), _solver(2, formulation)
    assert len(one.bodies["a"].cells) > 2 * CHUNK
    for s in (one, two):
        for _ in range(6):
            s.advance(0.8 * s.stable_time_step(), 25)
    for name in ("a", "b"):
        p, q = one.bodies[name], two.bodies[name]
        for k in ("x", "v", "a", "cell_stress", "eps_p"):
            assert np.array_equal(getattr(p, k), getattr(q, k)), (name, k)
    assert np.count_nonzero(one.bodies["a"].eps_p) > 100
    assert one.energies() == two.energies()
    assert one.energies()["plastic_J"] > 0.0


def test_threads_are_checked():
    with pytest.raises(ValueError, match="threads must be an integer from 1"):
        _solver(0, "plane_strain")
    with pytest.raises(ValueError, match="threads must be an integer from 1"):
        _solver(numba.config.NUMBA_NUM_THREADS + 1, "plane_strain")


@needs_two
def test_threads_need_the_compiled_path():
    a = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([0.0, 0.0]), np.array([0.02, 0.02])], [4, 4])
    with pytest.raises(ValueError, match="needs the compiled block path"):
        ExplicitSolver([BodySpec("a", a, AL)], formulation="plane_strain", comm=MPI.COMM_SELF,
                       compiled_steps=False, threads=2)
