"""A ``pulseform run`` stopped by SIGINT after its first checkpoint, then resumed: the procedure the
bitwise-resume tests share (the assertions stay in the tests)."""
from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest


def sigint_then_resume(args: list[str], out: Path, delay: float = 0.2
                       ) -> tuple[subprocess.Popen, str, dict, subprocess.CompletedProcess]:
    """Start ``args`` (a ``pulseform run`` into ``out``), send SIGINT ``delay`` s after its first checkpoint, wait,
    then run ``args + ["--resume"]``. Returns (the stopped process, its stderr, the stopped run's metrics,
    the resumed run's completed process); skips the test when the run finished before the signal."""
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 300
    while not (out / "checkpoint.npz").exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.005)
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    if proc.returncode == 0:
        pytest.skip("the run finished before the signal")
    stopped = json.loads((out / "metrics.json").read_text()) if proc.returncode == 130 else {}
    resumed = subprocess.run(args + ["--resume"], capture_output=True, text=True)
    return proc, err, stopped, resumed


#: metrics that are wall times or timers (a resumed run's differ) in the results of a coupled 3D run
TIMERS_3D = ("load_time_s", "mech_time_s", "setup_time_s", "wall_time_s", "em_time_s", "em_s_per_step",
             "mech_ms_per_step")
TIMER_PREFIXES_3D = ("em_getdp", "em_mesh_motion", "em_transfer", "em_res", "em_remesh_s", "getdp_")


def assert_coupled3d_outputs_bitwise(ref: Path, out: Path) -> dict:
    """The results folder ``out`` of a coupled 3D run (a resumed run) equals ``ref`` (the uninterrupted one) bit
    for bit: every metric but the timers and the status, the whole history.csv, and the force density per
    tetrahedron of the EM snapshot at the peak coil current (``fields/em3d/em_peak_current.vtu``, with its time
    and current). Returns ``out``'s metrics."""
    import meshio
    import numpy as np

    want = json.loads((ref / "metrics.json").read_text())
    got = json.loads((out / "metrics.json").read_text())
    for k, v in want.items():
        if k not in TIMERS_3D and not k.startswith(TIMER_PREFIXES_3D) and k != "status":
            assert got[k] == v, k   # bitwise
    h_ref = np.loadtxt(ref / "history.csv", delimiter=",", skiprows=1)
    h_got = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1)
    assert h_got.shape == h_ref.shape and np.array_equal(h_got, h_ref)
    peak = Path("fields") / "em3d" / "em_peak_current"
    a, b = (meshio.read(p / peak.with_suffix(".vtu")) for p in (ref, out))
    assert np.array_equal(a.points, b.points)
    assert np.array_equal(a.cell_data["force_density_N_m3"][0], b.cell_data["force_density_N_m3"][0])
    assert json.loads((ref / peak.with_suffix(".json")).read_text()) == \
        json.loads((out / peak.with_suffix(".json")).read_text())
    return got


def checkpoint_arrays(out: Path) -> dict:
    """The run state of ``out/checkpoint.npz`` (its ``a/`` arrays, without the prefix)."""
    import numpy as np

    with np.load(out / "checkpoint.npz") as z:
        return {k[2:]: z[k] for k in z.files if k.startswith("a/")}


def interrupted_run(argv: list[str], out: Path) -> dict:
    """Run ``argv`` (a ``pulseform run`` into ``out`` that signals itself, e.g. tests/coupling/forced_remesh_run.py
    with ``--sigint-in-step``); asserts it stopped as interrupted (exit 130) and returns its metrics."""
    r = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, timeout=600)
    assert r.returncode == 130, r.stderr[-3000:]
    cut = json.loads((out / "metrics.json").read_text())
    assert cut["status"] == "interrupted"
    return cut
