"""`pulseform run` with ``mechanics.integrator = "implicit"`` (issue 34 item 1): a slow elastic-plastic
cantilever under a pressure pulse end to end, its schema checks, the one-line stop of a singular static
system with the results so far on disk, [springback] after a run, and (slow) the same case run explicitly: peak and final tip
deflection within 1 %."""
from __future__ import annotations

import copy
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from pulseform.orchestrator.cli import main

EXE = str(Path(sys.executable).with_name("pulseform"))

#: a 100 x 5 mm aluminium cantilever (plane stress, 10 mm thick) under a sin^2 pressure pulse on its upper face,
#: 3.1 ms long (first bending period 2.4 ms): it bends past yield and rings after the pulse
CASE = {
    "case": {"name": "implicit_cantilever", "kind": "mechanics"},
    "time": {"end": 6.0e-3},
    "mechanics": {"formulation": "plane_stress", "thickness": 0.01, "integrator": "implicit",
                  "implicit": {"dt": 5.0e-5, "scheme": "trapezoidal"}},
    "materials": {"al": {"density": 2700.0, "shear_modulus": 26.0e9, "bulk_modulus": 70.0e9,
                         "yield_stress": 100.0e6, "hardening_modulus": 500.0e6}},
    "bodies": [{"name": "beam", "material": "al",
                "shape": {"type": "rectangle", "origin": [0.0, 0.0], "width": 0.1, "height": 0.005},
                "mesh_size": 0.00125, "fixed": [{"where": {"xmax": 1e-9}, "components": [0, 1]}]}],
    "loads": [{"type": "pulse_sin2", "body": "beam", "surface": {"ymin": 0.004999}, "amplitude": 2.0e5,
               "omega": 1000.0, "beta": 0.0, "t_start": 0.0, "t_end": 3.14159e-3}],
    "probes": [{"name": "tip", "body": "beam", "point": [0.1, 0.0025], "quantity": "displacement"}],
    "output": {"field_interval": 1.0e-3, "plots": False},
}
#: the fast variant: two cells through the thickness, 1 ms
COARSE = ["--set", "bodies.beam.mesh_size=0.0025", "--set", "time.end=1e-3", "--set", "output.field_interval=5e-4"]


def _write(tmp_path: Path, data: dict) -> Path:
    p = tmp_path / "case.toml"
    p.write_text(tomli_w.dumps(data))
    return p


def _run(file: Path, out: Path, *sets: str) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, "run", str(file), "--out", str(out), "--quiet", *sets], capture_output=True, text=True,
                          timeout=900)


def test_implicit_run_end_to_end(tmp_path):
    """The implicit run finishes, writes its history with the implicit ledger (the trapezoidal rule's algorithmic
    dissipation zero to the Newton tolerance: below 1e-9 of the external work), fields and metrics."""
    r = _run(_write(tmp_path, CASE), tmp_path / "out", *COARSE)
    assert r.returncode == 0, r.stderr[-2000:]
    out = tmp_path / "out"
    h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    assert h["time_s"][-1] == pytest.approx(1e-3, rel=1e-12)
    assert np.allclose(np.diff(h["time_s"]), 5e-5)                # the implicit step, not the explicit one
    assert h["tip_displacement_y_m"][-1] < -1e-4                  # pushed down
    assert h["energy_external_work_J"][-1] > 0
    assert np.abs(h["energy_algorithmic_dissipation_J"]).max() < 1e-9 * h["energy_external_work_J"][-1]
    assert (out / "fields").is_dir()
    assert json.loads((out / "metrics.json").read_text())["status_ok"] == 1.0


def test_singular_static_run_stops_in_one_line(tmp_path):
    """A static implicit run of a body without supports: exit 1, one line naming the body and its free motions,
    the log and metrics (status failed) on disk."""
    data = copy.deepcopy(CASE)
    data["bodies"][0].pop("fixed")
    data["mechanics"]["implicit"]["scheme"] = "static"
    out = tmp_path / "out"
    r = _run(_write(tmp_path, data), out, *COARSE)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    print(r.stderr)
    assert r.returncode == 1 and len(lines) == 1 and "Traceback" not in r.stderr
    assert "body 'beam' can move rigidly" in lines[0] and "translation x" in lines[0]
    assert (out / "run.log").is_file()
    assert json.loads((out / "metrics.json").read_text())["status"] == "failed"


@pytest.mark.parametrize("edit,key", [
    ({"implicit": {"scheme": "trapezoidal"}}, "mechanics.implicit.dt"),
    ({"implicit": {"dt": 1e-4, "alpha": -0.5, "scheme": "hht"}}, "mechanics.implicit.alpha"),
    ({"implicit": {"dt": 1e-4, "scheme": "euler"}}, "mechanics.implicit.scheme"),
    ({"integrator": "newmark"}, "mechanics.integrator"),
    ({"kinetic_damping_until": 1e-3}, "mechanics.kinetic_damping_until"),
])
def test_bad_implicit_keys_are_one_line(tmp_path, capsys, edit, key):
    """Bad implicit keys: exit 2, one line naming the file and the key."""
    data = copy.deepcopy(CASE)
    data["mechanics"].update(edit)
    file = _write(tmp_path, data)
    rc = main(["check", str(file)])
    _, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and key in lines[0] and str(file) in lines[0], err


