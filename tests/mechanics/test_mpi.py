"""``mpirun -n 2`` gives the same bar-impact and kinetic-damping metrics as a serial run (to 1e-10
relative)."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).with_name("mpi_bar_metrics.py")


def _run(argv):
    # numba's error-message highlighting writes an ANSI reset ("\x1b[0m") to stdout under mpirun
    # (also at d149021, before the compiled steps), which cut the JSON line in two
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", NUMBA_DISABLE_ERROR_MESSAGE_HIGHLIGHTING="1")
    r = subprocess.run(argv, capture_output=True, text=True, timeout=900, env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.mpi
def test_two_ranks_match_serial():
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        pytest.skip("mpirun not found")
    serial = _run([sys.executable, str(SCRIPT)])
    par = _run([mpirun, "-n", "2", sys.executable, str(SCRIPT)])
    for case in serial:
        for key, val in serial[case].items():
            print(f"{case} {key}: serial {val!r} mpi {par[case][key]!r}")
            assert par[case][key] == pytest.approx(val, rel=1e-10, abs=1e-12), (case, key)
