"""`pulseform sweep --mpi` under `mpirun -n 2` (mpi4py.futures: rank 0 manages, rank 1 runs members)."""

from __future__ import annotations

import csv
import os
import shutil
import subprocess

import pytest

from wf_helpers import EXE, REPO

SMALL = ["--set", "bodies.left.mesh_size=0.25", "--set", "bodies.right.mesh_size=0.25",
         "--set", "time.end=2e-4", "--set", "output.field_interval=1e-4"]


@pytest.mark.mpi
def test_sweep_through_mpi4py_futures(tmp_path):
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        pytest.skip("mpirun not found")
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    out = tmp_path / "sw"
    r = subprocess.run([mpirun, "-n", "2", EXE, "sweep", str(REPO / "cases/bar_impact"), "--mpi", "--out", str(out),
                        "--param", "time.cfl=0.5,2.0,0.4", *SMALL], capture_output=True, text=True, env=env,
                       timeout=600)
    assert r.returncode == 1, r.stdout + r.stderr[-3000:]  # the cfl = 2.0 member fails alone
    rows = {row["time.cfl"]: row for row in csv.DictReader(open(out / "sweep.csv"))}
    assert set(rows) == {"0.5", "2.0", "0.4"}
    assert rows["2.0"]["returncode"] == "2" and "time.cfl" in rows["2.0"]["error"]
    for cfl in ("0.5", "0.4"):
        assert rows[cfl]["returncode"] == "0" and float(rows[cfl]["mech_steps"]) > 0
        assert rows[cfl]["worker"]  # run by the worker rank
    # a smaller CFL number takes more steps: the members really ran with their own values
    assert float(rows["0.4"]["mech_steps"]) > float(rows["0.5"]["mech_steps"])
    assert r.stdout.count("sweep.csv") == 1  # only rank 0 reports
    assert "Traceback" not in r.stderr


def test_mpi_without_mpirun_is_bad_input(tmp_path):
    """One rank cannot manage and work: a one-line hint to start under mpirun (or use --jobs)."""
    from wf_helpers import one_line_error, pulseform

    r = pulseform("sweep", str(REPO / "cases/bar_impact"), "--mpi", "--out", str(tmp_path / "sw"),
                  "--param", "time.cfl=0.5")
    assert r.returncode == 2 and "mpirun" in one_line_error(r)
    assert not (tmp_path / "sw").exists()
