"""TEAM Workshop Problem 28 (cases/team28_levitation) in `pulseform validate --suite full`.

- The case file states the problem's specification (cases/team28_levitation/reference/team28_spec.toml:
  the problem description, Karl et al. 1997, and the reproductions its README names): the coils, their
  turns, currents and directions, the plate, its conductivity, mass and rest height, gravity.
- The four TEAM 28 entries belong to the full suite (not the fast one); fed the filament model's own
  curve as the run (no solver), each judges it and draws the measured curve and the filament model
  beside the run: against itself the error is 0, against the measurement it is the ideal problem's own
  distance to Table I (0.236 of the 18.2 mm peak: its first rise leads the measurement).
- A short run of the case file (30 ms, 60 EM steps, the first rise) follows the filament model of the
  same spec within 3 % of the rise (the jumping ring's tolerance for its lumped model; measured 1.2 %).
- slow: `pulseform validate --suite full --only team28_levitation`, the whole 1.7 s (3,400 EM steps, ~4 min):
  every entry passes and each picture holds the run, the measured curve and the filament model.
"""
from __future__ import annotations

import json
import math
import tomllib

import numpy as np
import pytest

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.workflows.registry import REGISTRY, RUNS, RunOutput
from pulseform.orchestrator.workflows import validate
from pulseform.orchestrator.workflows.validate import run_validation, select

from wf_helpers import REPO, pulseform

CASE = REPO / "cases/team28_levitation"
REF = CASE / "reference"
NAMES = ["team28_levitation.height_vs_measured", "team28_levitation.settled_height", "team28_levitation.first_peak",
         "team28_levitation.height_vs_filament_model"]


def _curve(name: str) -> tuple[np.ndarray, np.ndarray]:
    d = np.genfromtxt(REF / name, delimiter=",", names=True, skip_header=4)
    return d["time_ms"], d["height_mm"]


def test_case_file_states_the_team28_spec():
    spec = tomllib.loads((REF / "team28_spec.toml").read_text())
    case, _ = load_case(CASE)
    g, p = case.geometry, spec["plate"]
    assert g.workpiece.box == pytest.approx((0.0, p["start_height"], p["radius"], p["start_height"] + p["thickness"]))
    body = case.bodies[0]
    mat = case.materials[body.material]
    assert body.rigid and body.region == "workpiece" and mat.electrical_conductivity == p["conductivity"]
    assert mat.density * math.pi * p["radius"] ** 2 * p["thickness"] == pytest.approx(p["mass"], rel=1e-5)
    assert tuple(case.mechanics.gravity) == (0.0, -9.81)
    assert [s.position for s in body.stops] == [0.0]  # at rest on its support at the start height
    sources = {s.name: s for s in case.em.sources}
    drives = {c.name: c for c in case.em.coils}
    for coil, want in zip(g.coils, spec["coils"]):
        assert (coil.name, coil.turns) == (want["name"], want["turns"])
        assert [tuple(w) for w in coil.windings] == [tuple(want["winding"])]
        src = sources[drives[coil.name].source]
        assert (src.amplitude, src.frequency, src.decay, src.phase, src.t_on) == \
            (spec["current_amplitude"], spec["frequency"], 0.0, 0.0, 0.0)
        assert drives[coil.name].sign == want["sign"]
    t_measured = _curve("measured_height.csv")[0]
    assert abs(case.time.end * 1e3 - t_measured[-1]) < 2 * (t_measured[1] - t_measured[0])  # the measured span


def test_entries_judge_the_run_and_draw_both_references(tmp_path, monkeypatch):
    assert [e.name for e in select("full") if e.case == "team28_levitation"] == NAMES
    assert not [e for e in select("fast") if e.case == "team28_levitation"]
    t, z = _curve("filament_model.csv")

    def fake(work):
        out = RunOutput()
        out.curves["height"] = (t, z)
        out.labels["height"] = ("time (ms)", "levitation height z (mm)")
        return out

    monkeypatch.setitem(RUNS, "case_team28_levitation", fake)
    monkeypatch.setattr(validate, "_environment", lambda: {"pulseform": "test"})  # no program version queries
    out = {o.entry.name: o for o in run_validation([REGISTRY[n] for n in NAMES], tmp_path / "val")}
    assert out["team28_levitation.height_vs_filament_model"].error == 0.0
    measured = out["team28_levitation.height_vs_measured"]
    assert measured.error == pytest.approx(0.236, abs=0.001) and measured.passed
    assert out["team28_levitation.settled_height"].reference == pytest.approx(11.319, abs=1e-3)  # Table I, 1.2-1.7 s
    assert out["team28_levitation.first_peak"].reference == pytest.approx(18.2)
    rep = json.loads((tmp_path / "val" / "report.json").read_text())
    for e in rep["entries"]:
        assert e["plot"] and (tmp_path / "val" / e["plot"]).stat().st_size > 5000
        drawn = e["provenance"]["also drawn"]
        assert ("filament_model.csv" in drawn) != ("filament_model" in e["name"])
        assert "Table I" in e["provenance"]["source"] or "filament" in e["provenance"]["source"]


@pytest.mark.getdp
def test_first_rise_follows_the_filament_model(tmp_path):
    out = tmp_path / "run"
    r = pulseform("run", str(CASE), "--out", str(out), "--quiet", "--set", "time.end=0.03",
                  "--set", "output.field_interval=0.03", "--set", "output.plots=false")
    assert r.returncode == 0, r.stderr[-3000:]
    h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    t, z = h["time_s"] * 1e3, 3.8 + h["plate_travel_y_m"] * 1e3
    zf = np.interp(t, *_curve("filament_model.csv"))
    rise = zf.max() - 3.8
    err = float(np.abs(z - zf).max() / rise)
    print(f"\nheight {z[-1]:.3f} mm at 30 ms (filament model {zf[-1]:.3f}); largest difference {err:.2%} of the rise")
    assert rise > 5.0 and err < 0.03


@pytest.mark.slow
@pytest.mark.getdp
def test_full_suite_team28_entries_pass(tmp_path):
    out = tmp_path / "val"
    r = pulseform("validate", "--suite", "full", "--only", "team28_levitation", "--out", str(out), timeout=3000)
    print(r.stdout)
    assert r.returncode == 0, r.stdout + r.stderr[-3000:]
    rep = json.loads((out / "report.json").read_text())
    assert [e["name"] for e in rep["entries"]] == NAMES and rep["passed"]
    for e in rep["entries"]:
        print(f"{e['name']}: error {e['error']:.4g} (tolerance {e['tolerance']:g})")
        assert (out / e["plot"]).stat().st_size > 5000