def test_implicit_takes_walls_and_refuses_contact_friction_in_one_line(tmp_path, capsys):
    """Walls and elastic contact pairs are in the implicit integrator (issue 34, item 1): the case check passes
    them; a pair with friction (velocity-dependent, not in the implicit integrator) is refused in one line
    naming the file and the key."""
    data = copy.deepcopy(CASE)
    data["walls"] = [{"point": [0.0, -0.01], "normal": [0.0, 1.0]}]
    assert main(["check", str(_write(tmp_path, data))]) == 0
    capsys.readouterr()
    die = copy.deepcopy(data["bodies"][0])
    die.update(name="die", shape={"type": "rectangle", "origin": [0.0, -0.006], "width": 0.1, "height": 0.005})
    data["bodies"].append(die)
    data["contact"] = [{"slave": "beam", "master": "die", "stiffness": 1e6, "h0": 1e-4, "friction": 0.2}]
    file = _write(tmp_path, data)
    rc = main(["check", str(file)])
    _, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and "contact[0].friction" in lines[0] and str(file) in lines[0], err


@pytest.mark.slow
def test_implicit_matches_explicit_on_a_slow_elastic_plastic_case(tmp_path):
    """The cantilever case (4 cells through the thickness, 6 ms: the pulse, yield at the clamp, the ringing
    after it) run with both integrators: the implicit run's 120 steps of 50 us and the explicit run's ~117 000
    steps give the peak and the final tip deflection within 1 % (measured 0.04 % and 0.16 %)."""
    file = _write(tmp_path, CASE)
    tips = {}
    for integrator in ("implicit", "explicit"):
        out = tmp_path / integrator
        r = _run(file, out, "--set", f"mechanics.integrator={integrator}")
        assert r.returncode == 0, r.stderr[-2000:]
        h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
        tips[integrator] = h["tip_displacement_y_m"]
        steps = json.loads((out / "metrics.json").read_text())["mech_steps"]
        print(integrator, "steps", steps, "peak", tips[integrator].min(), "final", tips[integrator][-1])
    imp, exp = tips["implicit"], tips["explicit"]
    assert np.max(-exp) > 0.01                                     # 10 mm: well past the elastic range
    assert imp.min() == pytest.approx(exp.min(), rel=0.01)
    assert imp[-1] == pytest.approx(exp[-1], rel=0.01)


def test_springback_after_the_run(tmp_path):
    """``[springback]`` after an implicit HHT run: the springback fields (a file ParaView opens: one output with
    the final shape and the residual stress, in fields/springback/, apart from the run's series), the metrics of
    the largest springback and of the tip probe, the residual stress, the picture before and after; the
    springback lifts the tip back up (the pulse pushed it down)."""
    import h5py

    data = copy.deepcopy(CASE)
    data["mechanics"]["implicit"] = {"dt": 5e-5, "scheme": "hht", "alpha": -0.1}
    data["springback"] = {"supports": "kept"}
    out = tmp_path / "out"
    r = _run(_write(tmp_path, data), out, *COARSE)
    assert r.returncode == 0, r.stderr[-2000:]
    m = json.loads((out / "metrics.json").read_text())
    assert m["beam_springback_max_m"] > 0 and m["tip_springback_y_m"] > 0
    assert m["beam_springback_max_m"] >= abs(m["tip_springback_y_m"])
    assert m["beam_residual_von_mises_max_Pa"] > 0
    with h5py.File(out / "fields" / "springback" / "implicit_cantilever_beam.h5", "r") as f:
        assert list(f["times"]) == [pytest.approx(1e-3)]
        assert f["Step_0000/stress_Pa"].shape[1] == 6
    assert (out / "fields" / "springback" / "implicit_cantilever_beam.xdmf").is_file()
    from pulseform.orchestrator.run.mech_fields import read_fields
    from pulseform.orchestrator.run.pictures_springback import draw_springback

    assert read_fields(out)["beam"].times[-1] == pytest.approx(1e-3)        # the run's own series, not springback's
    assert [p.name for p in draw_springback(out)] == ["springback_beam.png"]


@pytest.mark.parametrize("edit,key", [
    ({"springback": {"supports": "loose"}}, "springback.supports"),
    ({"springback": {"bodies": ["die"]}}, "springback.bodies[0]"),
    ({"springback": {"steps": 0}}, "springback.steps"),
    ({"springback": {"contact": "yes"}}, "springback.contact"),
    ({"springback": {"walls": True}}, "springback.walls"),
])
def test_bad_springback_keys_are_one_line(tmp_path, capsys, edit, key):
    """Bad springback keys: exit 2, one line naming the file and the key."""
    data = copy.deepcopy(CASE)
    data.update(edit)
    file = _write(tmp_path, data)
    rc = main(["check", str(file)])
    _, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and key in lines[0] and str(file) in lines[0], err
