"""``[[stages]]`` (issue 34, item 5): a run chained from stages in one results folder and one history.

The case: a 100 x 5 mm aluminium cantilever (plane stress, two cells through the thickness) hit twice by a short
sin² pressure pulse on its upper face (0.4 ms, 1.6 MPa; the first bending period is 2.4 ms), each pulse followed by
a springback with the clamp kept. What is checked, and against what:

* the stage boundaries: the state a springback stage leaves is, bit for bit, the state the next pulse starts from
  (its field file's first output, and the history row at its start);
* a chain of one pulse is today's plain run bit for bit (history), and a chain pulse + springback gives the plain
  run's ``[springback]`` metrics bit for bit;
* the ledger across stages: the energy balance (what the hand-overs take out counted) closes to 1e-4 of the work;
* an implicit static preform under a constant pressure handed to the explicit integrator stays at rest: the
  explicit stage starts in the static equilibrium (Newton tolerance), so no wave starts (measured: 2.7e-7 m/s, the
  tip still to 2e-11 m; with the stress lost the beam would swing at ω w ≈ 0.6 m/s, 2π/2.4 ms × 0.24 mm);
* a run interrupted in the second pulse resumes there to the uninterrupted run's history bit for bit;
* bad stage keys: one line naming the file and the key (exit 2).
"""
from __future__ import annotations

import copy
import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import tomli_w

from pulseform.orchestrator.cli import main

LOAD = {"type": "pulse_sin2", "body": "beam", "surface": {"ymin": 0.004999}, "amplitude": 1.6e6, "omega": 7854.0,
        "beta": 0.0}
CASE = {
    "case": {"name": "two_pulses", "kind": "mechanics"},
    "time": {"end": 2.0e-3},
    "mechanics": {"formulation": "plane_stress", "thickness": 0.01},
    "materials": {"al": {"density": 2700.0, "shear_modulus": 26.0e9, "bulk_modulus": 70.0e9,
                         "yield_stress": 100.0e6, "hardening_modulus": 500.0e6,
                         # a forming-limit check rides along through every springback (the demo's, which has one,
                         # stopped in its first springback stage: the monitor had no springback_metrics)
                         "forming_limit": {"minor_strain": [-0.2, 0.0, 0.2], "major_strain": [0.3, 0.2, 0.25]}}},
    "bodies": [{"name": "beam", "material": "al",
                "shape": {"type": "rectangle", "origin": [0.0, 0.0], "width": 0.1, "height": 0.005},
                "mesh_size": 0.0025, "fixed": [{"where": {"xmax": 1e-9}, "components": [0, 1]}]}],
    "loads": [dict(LOAD, t_start=0.0, t_end=0.4e-3), dict(LOAD, t_start=1.0e-3, t_end=1.4e-3)],
    "probes": [{"name": "tip", "body": "beam", "point": [0.1, 0.0025], "quantity": "displacement"}],
    "output": {"field_interval": 2.5e-4, "plots": False, "history_every": 50},
    "stages": [{"name": "press1", "kind": "pulse", "end": 1.0e-3},
               {"name": "release1", "kind": "springback"},
               {"name": "press2", "kind": "pulse", "end": 2.0e-3},
               {"name": "release2", "kind": "springback"}],
}


def _run(tmp_path: Path, data: dict, name: str, *extra: str) -> Path:
    folder = tmp_path / name
    folder.mkdir(exist_ok=True)
    file = folder / "case.toml"
    file.write_text(tomli_w.dumps(data))
    out = folder / "out"
    rc = main(["run", str(file), "--out", str(out), "--quiet", "--force", *extra])
    assert rc == 0, (out / "run.log").read_text()[-3000:]
    return out


def _history(out: Path) -> tuple[list[str], np.ndarray]:
    cols = (out / "history.csv").read_text().splitlines()[0].split(",")
    return cols, np.loadtxt(out / "history.csv", delimiter=",", skiprows=1)


def _last_fields(path: Path, first: bool = False) -> dict[str, np.ndarray]:
    with h5py.File(path, "r") as f:
        steps = sorted(g for g in f if g.startswith("Step_"))
        g = f[steps[0] if first else steps[-1]]
        return {k: g[k][...] for k in ("displacement_m", "stress_Pa", "plastic_strain")}


@pytest.fixture(scope="module")
def chain(tmp_path_factory) -> Path:
    """The two-pulse chain, run once."""
    return _run(tmp_path_factory.mktemp("stages"), CASE, "chain")


