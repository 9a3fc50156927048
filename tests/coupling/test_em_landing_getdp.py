"""Output times leave no mark on the demo's EM steps (issue 14): real GetDP + DOLFINx, 20 µs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from warm_cli import pulseform_cli

pytestmark = pytest.mark.getdp

REPO = Path(__file__).resolve().parents[2]
END, INTERVAL = 20e-6, 5e-6


def spike(x: np.ndarray) -> float:
    """max over EM steps k >= 3 of |x_k − (x_{k−1} + x_{k+1})/2|, relative to max |x|."""
    return float(np.abs(x[2:-1] - 0.5 * (x[1:-2] + x[3:])).max() / np.abs(x).max())


@pytest.fixture(scope="module")
def demo_history(tmp_path_factory):
    out = tmp_path_factory.mktemp("landing") / "demo"
    r = pulseform_cli(["run", str(REPO / "cases/emf_sheet_bulge"), "--out", str(out), "--quiet",
                       "--set", f"time.end={END}", "--set", f"output.field_interval={INTERVAL}",
                       "--set", "output.history_every=1"])
    assert r.returncode == 0, r.stderr[-3000:]
    h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    return h, json.loads((out / "metrics.json").read_text())


def test_no_spikes_at_output_times(demo_history):
    """The demo's first 20 µs with outputs every 5 µs, one history row per EM step. Before issue 14
    the last EM step before each output shrank (step ratios 0.13 to 7.6) and variable-step BDF2
    rang: the coil voltage's spike measure was 52.8 % of its peak (at 15 µs; 33 % at 20 µs in the
    full 60 µs demo with its 10 µs outputs), the force's 0.95 % (force_x 1.0 %, current 1.7 %).
    With equal EM steps to every output (ratio 1): 0.19 %, 0.17 % (0.14 %, 0.08 %)."""
    h, m = demo_history
    rows = h[1:]  # row 0: t = 0
    assert len(rows) == m["em_steps"]  # every EM step is a row
    for key in ("coil_voltage_V", "force_y_N", "force_x_N", "coil_current_A"):
        assert spike(rows[key]) <= 0.02, (key, spike(rows[key]))
    steps = rows["dt_s"] * rows["substeps"]
    ratio = steps[1:] / steps[:-1]
    assert 0.5 <= ratio.min() and ratio.max() <= 2.0, (ratio.min(), ratio.max())


def test_output_times_are_reached_exactly(demo_history):
    """Each output time is the end of an EM step (fields and checkpoints at exact times)."""
    h, _ = demo_history
    t = h["time_s"]
    for stop in INTERVAL * np.arange(1, 5):
        assert np.min(np.abs(t - stop)) <= 1e-12 * stop, stop


#: the full demo's metrics at 302d029 (before issue 14: the EM step shrank to land on outputs),
#: `pulseform run cases/emf_sheet_bulge` there, recorded in the issue-14 audit of 2026-11-25
#: (force_impulse_Ns was then |(summed radial load, axial)|; since issue 32 it is the axial impulse, 1.5e-4 lower
#: on this case: the 0.2 % bound holds either way)
BEFORE_LANDING = {"max_deflection_mm": 2.391033, "force_impulse_Ns": 0.7840221, "coil_current_peak_kA": 26.2910,
                  "sheet_max_speed_m_s": 88.4068, "plastic_work_J": 2.380376, "kinetic_energy_final_J": 20.7799,
                  "von_mises_final_max_MPa": 264.70}


def test_demo_metrics_move_less_than_0p2_percent(tmp_path):
    """Issue 14, done when: the demo's metrics move by less than 0.2 % from before the change (the
    spikes were an error of the old landing; measured: +0.012 % deflection, +0.013 % impulse,
    +0.028 % peak current, +0.040 % plastic work, the most)."""
    out = tmp_path / "demo"
    r = pulseform_cli(["run", str(REPO / "cases/emf_sheet_bulge"), "--out", str(out), "--quiet",
                       "--set", "output.plots=false"])
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads((out / "metrics.json").read_text())
    for key, before in BEFORE_LANDING.items():
        assert m[key] == pytest.approx(before, rel=2e-3), (key, m[key], before)
