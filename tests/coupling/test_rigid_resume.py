"""A rigid-body run stopped by SIGINT and resumed equals the uninterrupted run (cases/jumping_ring)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from .resume_check import sigint_then_resume

REPO = Path(__file__).resolve().parents[2]
CASE = REPO / "cases/jumping_ring"


@pytest.mark.slow
@pytest.mark.getdp
def test_jumping_ring_sigint_then_resume_is_bitwise(tmp_path):
    """(Slow, ~8 s: a second SIGINT/resume equality on another case. The default tier's companions: the SIGINT
    resume end to end, tests/coupling/test_coupled_getdp.py::test_sigint_between_outputs_then_resume_is_bitwise,
    and the rigid bodies' restart from their checkpoint state,
    tests/coupling/test_jumping_ring.py::test_rigid_participant_restarts_exactly and
    tests/coupling/test_rigid_case.py::test_mixed_mechanics_restarts_bit_for_bit.)
    A rigid-body run stopped by SIGINT after its first checkpoint and resumed gives every physics metric
    of an uninterrupted run bit for bit (the rigid bodies' state is in the checkpoint under rigid/)."""
    exe = str(Path(sys.executable).with_name("pulseform"))
    sets = ["--quiet", "--set", "time.end=0.03", "--set", "output.field_interval=0.005", "--set", "output.plots=false"]
    ref, out = tmp_path / "ref", tmp_path / "stopped"
    assert subprocess.run([exe, "run", str(CASE), "--out", str(ref), *sets], capture_output=True).returncode == 0
    args = [exe, "run", str(CASE), "--out", str(out), *sets]
    proc, err, stopped, r = sigint_then_resume(args, out)
    assert proc.returncode == 130 and "interrupted at t = " in err, err
    assert r.returncode == 0, r.stderr[-3000:]
    got = json.loads((out / "metrics.json").read_text())
    want = json.loads((ref / "metrics.json").read_text())
    assert stopped["end_time_s"] < want["end_time_s"]
    assert want["ring_max_position_y_mm"] > 5.0
    for k, v in want.items():
        if k.endswith("_s") and k != "end_time_s":  # wall-clock timings differ
            continue
        assert got[k] == v, k
