"""cases/jumping_ring from its case file (coaxial_coils, a 50 Hz sine source, a rigid ring with gravity
on a support; the EM step from the source: 40 per period) against its reference, the lumped R-L ring
model (cases/jumping_ring/reference/lumped_model.csv, written by studies/jumping_ring/lumped_reference.py).

Issue 17: the released ring's height follows the lumped model's ODE within 3 % of the maximum height.
Measured: to 80 ms (the jump, its apex at 67.5 ms) here in the default tier; the shipped 0.3 s run
(14.9 s wall, 600 EM steps) differs by at most 1.38 % of the max height (docs/cases.md).
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
    z = np.interp(t, h["time_s"], h["ring_position_y_m"])
    err = float(np.abs(z - z_ref).max() / z_ref.max())
    m = json.loads((out / "metrics.json").read_text())
    print(f"\nmax height {z.max() * 1e3:.3f} mm (lumped {z_ref.max() * 1e3:.3f}); largest difference {err:.2%} of it; "
          f"{m['em_steps']:.0f} EM steps")
    assert z_ref.max() > 0.01 and np.all(h["ring_position_y_m"] >= 0.0)  # it jumps, never below its support
    assert m["em_steps"] == pytest.approx(0.08 * 50 * 40, abs=1)  # 40 EM steps per period of the source
    assert err < 0.03


@pytest.mark.getdp
def test_jumping_ring_sigint_then_resume_is_bitwise(tmp_path):
    """A rigid-body run stopped by SIGINT after its first checkpoint and resumed gives every physics metric
    of an uninterrupted run bit for bit (the rigid bodies' state is in the checkpoint under rigid/)."""
    import signal
    import subprocess
    import sys
    import time

    exe = str(Path(sys.executable).with_name("pulseform"))
    sets = ["--quiet", "--set", "time.end=0.03", "--set", "output.field_interval=0.005", "--set", "output.plots=false"]
    ref, out = tmp_path / "ref", tmp_path / "stopped"
    assert subprocess.run([exe, "run", str(CASE), "--out", str(ref), *sets], capture_output=True).returncode == 0
    args = [exe, "run", str(CASE), "--out", str(out), *sets]
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 300
    while not (out / "checkpoint.npz").exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.005)
    time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    if proc.returncode == 0:
        pytest.skip("the run finished before the signal")
    assert proc.returncode == 130 and "interrupted at t = " in err, err
    stopped = json.loads((out / "metrics.json").read_text())
    r = subprocess.run(args + ["--resume"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    got = json.loads((out / "metrics.json").read_text())
    want = json.loads((ref / "metrics.json").read_text())
    assert stopped["end_time_s"] < want["end_time_s"]
    assert want["ring_max_position_y_mm"] > 5.0
    for k, v in want.items():
        if k.endswith("_s") and k != "end_time_s":  # wall-clock timings differ
            continue
        assert got[k] == v, k
