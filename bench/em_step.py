"""Wall time per EM step vs mesh size: the persistent getdp (one process for the run) vs one getdp
process per step vs one getdp stepping continuously by itself.

Geometry: 5-turn coil 1 mm under a 1 mm Al disk (R 60 mm), shell transformation, a demo-like
capacitor bank (50 uF, 6 kV, 10 mOhm, 2 uH), BDF2 with steps of about 0.5 us (a few shorter and
longer ones, as when the coupling lands on output times). The disk bulges (u_z = A(t)(1 - (r/R)^2),
air smoothed harmonically by the product's MeshMover); every node position is computed before timing.

Variants (N steps each, repeated ``--repeat`` times interleaved; medians printed):
  per-process  GetDPSolver(time_scheme="bdf2").step per EM step on the moved mesh (em.getdp_process =
               "per_step": a getdp start, pre-processing, MSH and text tables in and out per step)
  persistent   PersistentGetDPSolver.step per EM step on the moved mesh (em.getdp_process =
               "persistent": displacement through a FIFO, DeformMesh, BDF2 on GetDP's vectors, the
               per-element force table and the lean globals); its one start-up is printed apart
  continuous   the same resolution clocked by getdp itself (PF_SelfSteps): the same BDF2 loop,
               operations and per-step outputs on the fixed mesh, no Python, no FIFO, no motion;
               per step = (T(N steps) - T(1 step)) / (N - 1) of whole getdp runs

Targets (issue 15): persistent / continuous <= 1.1 at 10k nodes and <= 1.3 at 1k nodes;
persistent / per-process <= 0.35 at 1k nodes.

Usage: python bench/em_step.py [--steps 20] [--sizes 1e3 3e3 1e4 3e4] [--repeat 3] [--work DIR]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from pulseform.orchestrator.mesh.motion import MeshMover
from pulseform.solvers.getdp import Circuit, Coil, Conductor, EMModel, GetDPSolver, Rect, coil_conductor_mesh
from pulseform.solvers.getdp.mesh import AXIS, OUTER, SHELL, conductor_tag, coil_tag
from pulseform.solvers.getdp.persistent import PersistentGetDPSolver
from pulseform.solvers.getdp.persistent_process import FLAG_ELEM
from pulseform.solvers.getdp.runner import FAST_MPI_ENV, child_preexec

TURNS = [Rect(0.010 + i * 0.004, -0.003, 0.013 + i * 0.004, -0.001) for i in range(5)]
DISK = Rect(0.0, 0.0, 0.06, 0.001)
MODEL = EMModel(True, coils=[Coil(5)], conductors=[Conductor(2.5e7)],
                circuit=Circuit(C=50e-6, V0=6e3, R_ext=0.01, L_ext=2e-6), shell=(0.15, 0.1875))
DT = 0.5e-6


def mesh_with_about(n_nodes: float):
    """The bench mesh with a node count within 15 % of ``n_nodes`` (sizes scaled as 1/sqrt(n))."""
    scale = 1.0
    for _ in range(4):
        m = coil_conductor_mesh([TURNS], [DISK], r_domain=0.15, r_shell=0.1875, h_fine=1.2e-3 * scale,
                                h_coarse=2e-2 * scale, h_conductor=6e-4 * scale)
        ratio = m.n_nodes / n_nodes
        if 0.85 < ratio < 1.15:
            break
        scale *= np.sqrt(ratio)
    return m


class Motion:
    """Node positions over time: the disk bulges, u_z = A(t) (1 - (r/R)^2) for r < R = 50 mm with
    A(t) = a_max (t/T)^2; coil, shell and outer boundary fixed, axis nodes slide, air harmonic."""

    def __init__(self, mesh, a_max: float = 1.0e-3, t_ref: float = 30e-6, r_clamp: float = 0.05):
        self.x0 = mesh.points.copy()
        tri = mesh.triangles
        self.disk = np.unique(tri[mesh.tri_tags == conductor_tag(1)])
        fixed = np.unique(np.concatenate([tri[(mesh.tri_tags == coil_tag(1)) | (mesh.tri_tags == SHELL)].ravel(),
                                          mesh.lines[mesh.line_tags == OUTER].ravel(), self.disk]))
        axis = np.unique(mesh.lines[mesh.line_tags == AXIS].ravel())
        self.mover = MeshMover(self.x0, tri, (np.union1d(fixed, axis), fixed))
        self.a_max, self.t_ref, self.r_clamp = a_max, t_ref, r_clamp

    def points(self, t: float) -> np.ndarray:
        u = np.zeros_like(self.x0)
        r = self.x0[self.disk, 0]
        u[self.disk, 1] = self.a_max * (t / self.t_ref) ** 2 * np.clip(1 - (r / self.r_clamp) ** 2, 0, None)
        return self.mover.moved(u)


def step_times(n_steps: int, dt: float = DT) -> np.ndarray:
    """End times (s) of ``n_steps`` EM steps of about ``dt`` (every 7th pair 0.37 dt then 1.4 dt)."""
    dts = np.full(n_steps, dt)
    dts[5::7] = 0.37 * dt
    dts[6::7] = 1.4 * dt
    return np.cumsum(dts)


def per_process(mesh, pts, times, work: Path) -> tuple[float, float]:
    """(wall per step, start-up) in s: a getdp process per step."""
    s = GetDPSolver(MODEL, work, time_scheme="bdf2", keep_runs=2)
    st = s.initial_state()
    w0 = time.perf_counter()
    for k, t in enumerate(times):
        _, st = s.step(mesh.with_points(pts[k]), st, float(t), material_points=mesh.points)
    return (time.perf_counter() - w0) / len(times), 0.0


def persistent(mesh, pts, times, work: Path) -> tuple[float, float]:
    """(wall per step after the start-up, start-up) in s: one getdp process for the run."""
    s = PersistentGetDPSolver(MODEL, work)
    st = s.initial_state()
    w0 = time.perf_counter()
    for k, t in enumerate(times):  # the first step starts the process (s.startup_s, taken out)
        _, st = s.step(mesh.with_points(pts[k]), st, float(t), material_points=mesh.points)
    wall = (time.perf_counter() - w0 - s.startup_s) / len(times)
    s.close()
    return wall, s.startup_s


def continuous(mesh, pts, times, work: Path) -> tuple[float, float]:
    """(wall per step, wall of a 1-step run) in s: the persistent resolution clocked by getdp itself
    on the fixed mesh (PF_SelfSteps), the same per-step outputs, no Python in the loop."""
    s = PersistentGetDPSolver(MODEL, work)
    dt = float(times[-1] / len(times))
    env = dict(os.environ, **FAST_MPI_ENV)
    walls = []
    for n in (1, len(times)):
        p = s.make_process(mesh, mesh.points, s.initial_state(), work / f"self_{n}",
                           {"PF_SelfSteps": n, "PF_SelfDt": dt, "PF_SelfFlags": FLAG_ELEM})
        argv = list(p.argv)
        lines = p.run_dir / "lines.txt"
        argv[argv.index("PF_Out") + 1] = str(lines)  # a plain file instead of the FIFO
        w0 = time.perf_counter()
        with open(p.run_dir / "getdp.log", "w") as log:
            rc = subprocess.run(argv, cwd=p.run_dir, stdout=log, stderr=subprocess.STDOUT, env=env,
                                preexec_fn=child_preexec, timeout=3600).returncode
        walls.append(time.perf_counter() - w0)
        done = sum(1 for ln in open(lines) if ln.startswith("D "))
        p.close()  # never started: removes its FIFOs
        if rc != 0 or done != n:
            raise RuntimeError(f"self-clocked getdp: exit {rc}, {done} of {n} steps (log {p.run_dir}/getdp.log)")
    return (walls[1] - walls[0]) / (len(times) - 1), walls[0]


VARIANTS = {"per-process": per_process, "persistent": persistent, "continuous": continuous}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e3, 3e3, 1e4, 3e4])
    ap.add_argument("--repeat", type=int, default=3, help="trials per size, interleaved; medians printed")
    ap.add_argument("--work", type=Path, default=None)
    args = ap.parse_args(argv)
    print(f"load average at start: {os.getloadavg()[0]:.2f} ({os.cpu_count()} CPUs)")
    print(f"{'nodes':>7} {'per-process':>12} {'persistent':>11} {'continuous':>11} {'start-up':>9}"
          f" {'pers/cont':>10} {'pers/per-proc':>14}   (ms per EM step, median of {args.repeat})")
    ratios = {}
    with tempfile.TemporaryDirectory(prefix="em_step_") as tmp:
        work = (args.work or Path(tmp)).resolve()
        for n in args.sizes:
            mesh = mesh_with_about(n)
            times = step_times(args.steps)
            motion = Motion(mesh)
            pts = [motion.points(float(t)) for t in times]
            res = {v: [] for v in VARIANTS}
            for rep in range(args.repeat):
                for v, fn in VARIANTS.items():
                    res[v].append(fn(mesh, pts, times, work / f"n{mesh.n_nodes}_{v}_{rep}"))
            med = {v: np.median(np.array(r), axis=0) for v, r in res.items()}
            pc, pp, co = med["per-process"][0], med["persistent"][0], med["continuous"][0]
            ratios[mesh.n_nodes] = (pp / co, pp / pc)
            print(f"{mesh.n_nodes:7d} {pc * 1e3:12.2f} {pp * 1e3:11.2f} {co * 1e3:11.2f} "
                  f"{med['persistent'][1] * 1e3:9.0f} {pp / co:10.3f} {pp / pc:14.3f}", flush=True)
    nodes = np.array(sorted(ratios))
    small, ten_k = nodes[np.argmin(abs(nodes - 1e3))], nodes[np.argmin(abs(nodes - 1e4))]
    print(f"targets: persistent/continuous at {small} nodes {ratios[small][0]:.3f} (target <= 1.3), "
          f"at {ten_k} nodes {ratios[ten_k][0]:.3f} (target <= 1.1); persistent/per-process at {small} nodes "
          f"{ratios[small][1]:.3f} (target <= 0.35)")
    print(f"bench: em_step persistent_over_continuous_{ten_k}_nodes={ratios[ten_k][0]:.3f} target=1.1")
    return ratios


if __name__ == "__main__":
    main()
