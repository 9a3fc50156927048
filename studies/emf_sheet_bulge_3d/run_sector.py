"""The demo (cases/emf_sheet_bulge) as a coupled 3D sector vs the axisymmetric runs (issue 20, case (a)).

    .venv/bin/python studies/emf_sheet_bulge_3d/run_sector.py OUT [--sector 1.25]

Runs the coupled 3D sector (:func:`pulseform.orchestrator.run.coupled3d.run_sector`, 60 µs) and
``pulseform run cases/emf_sheet_bulge`` twice (the shipped mesh, and the 0.25 mm mesh that
cases/emf_sheet_bulge/reference/convergence.md finds within 0.7 % of converged), then prints the
comparison. The figures of 2026-11-26 are in ``reference/`` beside this file and in docs/coupling.md.
"""
import argparse
import json
import subprocess
import sys
from pathlib import Path

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.run.coupled3d import DEMO_SECTOR as REFERENCE
from pulseform.orchestrator.run.coupled3d import SectorOptions, run_sector

REPO = Path(__file__).resolve().parents[2]
FINE_2D = ["--set", "geometry.mesh_size_sheet=0.25e-3", "--set", "geometry.mesh_size_coil=0.5e-3",
           "--set", "geometry.mesh_size_air=0.01"]


def axisymmetric(out: Path, extra: list[str]) -> dict:
    exe = str(Path(sys.executable).with_name("pulseform"))
    subprocess.run([exe, "run", str(REPO / "cases/emf_sheet_bulge"), "--out", str(out), "--quiet", "--force",
                    "--set", "output.plots=false", *extra], check=True)
    return json.loads((out / "metrics.json").read_text())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--sector", type=float, default=REFERENCE.sector_deg)
    args = ap.parse_args()
    case, _ = load_case(REPO / "cases/emf_sheet_bulge/case.toml")
    opt = SectorOptions(**{**REFERENCE.__dict__, "sector_deg": args.sector})
    m3 = run_sector(case, args.out / "sector", opt)
    for name, extra in (("shipped", []), ("0.25 mm", FINE_2D)):
        m2 = axisymmetric(args.out / name.replace(" ", "").replace(".", "p"), extra)
        print(f"3D sector vs axisymmetric ({name}): max deflection {m3['max_deflection_mm']:.4f} vs "
              f"{m2['max_deflection_mm']:.4f} mm ({m3['max_deflection_mm'] / m2['max_deflection_mm'] - 1:+.2%}), "
              f"impulse z {m3['impulse_device_Ns']:.5f} vs {m2['force_impulse_z_Ns']:.5f} N s "
              f"({m3['impulse_device_Ns'] / m2['force_impulse_z_Ns'] - 1:+.2%}), peak force "
              f"{m3['force_peak_device_N']:.0f} vs {m2['force_peak_N']:.0f} N, ledger {m3['conservation_error_rel']:.1e}")


if __name__ == "__main__":
    main()
