"""The 3D element kernel on several threads (solvers/dolfinx/tet_threads.py, issue 31) gives the
serial results bit for bit: the cells go in the serial kernels' own fixed chunks, a node inside one
chunk gets its forces from that chunk in cell order, a node shared by chunks gets its cells'
stored forces gathered in cell order, and the chunks' dissipation is summed in chunk order — the
serial sums in the serial order. Reference: the serial kernels (``tet_step_batched``, and
``tet_step`` for a rate law) and the one-thread solver."""
import os
import subprocess
import sys

import numba
import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import (BodySpec, ContactPairSpec, CowperSymonds, ExplicitSolver3D,
                                       Material, RigidWallSpec)
from pulseform.solvers.dolfinx.kernels import pack_parameters
from pulseform.solvers.dolfinx.tet_batch import TET_WORK_SIZE, tet_step_batched
from pulseform.solvers.dolfinx.tet_kernel import MODE_SOLID, TET_CHUNK, tet_chunk_size, tet_step
from pulseform.solvers.dolfinx.tet_threads import tet_step_threaded, tet_thread_arrays

AL = Material(2735.0, 26.5e9, 65.1e9, 195e6, 520e6)
AL_RATE = Material(2735.0, 26.5e9, 65.1e9, 195e6, 520e6, rate_law=CowperSymonds(D=6500.0, p=4.0))
needs_two = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba sees one core")


def brick_tets(nx: int, ny: int, nz: int, h: float, seed: int = 0):
    """Node positions (m) and positively oriented tetrahedra of nx x ny x nz bricks of side h (six
    tetrahedra each), bricks in C order (so that index-ordered chunks of cells are slabs with
    shared nodes between them), nodes moved randomly by up to 0.15 h."""
    idx = np.arange((nx + 1) * (ny + 1) * (nz + 1)).reshape(nx + 1, ny + 1, nz + 1)
    g = np.stack(np.meshgrid(*(np.arange(k + 1) * h for k in (nx, ny, nz)), indexing="ij"), -1)
    x = g.reshape(-1, 3) + np.random.default_rng(seed).uniform(-0.15 * h, 0.15 * h, (idx.size, 3))
    corner = lambda a, b, c: idx[a:a + nx, b:b + ny, c:c + nz].reshape(-1)  # noqa: E731
    tets = []
    for p in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):   # Kuhn's six paths
        step = np.zeros(3, int)
        path = [corner(0, 0, 0)]
        for ax in p[:2]:
            step[ax] = 1
            path.append(corner(*step))
        path.append(corner(1, 1, 1))
        tets.append(np.stack(path, axis=1))
    cells = np.stack(tets, axis=1).reshape(-1, 4).astype(np.int32)
    e = x[cells]
    det = np.einsum("ij,ij->i", e[:, 1] - e[:, 0], np.cross(e[:, 2] - e[:, 0], e[:, 3] - e[:, 0]))
    cells[det < 0] = cells[det < 0][:, [0, 2, 1, 3]]
    return x, cells


