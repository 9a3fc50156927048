"""The coupled 3D sector case with its air meshed again mid-run, through the CLI (``pulseform run
cases/emf_sheet_bulge_3d``, a 3D geometry file: ``geometry.on_mesh_break = "remesh"``, the default): the coarse
5 degree sector of tests/coupling/sector_case.py, 2 us (6 EM steps of 1/3 us), a field output and checkpoint every 1 us;
the air is meshed again before EM step ``K`` whatever its quality (``remesh_before_steps``, set by the helper
tests/coupling/forced_remesh_run.py: the coarse sector's air never breaks in 2 us).

References:
(1) the sheet's force history of the run with the remesh against the run without: identical (bitwise) before
    the remesh; after it only the air differs (the sheet's tetrahedra and nodes, the coil and the EM state
    are carried exactly), so the histories differ by a mesh-to-mesh amount. Its size is measured by a third
    run whose air is meshed again before the first step (the same remesh of the fresh geometry, no state to
    carry: the whole run on another air mesh of the same sizes): the mid-run remesh must change the force by
    more than 0 (another air) and by no more than 2x that difference, and the difference must be small
    against the force (< 5 %);
(2) the ledger (nodal forces vs GetDP's integral over the sheet) stays at round-off: exact by construction;
(3) SIGINT after the remesh, then ``--resume``, equals the uninterrupted run bitwise: the checkpoint carries the
    remeshed EM mesh, the EM state, the edge-unknown map and the fresh mesh's plane faces (the size reference).
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from .resume_check import checkpoint_arrays, interrupted_run
from .sector_case import CASE as CASE_DIR, MESH, sets

pytestmark = pytest.mark.getdp

CASE = str(CASE_DIR)
HELPER = str(Path(__file__).with_name("forced_remesh_run.py"))
#: the air meshed again before this EM step (t = 2/3 us)
K = 3
ARGS = sets(MESH + ["time.end=2e-6", "output.field_interval=1e-6", "output.plots=false"])
TIMERS = ("load_time_s", "mech_time_s", "setup_time_s", "wall_time_s", "em_time_s")
#: the history's force columns compared (N): the loop's held force on the sheet and GetDP's at the step's end
FORCES = ("force_z_N", "getdp_force_z_N")


def _argv(out: Path, steps: str, *extra: str, sigint_in_step: int = 0) -> list[str]:
    signal_at = [f"--sigint-in-step={sigint_in_step}"] if sigint_in_step else []
    return [sys.executable, HELPER, steps, *signal_at, "run", CASE, "--out", str(out), "--quiet", *ARGS, *extra]


def _history(out: Path) -> dict[str, np.ndarray]:
    rows = list(csv.DictReader(open(out / "history.csv")))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    """The runs without a remesh ("0": never), with one before step K, and with one before step 1."""
    root = tmp_path_factory.mktemp("sector_remesh")
    out = {}
    for name, steps in (("plain", "0"), ("forced", str(K)), ("scratch", "1")):
        out[name] = root / name
        r = subprocess.run(_argv(out[name], steps), capture_output=True, text=True)
        assert r.returncode == 0, r.stderr[-3000:]
    return out


# slow (a repeated end-to-end run; covered in the default tier by the same reference (forced remesh vs none vs from
# scratch) on the racetrack: test_racetrack_remesh3d.py::test_forced_remesh_of_an_undeformed_mesh; the sector's
# remesh: test_sector_remesh3d.py; a forced remesh through the CLI: test_case_racetrack_remesh.py)
@pytest.mark.slow
def test_a_remesh_mid_run_changes_the_force_by_a_mesh_to_mesh_amount(runs):
    h = {k: _history(p) for k, p in runs.items()}
    m = {k: json.loads((p / "metrics.json").read_text()) for k, p in runs.items()}
    assert list(h["forced"]["em_remeshes"]) == [0.0] * K + [1.0] * (7 - K) and m["forced"]["em_remeshes"] == 1
    assert m["plain"]["em_remeshes"] == 0 and m["forced"]["em_steps"] == 6 and m["forced"]["status"] == "ok"
    plain = np.stack([h["plain"][c] for c in FORCES], axis=1)
    forced = np.stack([h["forced"][c] for c in FORCES], axis=1)
    scratch = np.stack([h["scratch"][c] for c in FORCES], axis=1)
    scale = np.abs(plain).max(axis=0)
    d_forced = np.abs(forced - plain).max(axis=0) / scale
    d_mesh = np.abs(scratch - plain).max(axis=0) / scale
    ledger = m["forced"]["conservation_error_rel"]
    print(f"\nsheet force {FORCES} vs no remesh: remesh before step {K} {d_forced}, air meshed again before step 1 "
          f"{d_mesh}; ledger {ledger:.1e}; max |F_z| {scale} N (sector); the remesh "
          f"{m['forced']['em_remesh_s']:.2f} s")
    assert np.array_equal(forced[:K], plain[:K])   # rows at t = 0 .. step K-1: identical until the remesh
    assert np.all(d_forced > 0) and np.all(d_forced <= 2 * d_mesh) and np.all(d_mesh < 0.05)
    assert ledger < 1e-12


def _stop_in(out: Path, step: int) -> None:
    """The forced run SIGINTs itself as EM step ``step`` starts; it stops (interrupted) at the next output."""
    interrupted_run(_argv(out, str(K), sigint_in_step=step), out)


# slow (a repeated end-to-end run; covered in the default tier by the same SIGINT after a remesh then --resume,
# bitwise, on the racetrack:
# test_case_racetrack_remesh.py::test_sigint_after_the_remesh_then_resume_equals_the_uninterrupted_run)
@pytest.mark.slow
def test_sigint_after_the_remesh_then_resume_equals_the_uninterrupted_run(runs, tmp_path):
    out = tmp_path / "cut"
    _stop_in(out, K)   # SIGINT in step 3 (which starts with the remesh): stops at the checkpoint at 1 us
    cp = checkpoint_arrays(out)
    steps = int(cp["load/steps"])
    assert K <= steps < 6 and int(cp["load/remesh/count"]) == 1
    assert all(f"load/remesh/plane_air/{k}/{a}" in cp for k in (0, 1) for a in ("uv", "tris"))
    r = subprocess.run(_argv(out, str(K), "--resume"), capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    want = json.loads((runs["forced"] / "metrics.json").read_text())
    got = json.loads((out / "metrics.json").read_text())
    for k, v in want.items():
        if k not in TIMERS and not k.startswith(("em_getdp", "em_mesh_motion", "em_transfer", "em_res", "em_remesh_s",
                                                 "getdp_")) and k != "status":
            assert got[k] == v, k   # bitwise
    h_ref = np.loadtxt(runs["forced"] / "history.csv", delimiter=",", skiprows=1)
    h_got = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1)
    assert h_got.shape == h_ref.shape and np.array_equal(h_got, h_ref)
    print(f"\nstopped after EM step {steps} (remesh before step {K}); resumed: impulse {got['force_impulse_z_Ns']!r} "
          f"N s, deflection {got['sheet_max_uz_mm']!r} mm (bitwise the uninterrupted run's)")
