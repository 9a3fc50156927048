"""Accuracy: the persistent getdp (one process, DeformMesh, BDF2 on GetDP's vectors) against
today's path (GetDPSolver(time_scheme="bdf2"): one getdp process per step, Init path) on the SAME
sequence of moved meshes, capacitor circuit.  Prints per-step relative differences of coil current,
capacitor voltage, the GetDP force integral on the disk and the per-element force densities, and
the same with the mesh held fixed.

Usage: .venv/bin/python studies/persistent_getdp/compare.py [--nodes 1000] [--steps 40] [--work DIR]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import MODEL, Motion, make_mesh, step_times  # noqa: E402
from persistent import FLAG_ELEM, PersistentGetDP  # noqa: E402

from pulseform.solvers.getdp import GetDPSolver  # noqa: E402


def run_today(mesh, motion, times, work: Path, move: bool):
    s = GetDPSolver(MODEL, work / "today", time_scheme="bdf2", keep_runs=2)
    st = s.initial_state()
    rows = []
    for k, t in enumerate(times):
        pts = motion.points(t) if move else mesh.points
        r, st = s.step(mesh.with_points(pts), st, float(t), material_points=mesh.points)
        rows.append(dict(I=r.coil_current[-1, 0], Vc=r.capacitor_voltage[-1], F=r.conductor_force[-1, 0].copy(),
                         el=r.elements.copy(), f=r.force_density[-1].copy(), t=r.times[-1], P=r.coil_power[-1, 0],
                         KP=r.conductor_power[-1, 0], W=r.magnetic_energy[-1]))
    return rows


def run_persistent(mesh, motion, times, work: Path, move: bool, lean: bool = False):
    p = PersistentGetDP(MODEL, work / ("persistent_lean" if lean else "persistent"), lean=lean)
    p.start(mesh)
    rows = []
    try:
        for k, t in enumerate(times):
            pts = motion.points(t) if move else mesh.points
            o = p.step(pts, float(t), FLAG_ELEM)
            rows.append(dict(I=o.coil[0, 0], Vc=o.glob[1], F=o.cond[0, 1:3].copy(), el=o.elements.copy(),
                             f=o.force_density.copy(), t=o.t, P=o.coil[0, 2], KP=o.cond[0, 0], W=o.glob[0]))
    finally:
        rc = p.close()
    assert rc == 0, rc
    return rows


def compare(a, b) -> dict:
    out = {"I": [], "Vc": [], "F": [], "f": [], "P": [], "KP": [], "W": [], "I_abs": [], "F_abs": []}
    for ra, rb in zip(a, b):
        assert np.array_equal(ra["el"], rb["el"])
        out["I"].append(abs(ra["I"] - rb["I"]) / abs(ra["I"]))
        out["Vc"].append(abs(ra["Vc"] - rb["Vc"]) / abs(ra["Vc"]))
        out["F"].append(float(np.linalg.norm(ra["F"] - rb["F"]) / np.linalg.norm(ra["F"])))
        out["f"].append(float(np.abs(ra["f"] - rb["f"]).max() / np.abs(ra["f"]).max()))
        for q in ("P", "KP", "W"):
            out[q].append(abs(ra[q] - rb[q]) / abs(ra[q]))
        out["I_abs"].append(ra["I"])
        out["F_abs"].append(ra["F"][1])
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nodes", type=float, default=1e3)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--work", type=Path, default=None)
    ap.add_argument("--json", type=Path, default=None, help="write the per-step differences here")
    args = ap.parse_args(argv)
    mesh = make_mesh(args.nodes)
    motion = Motion(mesh)
    times = step_times(args.steps)
    print(f"mesh: {mesh.n_nodes} nodes, {len(mesh.triangles)} triangles; {args.steps} BDF2 steps to "
          f"t = {times[-1] * 1e6:.3f} us (dt 0.5 us, some 0.185 / 0.7 us); disk lift at the end "
          f"{motion.a_max * (times[-1] / motion.t_ref) ** 2 * 1e3:.3f} mm")
    result = {}
    with tempfile.TemporaryDirectory(prefix="pgdp_cmp_") as tmp:
        work = (args.work or Path(tmp)).resolve()
        for move, lean in ((False, False), (True, False), (True, True)):
            tag = ("moving mesh" if move else "fixed mesh") + (", lean outputs" if lean else "")
            folder = work / tag.replace(" ", "_").replace(",", "")
            a = run_today(mesh, motion, times, folder, move)
            b = run_persistent(mesh, motion, times, folder, move, lean)
            d = compare(a, b)
            result[tag] = d
            print(f"\n{tag}: max over the steps of |persistent - per-process| / |per-process|")
            print(f"  coil current {max(d['I']):.2e}   capacitor voltage {max(d['Vc']):.2e}   "
                  f"disk force (GetDP integral) {max(d['F']):.2e}   element force density (max-norm) {max(d['f']):.2e}")
            print(f"  coil Joule power {max(d['P']):.2e}   disk Joule power {max(d['KP']):.2e}   "
                  f"magnetic energy {max(d['W']):.2e}")
            print(f"  end values: I = {a[-1]['I']:.6f} A vs {b[-1]['I']:.6f} A; F_z = {a[-1]['F'][1]:.6f} N vs "
                  f"{b[-1]['F'][1]:.6f} N")
            k = int(np.argmax(d["I"]))
            print(f"  worst current step {k + 1}: {d['I'][k]:.2e}; per step: "
                  + " ".join(f"{x:.0e}" for x in d["I"][:: max(1, len(d["I"]) // 10)]))
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    worst = max(max(v) for d in result.values() for kk, v in d.items() if not kk.endswith("_abs"))
    print(f"\ncompare: worst relative difference {worst:.2e} (round-off: < 1e-10)")


if __name__ == "__main__":
    main()
