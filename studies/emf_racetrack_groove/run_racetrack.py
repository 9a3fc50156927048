"""Issue 20, case (b): the racetrack coil forms a rectangular sheet into the groove of a deformable die,
coupled end to end in 3D (quarter model).

    .venv/bin/python studies/emf_racetrack_groove/run_racetrack.py OUT [--scale 1] [--t-end 80e-6]
        [--no-pictures] [--reference]

Runs :func:`pulseform.orchestrator.run.coupled_racetrack.run_racetrack` (geometry, bank and
materials of :mod:`pulseform.orchestrator.run.racetrack_design`), prints the figures and draws the
pictures (:mod:`pulseform.orchestrator.run.pictures_racetrack`) into OUT/plots. ``--reference``
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

from pulseform.orchestrator.run.coupled_racetrack import RacetrackOptions, run_racetrack
from pulseform.orchestrator.run.pictures_racetrack import draw_racetrack

HERE = Path(__file__).resolve().parent
SHOWN = ("max_deflection_into_groove_mm", "die_max_displacement_mm", "impulse_device_z_Ns", "sheet_impulse_device_z_Ns",
         "die_impulse_device_z_Ns", "force_peak_device_z_N", "die_force_peak_device_z_N", "coil_current_peak_kA",
         "t_peak_current_s", "contact_pressure_peak_Pa", "first_contact_s", "max_sheet_speed_m_s",
         "conservation_error_rel", "sheet_ledger_rel", "die_ledger_rel", "sheet_momentum_vs_impulse_rel",
         "die_momentum_vs_impulse_rel", "energy_balance_error_rel", "plastic_work_device_J", "em_steps", "mech_steps",
         "n", "em_tets", "sheet_tets", "die_tets", "wall_s", "setup_s", "em_time_s", "mech_time_s", "em_s_per_step",
         "mech_ms_per_step", "getdp_getdp_process_s", "em_mesh_motion_s", "min_em_quality")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--scale", type=float, default=1.0, help="element sizes times this (2: the coarse test mesh)")
    ap.add_argument("--t-end", type=float, default=RacetrackOptions.t_end)
    ap.add_argument("--outputs", type=int, default=RacetrackOptions.outputs)
    ap.add_argument("--no-pictures", action="store_true")
    ap.add_argument("--reference", action="store_true", help="copy the figures into reference/")
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    logging.getLogger("pulseform.solvers.getdp").setLevel(logging.WARNING)
    base = RacetrackOptions()
    opt = replace(base, geometry=base.geometry.scaled(a.scale), t_end=a.t_end, outputs=a.outputs)
    m = run_racetrack(a.out, opt)
    for k in SHOWN:
        print(f"{k:40s} {m[k]:.6g}" if isinstance(m[k], float) else f"{k:40s} {m[k]}")
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
