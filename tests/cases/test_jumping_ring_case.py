"""cases/jumping_ring from its case file (coaxial_coils, a 50 Hz sine source, a rigid ring with gravity
on a support; the EM step from the source: 40 per period) against its reference, the lumped R-L ring
model (cases/jumping_ring/reference/lumped_model.csv, written by studies/jumping_ring/lumped_reference.py).

Issue 17: the released ring's height follows the lumped model's ODE within 3 % of the maximum height.
Measured: to 80 ms (the jump, its apex at 67.5 ms) here in the default tier; the shipped 0.3 s run
(14.9 s wall, 600 EM steps) differs by at most 1.38 % of the max height (docs/cases.md). Its
SIGINT-and-resume test: tests/coupling/test_rigid_resume.py.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pulseform.orchestrator.cli import main

REPO = Path(__file__).resolve().parents[2]
CASE = REPO / "cases/jumping_ring"


@pytest.mark.getdp
def test_jumping_ring_case_follows_the_lumped_model(tmp_path, capsys):
    out = tmp_path / "run"
    rc = main(["run", str(CASE), "--out", str(out), "--quiet", "--set", "time.end=0.08",
               "--set", "output.field_interval=0.04", "--set", "output.plots=false"])
    assert rc == 0, capsys.readouterr().err
    ref = np.genfromtxt(CASE / "reference/lumped_model.csv", delimiter=",", names=True, skip_header=4)
    h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    keep = ref["time_s"] <= h["time_s"][-1] * (1 + 1e-12)
    t, z_ref = ref["time_s"][keep], ref["position_m"][keep]
    z = np.interp(t, h["time_s"], h["ring_travel_y_m"])
    err = float(np.abs(z - z_ref).max() / z_ref.max())
    m = json.loads((out / "metrics.json").read_text())
    print(f"\nmax height {z.max() * 1e3:.3f} mm (lumped {z_ref.max() * 1e3:.3f}); largest difference {err:.2%} of it; "
          f"{m['em_steps']:.0f} EM steps")
    assert z_ref.max() > 0.01 and np.all(h["ring_travel_y_m"] >= 0.0)  # it jumps, never below its support
    assert m["em_steps"] == pytest.approx(0.08 * 50 * 40, abs=1)  # 40 EM steps per period of the source
    assert err < 0.03

