"""Results folder behaviour and the paper's pressure pulses (eq. 7, 8)."""

import json
import math

import numpy as np
import pytest
from scipy.integrate import quad

from pulseform.orchestrator.case.model import Box, PulseExp, PulseSin2
from pulseform.orchestrator.mech.pulses import pulse_impulse_per_area, pulse_pressure
from pulseform.orchestrator.run.results import ResultsExistError, ResultsFolder, atomic_write_text
from pulseform.orchestrator.run.output_times import milestones


def test_existing_results_need_force(tmp_path):
    r = ResultsFolder(tmp_path / "r")
    r.write_text("x.txt", "1")
    for kw in ({}, {"force": True}, {"resume": True}):  # a folder in use is refused, whatever the flags
        with pytest.raises(ResultsExistError, match="in use by a running pulseform"):
            ResultsFolder(tmp_path / "r", **kw)
    r.release()
    with pytest.raises(ResultsExistError, match="--force"):
        ResultsFolder(tmp_path / "r")
    ResultsFolder(tmp_path / "r", resume=True).release()
    assert (tmp_path / "r" / "x.txt").exists()
    ResultsFolder(tmp_path / "r", force=True).release()
    assert not (tmp_path / "r" / "x.txt").exists()
    assert (tmp_path / "r" / ".pulseform").is_file()  # the marker: --force may replace it again


def test_force_refuses_a_folder_pulseform_did_not_make(tmp_path):
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "thesis.tex").write_text("years of work")
    with pytest.raises(ResultsExistError, match="not a results folder made by pulseform"):
        ResultsFolder(victim, force=True)
    assert [f.name for f in victim.iterdir()] == ["thesis.tex"]


def test_results_files_follow_the_umask(tmp_path):
    import os

    old = os.umask(0o027)
    try:
        r = ResultsFolder(tmp_path / "r")
        mode = r.write_text("x.txt", "1").stat().st_mode & 0o777
        r.release()
    finally:
        os.umask(old)
    assert mode == 0o640  # 0o666 & ~0o027; mkstemp alone would give 0o600


@pytest.mark.getdp
def test_every_file_of_a_run_follows_the_umask(shared_run):
    """Issue 14: a whole coupled run (short demo, pictures on) under umask 027: every file it writes
    (metrics, history, case, checkpoint, field files, EM snapshots, getdp run folders, pictures, log,
    marker) is 0640 and every folder 0750 — what the umask allows, not mkstemp's 0600."""
    # `pulseform run cases/emf_sheet_bulge --quiet` under umask 027, asserted to exit 0: the same run as
    # test_field_files' demo (conftest.py)
    out = shared_run("emf_sheet_bulge", ["--set", "time.end=4e-6", "--set", "output.field_interval=2e-6"], umask=0o027)
    files = [p for p in out.rglob("*") if p.is_file()]
    names = {p.name for p in files}
    for expected in ("metrics.json", "history.csv", "case.toml", "checkpoint.npz", "run.log", ".pulseform",
                     "em.pvd", "em_peak_current.vtu", "emf_sheet_bulge_sheet.h5", "shapes.png"):
        assert expected in names, expected
    wrong = [f"{oct(p.stat().st_mode & 0o777)} {p.relative_to(out)}" for p in files if p.stat().st_mode & 0o777 != 0o640]
    wrong += [f"{oct(p.stat().st_mode & 0o777)} {p.relative_to(out)}/" for p in [out, *out.rglob("*")]
              if p.is_dir() and p.stat().st_mode & 0o777 != 0o750]
    assert not wrong, wrong[:20]


def test_out_is_a_file(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(ResultsExistError, match="not a folder"):
        ResultsFolder(tmp_path / "f", force=True)


def test_atomic_write_leaves_no_temp_and_replaces(tmp_path):
    p = tmp_path / "a.txt"
    atomic_write_text(p, "old")
    atomic_write_text(p, "new")
    assert p.read_text() == "new"
    assert [f.name for f in tmp_path.iterdir()] == ["a.txt"]


def test_metrics_json_flat_and_finite(tmp_path):
    r = ResultsFolder(tmp_path / "r")
    path = r.write_metrics({"b_MPa": np.float64(70.0), "a_s": float("nan"), "n": 3})
    data = json.loads(path.read_text())
    assert list(data) == ["a_s", "b_MPa", "n"] and data["a_s"] is None and data["b_MPa"] == 70.0


def test_pulse_sin2_is_eq7():
    ld = PulseSin2(type="pulse_sin2", body="b", surface=Box(), amplitude=30e6, beta=1e4, omega=1e5,
                   t_start=1e-5, t_end=4e-4)
    t = 1e-5 + 2.3e-5
    assert pulse_pressure(ld, t) == pytest.approx(30e6 * math.exp(-1e4 * 2.3e-5) * math.sin(1e5 * 2.3e-5) ** 2)
    assert pulse_pressure(ld, 0.5e-5) == 0.0 and pulse_pressure(ld, 4e-4) == 0.0


@pytest.mark.parametrize("ld", [
    PulseSin2(type="pulse_sin2", body="b", surface=Box(), amplitude=30e6, beta=1e4, omega=1e5, t_end=3e-4),
    PulseSin2(type="pulse_sin2", body="b", surface=Box(), amplitude=5e6, beta=0.0, omega=2e5, t_start=1e-4,
              t_end=2e-4),
    PulseExp(type="pulse_exp", body="b", surface=Box(), amplitude=350e6, decay_time=8.3e-6, t_end=6e-5),
])
def test_pulse_impulse_closed_form_matches_quadrature(ld):
    num, _ = quad(lambda t: pulse_pressure(ld, t), ld.t_start, ld.t_end, limit=1000, epsabs=0, epsrel=1e-12)
    assert pulse_impulse_per_area(ld) == pytest.approx(num, rel=1e-9)


def test_milestones_land_on_end():
    m = milestones(2.2e-3, 2e-4)
    assert m[-1] == 2.2e-3 and len(m) == 11
    m = milestones(1.0, 0.3)
    assert np.allclose(m, [0.3, 0.6, 0.9, 1.0])
