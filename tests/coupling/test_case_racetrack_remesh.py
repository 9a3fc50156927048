"""Checkpoints and ``--resume`` of a racetrack case run whose 3D air was meshed again (orchestrator/em/remesh3d.py,
``RemeshingGetDPLoad3D.state_dict``): the coarse racetrack case (the 3D geometry path) through the CLI (sizes x 2 as
tests/coupling/test_case_racetrack.py), 4 EM steps of 1 us, a field output (and a checkpoint) after every step,
the air meshed again before EM steps 3 and 4 whatever its quality (``remesh_before_steps``, set by the helper
tests/coupling/forced_remesh_run.py: the undeformed racetrack's air never breaks in 4 us); the second remesh
starts from the mesh, surface elements and edge unknowns of the first (after a resume: those of the checkpoint).

References: (1) the checkpoint after the remesh holds the EM mesh of the remesh (the file gmsh's air made,
``em/getdp/remesh_001/mesh.msh``, read back independently) and the run completes with its ledgers at round-off
(exact by construction); (2) and (3) the uninterrupted run of the same case, bitwise: a checkpoint sits on an
EM-step boundary and carries every double (the EM mesh, the bodies' EM nodes, the edge-unknown map, x_n, x_{n-1},
the circuit, the mechanics), and the resumed run seeds its getdp process with them at the same step as a resume
without a remesh does, or (3) meshes the air again at the same step from the same positions.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from .resume_check import assert_coupled3d_outputs_bitwise, checkpoint_arrays, interrupted_run

pytestmark = pytest.mark.getdp

REPO = Path(__file__).resolve().parents[2]
CASE = str(REPO / "cases/emf_racetrack_groove")
HELPER = str(Path(__file__).with_name("forced_remesh_run.py"))
#: the air meshed again before these EM steps (t = 2 us and 3 us)
REMESH_STEP = 3
REMESH_STEPS = f"{REMESH_STEP},{REMESH_STEP + 1}"
#: coarse mesh, 4 us, outputs (and checkpoints) every 1 us = every EM step: ~6 s a run
ARGS = ["--set", "geometry.parameters.h_sheet=4e-3", "--set", "geometry.parameters.sheet_layers=2",
        "--set", "geometry.parameters.h_coil=6e-3", "--set", "geometry.parameters.h_die=8e-3",
        "--set", "time.end=4e-6", "--set", "output.field_interval=1e-6", "--set", "output.plots=false",
        "--set", 'geometry.on_mesh_break="remesh"']


def _argv(out: Path, *extra: str, sigint_in_step: int = 0) -> list[str]:
    signal_at = [f"--sigint-in-step={sigint_in_step}"] if sigint_in_step else []
    return [sys.executable, HELPER, REMESH_STEPS, *signal_at, "run", CASE, "--out", str(out), "--quiet", *ARGS,
            *extra]


@pytest.fixture(scope="module")
def remeshed_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("racetrack_remesh") / "run"
    r = subprocess.run(_argv(out), capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


def _history(out: Path) -> dict[str, np.ndarray]:
    rows = list(csv.DictReader(open(out / "history.csv")))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_a_run_with_a_remesh_writes_its_checkpoints_and_completes(remeshed_run):
    from pulseform.solvers.getdp.mesh3d import read_msh22_tets

    out = remeshed_run
    m = json.loads((out / "metrics.json").read_text())
    h = _history(out)
    assert m["status"] == "ok" and m["em_steps"] == 4 and m["end_time_s"] == pytest.approx(4e-6, rel=1e-12)
    # the remeshes before steps 3 and 4 (t = 2 and 3 us): the history's rows at 0, 1, 2, 3, 4 us
    assert list(h["em_remeshes"]) == [0.0, 0.0, 0.0, 1.0, 2.0] and m["em_remesh_s"] > 0
    assert max(m["conservation_error_rel"], m["sheet_ledger_rel"], m["die_ledger_rel"]) < 1e-12
    # the last checkpoint (4 us) holds the EM mesh of the second remesh: gmsh's file, read back
    cp = checkpoint_arrays(out)
    points, tets, ids, tags = read_msh22_tets(out / "em" / "getdp" / "remesh_002" / "mesh.msh")
    assert int(cp["load/remesh/count"]) == 2 and int(cp["load/steps"]) == 4
    for name, ref in (("points", points), ("tets", tets), ("tet_ids", ids), ("tet_tags", tags)):
        assert np.array_equal(cp[f"load/remesh/{name}"], ref), name
    fresh = len(read_msh22_tets(out / "em" / "em3d.msh")[1])   # the fresh EM mesh (metrics' em_tets: the last one's)
    assert len(tets) != fresh and m["em_tets"] == len(tets)   # another air than the fresh mesh's
    print(f"\nremeshes at 2 and 3 us: {fresh} -> {len(tets)} EM tets, {m['em_remesh_s']:.2f} s; ledger "
          f"{m['conservation_error_rel']:.1e}; checkpoint {(out / 'checkpoint.npz').stat().st_size / 1e6:.2f} MB")


def _stop_in(out: Path, step: int) -> dict:
    """The run SIGINTs itself as EM step ``step`` starts: it completes that step, checkpoints and stops (exit 130);
    returns the stopped run's metrics."""
    cut = interrupted_run(_argv(out, sigint_in_step=step), out)
    assert cut["end_time_s"] == pytest.approx(1e-6 * step, rel=1e-9)
    return cut


