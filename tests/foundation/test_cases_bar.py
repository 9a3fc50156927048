"""The shipped bar-impact case files reproduce the paper's section 4 (issue 3's acceptance figures):
plateau ρ c v / 2 = 70 MPa within 3 % (c = sqrt(E/ρ) = 5000 m/s, v = 10 m/s), contact 2L/c = 1.6 ms
within 4 %, and the rigid-wall variant within 2 % of the two-body plateau."""

import json
from pathlib import Path

import pytest
from warm_cli import pulseform_cli

REPO = Path(__file__).resolve().parents[2]


def _metrics(case: str, out: Path) -> dict:
    # the case file as shipped; no pictures (nothing here looks at them; test_field_files does)
    r = pulseform_cli(["run", str(REPO / "cases" / case), "--out", str(out), "--quiet",
                       "--set", "output.plots=false"])
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
