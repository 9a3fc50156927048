"""The demo (cases/emf_sheet_bulge) as a coupled 3D sector vs the axisymmetric runs (issue 20, case (a)).

    .venv/bin/python studies/emf_sheet_bulge_3d/run_sector.py OUT [--sector 1.25]

Runs the 3D sector case file ``pulseform run cases/emf_sheet_bulge_3d`` (the general 3D geometry-file path: its gmsh
builder sector_geometry.py, 60 µs; ``--sector`` another angle: the builder's ``angle_deg`` and the second meridian
plane's normal [-sin a, cos a, 0]) and ``pulseform run cases/emf_sheet_bulge`` twice (the shipped mesh, and the
0.25 mm mesh that cases/emf_sheet_bulge/reference/convergence.md finds within 0.7 % of converged), then prints the
comparison. The figures of 2026-11-26 are in ``reference/`` beside this file and in docs/coupling.md.
"""
import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))
FINE_2D = ["--set", "geometry.mesh_size_sheet=0.25e-3", "--set", "geometry.mesh_size_coil=0.5e-3",
           "--set", "geometry.mesh_size_air=0.01"]


def run(case: str, out: Path, extra: list[str]) -> dict:
    subprocess.run([EXE, "run", str(REPO / "cases" / case), "--out", str(out), "--quiet", "--force",
                    "--set", "output.plots=false", *extra], check=True)
    return json.loads((out / "metrics.json").read_text())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--sector", type=float, default=1.25, help="the sector's angle (degrees)")
    args = ap.parse_args()
    a = math.radians(args.sector)
    sector = ["--set", f"geometry.parameters.angle_deg={args.sector!r}",
              "--set", f"symmetry=[{{normal=[0.0, 1.0, 0.0]}}, {{normal=[{-math.sin(a)!r}, {math.cos(a)!r}, 0.0]}}]"]
    m3 = run("emf_sheet_bulge_3d", args.out / "sector", sector)
    for name, extra in (("shipped", []), ("0.25 mm", FINE_2D)):
        m2 = run("emf_sheet_bulge", args.out / name.replace(" ", "").replace(".", "p"), extra)
        d3, d2 = m3["sheet_max_uz_mm"], m2["max_deflection_mm"]
        print(f"3D sector vs axisymmetric ({name}): max deflection {d3:.4f} vs {d2:.4f} mm ({d3 / d2 - 1:+.2%}), "
              f"impulse z {m3['force_impulse_z_Ns']:.5f} vs {m2['force_impulse_z_Ns']:.5f} N s "
              f"({m3['force_impulse_z_Ns'] / m2['force_impulse_z_Ns'] - 1:+.2%}), peak force "
              f"{m3['force_peak_N']:.0f} vs {m2['force_peak_N']:.0f} N, ledger {m3['conservation_error_rel']:.1e}")


if __name__ == "__main__":
    main()
