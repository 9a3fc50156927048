"""Skin depth and conductor meshes (orchestrator/case/skin.py, orchestrator/em/skin_depth.py, issue 19):
δ = sqrt(2 / (ω μ0 σ)) is 0.67 mm for the issue's Al disk (σ 3.5e7 S/m) at ω = 1e5 rad/s (the issue
text's figure); a conductor whose elements are coarser than δ/3 gets one warning line naming the key, the
size and δ — from `pulseform check` (exit 0) and in a run's log — and none once refined; a drive without
a period (direct current) gives no advice. A conductor size the case leaves out defaults to δ/3 (at least
two layers through the thickness); a set size is kept; with no frequency to take δ from, the key is
required (one line, exit 2). The default's accuracy: the slow test against the independent 15.18 kN."""
from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import pytest
import tomli_w

from pulseform.orchestrator.case.io import CaseError, load_case
from pulseform.orchestrator.case.schema import SchemaError
from pulseform.orchestrator.cli import main
from pulseform.orchestrator.em.skin_depth import (SKIN_FRACTION, default_sizes, drive_omega, mesh_advice, skin_depth,
                                                   with_default_sizes)

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


def _without(case_dir: Path, tmp_path: Path, *keys: str, sets: dict | None = None) -> Path:
    """A copy of a shipped case file without the ``geometry`` keys ``keys`` (dotted below geometry)."""
    data = tomllib.loads((case_dir / "case.toml").read_text())
    for key in keys:
        *tables, name = key.split(".")
        node = data["geometry"]
        for t in tables:
            node = node[t]
        del node[name]
    for k, v in (sets or {}).items():
        data[k].update(v)
    out = tmp_path / case_dir.name
    out.mkdir()
    (out / "case.toml").write_text(tomli_w.dumps(data))
    return out


def test_unset_sheet_size_defaults_to_a_third_of_the_skin_depth(tmp_path):
    case, _ = load_case(_without(DISK, tmp_path, "mesh_size_sheet"))
    assert case.geometry.mesh_size_sheet is None
    filled = with_default_sizes(case)
    delta = skin_depth(1e5, 3.5e7)  # 0.674 mm; the 1 mm disk: delta / 3 is finer than two layers
    assert filled.geometry.mesh_size_sheet == pytest.approx(delta / 3, rel=1e-12)
    assert filled.geometry.mesh_size_coil == case.geometry.mesh_size_coil  # only the conductor's size
    assert mesh_advice(filled) == []  # a default never draws the advice
    shipped, _ = load_case(DISK)  # a set size is kept, however coarse
    assert default_sizes(shipped) == [] and with_default_sizes(shipped) is shipped


def test_default_keeps_two_layers_at_low_frequency(tmp_path):
    """At ω = 1e3 rad/s δ = 6.7 mm: δ/3 would be one layer of 2.2 mm through the 1 mm disk; it gets 0.5 mm."""
    folder = _without(DISK, tmp_path, "mesh_size_sheet", sets={"em": {"current": {"amplitude": 20e3, "beta": 10.0,
                                                                                  "omega": 1e3}}})
    case, _ = load_case(folder, ["coupling.steps_per_period=40", "time.end=1e-3"])
    assert SKIN_FRACTION * skin_depth(1e3, 3.5e7) > 2e-3
    assert with_default_sizes(case).geometry.mesh_size_sheet == pytest.approx(0.5e-3, rel=1e-12)


def test_bank_default_from_its_ringing(tmp_path):
    """A bank: ω from C and the coil's inductance before the run (the advice's figure: 7.1e4 rad/s)."""
    case, _ = load_case(_without(REPO / "cases/emf_actuator_disk", tmp_path, "mesh_size_sheet"))
    omega = drive_omega(case)
    assert 5e4 < omega < 1e5  # the lumped ringing 1/sqrt((L_coil + 1 µH) 100 µF): L_coil of a few µH
    size = with_default_sizes(case).geometry.mesh_size_sheet
    assert size == pytest.approx(skin_depth(omega, 3.5e7) / 3, rel=1e-12) and size < 1e-3  # 2 mm disk: δ/3 rules


