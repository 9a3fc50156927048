"""Wall (and CPU) time per EM step: persistent getdp vs today's one process per step vs one getdp
stepping continuously on a fixed mesh.  Bench geometry (coil + disk), demo-like capacitor circuit,
BDF2, dt ~ 0.5 us, the disk bulging (common.Motion); node positions are computed before timing.

Variants (each N steps, repeated ``--repeat`` times interleaved; medians printed):
  per-process  GetDPSolver(time_scheme="bdf2").step per EM step on the moved mesh (today's coupled
               path: Init path, full pre-processing, text tables, one getdp start per step)
  restart+cal  GetDPSolver(time_scheme="euler").step per EM step on the moved mesh: -restart from the
               previous .res with moved node coordinates and -cal with the previous .pre (the
               "restart from .res" alternative; first order, shown for its cost only)
  continuous   one getdp run of N implicit-Euler steps on the fixed mesh (bench/em_step.py's (a);
               prescribed-current-free circuit model; per-step element tables as there)
  persistent   PersistentGetDP: one process, ReadSolution on a FIFO + DeformMesh + BDF2 on GetDP's
               vectors, per-element force table each step (moving mesh); start-up reported apart
  pers-fixed   the same with zero displacement (the cost of the handshake without motion)
  self-clock   the persistent deck clocked by itself (PF_SelfSteps): the same BDF2 loop, operations and
               outputs on the fixed mesh, no Python, no FIFO: (T(N steps) - T(1 step)) / (N - 1) of
               whole getdp runs -- "one getdp stepping continuously" with today's outputs per step
  pers-lean    persistent with only the outputs the loop needs (PersistentGetDP(lean=True))
  self-lean    self-clock with the same lean outputs (PF_GlobalsSet = 37)

Usage: .venv/bin/python studies/persistent_getdp/bench.py [--sizes 1e3 1e4] [--steps 20] [--repeat 3]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import MODEL, Motion, make_mesh, step_times  # noqa: E402
from persistent import FLAG_ELEM, PersistentGetDP  # noqa: E402

from pulseform.solvers.getdp import GetDPSolver  # noqa: E402

TICK = os.sysconf("SC_CLK_TCK")


def _children_cpu() -> float:
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return c.ru_utime + c.ru_stime


def _proc_cpu(pid: int) -> float:
    f = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(f[11]) + int(f[12])) / TICK


def per_process(mesh, pts, times, work, scheme):
    s = GetDPSolver(MODEL, work, time_scheme=scheme, keep_runs=2)
    st = s.initial_state()
    w0, c0 = time.perf_counter(), time.process_time() + _children_cpu()
    for k, t in enumerate(times):
        _, st = s.step(mesh.with_points(pts[k]), st, float(t), material_points=mesh.points)
    w1, c1 = time.perf_counter(), time.process_time() + _children_cpu()
    return (w1 - w0) / len(times), (c1 - c0) / len(times), 0.0


def continuous(mesh, pts, times, work):
    s = GetDPSolver(MODEL, work, keep_runs=2)
    dt = times[-1] / len(times)
    w0, c0 = time.perf_counter(), time.process_time() + _children_cpu()
    s.step(mesh, s.initial_state(), len(times) * dt, len(times), run_name="continuous")
    w1, c1 = time.perf_counter(), time.process_time() + _children_cpu()
    return (w1 - w0) / len(times), (c1 - c0) / len(times), 0.0


def persistent(mesh, pts, times, work, move=True, lean=False):
    p = PersistentGetDP(MODEL, work, verbosity=3, lean=lean)
    s0 = time.perf_counter()
    p.start(mesh)
    startup = time.perf_counter() - s0
    pid = p.proc.pid
    w0, c0 = time.perf_counter(), time.process_time() + _proc_cpu(pid)
    for k, t in enumerate(times):
        p.step(pts[k] if move else mesh.points, float(t), FLAG_ELEM)
    w1, c1 = time.perf_counter(), time.process_time() + _proc_cpu(pid)
    assert p.close() == 0
    return (w1 - w0) / len(times), (c1 - c0) / len(times), startup


def self_clocked(mesh, pts, times, work, gset=31):
    """Per-step wall/CPU of the self-clocked deck: (run of N steps - run of 1 step) / (N - 1)."""
    import subprocess

    from pulseform.solvers.getdp.runner import FAST_MPI_ENV, child_preexec

    env = dict(os.environ)
    env.update(FAST_MPI_ENV)
    dt = float(times[-1] / len(times))
    res = []
    for n in (1, len(times)):
        p = PersistentGetDP(MODEL, work / f"self{n}", verbosity=3)
        argv = p.prepare(mesh, extra={"PF_SelfSteps": n, "PF_SelfDt": dt, "PF_GlobalsSet": gset},
                         out_path=work / f"self{n}" / "lines.txt")
        c0, w0 = _children_cpu(), time.perf_counter()
        with open(work / f"self{n}" / "getdp.log", "w") as log:
            rc = subprocess.run(argv, cwd=work / f"self{n}", stdout=log, stderr=subprocess.STDOUT, env=env,
                                preexec_fn=child_preexec).returncode
        res.append((time.perf_counter() - w0, _children_cpu() - c0))
        assert rc == 0, rc
        assert sum(1 for ln in open(work / f"self{n}" / "lines.txt") if ln.startswith("D ")) == n
    n = len(times)
    return (res[1][0] - res[0][0]) / (n - 1), (res[1][1] - res[0][1]) / (n - 1), res[0][0]


VARIANTS = {
    "per-process": lambda m, p, t, w: per_process(m, p, t, w, "bdf2"),
    "restart+cal": lambda m, p, t, w: per_process(m, p, t, w, "euler"),
    "continuous": continuous,
    "persistent": lambda m, p, t, w: persistent(m, p, t, w, True),
    "pers-fixed": lambda m, p, t, w: persistent(m, p, t, w, False),
    "self-clock": self_clocked,
    "pers-lean": lambda m, p, t, w: persistent(m, p, t, w, True, True),
    "self-lean": lambda m, p, t, w: self_clocked(m, p, t, w, 37),
}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e3, 1e4])
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS))
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    print(f"load average at start: {os.getloadavg()}")
    allres = {}
    with tempfile.TemporaryDirectory(prefix="pgdp_bench_") as tmp:
        for n in args.sizes:
            mesh = make_mesh(n)
            motion = Motion(mesh)
            times = step_times(args.steps)
            pts = [motion.points(t) for t in times]
            res = {v: [] for v in args.variants}
            for rep in range(args.repeat):
                for v in args.variants:
                    work = Path(tmp) / f"n{mesh.n_nodes}_{v}_{rep}"
                    res[v].append(VARIANTS[v](mesh, pts, times, work))
            med = {v: np.median(np.array(r), axis=0) for v, r in res.items()}
            allres[mesh.n_nodes] = {v: np.array(r).tolist() for v, r in res.items()}
            print(f"\n{mesh.n_nodes} nodes, {args.steps} steps, median of {args.repeat} "
                  f"(load average now {os.getloadavg()[0]:.2f})")
            print(f"{'variant':>12} {'wall ms/step':>13} {'CPU ms/step':>12} {'start-up ms':>12}   all wall ms/step")
            for v in args.variants:
                w, c, s = med[v]
                runs = " ".join(f"{r[0] * 1e3:.1f}" for r in res[v])
                print(f"{v:>12} {w * 1e3:13.1f} {c * 1e3:12.1f} {s * 1e3:12.1f}   {runs}")
            for mine, refs in (("persistent", ("per-process", "continuous", "self-clock")),
                               ("pers-lean", ("per-process", "continuous", "self-lean"))):
                for ref in refs:
                    if mine in med and ref in med:
                        print(f"  {mine} / {ref}: wall {med[mine][0] / med[ref][0]:.3f}, "
                              f"CPU {med[mine][1] / med[ref][1]:.3f}")
    if args.json:
        args.json.write_text(json.dumps(allres, indent=1))


if __name__ == "__main__":
    main()
