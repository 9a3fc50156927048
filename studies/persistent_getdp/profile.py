"""Where the time of one persistent EM step goes, inside getdp: the self-clocked loop (no Python,
no FIFO) with parts switched on one by one; per-step CPU and wall = (run of N steps - run of 1 step)
/ (N - 1), median of ``--repeat`` runs.

Usage: .venv/bin/python studies/persistent_getdp/profile.py [--sizes 1e3 1e4] [--steps 20] [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import MODEL, make_mesh  # noqa: E402
from persistent import PersistentGetDP  # noqa: E402

from pulseform.solvers.getdp.runner import FAST_MPI_ENV, child_preexec  # noqa: E402

#: (label, PF_GlobalsSet, flags): cumulative
CONFIGS = [
    ("step only (Generate + Solve + BDF2 vectors)", 0, 0),
    ("+ coil I, U, circuit (no integral)", 1, 0),
    ("+ magnetic energy as 1/2 (j, a) on coil + disk (Wj)", 33, 0),
    ("  (instead: W, integral over the whole domain)", 3, 0),
    ("+ conductor Joule power P (integral)", 37, 0),
    ("+ per-element force table elem_F (= lean)", 37, 1),
    ("+ conductor force F (integral = sum of elem_F)", 15, 1),
    ("+ coil P, F integrals (= today's outputs)", 31, 1),
    ("+ per-element P and b tables (field output)", 31, 3),
]


def run(mesh, work: Path, n: int, gset: int, flags: int) -> tuple[float, float]:
    env = dict(os.environ)
    env.update(FAST_MPI_ENV)
    p = PersistentGetDP(MODEL, work, verbosity=2)
    argv = p.prepare(mesh, extra={"PF_SelfSteps": n, "PF_SelfDt": 0.5e-6, "PF_GlobalsSet": gset,
                                  "PF_SelfFlags": flags}, out_path=work / "lines.txt")
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    c0, w0 = c.ru_utime + c.ru_stime, time.perf_counter()
    with open(work / "getdp.log", "w") as log:
        rc = subprocess.run(argv, cwd=work, stdout=log, stderr=subprocess.STDOUT, env=env,
                            preexec_fn=child_preexec).returncode
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert rc == 0, (rc, work)
    return time.perf_counter() - w0, c.ru_utime + c.ru_stime - c0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e3, 1e4])
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    print(f"load average at start: {os.getloadavg()}")
    with tempfile.TemporaryDirectory(prefix="pgdp_prof_") as tmp:
        for size in args.sizes:
            mesh = make_mesh(size)
            print(f"\n{mesh.n_nodes} nodes ({len(mesh.triangles)} triangles, "
                  f"{int((mesh.tri_tags == 201).sum())} in the disk): per step, median of {args.repeat}")
            print(f"{'':48} {'CPU ms':>8} {'wall ms':>8}")
            for label, gset, flags in CONFIGS:
                cpu, wall = [], []
                for rep in range(args.repeat):
                    w = Path(tmp) / f"{mesh.n_nodes}_{gset}_{flags}_{rep}"
                    w1, c1 = run(mesh, w / "a", 1, gset, flags)
                    wn, cn = run(mesh, w / "b", args.steps, gset, flags)
                    cpu.append((cn - c1) / (args.steps - 1))
                    wall.append((wn - w1) / (args.steps - 1))
                print(f"{label:48} {np.median(cpu) * 1e3:8.1f} {np.median(wall) * 1e3:8.1f}", flush=True)
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
