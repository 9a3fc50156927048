"""The independent model of cases/team28_levitation: the filament (mutual-inductance) model of TEAM
Workshop Problem 28 (orchestrator/em/filaments.py DrivenFilaments), built from the problem's
specification (cases/team28_levitation/reference/team28_spec.toml, not from the case file), written to
cases/team28_levitation/reference/filament_model.csv with its provenance; ``--check`` prints the
model's own convergence in the filament size instead.

The plate (r <= 65 mm, 3 mm, σ = 3.4e7 S/m, 0.107 kg) is cut into square filaments of side ``--size``
(default 1.5 mm: 43 x 2; the skin depth at 50 Hz is 12.2 mm); the two stranded coils (960 and 576
turns, ±20 A at 50 Hz) are cut into cells of at most 4 mm for averaging their coupling with each
filament over Gauss points; the plate rests 3.8 mm above the coils until the force exceeds its weight
(g = 9.81 m/s²), then flies (a return to its rest stops it there, as the case's stop).

Usage: .venv/bin/python studies/team28_levitation/filament_reference.py [--size 1.5e-3] [--check]
"""
from __future__ import annotations

import argparse
import math
import time
import tomllib
from pathlib import Path

import numpy as np

from pulseform.orchestrator.em.filaments import DrivenFilaments, filament_grid

REPO = Path(__file__).resolve().parents[2]
REF = REPO / "cases/team28_levitation/reference"
GRAVITY = 9.81  # m/s², the case file's mechanics.gravity


def model(size: float, end: float) -> tuple[DrivenFilaments, dict]:
    spec = tomllib.loads((REF / "team28_spec.toml").read_text())
    p = spec["plate"]
    plate = (0.0, p["start_height"], p["radius"], p["start_height"] + p["thickness"])
    n_r, n_z = max(1, round(p["radius"] / size)), max(1, round(p["thickness"] / size))
    w = 2.0 * math.pi * spec["frequency"]
    signs = np.array([c["sign"] for c in spec["coils"]], float)

    def currents(t: float) -> np.ndarray:
        return signs * spec["current_amplitude"] * math.sin(w * t)

    fm = DrivenFilaments([([tuple(c["winding"])], c["turns"]) for c in spec["coils"]], currents,
                         filament_grid(plate, n_r, n_z), p["conductivity"], p["mass"], gravity=GRAVITY,
                         z_max=0.025)
    return fm, spec


def summary(out: dict[str, np.ndarray], start: float) -> str:
    z = (out["position_m"] + start) * 1e3
    t = out["time_s"]
    k = int(np.argmax(z))
    late = t >= 1.2
    return (f"first peak {z[k]:.3f} mm at {t[k] * 1e3:.1f} ms, mean height over 1.2-{t[-1]:g} s "
            f"{z[late].mean():.3f} mm, height at the end {z[-1]:.3f} mm")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=1.5e-3, help="filament side (m)")
    ap.add_argument("--end", type=float, default=1.7, help="end time (s)")
    ap.add_argument("--check", action="store_true", help="convergence only: also twice the size, write nothing")
    a = ap.parse_args()
    t = np.linspace(0.0, a.end, int(round(a.end / 1e-3)) + 1)  # every millisecond
    results = {}
    for size in ((2 * a.size, a.size) if a.check else (a.size,)):
        t0 = time.perf_counter()
        fm, spec = model(size, a.end)
        out = fm.solve(a.end, t)
        results[size] = out
        start = spec["plate"]["start_height"]
        print(f"filaments {len(fm.filaments)} of {size * 1e3:g} mm ({time.perf_counter() - t0:.1f} s): "
              f"{summary(out, start)}")
    if a.check:
        z1, z2 = (results[s]["position_m"] for s in (2 * a.size, a.size))
        print(f"largest height difference between the two: {np.abs(z1 - z2).max() * 1e3:.4f} mm")
        return
    z = (out["position_m"] + start) * 1e3
    head = [
        "# source: filament (mutual-inductance) model of TEAM Workshop Problem 28: orchestrator/em/filaments.py "
        "DrivenFilaments, built from reference/team28_spec.toml by studies/team28_levitation/filament_reference.py",
        "# figure: none; the independent model of the same specification as the case (issue 32 item 11): the "
        "plate's height z(t) over 1.7 s",
        "# units: time_ms in ms, height_mm in mm (the plate's lower face above the coils' top), velocity_m_s in m/s, "
        "force_N in N (+z, magnetic only)",
        f"# obtained: {len(fm.filaments)} square filaments of {a.size * 1e3:g} mm in the plate (Rosa "
        "self-inductances, Maxwell mutual inductances between centres), coil-filament coupling averaged over "
        "2x2 Gauss points of 4 mm coil cells and of each filament (cubic splines in z), scipy Radau rtol 1e-7, "
        f"g = {GRAVITY} m/s^2; " + summary(out, start),
    ]
    rows = np.column_stack([out["time_s"] * 1e3, z, out["velocity_m_s"], out["force_N"]])
    body = "\n".join(",".join(f"{v:.7g}" for v in r) for r in rows)
    path = REF / "filament_model.csv"
    path.write_text("\n".join(head) + "\ntime_ms,height_mm,velocity_m_s,force_N\n" + body + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