def test_two_pulses_each_followed_by_springback(chain):
    """One history with a stage column, time going on; each springback's state is the next pulse's start, bit for
    bit; fields per stage; the second pulse forms further; the ledger closes."""
    cols, h = _history(chain)
    stage, t = h[:, cols.index("stage")], h[:, cols.index("time_s")]
    assert cols[:2] == ["time_s", "stage"]
    assert list(np.unique(stage)) == [1.0, 2.0, 3.0, 4.0] and np.all(np.diff(stage) >= 0)
    assert np.all(np.diff(t) >= 0) and t[-1] == pytest.approx(2.0e-3, rel=1e-12)
    state = [j for j, c in enumerate(cols) if c not in ("stage", "dt_s", "substeps", "iterations")]
    sb1 = np.flatnonzero(stage == 2)
    start2 = np.flatnonzero(stage == 3)[0]
    assert len(sb1) == 1 and t[sb1[0]] == 1.0e-3 and t[start2] == 1.0e-3
    assert np.array_equal(h[sb1[0], state], h[start2, state])            # the boundary, bit for bit
    assert not np.array_equal(h[sb1[0] - 1, state], h[sb1[0], state])   # the springback moved the beam
    fields, springback = chain / "fields", chain / "fields" / "springback"
    for name in ("press1", "press2"):
        assert (fields / f"two_pulses_{name}_beam.xdmf").is_file()
    released = _last_fields(springback / "two_pulses_release1_beam.h5")
    started = _last_fields(fields / "two_pulses_press2_beam.h5", first=True)
    for k in released:
        assert np.array_equal(released[k], started[k]), k
    m = json.loads((chain / "metrics.json").read_text())
    assert m["stages"] == 4.0 and m["status_ok"] == 1.0
    assert m["stage_release2_beam_residual_plastic_strain_max"] > m["stage_release1_beam_residual_plastic_strain_max"] > 0
    assert m["stage_press2_beam_max_uy_mm"] > m["stage_press1_beam_max_uy_mm"]
    assert m["stage_release1_tip_springback_y_m"] > 0 and m["stage_release2_tip_springback_y_m"] > 0   # back up
    assert m["energy_error_rel"] < 1e-4
    assert h[-1, cols.index("energy_stage_released_J")] > 0


def test_a_picture_per_springback_stage(chain):
    """plots/springback_<stage>_<body>.png (orchestrator/run/pictures_springback.py) for each springback stage: the
    state before is the output the stage started from (the end of the pulse before it, not the next pulse's start at
    the same time, which is the released state), so the largest springback drawn is the stage's metric."""
    from pulseform.orchestrator.run.pictures_springback import draw_springback, springback_states

    m = json.loads((chain / "metrics.json").read_text())
    states = springback_states(chain)
    assert [s[0] for s in states] == ["springback_release1_beam.png", "springback_release2_beam.png"]
    for picture, _, x0, x1 in states:
        stage = picture.split("_")[1]
        drawn = float(np.linalg.norm(x1 - x0, axis=1).max())
        assert drawn == pytest.approx(m[f"stage_{stage}_beam_springback_max_m"], rel=1e-12, abs=0.0), stage
    assert [p.name for p in draw_springback(chain)] == ["springback_release1_beam.png", "springback_release2_beam.png"]


def test_one_pulse_chain_is_the_plain_run(tmp_path):
    """A chain of one pulse stage is today's run bit for bit (history.csv but the stage column); pulse + springback
    stages give the plain run's [springback] metrics bit for bit."""
    plain = copy.deepcopy(CASE)
    del plain["stages"]
    plain["time"]["end"] = 1.0e-3
    plain["springback"] = {"supports": "kept"}
    staged = copy.deepcopy(plain)
    del staged["springback"]
    staged["stages"] = [{"name": "press", "kind": "pulse", "end": 1.0e-3},
                        {"name": "release", "kind": "springback", "springback": {"supports": "kept"}}]
    a, b = _run(tmp_path, plain, "plain"), _run(tmp_path, staged, "staged")
    ca, ha = _history(a)
    cb, hb = _history(b)
    assert set(ca) < set(cb) and len(hb) == len(ha) + 1                        # the last row: the springback's
    for c in ca:
        assert np.array_equal(ha[:, ca.index(c)], hb[:-1, cb.index(c)]), c
    ma, mb = (json.loads((o / "metrics.json").read_text()) for o in (a, b))
    springback = [k for k in ma if "springback" in k or "residual" in k]
    assert springback and all(mb[f"stage_release_{k}"] == ma[k] for k in springback)


def preform_case() -> dict:
    """The beam under a constant pressure (eq. (8) with T = 1000 s): an implicit static preform to 1 ms, then a
    'pulse' stage (explicit) under the same pressure to 1.2 ms."""
    data = copy.deepcopy(CASE)
    data["loads"] = [{"type": "pulse_exp", "body": "beam", "surface": {"ymin": 0.004999}, "amplitude": 2.0e4,
                      "decay_time": 1000.0, "t_start": 0.0, "t_end": 1.0}]
    data["time"]["end"] = 1.2e-3
    data["output"]["history_every"] = 20
    data["stages"] = [{"name": "preform", "kind": "quasi_static", "end": 1.0e-3, "dt": 2.5e-4},
                      {"name": "hold", "kind": "pulse", "end": 1.2e-3, "field_interval": 1e-4}]
    return data


