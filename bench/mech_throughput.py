"""Throughput of the explicit elastic-plastic step: element-updates per second
(elements x steps / loop time) on a ~100k-element P1 plastic block impacting a rigid wall, for the
compiled path (numba: the whole step in one compiled block, ``ExplicitSolver(compiled_steps=True)``)
and the plain vectorised-numpy reference kernel in the Python step loop (gather, element-wise
array arithmetic, np.bincount scatter; same algorithm), timed in the same run in alternating
rounds (the machine is shared), with their ratio. Targets (issue 15): full step >= 50 M
element-updates/s and >= 10x the numpy twin.

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


def time_steps(s: ExplicitSolver, steps: int) -> float:
    """Wall time per step of ``steps`` explicit steps, s."""
    dt = s.stable_time_step()
    t0 = time.perf_counter()
    s.advance(dt, steps)
    return (time.perf_counter() - t0) / steps


def time_kernel(kern, s: ExplicitSolver, reps: int) -> float:
    """Wall time per call of the element kernel alone on the solver's current state, s."""
    b = s.bodies["block"]
    prm = s._prm["block"]
    dt = s.stable_time_step()
    st, ep = b.cell_stress.copy(), b.eps_p.copy()
    f = np.zeros_like(b.v)
    acc = np.zeros(3)
    t0 = time.perf_counter()
    for _ in range(reps):
        f[:] = 0.0
        kern(b.cells, b.x, b.v, dt, prm, st, ep, f, acc)
    return (time.perf_counter() - t0) / reps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=224, help="cells per side / 2 (224 -> 100352 cells)")
    ap.add_argument("--steps", type=int, default=60)
    a = ap.parse_args()
    s_nb = build(a.n, "numba")
    s_np = build(a.n, "numpy")
    ne = s_nb.bodies["block"].cells.shape[0]
    for sv in (s_nb, s_np):                   # warm-up (JIT, caches)
        sv.advance(sv.stable_time_step(), 2)
    # the machine is shared: alternate the two in rounds and keep each one's best round
    rounds = 5
    per = max(a.steps // rounds, 1)
    t_nb, t_np, k_nb, k_np = [], [], [], []
    for _ in range(rounds):
        t_nb.append(time_steps(s_nb, per))
        t_np.append(time_steps(s_np, max(per // 4, 1)))
        k_nb.append(time_kernel(element_step, s_nb, 4))
        k_np.append(time_kernel(element_step_numpy, s_nb, 2))
    eps = s_nb.bodies["block"].eps_p
    print(f"block impact: {ne} P1 cells, plastic cells {np.count_nonzero(eps)} "
          f"(max eps_p {eps.max():.3e}) after {s_nb.step_count} steps; {rounds} alternating rounds,"
          f" best round shown (median in brackets)")
    for label, tb, tp in (("full explicit step", t_nb, t_np), ("element kernel only", k_nb, k_np)):
        print(f"{label:20s} numba: {ne / min(tb) / 1e6:7.2f} M element-updates/s "
              f"[{ne / np.median(tb) / 1e6:.2f}]   numpy: {ne / min(tp) / 1e6:6.2f} M/s "
              f"[{ne / np.median(tp) / 1e6:.2f}]   ratio {min(tp) / min(tb):5.2f}x "
              f"[{np.median(tp) / np.median(tb):.2f}x]")
    full = ne / min(t_nb) / 1e6
    print(f"full step numba {full:.2f} M element-updates/s (target 50)")
    print(f"bench: mech_throughput full_step_numba_over_numpy={min(t_np) / min(t_nb):.2f} target=10")


if __name__ == "__main__":
    main()
