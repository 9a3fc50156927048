"""Mesh convergence of the racetrack case's EM loads (issue 20, case b): the sheet's peak force and its
impulse under the bank discharge on systematically refined meshes of the same geometry (fixed mesh, no
motion), with the grid convergence index of ``orchestrator/workflows/gci.py``.

Usage: python em_convergence.py OUT [--factors 1.25 1 0.8] [--t-end 6e-5] [--steps 40] [--order 2]
Prints one line per level and the GCI of each quantity; writes OUT/em_convergence.json.
The geometry and bank are :data:`design.RACETRACK` / ``RACETRACK_BANK`` (this folder) (``--old``: the first design, C = 50 uF, 6 kV, long straight sides). ``--order 2``: the
deck's hierarchical second-order edge elements (``EM3DModel.order``).
"""
import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from design import OLD_DESIGN, RACETRACK, em_model
from pulseform.orchestrator.workflows.gci import grid_convergence
from pulseform.solvers.getdp.racetrack_mesh import racetrack_groove_mesh
from pulseform.solvers.getdp.solver3d import solve_transient3d


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--factors", type=float, nargs="+", default=[1.25, 1.0, 0.8])
    ap.add_argument("--t-end", type=float, default=60e-6)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--scheme", default="bdf2")
    ap.add_argument("--old", action="store_true")
    ap.add_argument("--layers", type=int, default=None, help="sheet layers on every level (default: scaled)")
    ap.add_argument("--geometry", default="{}", help="JSON of RacetrackGroove fields replaced before scaling")
    ap.add_argument("--order", type=int, default=1, choices=(1, 2), help="edge element order of the EM deck")
    ap.add_argument("--numbers", default="{}", help="JSON of more -setnumber inputs of the deck (e.g. Air_Order)")
    a = ap.parse_args(argv)
    design, bank = OLD_DESIGN if a.old else (RACETRACK, None)
    a.out.mkdir(parents=True, exist_ok=True)
    levels = []
    for f in a.factors:
        g = replace(design, **json.loads(a.geometry)).scaled(f)
        if a.layers:
            g = replace(g, sheet_layers=a.layers)
        t0 = time.perf_counter()
        m = racetrack_groove_mesh(a.out / f"level{f:.4f}.msh", g)
        model = replace(em_model(g, bank), order=a.order)
        r = solve_transient3d(model, m, a.t_end, a.steps, a.out / f"run{f:.4f}", element_output="none",
                              time_scheme=a.scheme, extra_numbers=json.loads(a.numbers))
        s = model.symmetry_factor
        fz = r.conductor_force[:, 0, 2] * s
        t = r.times
        dt = np.diff(np.concatenate([[0.0], t]))
        lev = {"factor": f, "order": a.order, "numbers": json.loads(a.numbers), "h_sheet_m": g.h_sheet, "layers": g.sheet_layers, "tets": m.n_tets, "sheet_tets": int((m.tet_tags == 201).sum()), "dofs": r.n_dofs,
               "peak_force_N": float(fz.max()), "t_peak_us": 1e6 * float(t[np.argmax(fz)]),
               "impulse_Ns": float(np.sum(fz * dt)), "die_peak_N": float(np.abs(r.conductor_force[:, 1, 2] * s).max()),
               "peak_current_kA": float(np.abs(r.coil_current[:, 0]).max()) / 1e3,
               "t_peak_current_us": 1e6 * float(t[np.argmax(np.abs(r.coil_current[:, 0]))]),
               "cpu_per_step_s": r.cpu_per_step, "wall_per_step_s": r.wall_per_step,
               "wall_total_s": time.perf_counter() - t0}
        levels.append(lev)
        print(json.dumps(lev), flush=True)
    out = {"levels": levels, "t_end_s": a.t_end, "steps": a.steps, "scheme": a.scheme}
    if len(levels) >= 3:
        for q in ("peak_force_N", "impulse_Ns", "die_peak_N"):
            for j in range(len(levels) - 2):
                three = levels[j:j + 3][::-1]   # fine to coarse
                h = [lv["factor"] for lv in three]
                res = grid_convergence(h, [lv[q] for lv in three]).to_dict()
                out[f"gci_{q}_{j}"] = res
                print(q, h, json.dumps(res), flush=True)
    (a.out / "em_convergence.json").write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