def test_quasi_static_preform_handed_to_the_explicit_integrator(tmp_path):
    """An implicit static preform under a constant pressure (eq. (8) with T = 1000 s), then an explicit stage under
    the same pressure: the explicit solver starts from the static equilibrium, so the beam stays where the preform
    left it — its fastest node below 1e-5 m/s (a lost stress: ~0.6 m/s)."""
    data = preform_case()
    out = _run(tmp_path, data, "preform")
    cols, h = _history(out)
    stage = h[:, cols.index("stage")]
    uy = h[:, cols.index("tip_displacement_y_m")]
    pre, hold = stage == 1, stage == 2
    assert uy[pre][-1] < -1e-4                                               # the preform bent it down
    assert np.abs(h[hold, cols.index("beam_max_speed_m_s")]).max() < 1e-5
    assert np.abs(uy[hold] - uy[pre][-1]).max() < 1e-5 * abs(uy[pre][-1])
    assert json.loads((out / "metrics.json").read_text())["stage_hold_mech_steps"] > 100


def test_interrupted_in_the_second_pulse_resumes_there(tmp_path, monkeypatch, chain):
    """A stop in stage 3 (after its first output time) ends the run with a checkpoint; --resume continues in stage 3
    with its solver to the uninterrupted history bit for bit."""
    from pulseform.orchestrator.run import driver, interrupt

    real = driver.CaseDriver._check_interrupt

    def stop_in_stage_3(self):
        if self.staged is not None and self.staged.current == 2 and self.mechanics.time > 1.2e-3:
            raise interrupt.StopRequested(2)
        real(self)

    folder = tmp_path / "stop"
    folder.mkdir()
    file = folder / "case.toml"
    file.write_text(tomli_w.dumps(CASE))
    out = folder / "out"
    monkeypatch.setattr(driver.CaseDriver, "_check_interrupt", stop_in_stage_3)
    assert main(["run", str(file), "--out", str(out), "--quiet"]) == 130
    monkeypatch.setattr(driver.CaseDriver, "_check_interrupt", real)
    _, part = _history(out)
    assert part[-1, 1] == 3.0 and part[-1, 0] < 2.0e-3
    assert main(["run", str(file), "--out", str(out), "--quiet", "--resume"]) == 0
    ca, ha = _history(chain)
    cb, hb = _history(out)
    assert ca == cb and np.array_equal(ha, hb)


@pytest.mark.parametrize("stages,key", [
    ([{"name": "a", "kind": "press", "end": 2e-3}], "stages[0].kind"),
    ([{"name": "a", "kind": "springback"}, {"name": "b", "kind": "pulse", "end": 2e-3}], "stages[0].kind"),
    ([{"name": "a", "kind": "pulse", "end": 1e-3}, {"name": "b", "kind": "pulse", "end": 1e-3}], "stages[1].end"),
    ([{"name": "a", "kind": "pulse", "end": 1e-3}], "stages[0].end"),
    ([{"name": "a", "kind": "pulse", "end": 2e-3}, {"name": "b", "kind": "springback", "end": 2e-3}],
     "stages[1].end"),
    ([{"name": "a", "kind": "pulse", "end": 2e-3, "dt": 1e-5}], "stages[0].dt"),
    ([{"name": "a", "kind": "pulse", "end": 2e-3, "springback": {"supports": "kept"}}], "stages[0].springback"),
    ([{"name": "a", "kind": "pulse", "end": 2e-3, "voltage": 5e3}], "stages[0].voltage"),
    ([{"name": "a", "kind": "quasi_static", "end": 2e-3}], "stages[0].dt"),
    ([{"name": "a", "kind": "quasi_static", "end": 2e-3, "dt": 1e-4, "velocities": "kept"}],
     "stages[0].velocities"),
    ([{"name": "a", "kind": "pulse", "end": 2e-3}, {"name": "a", "kind": "springback"}], "stages[1].name"),
])
def test_bad_stages_are_one_line(tmp_path, capsys, stages, key):
    """Bad stage keys: exit 2, one line naming the file and the key."""
    data = copy.deepcopy(CASE)
    data["stages"] = stages
    file = tmp_path / "case.toml"
    file.write_text(tomli_w.dumps(data))
    rc = main(["check", str(file)])
    _, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and key in lines[0] and str(file) in lines[0], err


def test_springback_table_with_stages_is_one_line(tmp_path, capsys):
    """[springback] and [[stages]] together: the springback goes in a stage (one line, exit 2)."""
    data = copy.deepcopy(CASE)
    data["springback"] = {"supports": "kept"}
    file = tmp_path / "case.toml"
    file.write_text(tomli_w.dumps(data))
    assert main(["check", str(file)]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and "springback" in err[0] and "stage" in err[0]