def _resume_equals(out: Path, ref: Path) -> dict:
    r = subprocess.run(_argv(out, "--resume"), capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    # the force density at the peak coil current: the last step's (4 us, the current still rising), after the resume
    return assert_coupled3d_outputs_bitwise(ref, out)


def test_sigint_after_the_remesh_then_resume_equals_the_uninterrupted_run(remeshed_run, tmp_path):
    out = tmp_path / "cut"
    _stop_in(out, REMESH_STEP)   # stops after step 3, whose start meshed the air again; the resume remeshes
    cp = checkpoint_arrays(out)                # before step 4 from the checkpoint's mesh
    assert int(cp["load/steps"]) == REMESH_STEP and int(cp["load/remesh/count"]) == 1
    got = _resume_equals(out, remeshed_run)
    h = _history(out)
    print(f"\nstopped at {REMESH_STEP} us, after the remesh; resumed: impulse {got['force_impulse_z_Ns']!r} N s, "
          f"coil current at 4 us {h['coil_current_A'][-1]!r} A (bitwise the uninterrupted run's)")


# slow (a repeated end-to-end run; covered in the default tier by a resume of a remeshing run through the CLI,
# bitwise: test_sigint_after_the_remesh_then_resume_equals_the_uninterrupted_run; the forced remeshes at steps 3, 4:
# test_a_run_with_a_remesh_writes_its_checkpoints_and_completes)
@pytest.mark.slow
def test_resume_from_before_the_remesh_remeshes_at_the_same_step(remeshed_run, tmp_path):
    out = tmp_path / "cut"
    _stop_in(out, REMESH_STEP - 1)   # stops after step 2: before the remesh
    cp = checkpoint_arrays(out)
    assert int(cp["load/steps"]) == REMESH_STEP - 1 and "load/remesh/count" not in cp
    _resume_equals(out, remeshed_run)
    assert list(_history(out)["em_remeshes"]) == [0.0, 0.0, 0.0, 1.0, 2.0]
    for k in ("001", "002"):
        assert (out / "em" / "getdp" / f"remesh_{k}" / "mesh.msh").read_bytes() == \
            (remeshed_run / "em" / "getdp" / f"remesh_{k}" / "mesh.msh").read_bytes()


def test_the_edge_unknowns_map_round_trips_through_arrays():
    """EdgeDofs.to_arrays / from_arrays (the checkpoint's ``load/remesh/dofs/*``): every field back exactly
    (reference: the map written, field for field)."""
    from pulseform.solvers.getdp.state_carry3d import EdgeDofs

    rng = np.random.default_rng(3)
    a = EdgeDofs(edges=np.sort(rng.integers(0, 900, (40, 2)), axis=1), dof=rng.integers(-1, 60, 40),
                 sign=rng.choice([-1, 1], 40), globals={(4, 101, 0): 61, (5, 101, 0): 62, (4, 102, 1): 63},
                 n_dofs=64, system=1)
    b = EdgeDofs.from_arrays({k: np.array(v) for k, v in a.to_arrays().items()})
    for k in ("edges", "dof", "sign"):
        assert np.array_equal(getattr(b, k), getattr(a, k)) and getattr(b, k).dtype == np.int64, k
    assert b.globals == a.globals and (b.n_dofs, b.system) == (64, 1)