def test_without_a_frequency_the_size_is_required(tmp_path, capsys):
    """Direct currents: no skin depth, no default — one line naming the key, exit 2."""
    sets = ['em.sources=[{name = "main", type = "dc", current = 100.0}, {name = "late", type = "dc", current = 50.0}]',
            "geometry.workpiece={ r0 = 0.0, z0 = 1e-3, r1 = 45e-3, z1 = 2e-3 }"]
    case, _ = load_case(REPO / "cases/two_coils_plate", sets)
    with pytest.raises(SchemaError, match="missing: no source has a frequency"):
        with_default_sizes(case)
    assert main(["check", str(REPO / "cases/two_coils_plate"), *[a for s in sets for a in ("--set", s)]]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "geometry.workpiece.mesh_size: missing" in err[0]


def test_guards_estimate_an_unset_size(tmp_path):
    """Before ω is known the guards estimate the unset size from the period bound (exact for a prescribed
    current): ~3000 cells with the default 0.225 mm sheet (2.31 × 60 mm × 1 mm / h², ~2700) against ~830 with
    the shipped 0.5 mm; a limit of 2000 passes the latter and refuses the former at load, naming the key."""
    load_case(DISK, ["limits.max_cells=2000"])
    with pytest.raises(CaseError, match="geometry.mesh_size_sheet: got 0.000224"):
        load_case(_without(DISK, tmp_path, "mesh_size_sheet"), ["limits.max_cells=2000"])


def test_check_shows_the_default(tmp_path, capsys):
    assert main(["check", str(_without(DISK, tmp_path, "mesh_size_sheet"))]) == 0
    out, err = capsys.readouterr()
    assert "# geometry.mesh_size_sheet = 0.225 mm (default: δ/3; skin depth 0.674 mm" in out and err == ""
    assert "mesh_size_sheet = 0.000224" in out  # the resolved case holds the number


@pytest.mark.slow
@pytest.mark.getdp
def test_default_mesh_peak_force_within_one_percent(tmp_path):
    """The issue's done-when: the default mesh of the emf_fixed_disk configuration (disk elements δ/3 =
    0.225 mm) gives a peak force within 1 % of the independent 15.18 kN (SOLVER_NOTES.md, converged ~10k
    nodes). Measured: 15142 N (−0.25 %) in ~8 s."""
    out = tmp_path / "run"
    assert main(["run", str(_without(DISK, tmp_path, "mesh_size_sheet")), "--out", str(out), "--quiet"]) == 0
    force = json.loads((out / "metrics.json").read_text())["force_peak_N"]
    assert force == pytest.approx(15.18e3, rel=0.01)
    assert "geometry.mesh_size_sheet = 0.225 mm (default" in (out / "run.log").read_text()


def test_converge_starts_from_the_default(tmp_path, monkeypatch):
    """`pulseform converge` on a case that leaves the sheet size out: level 0 is the default δ/3, level k
    δ/3 / 2^k (the levels' runs replaced by a stub: only the plan is checked here)."""
    from pulseform.orchestrator.workflows import converge

    def stub(case, member, sets, pool=None):
        member.returncode, member.metrics = 0, {"force_peak_N": 1.0 + 0.1 * 0.5 ** member.index}
        return member

    monkeypatch.setattr(converge, "run_member", stub)
    report = converge.run_converge(str(_without(DISK, tmp_path, "mesh_size_sheet")), tmp_path / "study",
                                   metrics=["force_peak_N"])
    sizes = [float(lv["overrides"]["geometry.mesh_size_sheet"]) for lv in report["levels"]]
    delta = skin_depth(1e5, 3.5e7)
    assert sizes == pytest.approx([delta / 3, delta / 6, delta / 12], rel=1e-12)
