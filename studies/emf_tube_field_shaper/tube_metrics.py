"""Radial figures of the field-shaper tube compression (cases/emf_tube_field_shaper) that the run's
metrics.json does not hold, from a results folder -- or, for a ``pulseform converge`` folder, from each
level with their grid convergence index:

* ``u_r_min_mm``: the largest inward radial displacement of the tube at the end (any node);
* ``u_r_slit_mm`` / ``u_r_solid_mm``: the mean radial displacement of the outer surface's nodes on the
  mid-plane z = 0 within 15 degrees of the slit (phi = 0) / of the side opposite it (phi = 180 deg);
* ``impulse_y_quarter_Ns``: the time integral of the modelled quarter tube's y-force (history
  ``force_y_N``, trapezoid over the EM steps' rows), and ``radial_impulse_device_Ns`` = 2 pi times its
  magnitude: the whole tube's radial impulse (the integral of |f . e_r| dV dt) if the pressure were
  axisymmetric (a quarter y >= 0, z >= 0 under a pressure p(z) has F_y = -2 R int_0 p dz, the whole tube
  2 pi R int p dz over both halves in z); the slit's weaker pressure makes it an estimate (at the design
  run's peak current it was 1.9 % above 4 x the quarter's sum of f . e_r dV, docs/cases.md).

Usage: python studies/emf_tube_field_shaper/tube_metrics.py RESULTS_OR_CONVERGE_FOLDER [--json OUT]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import numpy as np


def tube_metrics(folder: Path) -> dict[str, float]:
    """The module docstring's figures of one results folder (SI displacements converted to mm)."""
    import meshio

    folder = Path(folder)
    xdmf = next(folder.glob("fields/*_tube.xdmf"))
    with meshio.xdmf.TimeSeriesReader(str(xdmf)) as reader:
        x, _ = reader.read_points_cells()
        _, point_data, _ = reader.read_data(reader.num_steps - 1)
    u = point_data["displacement_m"]
    r = np.hypot(x[:, 0], x[:, 1])
    phi = np.degrees(np.arctan2(x[:, 1], x[:, 0]))
    u_r = (u[:, 0] * x[:, 0] + u[:, 1] * x[:, 1]) / r
    tol = 1e-6 * float(np.abs(x).max())
    mid = (np.abs(x[:, 2]) < tol) & (r > r.max() - tol)
    slit, solid = mid & (phi < 15.0), mid & (phi > 165.0)
    rows = list(csv.DictReader(open(folder / "history.csv")))
    t = np.array([float(row["time_s"]) for row in rows])
    fy = np.array([float(row["force_y_N"]) for row in rows])
    impulse = float(np.sum(0.5 * (fy[1:] + fy[:-1]) * np.diff(t)))
    return {"u_r_min_mm": 1e3 * float(u_r.min()), "u_r_slit_mm": 1e3 * float(u_r[slit].mean()),
            "u_r_solid_mm": 1e3 * float(u_r[solid].mean()), "impulse_y_quarter_Ns": impulse,
            "radial_impulse_device_Ns": 2.0 * math.pi * abs(impulse)}


def converge_table(study: Path) -> dict:
    """Per level the figures, and per figure the GCI of the three finest levels (converge.json's h)."""
    from pulseform.orchestrator.workflows.gci import grid_convergence

    report = json.loads((Path(study) / "converge.json").read_text())
    levels = sorted((lv for lv in report["levels"] if lv["returncode"] == 0), key=lambda lv: lv["level"])
    values = {lv["level"]: tube_metrics(Path(study) / f"level_{lv['level']}") for lv in levels}
    fine = levels[-3:][::-1]
    out = {"levels": values, "gci": {}}
    for name in next(iter(values.values())):
        h = [lv["h_rel"] for lv in fine]
        phi = [values[lv["level"]][name] for lv in fine]
        out["gci"][name] = {"values": phi, "h_rel": h, **grid_convergence(h, phi).to_dict()}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args(argv)
    if (a.folder / "converge.json").is_file():
        result = converge_table(a.folder)
        for name, g in result["gci"].items():
            print(f"{name}: fine/medium/coarse {', '.join(f'{v:.5g}' for v in g['values'])}; order {g['order']:.3g}, "
                  f"extrapolated {g['extrapolated']:.5g}, GCI fine {100 * g['gci_fine']:.3g} % ({g['convergence']})")
    else:
        result = tube_metrics(a.folder)
        for k, v in result.items():
            print(f"{k} = {v:.6g}")
    if a.json is not None:
        a.json.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
