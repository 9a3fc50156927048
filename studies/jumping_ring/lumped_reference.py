"""The reference of cases/jumping_ring: the lumped R-L ring model of orchestrator/em/lumped.py (the ring
an R-L loop coupled to the coil through the section-averaged Maxwell mutual inductance M(z) and its
gradient, Rosa's self-inductance, the ring's axial motion under i_coil i_ring dM/dz and gravity,
resting on its support until lifted), solved with scipy's Radau to rtol 1e-8, written to
cases/jumping_ring/reference/lumped_model.csv with its provenance.

Usage: .venv/bin/python studies/jumping_ring/lumped_reference.py
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.em.lumped import (RingCircuit, ring_resistance, ring_self_inductance,
                                              section_mutual_inductance)

REPO = Path(__file__).resolve().parents[2]
CASE = REPO / "cases/jumping_ring"


def main() -> None:
    case, _ = load_case(CASE)
    g, src = case.geometry, case.em.sources[0]
    coil, turns = g.coils[0].windings[0], g.coils[0].turns
    ring = g.workpiece.box
    mat = case.materials[case.bodies[0].material]
    rc, wc, hc = 0.5 * (ring[0] + ring[2]), ring[2] - ring[0], ring[3] - ring[1]
    mass = mat.density * 2 * math.pi * rc * wc * hc
    z0 = 0.5 * (ring[1] + ring[3]) - 0.5 * (coil[1] + coil[3])  # ring centre over the coil's centre
    w = 2 * math.pi * src.frequency

    def coupling(z):  # the ring's section moved to height z
        return section_mutual_inductance(coil, (ring[0], ring[1] + z - z0, ring[2], ring[3] + z - z0), n=3)

    model = RingCircuit(0.5 * (coil[0] + coil[2]), rc, ring_resistance(rc, wc, hc, mat.electrical_conductivity),
                        ring_self_inductance(rc, wc, hc), mass=mass, gravity=-case.mechanics.gravity[1],
                        coupling=coupling)
    t = np.arange(0.0, case.time.end + 1e-12, 1.0 / (src.frequency * 40))
    sol = model.solve(lambda s: (turns * src.amplitude * math.sin(w * s), turns * src.amplitude * w * math.cos(w * s)),
                      case.time.end, z0, t_eval=t, rtol=1e-8)
    z = sol.y[0] - z0
    k = int(np.argmax(z))
    head = [
        "# source: lumped R-L ring model (orchestrator/em/lumped.py RingCircuit), written by "
        "studies/jumping_ring/lumped_reference.py",
        "# figure: none; independent reference of the jumping-ring case (issue 17): the ring's height over its support",
        "# units: time_s in s, position_m in m (the ring's rise from its support), velocity_m_s in m/s, "
        "ring_current_A in A",
        f"# obtained: coil {turns} turns x {src.amplitude:g} A at {src.frequency:g} Hz, ring R = "
        f"{model.resistance:.6g} Ohm, L = {model.inductance:.6g} H, mass {mass:.6g} kg, M(z) and dM/dz averaged "
        f"over 3x3 Gauss points of both sections; scipy Radau rtol 1e-8; max height {z[k] * 1e3:.4f} mm at "
        f"{t[k] * 1e3:.2f} ms, height at the end {z[-1] * 1e3:.4f} mm",
    ]
    rows = np.column_stack([t, z, sol.y[1], sol.y[2]])
    path = CASE / "reference" / "lumped_model.csv"
    path.write_text("\n".join(head) + "\ntime_s,position_m,velocity_m_s,ring_current_A\n"
                    + "\n".join(",".join(f"{v:.9g}" for v in r) for r in rows) + "\n")
    print(f"wrote {path}: max height {z[k] * 1e3:.4f} mm at {t[k] * 1e3:.2f} ms, end {z[-1] * 1e3:.4f} mm")


if __name__ == "__main__":
    main()
