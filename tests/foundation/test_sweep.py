"""`pulseform sweep`: full grid, parallel members, a bad member fails alone."""

import csv
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))


def test_sweep_grid_with_failing_members(tmp_path):
    out = tmp_path / "sw"
    r = subprocess.run([EXE, "sweep", str(REPO / "cases/bar_impact"), "--out", str(out), "--jobs", "2",
                        "--param", "time.cfl=0.5,2.0",
                        "--param", "bodies.left.initial_velocity=[10.0, 0.0],[3000.0, 0.0]",
                        "--set", "bodies.left.mesh_size=0.25", "--set", "bodies.right.mesh_size=0.25",
                        "--set", "time.end=2e-4", "--set", "output.field_interval=1e-4"],
                       capture_output=True, text=True)
    assert r.returncode == 1, r.stderr
    rows = list(csv.DictReader(open(out / "sweep.csv")))
    assert len(rows) == 4
    status = {(row["time.cfl"], row["bodies.left.initial_velocity"]): int(row["returncode"]) for row in rows}
    # cfl 2.0 is rejected by validation (2); 3 km/s into the contact layer stops the solver (1)
    assert status[("0.5", "[10.0, 0.0]")] == 0
    assert status[("0.5", "[3000.0, 0.0]")] == 1
    assert status[("2.0", "[10.0, 0.0]")] == 2 and status[("2.0", "[3000.0, 0.0]")] == 2
    ok = next(row for row in rows if row["returncode"] == "0")
    assert float(ok["mech_steps"]) > 0 and float(ok["wall_time_s"]) > 0
    assert "time.cfl" in r.stdout and "FAILED(1)" in r.stdout
    assert "Traceback" not in r.stderr


def test_sweep_bad_param_syntax_is_bad_input(tmp_path):
    r = subprocess.run([EXE, "sweep", str(REPO / "cases/bar_impact"), "--out", str(tmp_path / "x"),
                        "--param", "time.cfl"], capture_output=True, text=True)
    assert r.returncode == 2 and "time.cfl" in r.stderr and "Traceback" not in r.stderr
