"""Steps per second of a ten-node body (issue 34, item 4: the explicit plastic hinge): the cantilever strips of
tests/mechanics/cantilever_strip.py (square section, three ten-node tetrahedra through the thickness) under a tip
force with kinetic damping, in the Python step loop (``ExplicitSolver3D(compiled_steps=False)``) and in the compiled
steps (:mod:`pulseform.solvers.dolfinx.tet10_steps`, the default), and the element kernel alone on the same
state; the process's CPU time (one thread: not inflated by other processes on a shared machine, as wall time is),
best of ``--rounds`` alternated rounds, the load average beside. The two solvers take
the same steps: their states are then compared bit for bit.

Usage: .venv/bin/python bench/tet10_steps.py [--strips "0.01,10,1.5 0.04,40,1"] [--steps 2000] [--rounds 3]
(a strip is length m, bricks along, grading).
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

from pulseform.solvers.dolfinx import ExplicitSolver3D, Material
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "mechanics"))  # the tests' strip: one home
from cantilever_strip import Strip, hinge_load, strip_body, tip_load  # noqa: E402

E, NU = 200e9, 0.3
G, K = E / (2 * (1 + NU)), E / (3 * (1 - 2 * NU))
MAT = Material(7800.0, G, K, 250e6, 0.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--strips", default="0.01,10,1.5 0.04,40,1")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    for spec in a.strips.split():
        L, nl, gr = spec.split(",")
        st = Strip(length=float(L), width=0.001, n_length=int(nl), n_width=1, n_thick=3, grading=float(gr))
        solvers = {c: ExplicitSolver3D([strip_body(st, MAT, "tet10")], cfl=0.8, compiled_steps=c)
                   for c in (False, True)}
        best = {False: np.inf, True: np.inf, "kernel": np.inf}
        for s in solvers.values():
            s.kinetic_damping = True
            f = {"strip": tip_load(s.bodies["strip"], st, 0.9 * hinge_load(st, MAT))}
            s.advance(s.stable_time_step(), 10, f)          # compile, load
        dt = solvers[True].stable_time_step()
        for _ in range(a.rounds):
            for c, s in solvers.items():
                t0 = time.process_time()
                s.advance(dt, a.steps)
                best[c] = min(best[c], time.process_time() - t0)
            s = solvers[False]
            b = s.bodies["strip"]
            k, f, acc = s._kernels["strip"], np.zeros_like(b.x), np.zeros(3)
            stress, ep, temp = b.cell_stress.copy(), b.eps_p.copy(), b.temperature.copy()
            t0 = time.process_time()
            for _ in range(a.steps):
                k(b.cells, b.x, b.v, dt, s._prm["strip"], stress, ep, f, acc, None, temp)
            best["kernel"] = min(best["kernel"], time.process_time() - t0)
        b0, b1 = solvers[False].bodies["strip"], solvers[True].bodies["strip"]
        same = all(np.array_equal(getattr(b0, n), getattr(b1, n)) for n in ("x", "v", "a", "cell_stress", "eps_p"))
        print(f"L = {float(L) * 1e3:.0f} mm, {nl} bricks along (grading {gr}): {len(b0.cells)} cells, "
              f"dt {dt:.3e} s; steps/s: Python loop {a.steps / best[False]:.0f}, compiled "
              f"{a.steps / best[True]:.0f} (x{best[False] / best[True]:.2f}), kernel alone "
              f"{a.steps / best['kernel']:.0f}; same bits: {same}; load {os.getloadavg()[0]:.2f}", flush=True)


if __name__ == "__main__":
    main()
