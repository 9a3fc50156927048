"""A long persistent run: memory (VmRSS of getdp), log size and per-step time stay flat?

Runs ``--steps`` BDF2 steps (1k-node bench mesh, capacitor circuit, the disk bulging and coming back
so the mesh stays valid) in one getdp process and prints, every ``--every`` steps, getdp's resident
memory, the log size and the median step time.

Usage: .venv/bin/python studies/persistent_getdp/longrun.py [--steps 2000] [--every 250] [--verbosity 2]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import MODEL, Motion, make_mesh  # noqa: E402
from persistent import FLAG_ELEM, PersistentGetDP  # noqa: E402


def rss_mb(pid: int) -> float:
    for ln in open(f"/proc/{pid}/status"):
        if ln.startswith("VmRSS:"):
            return int(ln.split()[1]) / 1024
    return float("nan")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nodes", type=float, default=1e3)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--every", type=int, default=250)
    ap.add_argument("--verbosity", type=int, default=2)
    args = ap.parse_args(argv)
    mesh = make_mesh(args.nodes)
    motion = Motion(mesh, a_max=0.5e-3, t_ref=1.0)
    with tempfile.TemporaryDirectory(prefix="pgdp_long_") as tmp:
        p = PersistentGetDP(MODEL, Path(tmp) / "run", verbosity=args.verbosity, lean=True)
        p.start(mesh)
        dt = 0.05e-6
        times = []
        print(f"{mesh.n_nodes} nodes, {args.steps} steps of {dt * 1e6:g} us, getdp -v {args.verbosity}")
        print(f"{'step':>6} {'getdp RSS MB':>13} {'log kB':>8} {'median ms/step':>15}")
        for k in range(1, args.steps + 1):
            phase = np.sin(np.pi * k / 500.0) ** 2          # up and down: the mesh never degrades
            o = p.step(motion.points(phase), k * dt, FLAG_ELEM)
            times.append(sum(o.timing.values()))
            if k == 1 or k % args.every == 0:
                print(f"{k:6d} {rss_mb(p.proc.pid):13.1f} {os.path.getsize(p.log_path) / 1024:8.1f} "
                      f"{np.median(times[-args.every:]) * 1e3:15.2f}", flush=True)
        assert p.close() == 0


if __name__ == "__main__":
    main()
