"""A coupled run with a magnetised body (issue 35): the demo's sheet given a B–H curve, a short run.

What only the whole loop shows: the curve reaches GetDP (Newton's counts in the history), the magnetisation
force joins the Lorentz force through the conservation ledger (its error stays at round-off), and it pulls the
sheet towards the coil (a magnetised body is attracted to the stronger field): the force on the sheet,
``force_y_N``, is below GetDP's Lorentz force ``getdp_force_z_N`` at every step.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from warm_cli import pulseform_cli

pytestmark = pytest.mark.getdp

REPO = Path(__file__).resolve().parents[2]
CURVE = ("materials.al_blank.bh_curve={field_strength=[0,100,200,400,1000,3000,10000,1e5], "
         "flux_density=[0,0.8,1.1,1.3,1.45,1.6,1.75,2.1]}")


def test_magnetised_sheet_runs_coupled(tmp_path):
    out = tmp_path / "out"
    r = pulseform_cli(["run", str(REPO / "cases/emf_sheet_bulge"), "--out", str(out), "--quiet", "--set",
                       "time.end=2e-6", "--set", "output.field_interval=2e-6", "--set", "output.plots=false",
                       "--set", CURVE])
    assert r.returncode == 0, r.stderr[-3000:]
    assert json.loads((out / "metrics.json").read_text())["conservation_error_rel"] <= 1e-10
    rows = list(csv.DictReader((out / "history.csv").open()))[1:]
    assert len(rows) >= 4
    for row in rows:
        assert 1 <= float(row["em_newton_iterations"]) <= 30
        lorentz, total = float(row["getdp_force_z_N"]), float(row["force_y_N"])
        assert 0 < total < lorentz


@pytest.mark.slow
def test_magnetised_sheet_runs_coupled_3d(tmp_path):
    """The same in 3D (the coarse 5° sector of cases/emf_sheet_bulge_3d, 3 us): Newton's counts, the ledger at
    round-off, the sheet's force (``force_z_N``) below GetDP's Lorentz force at every step."""
    from .sector_case import CASE, COARSE, sets

    out = tmp_path / "out"
    r = pulseform_cli(["run", str(CASE), "--out", str(out), "--quiet",
                       *sets(COARSE + ["output.plots=false", CURVE])])
    assert r.returncode == 0, r.stderr[-3000:]
    assert json.loads((out / "metrics.json").read_text())["conservation_error_rel"] <= 1e-10
    rows = list(csv.DictReader((out / "history.csv").open()))[1:]
    assert len(rows) >= 5
    for row in rows:
        assert 1 <= float(row["em_newton_iterations"]) <= 30
        assert 0 < float(row["force_z_N"]) < float(row["getdp_force_z_N"])
