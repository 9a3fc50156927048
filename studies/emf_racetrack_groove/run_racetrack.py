"""Issue 20, case (b): the racetrack coil forms a rectangular sheet into the groove of a deformable die,
coupled end to end in 3D (quarter model).

    .venv/bin/python studies/emf_racetrack_groove/run_racetrack.py OUT [--scale 1] [--t-end 80e-6]
        [--no-pictures] [--reference]

Runs :func:`racetrack_run.run_racetrack` (this folder: the study's own runner; geometry, bank and
materials of :mod:`design`), prints the figures and draws the pictures (:mod:`racetrack_pictures`) into
OUT/plots. The case file ``cases/emf_racetrack_groove`` runs the same model through ``pulseform run`` (the 3D
geometry path) and reproduces these figures to round-off. ``--reference``
copies metrics, history and the pictures into ``reference/`` beside this file (the figures of
docs/coupling.md, "Case (b)").
"""
import argparse
import json
import logging
import shutil
import sys
from dataclasses import replace
from pathlib import Path

from racetrack_pictures import draw_racetrack
from racetrack_run import RacetrackOptions, run_racetrack

HERE = Path(__file__).resolve().parent
SHOWN = ("max_deflection_into_groove_mm", "die_max_displacement_mm", "impulse_device_z_Ns", "sheet_impulse_device_z_Ns",
         "die_impulse_device_z_Ns", "force_peak_device_z_N", "die_force_peak_device_z_N", "coil_current_peak_kA",
         "t_peak_current_s", "contact_pressure_peak_Pa", "first_contact_s", "max_sheet_speed_m_s",
         "conservation_error_rel", "sheet_ledger_rel", "die_ledger_rel", "sheet_momentum_vs_impulse_rel",
         "die_momentum_vs_impulse_rel", "energy_balance_error_rel", "plastic_work_device_J", "em_steps", "mech_steps",
         "n", "em_tets", "sheet_tets", "die_tets", "wall_s", "setup_s", "em_time_s", "mech_time_s", "em_s_per_step",
         "mech_ms_per_step", "getdp_getdp_process_s", "em_mesh_motion_s", "min_em_quality", "em_mesh_frozen_at_s",
         "impulse_after_freeze_device_z_Ns", "em_remeshes")


def fixed_mesh_check(out: Path, opt: RacetrackOptions, k: int) -> dict:
    """GetDP's sheet and die forces of the first ``k`` coupled EM steps against one fixed-mesh BDF2 run of
    the same model, mesh (re-meshed: the same nodes as the run's racetrack.msh, checked) and steps."""
    import numpy as np

    from design import em_model
    from pulseform.solvers.getdp.mesh3d import read_msh22_tets
    from pulseform.solvers.getdp.racetrack_mesh import racetrack_groove_mesh
    from pulseform.solvers.getdp.solver3d import solve_transient3d

    h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)[:k]
    steps = h["dt_s"] * h["substeps"]
    if np.ptp(steps) > 1e-9 * steps.max():
        raise ValueError("the first EM steps are not equal: no fixed-mesh BDF2 comparison")
    mesh = racetrack_groove_mesh(out / "fixed_check" / "mesh.msh", opt.geometry)
    if not np.array_equal(read_msh22_tets(out / "racetrack.msh")[0], mesh.points):
        raise ValueError("re-meshing did not give the run's mesh")
    r = solve_transient3d(em_model(opt.geometry, opt.bank), mesh, float(h["time_s"][-1]), k, out / "fixed_check",
                          time_scheme="bdf2", element_output="none")
    res = {"fixed_check_steps": k}
    for j, name in enumerate(("sheet", "die")):
        ref = r.conductor_force[:, j, 2]
        res[f"fixed_check_{name}_force_rel"] = float(np.abs(h[f"{name}_getdp_force_z_N"] - ref).max() / np.abs(ref).max())
    return res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--scale", type=float, default=1.0, help="element sizes times this (2: the coarse test mesh)")
    ap.add_argument("--t-end", type=float, default=RacetrackOptions.t_end)
    ap.add_argument("--outputs", type=int, default=RacetrackOptions.outputs)
    ap.add_argument("--no-pictures", action="store_true")
    ap.add_argument("--fixed-check", type=int, default=5, help="EM steps compared with the fixed-mesh solve (0: none)")
    ap.add_argument("--reference", action="store_true", help="copy the figures into reference/")
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    logging.getLogger("pulseform.solvers.getdp").setLevel(logging.WARNING)
    base = RacetrackOptions()
    opt = replace(base, geometry=base.geometry.scaled(a.scale), t_end=a.t_end, outputs=a.outputs)
    m = run_racetrack(a.out, opt)
    if a.fixed_check:
        m.update(fixed_mesh_check(a.out, opt, a.fixed_check))
        (a.out / "metrics.json").write_text(json.dumps(m, indent=2, default=float))
    for k in SHOWN + tuple(k for k in m if k.startswith("fixed_check")):
        v = m.get(k, "-")
        print(f"{k:40s} {v:.6g}" if isinstance(v, float) else f"{k:40s} {v}")
    for r in m.get("em_remesh_log", []):
        print("remesh at {time_s:.4g} s: {tets} tets, worst quality {min_quality:.3g}, {wall_s:.1f} s".format(**r))
    paths = [] if a.no_pictures else draw_racetrack(a.out, opt.geometry)
    for p in paths:
        print("picture", p)
    if a.reference:
        ref = HERE / "reference"
        ref.mkdir(exist_ok=True)
        shutil.copy(a.out / "metrics.json", ref / "racetrack_metrics.json")
        shutil.copy(a.out / "history.csv", ref / "racetrack_history.csv")
        for p in paths:
            if p.parent.name == "plots":
                shutil.copy(p, ref / p.name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
