"""Skin-depth advice (orchestrator/em/skin_depth.py, issue 19): δ = sqrt(2 / (ω μ0 σ)) is 0.67 mm for the
issue's Al disk (σ 3.5e7 S/m) at ω = 1e5 rad/s (the issue text's figure); a conductor whose elements are
coarser than δ/3 gets one warning line naming the key, the size and δ — from `pulseform check` (exit 0)
and in a run's log — and none once refined; a drive without a period (direct current) gives no advice."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.cli import main
from pulseform.orchestrator.em.skin_depth import SKIN_FRACTION, drive_omega, mesh_advice, skin_depth

REPO = Path(__file__).resolve().parents[2]
DISK = REPO / "cases/emf_fixed_disk"


def test_skin_depth_of_the_issue_disk():
    assert skin_depth(1e5, 3.5e7) == pytest.approx(0.674e-3, rel=2e-3)
    assert skin_depth(4e5, 3.5e7) == pytest.approx(0.5 * skin_depth(1e5, 3.5e7), rel=1e-12)  # 1/sqrt(ω)


def test_advice_names_the_coarse_sheet_only():
    case, _ = load_case(DISK)
    assert drive_omega(case) == pytest.approx(1e5, rel=1e-12)
    lines = mesh_advice(case)
    assert len(lines) == 1 and lines[0].startswith("geometry.mesh_size_sheet = 0.5 mm") and "0.674 mm" in lines[0]
    fine, _ = load_case(DISK, [f"geometry.mesh_size_sheet={0.99 * SKIN_FRACTION * skin_depth(1e5, 3.5e7)}"])
    assert mesh_advice(fine) == []


def test_no_advice_without_a_period():
    case, _ = load_case(REPO / "cases/two_coils_plate", [
        'em.sources=[{name = "main", type = "dc", current = 100.0}, {name = "late", type = "dc", current = 50.0}]'])
    assert drive_omega(case) is None and mesh_advice(case) == []


def test_check_warns_and_passes(capsys):
    assert main(["check", str(DISK)]) == 0
    err = capsys.readouterr().err
    assert err.startswith("pulseform: warning: geometry.mesh_size_sheet") and len(err.strip().splitlines()) == 1


@pytest.mark.getdp
def test_quiet_run_keeps_the_advice_in_its_log(tmp_path, capsys):
    """With --quiet the advice goes to run.log only (a failing run's stderr stays one line)."""
    out = tmp_path / "run"
    assert main(["run", str(DISK), "--out", str(out), "--quiet", "--set", "time.end=1e-6",
                 "--set", "output.field_interval=1e-6"]) == 0
    assert "coarser than" not in capsys.readouterr().err
    assert "geometry.mesh_size_sheet = 0.5 mm is coarser than" in (out / "run.log").read_text()
