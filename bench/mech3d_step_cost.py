"""Per-step cost of the 3D explicit solver (issues 20 and 31) against the number of tetrahedra, on
one thread and on ``--threads`` threads: a quarter bar (4 x 1 x 1 m, ``create_box``, six
tetrahedra per brick) at 5 m/s pressed on a sliding rigid wall, so that the wall, the roller
planes and the ledger are active. For each mesh, two solvers on the same mesh
(``ExplicitSolver3D(threads=1)`` and ``threads=n``) and, best of ``--rounds`` rounds alternated
(the machine is shared): the full step through ``advance`` (Python step loop around the compiled
kernel) of each, and the element kernels alone on the same state (the vectorised
``tet_step_batched`` the serial solver uses, the threaded ``tet_step_threaded``, the scalar
``tet_step``), as ms per step and M element-updates/s (cells x steps / wall time). The two solvers
take the same steps: their states are then compared bit for bit. A body of one chunk (at most
``TET_CHUNK`` = 65 536 cells) keeps the serial kernel in the solver (the kernel-alone column runs
the threaded one on its single chunk). The load average (1 min) is printed beside every line;
issue 31's target is two threads >= 32 M/s at 192 000 tets.

Usage: .venv/bin/python bench/mech3d_step_cost.py [--sizes 10 20] [--steps 100] [--rounds 3]
[--threads 2] (a size n is the mesh 4n x n x n bricks = 24 n^3 tetrahedra).
"""
from __future__ import annotations

import argparse
import os
import time

import numba
import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, ExplicitSolver3D, RigidWallSpec
from pulseform.solvers.dolfinx.tet_batch import TET_WORK_SIZE, tet_step_batched
from pulseform.solvers.dolfinx.tet_kernel import tet_step
from pulseform.solvers.dolfinx.tet_threads import tet_step_threaded, tet_thread_arrays
from pulseform.solvers.dolfinx.verification import PAPER_BAR_MATERIAL

#: issue 31: two threads, 192 000 tetrahedra, M element-updates/s
TARGET = 32.0
TARGET_CELLS = 192_000


def build(n: int, threads: int = 1) -> ExplicitSolver3D:
    """The quarter bar of 4n x n x n bricks on the sliding wall, on ``threads`` threads."""
    msh = dmesh.create_box(MPI.COMM_SELF, [np.zeros(3), np.array([4.0, 1.0, 1.0])], [4 * n, n, n],
                           dmesh.CellType.tetrahedron)
    fixed = ((lambda x: np.isclose(x[1], 0.0), (1,)), (lambda x: np.isclose(x[2], 0.0), (2,)))
    wall = RigidWallSpec(point=(4.0, 0.0, 0.0), normal=(-1.0, 0.0, 0.0), sliding=True)
    return ExplicitSolver3D([BodySpec("bar", msh, PAPER_BAR_MATERIAL, initial_velocity=(5.0, 0, 0),
                                      fixed=fixed)], rigid_walls=(wall,), comm=MPI.COMM_SELF,
                            threads=threads)


def same_state(a: ExplicitSolver3D, b: ExplicitSolver3D) -> bool:
    """The two solvers' bodies and ledgers bitwise equal."""
    p, q = a.bodies["bar"], b.bodies["bar"]
    return (all(np.array_equal(getattr(p, k), getattr(q, k))
                for k in ("x", "v", "a", "cell_stress", "eps_p"))
            and a.energies() == b.energies() and a.time == b.time)


def load() -> float:
    """Load average over the last minute."""
    return os.getloadavg()[0]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20])
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args()
    nt = a.threads
    print(f"load average {load():.2f} (1 min; {os.cpu_count()} vCPUs), numba sees "
          f"{numba.config.NUMBA_NUM_THREADS} threads; full step = advance(), kernel = element kernel alone")
    print(f"{'tets':>9} {'nodes':>8} {'1 thr ms':>9} {'M/s':>6} {f'{nt} thr ms':>9} {'M/s':>6} "
          f"{'ratio':>6} | {'kernel 1 thr':>12} {'M/s':>6} {f'kernel {nt} thr':>12} {'M/s':>6} "
          f"{'scalar ms':>9} {'M/s':>6} | {'load':>5} {'bitwise':>7}")
    at_target = None
    for n in a.sizes:
        one, many = build(n, 1), build(n, nt)
        b = one.bodies["bar"]
        nc = len(b.cells)
        dt = one.stable_time_step()
        for s in (one, many):
            s.advance(dt, 2)                      # compile / warm up
        load0 = load()
        best = dict.fromkeys(("one", "many", "k_one", "k_many", "k_scalar"), np.inf)
        f = np.zeros_like(b.x)
        acc = np.zeros(3)
        work = np.zeros(TET_WORK_SIZE)
        no_temp = np.empty(0)  # no temperature per cell
        arrays = tet_thread_arrays(b.cells, len(b.x))
        prm = one._prm["bar"]
        kernels = (("k_one", 1, lambda *g: tet_step_batched(*g, work, no_temp)),
                   ("k_many", nt, lambda *g: tet_step_threaded(*g, arrays)),
                   ("k_scalar", 1, lambda *g: tet_step(*g, work, no_temp)))
        for _ in range(a.rounds):
            for name, s in (("one", one), ("many", many)):
                t0 = time.perf_counter()
                s.advance(dt, a.steps)
                best[name] = min(best[name], (time.perf_counter() - t0) / a.steps)
            for name, threads, kernel in kernels:
                numba.set_num_threads(threads)
                st, ep = b.cell_stress.copy(), b.eps_p.copy()
                t0 = time.perf_counter()
                for _ in range(a.steps):
                    f[...] = 0.0
                    kernel(b.cells, b.x, b.v, dt, prm, st, ep, f, acc)
                best[name] = min(best[name], (time.perf_counter() - t0) / a.steps)
        bitwise = same_state(one, many)
        rate = {k: nc / v / 1e6 for k, v in best.items()}
        print(f"{nc:9d} {b.n_owned:8d} {best['one'] * 1e3:9.3f} {rate['one']:6.1f} "
              f"{best['many'] * 1e3:9.3f} {rate['many']:6.1f} {rate['many'] / rate['one']:6.2f} | "
              f"{best['k_one'] * 1e3:12.3f} {rate['k_one']:6.1f} {best['k_many'] * 1e3:12.3f} "
              f"{rate['k_many']:6.1f} {best['k_scalar'] * 1e3:9.3f} {rate['k_scalar']:6.1f} | "
              f"{load0:5.2f} {'yes' if bitwise else 'NO':>7}", flush=True)
        if nc == TARGET_CELLS:
            at_target = (rate["one"], rate["many"], load0, load())
    if at_target is not None:
        r1, rn, l0, l1 = at_target
        verdict = "met" if nt == 2 and rn >= TARGET else "not met"
        print(f"{TARGET_CELLS} tets: 1 thread {r1:.1f} M/s, {nt} threads {rn:.1f} M/s, ratio {rn / r1:.2f}; "
              f"target two threads >= {TARGET:.0f} M/s: {verdict} (load average {l0:.2f} -> {l1:.2f})")


if __name__ == "__main__":
    main()
