"""Throughput of the explicit elastic-plastic step: element-updates per second
(elements x steps / loop time) on a ~100k-element P1 plastic block impacting a rigid wall, for the
compiled (numba) kernel and the plain vectorised-numpy reference kernel (gather + einsum +
np.bincount), timed in the same run, with their ratio.

Usage: .venv/bin/python bench/mech_throughput.py [--n 224] [--steps 60]
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, ExplicitSolver, Material, RigidWallSpec
from pulseform.solvers.dolfinx.kernels import element_step
from pulseform.solvers.dolfinx.reference_kernel import element_step_numpy


def build(n: int, kernel: str) -> ExplicitSolver:
    # 0.1 m block at 200 m/s onto a rigid wall: yields within a few steps (Al, paper section 5)
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([0.0, 0.0]), np.array([0.1, 0.1])],
                                 [n, n])
    mat = Material(2735.0, 26.5e9, 65.1e9, 195e6, 520e6)
    return ExplicitSolver([BodySpec("block", msh, mat, initial_velocity=(-200.0, 0.0))],
                          formulation="plane_strain",
                          rigid_walls=(RigidWallSpec((0.0, 0.0), (1.0, 0.0)),), comm=msh.comm,
                          kernel=kernel)


def time_solver(s: ExplicitSolver, steps: int) -> float:
    dt = s.stable_time_step()
    s.advance(dt, 2)                         # warm-up (JIT, caches)
    t0 = time.perf_counter()
    s.advance(dt, steps)
    return time.perf_counter() - t0


def time_kernel(kern, s: ExplicitSolver, reps: int) -> float:
    b = s.bodies["block"]
    prm = s._prm["block"]
    dt = s.stable_time_step()
    st, ep = b.cell_stress.copy(), b.eps_p.copy()
    f = np.zeros_like(b.v)
    acc = np.zeros(3)
    kern(b.cells, b.x, b.v, dt, prm, st, ep, f, acc)
    t0 = time.perf_counter()
    for _ in range(reps):
        f[:] = 0.0
        kern(b.cells, b.x, b.v, dt, prm, st, ep, f, acc)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=224, help="cells per side / 2 (224 -> 100352 cells)")
    ap.add_argument("--steps", type=int, default=60)
    a = ap.parse_args()
    s_nb = build(a.n, "numba")
    s_np = build(a.n, "numpy")
    ne = s_nb.bodies["block"].cells.shape[0]
    t_nb = time_solver(s_nb, a.steps)
    t_np = time_solver(s_np, a.steps)
    eps = s_nb.bodies["block"].eps_p
    # the two solvers ran the same steps: same state up to round-off
    dx = np.abs(s_nb.bodies["block"].x - s_np.bodies["block"].x).max()
    k_nb = time_kernel(element_step, s_nb, a.steps)
    k_np = time_kernel(element_step_numpy, s_nb, a.steps)
    r_step = t_np / t_nb
    r_kern = k_np / k_nb
    print(f"block impact: {ne} P1 cells, {a.steps} steps, plastic cells {np.count_nonzero(eps)}"
          f" (max eps_p {eps.max():.3e}), max |x_numba - x_numpy| {dx:.2e} m")
    print(f"full explicit step  numba: {ne * a.steps / t_nb / 1e6:8.2f} M element-updates/s"
          f"  ({t_nb / a.steps * 1e3:.2f} ms/step)")
    print(f"full explicit step  numpy: {ne * a.steps / t_np / 1e6:8.2f} M element-updates/s"
          f"  ({t_np / a.steps * 1e3:.2f} ms/step)")
    print(f"element kernel only numba: {ne * a.steps / k_nb / 1e6:8.2f} M/s, "
          f"numpy: {ne * a.steps / k_np / 1e6:8.2f} M/s")
    print(f"ratio numba / numpy: full step {r_step:.2f}x, kernel only {r_kern:.2f}x (target >= 4x)")


if __name__ == "__main__":
    main()