def compare_kernels(threads: int) -> None:
    """The threaded kernel on 1..``threads`` threads against the serial kernels, over three calls
    on a plastic state: just over 2 * TET_CHUNK cells (four chunks, the last one shorter), one
    cell inverted in the second chunk, rate-independent (vectorised kernel) and Cowper-Symonds
    (scalar kernel) materials."""
    nx = -(-2 * TET_CHUNK // (6 * 23 * 23)) + 1
    x0, cells = brick_tets(nx, 23, 23, 1e-3)
    nc = len(cells)
    cs = tet_chunk_size(nc)
    assert nc > 2 * TET_CHUNK and -(-nc // cs) == 4 and nc % cs > 0
    bad = cs + cs // 2
    x0[cells[bad, 1]], x0[cells[bad, 2]] = x0[cells[bad, 2]].copy(), x0[cells[bad, 1]].copy()
    rng = np.random.default_rng(1)
    v = rng.normal(scale=40.0, size=x0.shape)
    st0 = rng.normal(scale=150e6, size=(nc, 6))
    T = tet_thread_arrays(cells, len(x0))
    assert len(T.gather) > 1000
    for mat, serial in ((AL, tet_step_batched), (AL_RATE, tet_step)):
        prm = pack_parameters(mat, MODE_SOLID, 1.0, 0.06, 1.2, True)
        runs = []
        for n in [0] + list(range(1, threads + 1)):
            x, st, ep = x0.copy(), st0.copy(), np.full(nc, 0.01)
            out = []
            for _ in range(3):
                x += 2e-8 * v
                f, acc = np.zeros_like(x), np.zeros(3)
                if n == 0:
                    d = serial(cells, x, v, 2e-8, prm, st, ep, f, acc, np.zeros(TET_WORK_SIZE), np.empty(0))
                else:
                    numba.set_num_threads(n)
                    d = tet_step_threaded(cells, x, v, 2e-8, prm, st, ep, f, acc, T)
                out.append((d, f, acc, st.copy(), ep.copy()))
            runs.append(out)
        ref = runs[0]
        assert cs <= ref[0][2][2] < 2 * cs and np.count_nonzero(ref[-1][4] > 0.01) > nc // 4
        for n, out in enumerate(runs[1:], start=1):
            for (d0, *a0), (d1, *a1) in zip(ref, out):
                assert d0 == d1, (mat.rate_law, n)
                for p, q in zip(a0, a1):
                    assert np.array_equal(p, q), (mat.rate_law, n)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)


@needs_two
def test_threaded_kernel_gives_the_serial_bits():
    compare_kernels(2)


def test_three_threads_give_the_serial_bits():
    """Three threads (more than this machine's cores: numba is told so in a fresh process)."""
    env = dict(os.environ, NUMBA_NUM_THREADS="3")
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import test_3d_threads as t; "
            "t.compare_kernels(3); print('ok')")
    r = subprocess.run([sys.executable, "-c", code, os.path.dirname(__file__)], env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), r.stderr[-2000:]


def _solver(threads: int) -> ExplicitSolver3D:
    """A plate (TET_CHUNK + 4 224 tetrahedra: two chunks) thrown at 150 m/s onto a rigid wall and
    into a second, rate-dependent body (the scalar kernel) through node-to-face soft contact:
    plastic, with contact and wall forces."""
    n = -(-(TET_CHUNK + 4224) // (6 * 16 * 16))
    a = dmesh.create_box(MPI.COMM_SELF, [np.zeros(3), np.array([n * 1e-3, 0.016, 0.016])],
                         [n, 16, 16], dmesh.CellType.tetrahedron)
    b = dmesh.create_box(MPI.COMM_SELF, [np.array([0.0, 0.0, 0.0161]), np.array([0.02, 0.016, 0.0241])],
                         [10, 8, 4], dmesh.CellType.tetrahedron)
    return ExplicitSolver3D([BodySpec("a", a, AL, initial_velocity=(0.0, 0.0, -150.0)),
                             BodySpec("b", b, AL_RATE, initial_velocity=(0.0, 0.0, -200.0))],
                            contact_pairs=(ContactPairSpec(slave="b", master="a", stiffness=1e5,
                                                           h0=2e-4),),
                            rigid_walls=(RigidWallSpec((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),),
                            comm=MPI.COMM_SELF, threads=threads)


@needs_two
def test_two_threads_give_the_serial_states():
    one, two = _solver(1), _solver(2)
    assert len(one.bodies["a"].cells) > TET_CHUNK
    assert len(two._kernels["a"].arrays.gather) > 100
    for s in (one, two):
        for _ in range(4):
            s.advance(0.8 * s.stable_time_step(), 10)
    for name in ("a", "b"):
        p, q = one.bodies[name], two.bodies[name]
        for k in ("x", "v", "a", "cell_stress", "eps_p"):
            assert np.array_equal(getattr(p, k), getattr(q, k)), (name, k)
        assert np.count_nonzero(p.eps_p) > 100, name
    assert one.energies() == two.energies()
    assert one.energies()["contact_stored_J"] > 0.0


def test_threads_are_checked():
    msh = dmesh.create_box(MPI.COMM_SELF, [np.zeros(3), np.ones(3)], [1, 1, 1],
                           dmesh.CellType.tetrahedron)
    for bad in (0, 1.5, numba.config.NUMBA_NUM_THREADS + 1):
        with pytest.raises(ValueError, match="threads must be an integer from 1"):
            ExplicitSolver3D([BodySpec("a", msh, AL, initial_velocity=(0.0, 0.0, 0.0))],
                             comm=MPI.COMM_SELF, threads=bad)
