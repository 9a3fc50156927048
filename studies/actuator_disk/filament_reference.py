"""The reference of cases/emf_actuator_disk: the filament model (orchestrator/em/filaments.py) of its
coil, bank and disk, written to cases/emf_actuator_disk/reference/filament_model.csv with its
provenance, and the model's own convergence in the filament size printed.

The disk (R 40 mm, 2 mm thick, Al 3.5e7 S/m) is cut into square filaments of side ``--size``
(default 0.5 mm: 80 x 4; the skin depth at the ~12 kHz ringing is 0.77 mm); the coil's five turns are
in series with the bank (100 µF, 2 kV, 10 mΩ, 1 µH), copper 5.8e7 S/m; the disk rests on its support
until the force exceeds its weight, then flies (gravity 9.81 m/s²).

Usage: .venv/bin/python studies/actuator_disk/filament_reference.py [--size 0.5e-3] [--check]
(``--check``: also the model at twice the filament size, for its convergence; nothing written)
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.em.filaments import FilamentActuator, filament_grid
from pulseform.orchestrator.mesh.em_geometry import flat_coil_turns

REPO = Path(__file__).resolve().parents[2]
CASE = REPO / "cases/emf_actuator_disk"


def model(size: float) -> FilamentActuator:
    case, _ = load_case(CASE)
    g, c = case.geometry, case.em.circuit
    body = case.bodies[0]
    mat = case.materials[body.material]
    disk = (0.0, g.coil_gap, g.sheet_radius, g.coil_gap + g.sheet_thickness)
    n_r, n_z = round(g.sheet_radius / size), round(g.sheet_thickness / size)
    mass = mat.density * math.pi * g.sheet_radius ** 2 * g.sheet_thickness
    return FilamentActuator([(t.x0, t.y0, t.x1, t.y1) for t in flat_coil_turns(g)], filament_grid(disk, n_r, n_z),
                            mat.electrical_conductivity, c.capacitance, c.voltage, c.resistance, c.inductance, mass,
                            coil_sigma=case.em.coil_conductivity, gravity=-case.mechanics.gravity[1])


def summary(out: dict[str, np.ndarray]) -> str:
    i = np.abs(out["coil_current_A"])
    k = int(np.argmax(i))
    t = out["time_s"]
    return (f"peak |I| {i[k] / 1e3:.4f} kA at {t[k] * 1e6:.2f} µs, peak F {out['force_N'].max() / 1e3:.4f} kN, "
            f"v(end) {out['velocity_m_s'][-1]:.4f} m/s, z(end) {out['position_m'][-1] * 1e3:.4f} mm")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.5e-3, help="filament side (m)")
    ap.add_argument("--check", action="store_true", help="convergence only: also twice the size, write nothing")
    a = ap.parse_args()
    case, _ = load_case(CASE)
    t = np.linspace(0.0, case.time.end, int(round(case.time.end / 1e-6)) + 1)
    for size in ((2 * a.size, a.size) if a.check else (a.size,)):
        t0 = time.perf_counter()
        fa = model(size)
        out = fa.solve(case.time.end, t)
        print(f"filaments {len(fa.filaments)} of {size * 1e3:g} mm ({time.perf_counter() - t0:.1f} s): {summary(out)}")
    if a.check:
        return
    path = CASE / "reference" / "filament_model.csv"
    path.parent.mkdir(exist_ok=True)
    head = [
        "# source: filament (lumped-circuit) model of the case's coil, bank and disk: orchestrator/em/filaments.py, "
        "written by studies/actuator_disk/filament_reference.py",
        "# figure: none; independent reference of the actuator case (issue 17): coil current, force on the disk, "
        "its height and velocity",
        "# units: time_s in s, coil_current_A in A (its sign: the bank's discharge direction), force_N in N (+z: "
        "away from the coil), position_m in m, velocity_m_s in m/s",
        f"# obtained: {len(fa.filaments)} square filaments of {a.size * 1e3:g} mm in the disk (Rosa self-inductances, "
        "Maxwell mutual inductances between centres; coil-filament coupling averaged over 2x2 Gauss points, cubic "
        "splines in z), 5 coil turns in series with the bank, scipy Radau rtol 1e-7; " + summary(out),
    ]
    rows = np.column_stack([out["time_s"], out["coil_current_A"], out["force_N"], out["position_m"],
                            out["velocity_m_s"]])
    body = "\n".join(",".join(f"{v:.9g}" for v in r) for r in rows)
    path.write_text("\n".join(head) + "\ntime_s,coil_current_A,force_N,position_m,velocity_m_s\n" + body + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
