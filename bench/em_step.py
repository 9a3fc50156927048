"""Wall time per EM step vs mesh size: one getdp process stepping vs one process per step.

(a) one getdp process runs N implicit Euler steps (GetDPSolver.step with n_sub = N);
(b) the staggered loop's way: N calls of GetDPSolver.step(n_sub = 1), each a new getdp process
    that writes the MSH 2.2 mesh, restarts from the previous .res and reads the outputs.
Geometry: 5-turn coil 1 mm under a 1 mm Al disk (R 60 mm), shell transformation; prescribed
20 kA e^(-1e4 t) sin(1e5 t), dt = 0.5 us.  Prints (b)/(a) per mesh size (target <= 1.3 at 10k nodes).

Usage: python bench/em_step.py [--steps 20] [--sizes 1e3 3e3 1e4 3e4] [--work DIR]
"""
from __future__ import annotations

import argparse
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


def bench(n_nodes: float, steps: int, work: Path) -> tuple[int, float, float]:
    mesh = mesh_with_about(n_nodes)
    solver = GetDPSolver(MODEL, work / f"n{int(n_nodes)}")
    # (a) one process, many steps
    t0 = time.perf_counter()
    solver.step(mesh, solver.initial_state(), steps * DT, steps, run_name="continuous")
    t_a = (time.perf_counter() - t0) / steps
    # (b) one process per step, restart from the previous .res
    state = solver.initial_state()
    t0 = time.perf_counter()
    for k in range(steps):
        _, state = solver.step(mesh, state, (k + 1) * DT, 1, run_name=f"step_{k % 2}")
    t_b = (time.perf_counter() - t0) / steps
    return mesh.n_nodes, t_a, t_b


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e3, 3e3, 1e4, 3e4])
    ap.add_argument("--work", type=Path, default=None)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="em_step_") as tmp:
        work = (args.work or Path(tmp)).resolve()
        print(f"{'nodes':>7} {'(a) s/step':>11} {'(b) s/step':>11} {'(b)/(a)':>8}")
        for n in args.sizes:
            nodes, t_a, t_b = bench(n, args.steps, work)
            print(f"{nodes:7d} {t_a:11.4f} {t_b:11.4f} {t_b / t_a:8.2f}", flush=True)


if __name__ == "__main__":
    main()
