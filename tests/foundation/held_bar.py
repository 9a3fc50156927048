"""The held bar of the quadratic elements' case-file tests (test_case_tet10.py, test_case_tri6.py): the paper's
section 4 bar at 5 m/s, its end x = 0 held, so that a compression wave of sigma = rho c v = 70 MPa (c = sqrt(E /
rho) = 5000 m/s) runs along it; the probe ``mid``'s von Mises stress averaged between the wave's passage (0.6 ms)
and 1.1 ms within 10 % of 70 MPa."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from warm_cli import pulseform_cli


def run_held_bar(case_toml: str, tmp_path: Path) -> Path:
    """Run the case ``case_toml`` (its text) through the CLI, check the wave's plateau and the status; returns the
    results folder."""
    (tmp_path / "case").mkdir()
    (tmp_path / "case" / "case.toml").write_text(case_toml)
    out = tmp_path / "out"
    r = pulseform_cli(["run", str(tmp_path / "case"), "--out", str(out), "--quiet"])
    assert r.returncode == 0, r.stderr[-2000:]
    rows = list(csv.DictReader((out / "history.csv").open()))
    t = np.array([float(x["time_s"]) for x in rows])
    vm = np.array([float(x["mid_von_mises_Pa"]) for x in rows])
    window = (t > 0.6e-3) & (t < 1.1e-3)
    assert window.sum() > 50
    assert vm[window].mean() == pytest.approx(2800.0 * 5000.0 * 5.0, rel=0.10)
    m = json.loads((out / "metrics.json").read_text())
    assert m["status_ok"] == 1.0
    return out
