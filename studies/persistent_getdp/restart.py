"""Restarting a persistent getdp: (1) resume on the same mesh (a checkpoint: the process ends after
step m, a new one is seeded with both BDF2 history states through the two-valued Init constraints);
(2) remesh (a new mesh of other connectivity at step m: the states are interpolated in material
coordinates with the product's routine).  Compared with (1) the uninterrupted persistent run and
(2) today's per-process path (GetDPSolver(time_scheme="bdf2"), force_init_path after the remesh)
on the same meshes.  Capacitor circuit, moving disk, variable steps.

Usage: .venv/bin/python studies/persistent_getdp/restart.py [--nodes 1000] [--steps 30] [--at 15]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import MODEL, Motion, make_mesh, step_times  # noqa: E402
from persistent import FLAG_ELEM, FLAG_STATE, PersistentGetDP, seed_from_state, state_from_query  # noqa: E402

from pulseform.solvers.getdp import GetDPSolver  # noqa: E402


def rel(a, b):
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(b)))


def persistent_segment(mesh, motion, times, k0, k1, work, seed=None):
    """Steps k0..k1-1 on ``mesh`` (positions from ``motion``); returns rows and the state after k1."""
    p = PersistentGetDP(MODEL, work)
    if seed is None:
        p.start(mesh)
    else:
        init, init2 = seed
        start_mesh = mesh.with_points(motion.points(times[k0 - 1]))
        p.start(start_mesh, t1=float(times[k0 - 1]), t2=float(times[k0 - 2]),
                dt_prev=float(times[k0 - 1] - times[k0 - 2]), step0=k0, init=init, init2=init2)
    rows, prev = [], (MODEL.circuit.V0, 0.0)
    for k in range(k0, k1):
        glob_before = getattr(p, "last_glob", None)
        o = p.step(motion.points(times[k]), float(times[k]), FLAG_ELEM)
        rows.append((o.coil[0, 0], o.glob[1], o.cond[0, 1:3].copy(), o.force_density.copy()))
        if glob_before is not None:
            prev = (glob_before[1], glob_before[2])
    q = p.query(FLAG_STATE)
    state = state_from_query(p, q, mesh.points, prev, float(times[k1 - 1] - times[k1 - 2]))
    assert p.close() == 0
    return rows, state


def today(meshes, motions, times, at, work):
    s = GetDPSolver(MODEL, work, time_scheme="bdf2", keep_runs=2)
    st = s.initial_state()
    rows = []
    for k, t in enumerate(times):
        i = 0 if k < at else 1
        m = meshes[i]
        r, st = s.step(m.with_points(motions[i].points(t)), st, float(t), material_points=m.points,
                       force_init_path=i > 0)
        rows.append((r.coil_current[-1, 0], r.capacitor_voltage[-1], r.conductor_force[-1, 0].copy(),
                     r.force_density[-1].copy()))
    return rows


def report(name, a, b, elements=True):
    dI = max(rel(x[0], y[0]) for x, y in zip(a, b))
    dV = max(rel(x[1], y[1]) for x, y in zip(a, b))
    dF = max(rel(x[2], y[2]) for x, y in zip(a, b))
    df = max(rel(x[3], y[3]) for x, y in zip(a, b)) if elements else 0.0
    print(f"{name}: max relative difference over {len(a)} steps: current {dI:.1e}, capacitor voltage {dV:.1e}, "
          f"disk force {dF:.1e}" + (f", element force density {df:.1e}" if elements else ""))
    return max(dI, dV, dF, df)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nodes", type=float, default=1e3)
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--at", type=int, default=15, help="restart / remesh after this many steps")
    args = ap.parse_args(argv)
    times = step_times(args.steps)
    at = args.at
    mesh_a = make_mesh(args.nodes)
    mesh_b = make_mesh(args.nodes * 1.3)   # other connectivity: the "remeshed" mesh
    mot_a, mot_b = Motion(mesh_a), Motion(mesh_b)
    print(f"meshes: {mesh_a.n_nodes} nodes, remeshed {mesh_b.n_nodes} nodes; {args.steps} steps, restart after {at}")
    worst = 0.0
    with tempfile.TemporaryDirectory(prefix="pgdp_restart_") as tmp:
        w = Path(tmp)
        # (1) resume on the same mesh
        full, _ = persistent_segment(mesh_a, mot_a, times, 0, args.steps, w / "full")
        first, state = persistent_segment(mesh_a, mot_a, times, 0, at, w / "first")
        p_new = PersistentGetDP(MODEL, w / "tmp")
        seed = seed_from_state(p_new, mesh_a, mesh_a.points, state)
        second, _ = persistent_segment(mesh_a, mot_a, times, at, args.steps, w / "second", seed)
        worst = max(worst, report("resume (same mesh) vs uninterrupted persistent", full[at:], second))
        # (2) remesh: persistent restarted on mesh_b vs today's per-process path on the same meshes
        ref = today([mesh_a, mesh_b], [mot_a, mot_b], times, at, w / "today")
        seed_b = seed_from_state(p_new, mesh_b, mesh_b.points, state)
        after, _ = persistent_segment(mesh_b, mot_b, times, at, args.steps, w / "remeshed", seed_b)
        worst = max(worst, report("before the remesh: persistent vs per-process", ref[:at], first))
        worst = max(worst, report("after the remesh:  persistent vs per-process", ref[at:], after))
        # what the remesh itself changes (for scale): per-process with vs without remesh
        ref_a = today([mesh_a, mesh_a], [mot_a, mot_a], times, args.steps, w / "today_a")
        report("(scale) per-process remeshed vs not remeshed", ref[at:], ref_a[at:], elements=False)
    print(f"restart: worst relative difference {worst:.1e} (round-off: < 1e-10)")


if __name__ == "__main__":
    main()
