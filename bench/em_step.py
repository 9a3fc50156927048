"""Wall time per EM step vs mesh size: one getdp process stepping vs one process per step.

(a) one getdp process runs N implicit Euler steps (GetDPSolver.step with n_sub = N);
(b) the staggered loop's way: N calls of GetDPSolver.step(n_sub = 1), each a new getdp process
    that writes the MSH 2.2 mesh, restarts from the previous .res and reads the outputs.
Geometry: 5-turn coil 1 mm under a 1 mm Al disk (R 60 mm), shell transformation; prescribed
20 kA e^(-1e4 t) sin(1e5 t), dt = 0.5 us.  Prints (b)/(a) per mesh size (target <= 1.3 at 10k nodes),
for wall time and for CPU time (getdp children + this process; steadier on a shared machine).

Usage: python bench/em_step.py [--steps 20] [--sizes 1e3 3e3 1e4 3e4] [--repeat 1] [--work DIR]
"""
from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp import Coil, Conductor, DampedSine, EMModel, GetDPSolver, Rect, coil_conductor_mesh

TURNS = [Rect(0.010 + i * 0.004, -0.003, 0.013 + i * 0.004, -0.001) for i in range(5)]
DISK = Rect(0.0, 0.0, 0.06, 0.001)
MODEL = EMModel(True, coils=[Coil(5, waveform=DampedSine(20e3, 1e4, 1e5))], conductors=[Conductor(3.5e7)],
                shell=(0.15, 0.1875))
DT = 0.5e-6


def mesh_with_about(n_nodes: float):
    """Scale the mesh sizes until the node count is near n_nodes (h ~ 1/sqrt(n))."""
    scale = 1.0
    for _ in range(4):
        m = coil_conductor_mesh([TURNS], [DISK], r_domain=0.15, r_shell=0.1875, h_fine=1.2e-3 * scale,
                                h_coarse=2e-2 * scale, h_conductor=6e-4 * scale)
        ratio = m.n_nodes / n_nodes
        if 0.85 < ratio < 1.15:
            break
        scale *= np.sqrt(ratio)
    return m


def _clock() -> tuple[float, float]:
    """(wall, CPU of this process and its finished children) in seconds."""
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.perf_counter(), time.process_time() + c.ru_utime + c.ru_stime


def bench(n_nodes: float, steps: int, work: Path, repeat: int = 1) -> tuple[int, float, float, float, float]:
    """(nodes, wall (a), wall (b), CPU (a), CPU (b)) per EM step; minimum over ``repeat`` trials."""
    mesh = mesh_with_about(n_nodes)
    solver = GetDPSolver(MODEL, work / f"n{int(n_nodes)}", keep_runs=2)   # old runs deleted in a thread
    best = np.full(4, np.inf)
    for trial in range(repeat):
        # (a) one process, many steps
        w0, c0 = _clock()
        solver.step(mesh, solver.initial_state(), steps * DT, steps, run_name=f"continuous_{trial}")
        w1, c1 = _clock()
        # (b) one process per step, restart from the previous .res
        state = solver.initial_state()
        for k in range(steps):
            _, state = solver.step(mesh, state, (k + 1) * DT, 1, run_name=f"step_{trial}_{k}")
        w2, c2 = _clock()
        best = np.minimum(best, np.array([w1 - w0, w2 - w1, c1 - c0, c2 - c1]) / steps)
    return (mesh.n_nodes, *best.tolist())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e3, 3e3, 1e4, 3e4])
    ap.add_argument("--work", type=Path, default=None)
    ap.add_argument("--repeat", type=int, default=1, help="trials per size; the minimum is printed")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="em_step_") as tmp:
        work = (args.work or Path(tmp)).resolve()
        print("wall and CPU (this process + getdp children) per EM step; the machine may be shared,"
              " so CPU ratios are the steadier figure")
        print(f"{'nodes':>7} {'(a) wall s':>11} {'(b) wall s':>11} {'(b)/(a)':>8}   "
              f"{'(a) CPU s':>10} {'(b) CPU s':>10} {'(b)/(a)':>8}")
        for n in args.sizes:
            nodes, t_a, t_b, c_a, c_b = bench(n, args.steps, work, args.repeat)
            print(f"{nodes:7d} {t_a:11.4f} {t_b:11.4f} {t_b / t_a:8.2f}   {c_a:10.4f} {c_b:10.4f} {c_b / c_a:8.2f}",
                  flush=True)


if __name__ == "__main__":
    main()
