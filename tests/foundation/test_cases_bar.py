"""The shipped bar-impact case files reproduce the paper's section 4 (issue 3's acceptance figures):
plateau ρ c v / 2 = 70 MPa within 3 % (c = sqrt(E/ρ) = 5000 m/s, v = 10 m/s), contact 2L/c = 1.6 ms
within 4 %, and the rigid-wall variant within 2 % of the two-body plateau."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))


def _metrics(case: str, out: Path) -> dict:
    # the case file as shipped; no pictures (nothing here looks at them; test_field_files does)
    r = subprocess.run([EXE, "run", str(REPO / "cases" / case), "--out", str(out), "--quiet",
                        "--set", "output.plots=false"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads((out / "metrics.json").read_text())


@pytest.fixture(scope="module")
def two_body(tmp_path_factory):
    return _metrics("bar_impact", tmp_path_factory.mktemp("bar") / "two")


def test_two_body_plateau_and_duration(two_body):
    assert two_body["contact_stress_plateau_MPa"] == pytest.approx(70.0, rel=0.03)
    assert two_body["contact_duration_ms"] == pytest.approx(1.6, rel=0.04)
    assert two_body["energy_error_rel"] < 0.01


def test_rigid_wall_matches_two_body(two_body, tmp_path):
    wall = _metrics("bar_impact_wall", tmp_path / "wall")
    assert wall["contact_stress_plateau_MPa"] == pytest.approx(two_body["contact_stress_plateau_MPa"], rel=0.02)
    assert wall["contact_duration_ms"] == pytest.approx(1.6, rel=0.04)
