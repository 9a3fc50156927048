"""Per-step cost of the 3D explicit solver (issue 20) against the number of tetrahedra: a quarter
bar (4 x 1 x 1 m, ``create_box``, six tetrahedra per brick) at 5 m/s pressed on a sliding rigid
wall, so that the wall, the roller planes and the ledger are active. For each mesh: the full step
through ``ExplicitSolver3D.advance`` (Python step loop around the compiled kernel) and the element
kernels alone on the same state (the vectorised ``tet_step_batched`` the solver uses, and the
scalar ``tet_step``), best of ``--rounds`` rounds, alternated (the machine is shared), as steps/s
and M element-updates/s (cells x steps / wall time).

Usage: .venv/bin/python bench/mech3d_step_cost.py [--sizes 10 20 30 40] [--steps 100] [--rounds 3]
(a size n is the mesh 4n x n x n bricks = 24 n^3 tetrahedra).
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, ExplicitSolver3D, RigidWallSpec
from pulseform.solvers.dolfinx.tet_batch import TET_WORK_SIZE, tet_step_batched
from pulseform.solvers.dolfinx.tet_kernel import tet_step
from pulseform.solvers.dolfinx.verification import PAPER_BAR_MATERIAL


def build(n: int) -> ExplicitSolver3D:
    msh = dmesh.create_box(MPI.COMM_SELF, [np.zeros(3), np.array([4.0, 1.0, 1.0])], [4 * n, n, n],
                           dmesh.CellType.tetrahedron)
    fixed = ((lambda x: np.isclose(x[1], 0.0), (1,)), (lambda x: np.isclose(x[2], 0.0), (2,)))
    wall = RigidWallSpec(point=(4.0, 0.0, 0.0), normal=(-1.0, 0.0, 0.0), sliding=True)
    return ExplicitSolver3D([BodySpec("bar", msh, PAPER_BAR_MATERIAL, initial_velocity=(5.0, 0, 0),
                                      fixed=fixed)], rigid_walls=(wall,), comm=MPI.COMM_SELF)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 30, 40])
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} (2 vCPUs)")
    print(f"{'tets':>9} {'nodes':>8} {'step ms':>9} {'steps/s':>9} {'M upd/s':>8} "
          f"{'batched ms':>10} {'M/s':>6} {'scalar ms':>10} {'M/s':>6} {'step/batched':>12}")
    for n in a.sizes:
        s = build(n)
        b = s.bodies["bar"]
        nc = len(b.cells)
        dt = s.stable_time_step()
        s.advance(dt, 2)                      # compile / warm up
        best = {"step": np.inf, "batched": np.inf, "scalar": np.inf}
        f = np.zeros_like(b.x)
        acc = np.zeros(3)
        work = np.zeros(TET_WORK_SIZE)
        for _ in range(a.rounds):
            t0 = time.perf_counter()
            s.advance(dt, a.steps)
            best["step"] = min(best["step"], (time.perf_counter() - t0) / a.steps)
            for name, kernel in (("batched", tet_step_batched), ("scalar", tet_step)):
                st, ep = b.cell_stress.copy(), b.eps_p.copy()
                t0 = time.perf_counter()
                for _ in range(a.steps):
                    f[...] = 0.0
                    kernel(b.cells, b.x, b.v, dt, s._prm["bar"], st, ep, f, acc, work)
                best[name] = min(best[name], (time.perf_counter() - t0) / a.steps)
        bs, bb, bk = best["step"], best["batched"], best["scalar"]
        print(f"{nc:9d} {b.n_owned:8d} {bs * 1e3:9.3f} {1 / bs:9.1f} {nc / bs / 1e6:8.2f} "
              f"{bb * 1e3:10.3f} {nc / bb / 1e6:6.1f} {bk * 1e3:10.3f} {nc / bk / 1e6:6.1f} "
              f"{bs / bb:12.2f}")


if __name__ == "__main__":
    main()
