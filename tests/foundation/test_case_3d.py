"""3D cases from case files (issue 20, deliverable 5c): ``pulseform run cases/bar_impact_3d`` reproduces
the paper's section 4 bar impact on tetrahedra, and the 2D / 3D keys refuse each other in one line.

References: eq. (6) sigma = rho c v / 2 = 70 MPa with the 1D bar speed c = sqrt(E / rho) = 5000 m/s
and the relative speed 10 m/s; contact lasts 2 L / c = 1.6 ms (paper section 4). Tolerances as for
the 2D cases (tests/foundation/test_cases_bar.py) and the solver-level 3D test
(tests/mechanics/test_3d_bar_impact.py): 3 % and 4 %; energy balance within 1 %.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numba
import numpy as np
import pytest
from mpi4py import MPI

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.cli import main
from pulseform.solvers.dolfinx.verification import PAPER_BAR_MATERIAL as MAT
from warm_cli import pulseform_cli

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))
CASE = str(REPO / "cases/bar_impact_3d")
RHO_C_V_2_MPA = MAT.density * MAT.bar_wave_speed * 10.0 / 2.0 / 1e6   # 70.0 MPa
DURATION_MS = 2 * 4.0 / MAT.bar_wave_speed * 1e3                       # 1.6 ms


@pytest.fixture(scope="module")
def run3d(tmp_path_factory):
    out = tmp_path_factory.mktemp("bar3d") / "run"
    t0 = time.perf_counter()
    r = pulseform_cli(["run", CASE, "--out", str(out), "--quiet"])
    assert r.returncode == 0, r.stderr[-2000:]
    m = json.loads((out / "metrics.json").read_text())
    print(f"\n3D bar impact case (mesh_size 0.125 m): plateau {m['contact_stress_plateau_MPa']:.2f} MPa "
          f"vs {RHO_C_V_2_MPA:.2f}, duration {m['contact_duration_ms']:.4f} ms vs {DURATION_MS:.3f}, energy "
          f"error {m['energy_error_rel']:.2e}, {m['mech_steps']:.0f} steps, run {time.perf_counter() - t0:.1f} s")
    return out, m


def test_case_matches_the_paper(run3d):
    _, m = run3d
    assert m["contact_stress_plateau_MPa"] == pytest.approx(RHO_C_V_2_MPA, rel=0.03)
    assert m["contact_duration_ms"] == pytest.approx(DURATION_MS, rel=0.04)
    assert m["energy_error_rel"] < 0.01
    assert m["plastic_work_J"] == 0.0   # 70 MPa is below the 240 MPa yield
    assert m["status_ok"] == 1.0


# slow (a second end-to-end run of the 3D bar; its code is covered in the default tier: the two bars across the
# soft layer vs the paper and the wall run, tests/mechanics/test_3d_contact.py::test_two_bar_impact_3d_coarse; the
# 3D bar case through the CLI, test_case_matches_the_paper)
@pytest.mark.slow
def test_two_bodies_match_the_paper_and_the_wall(run3d, tmp_path):
    """The paper's own set-up, two bars across the soft layer of eq. (5) (node to triangle face):
    70 MPa +-3 %, 1.6 ms +-4 %, and the wall run's plateau within 2 % (the 2D cases' check,
    tests/foundation/test_cases_bar.py)."""
    out = tmp_path / "two"
    r = pulseform_cli(["run", str(REPO / "cases/bar_impact_3d/two_bodies.toml"), "--out", str(out),
                       "--quiet", "--set", "output.plots=false"])
    assert r.returncode == 0, r.stderr[-2000:]
    m = json.loads((out / "metrics.json").read_text())
    print(f"\n3D two bars: plateau {m['contact_stress_plateau_MPa']:.2f} MPa, duration "
          f"{m['contact_duration_ms']:.4f} ms, energy error {m['energy_error_rel']:.2e}")
    assert m["contact_stress_plateau_MPa"] == pytest.approx(RHO_C_V_2_MPA, rel=0.03)
    assert m["contact_duration_ms"] == pytest.approx(DURATION_MS, rel=0.04)
    assert m["energy_error_rel"] < 0.01
    assert run3d[1]["contact_stress_plateau_MPa"] == pytest.approx(m["contact_stress_plateau_MPa"], rel=0.02)


def test_outputs_are_3d(run3d):
    """history.csv carries the z displacement, the field file holds tetrahedra with (x, y, z)
    displacements, and the pictures include the deformed 3D surface."""
    out, _ = run3d
    h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    # quarter of the 4 m x 2 m x 2 m bar at 5 m/s: KE0 = 1/2 rho (4 x 1 x 1 m^3) v^2 = 140 kJ
    assert h["energy_kinetic_J"][0] == pytest.approx(0.5 * 2800 * 4.0 * 25.0, rel=1e-12)
    assert "bar_max_uz_m" in h.dtype.names
    import h5py

    with h5py.File(out / "fields/bar_impact_3d_bar.h5", "r") as f:
        assert f.attrs["formulation"] == "3d"
        assert f["Mesh/tetrahedra"].shape[1] == 4
        last = sorted(g for g in f if g.startswith("Step_"))[-1]
        u = f[last]["displacement_m"][...]
    assert np.abs(u[:, 2]).max() > 0.0            # Poisson expansion of the face: a 3D field
    assert np.abs(u[:, 1]).min() == 0.0           # nodes on the symmetry plane y = 0 stay on it
    pngs = {p.name for p in (out / "plots").glob("*.png")}
    assert {"energies.png", "wall_mid_wall_pressure_Pa.png", "deformed_von_mises.png"} <= pngs
    assert (out / "checkpoint.npz").is_file()


@pytest.mark.mpi
def test_two_ranks_match_serial(run3d, tmp_path):
    """``mpirun -n 2 pulseform run`` gives the serial metrics (the runs differ by summation order
    only; the 2D and solver-level bound 1e-10, tests/mechanics/test_3d_mpi.py)."""
    import shutil

    mpirun = shutil.which("mpirun")
    if mpirun is None:
        pytest.skip("mpirun not found")
    out = tmp_path / "mpi"
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    r = subprocess.run([mpirun, "-n", "2", EXE, "run", CASE, "--out", str(out), "--quiet", "--set",
                        "output.plots=false"], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr[-2000:]
    got = json.loads((out / "metrics.json").read_text())
    _, want = run3d
    for k, v in want.items():
        if isinstance(v, float) and (not k.endswith("_s") or k == "end_time_s"):
            assert got[k] == pytest.approx(v, rel=1e-10, abs=1e-300), k


# slow (a repeated end-to-end run; covered in the default tier by the 3D mechanics' restart, bitwise:
# tests/mechanics/test_3d_restart_output.py::test_restart_is_bitwise; SIGINT/--resume of a 3D case through the CLI:
# tests/coupling/test_case_racetrack_remesh.py::test_sigint_after_the_remesh_then_resume_equals_the_uninterrupted_run)
@pytest.mark.slow
def test_sigint_then_resume_equals_uninterrupted(tmp_path):
    """The 2D checkpoint machinery carries over: SIGINT after the first checkpoint, --resume, and
    every physics metric equals the uninterrupted run's (coarse 0.25 m mesh)."""
    coarse = ["--set", "bodies.bar.mesh_size=0.25", "--set", "output.plots=false", "--quiet"]
    ref = tmp_path / "ref"
    subprocess.run([EXE, "run", CASE, "--out", str(ref), *coarse], check=True, capture_output=True)
    out = tmp_path / "int"
    args = [EXE, "run", CASE, "--out", str(out), *coarse]
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while not (out / "checkpoint.npz").exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.005)
    proc.send_signal(signal.SIGINT)
    proc.wait()
    if (out / "metrics.json").exists() and json.loads((out / "metrics.json").read_text()).get("status_ok") == 1.0:
        pytest.skip("the run finished before it could be interrupted")
    r = subprocess.run(args + ["--resume"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    got = json.loads((out / "metrics.json").read_text())
    want = json.loads((ref / "metrics.json").read_text())
    for k in [k for k in want if not k.endswith("_s") or k == "end_time_s"]:
        assert got[k] == pytest.approx(want[k], rel=1e-12, abs=1e-300), k
    assert "resumed at" in (out / "run.log").read_text()


def test_shipped_3d_case_checks():
    case, _ = load_case(CASE)
    assert case.mechanics.formulation == "3d"


@pytest.mark.skipif(min(os.cpu_count() or 1, numba.config.NUMBA_NUM_THREADS) < 2, reason="one core")
def test_threads_reach_the_3d_solver():
    """``mechanics.threads`` of a 3D case is the 3D solver's (issue 31), as in 2D."""
    from pulseform.orchestrator.mech.model import build_solver

    case, _ = load_case(CASE, ["mechanics.threads=2", "bodies.bar.mesh_size=0.5"])
    solver = build_solver(case, MPI.COMM_SELF)
    assert solver.formulation == "3d" and solver.threads == 2


BAD = [  # (case, --set overrides, text the one line must hold)
    ("bar_impact_3d", ["mechanics.thickness=1.0"], "mechanics.thickness"),
    ("bar_impact_3d", ["mechanics.formulation=\"axisymmetric\""], "symmetry"),
    ("bar_impact_3d", ["bodies.bar.shape={type=\"rectangle\", width=4.0, height=1.0}"], "bodies[0].shape.type"),
    ("bar_impact_3d", ["bodies.bar.fixed=[{where={xmin=0.0, xmax=0.0}}]"], "bodies[0].fixed"),
    ("bar_impact_3d", ["walls[0].point=[4.005, 0.0]"], "walls[0].point"),
    ("bar_impact_3d", ["probes[0].point=[4.0, 0.0]"], "probes[0].point"),
    ("bar_impact_3d", ["bodies.bar.initial_velocity=[5.0, 0.0]"], "bodies[0].initial_velocity"),
    ("bar_impact_3d", ["symmetry[0].normal=[0.0, 0.0, 0.0]"], "symmetry[0].normal"),
    ("bar_impact_3d", ["case.kind=\"coupled\""], "geometry: missing required table"),  # coupled 3D: issue 20 (a)
    ("bar_impact_3d", ["symmetry[1].point=[0.0, 0.0, 0.5]"], "symmetry[1].point"),
    ("bar_impact_3d", ["limits.max_cells=1000"], "bodies[0].mesh_size"),
    ("bar_impact_wall", ["symmetry=[{normal=[0.0, 1.0, 0.0]}]"], "symmetry"),
    ("bar_impact_wall", ["bodies.bar.shape={type=\"box\", size=[4.0, 2.0, 1.0]}"], "bodies[0].shape.type"),
    ("bar_impact_wall", ["bodies.bar.initial_velocity=[5.0, 0.0, 0.0]"], "bodies[0].initial_velocity"),
    ("bar_impact_wall", ["walls[0].normal=[-1.0, 0.0, 0.0]"], "walls[0].normal"),
]


@pytest.mark.parametrize("case,sets,says", BAD, ids=[f"{c}:{s[0].split('=')[0]}" for c, s, _ in BAD])
def test_2d_and_3d_keys_refuse_each_other(capsys, case, sets, says):
    args = ["check", str(REPO / "cases" / case)]
    for s in sets:
        args += ["--set", s]
    rc = main(args)
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("pulseform: error: ") and "case.toml" in lines[0], lines[0]
    assert says in lines[0], lines[0]
    print(lines[0])


@pytest.mark.parametrize("shape,exact,rel", [
    ({"type": "box", "origin": [1.0, -2.0, 0.5], "size": [4.0, 1.0, 0.5]}, 2.0, 1e-12),
    # quarter of a cylinder r = 0.5 m, length 1 m: pi r^2 L / 4 = 0.19635 m^3; the faceted arc with
    # 0.05 m chords (angle 0.1 rad) loses (1 - sin(0.1) / 0.1) = 0.17 % of the area
    ({"type": "cylinder", "axis": [0.0, 0.0, 1.0], "radius": 0.5, "angle": np.pi / 2}, np.pi * 0.25 / 4, 3e-3),
], ids=["box", "quarter_cylinder"])
def test_solid_shapes_mesh_their_volume(shape, exact, rel):
    """gmsh's tetrahedra of a case shape fill its analytic volume (the cylinder up to its facets)
    and lie inside its bounds."""
    from pulseform.orchestrator.case.schema import convert
    from pulseform.orchestrator.case.parts import Shape
    from pulseform.orchestrator.mesh.solids import mesh_solid
    from pulseform.solvers.dolfinx.tet_fields import tet_volumes

    s = convert(Shape, shape, "shape")
    msh = mesh_solid(s, 0.05, name="solid")
    x = msh.geometry.x
    cells = msh.geometry.dofmap.array.reshape(-1, 4).astype(np.int32)
    vol = np.abs(tet_volumes(cells, x)).sum()
    print(f"\n{shape['type']}: {len(cells)} tets, volume {vol:.6f} m^3 vs {exact:.6f} ({vol / exact - 1:+.2e})")
    assert vol == pytest.approx(exact, rel=rel)
    assert vol <= exact * (1 + 1e-12)   # facets inside the curved surface, never outside
