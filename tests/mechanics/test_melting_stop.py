"""The stop when a cell reaches its material's melting temperature (issue 33).

A 20 mm × 1 mm aluminium strip, clamped at its outer end, under a sin² pressure pulse that yields it: its cells
heat by β × the plastic work (adiabatic, ρ c_p dT = β σ_y dε_p) to ~306 K in 40 µs. With a melting temperature of
300 K the run must stop at the first EM step whose cells are at or above it (history_every = 1: the check runs
after every step), in one line naming the body, the cell's position, its temperature and the time, with the
history up to the stop kept and equal to the unstopped run's; with 400 K it runs to its end."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from pulseform.orchestrator.run.history import History
from pulseform.orchestrator.run.temperature import MeltingReached, check_melting
from warm_cli import pulseform_cli

CASE = """
[case]
name = "hot_strip"
kind = "mechanics"

[time]
end = 4.0e-5
cfl = 0.5

[mechanics]
formulation = "plane_strain"
thickness = 1.0

[materials.al]
density = 2700.0
shear_modulus = 26.0e9
bulk_modulus = 68.0e9
yield_stress = 100e6
hardening_modulus = 500e6
specific_heat = 900.0
melting_temperature = {melt}

[[bodies]]
name = "strip"
material = "al"
shape = {{ type = "rectangle", origin = [0.0, 0.0], width = 0.02, height = 0.001 }}
mesh_size = 5.0e-4
fixed = [ {{ where = {{ xmin = 0.0195 }}, components = [0, 1] }}, {{ where = {{ xmax = 1.0e-9 }}, components = [0] }} ]

[[loads]]
type = "pulse_sin2"
body = "strip"
surface = {{ ymin = 0.0009 }}
amplitude = 30e6
beta = 1.0e4
omega = 1.0e5
t_start = 0.0
t_end = 3.1416e-5

[output]
field_interval = 1.0e-5
plots = false
"""
MELT = 300.0


def _run(tmp_path: Path, melt: float):
    case = tmp_path / f"case_{melt:g}"
    case.mkdir()
    (case / "case.toml").write_text(CASE.format(melt=melt))
    out = tmp_path / f"run_{melt:g}"
    return pulseform_cli(["run", str(case), "--out", str(out), "--quiet"]), out


def test_a_cell_at_melting_stops_the_run_in_one_line_with_the_history_kept(tmp_path):
    full, full_out = _run(tmp_path, 400.0)
    assert full.returncode == 0, full.stderr[-2000:]
    ref = History.read(full_out / "history.csv")
    tmax = ref.column("strip_temperature_max_K")
    assert tmax.max() > MELT + 3.0                           # the pulse heats the strip well past 300 K
    first = int(np.argmax(tmax >= MELT))                     # the first row (one per EM step) at or above it

    r, out = _run(tmp_path, MELT)
    assert r.returncode == 1, r.stderr[-2000:]
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    line = lines[0]
    assert "hot_strip: body 'strip' melts: cell" in line and "melting temperature 300 K" in line, line
    assert "Traceback" not in r.stderr
    h = History.read(out / "history.csv")
    t = h.column("time_s")
    # stopped at the first step at or above 300 K: the rows up to it are the unstopped run's, bitwise
    assert len(t) == first + 1
    for c in h.columns:
        np.testing.assert_array_equal(h.column(c), ref.column(c)[: first + 1], err_msg=c)
    assert h.column("strip_temperature_max_K")[-2] < MELT <= h.column("strip_temperature_max_K")[-1]
    # the line names that step's time and its hottest cell's temperature (6 digits)
    assert f"at t = {t[-1]:.6g} s" in line, line
    assert f"reached {h.column('strip_temperature_max_K')[-1]:.6g} K" in line, line
    x, y = (float(v) for v in line.split(" at (")[1].split(") m")[0].split(","))
    assert -1e-4 < x < 0.0201 and -2e-3 < y < 3e-3           # a point of the (bent) strip
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "failed"
    assert (out / "run.log").read_text().count("melts") >= 1


class _Body:
    def __init__(self, temperature, thermal=True):
        self.temperature = np.asarray(temperature, float)
        self.x = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
        self.cells = np.array([[0, 1, 2], [1, 3, 2]])
        self.material = type("M", (), {"thermal": thermal})()


def test_check_melting_names_the_cell_furthest_past_its_melting_temperature():
    solver = type("S", (), {})()
    solver.time = 1.5e-5
    solver.bodies = {"a": _Body([310.0, 320.0]), "b": _Body([905.0, 880.0]), "c": _Body([5000.0, 0.0], False)}
    check_melting(solver, {"a": 321.0, "b": 906.0, "c": 400.0}, MPI.COMM_SELF)   # none reached: nothing
    with pytest.raises(MeltingReached) as err:
        check_melting(solver, {"a": 315.0, "b": 900.0}, MPI.COMM_SELF)        # a and b both 5 K past
    e = err.value
    assert (e.body, e.cell, e.temperature, e.melting) == ("a", 1, 320.0, 315.0)   # a tie: the first body by name
    np.testing.assert_allclose(e.centroid, [2.0 / 3.0, 2.0 / 3.0])
    with pytest.raises(MeltingReached) as err:
        check_melting(solver, {"a": 318.0, "b": 900.0}, MPI.COMM_SELF)
    assert (err.value.body, err.value.cell, err.value.temperature) == ("b", 0, 905.0)
    assert "body 'b' melts: cell 0 at (0.333333, 0.333333) m reached 905 K >= its melting temperature 900 K " \
           "at t = 1.5e-05 s" in str(err.value)


def test_check_melting_in_3d_names_the_tetrahedron_centroid():
    body = _Body([300.0, 1000.0])
    body.x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]])
    body.cells = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    solver = type("S", (), {"time": 2e-6, "bodies": {"tube": body}})()
    with pytest.raises(MeltingReached) as err:
        check_melting(solver, {"tube": 925.0}, MPI.COMM_SELF)
    np.testing.assert_allclose(err.value.centroid, [0.5, 0.5, 0.5])
    assert "body 'tube' melts: cell 1 at (0.5, 0.5, 0.5) m reached 1000 K" in str(err.value)
