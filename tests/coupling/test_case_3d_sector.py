"""The coupled 3D case file (issue 20, case (a); issue 29: on the general 3D geometry-file path): ``pulseform run
cases/emf_sheet_bulge_3d`` (a gmsh builder of its folder, sector_geometry.py) on a coarse, short sector through the
driver (history, metrics under the 2D names, XDMF and VTU fields, pictures, checkpoints), a stop signal then
``--resume`` equal to the uninterrupted run, a sweep of it, and what a user of the sector's geometry file can get
wrong (one line, exit 2).

References: (1) resume = the uninterrupted run bitwise: the checkpoint sits on an EM-step boundary and
carries the EM state's doubles exactly (x_n written back in 17 digits); (2) the run's device metrics
are the sector's times the symmetry factor 360 / angle (read from the mesh's angular extent, to round-off; the
history's sector columns), and GetDP's force at the end of each step vs the loop's held force; (3) the slow
comparison with the axisymmetric run is in tests/coupling/test_coupled_3d_sector.py.
"""

from __future__ import annotations

import csv
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import meshio
import numpy as np
import pytest

from pulseform.orchestrator.cli import main

from .bad_input import one_line_refusal
from .sector_case import CASE as CASE_DIR, COARSE as COARSE_SETS, MESH, REPO, planes, sets
from warm_cli import pulseform_cli

EXE = str(Path(sys.executable).with_name("pulseform"))
CASE = str(CASE_DIR)
#: a coarse 5 degree sector (11.7k EM tets, 1.8k sheet tets), 3 µs: 9 EM steps, ~10 s
COARSE = sets(COARSE_SETS)
TIMERS = ("load_time_s", "mech_time_s", "setup_time_s", "wall_time_s", "em_time_s")


@pytest.fixture(scope="module")
def coarse_run(sector_compare) -> Path:
    """The coarse sector's ``pulseform run CASE --quiet *COARSE``: the coupled run of the session's
    ``pulseform compare`` (tests/conftest.py; the same command plus --force), complete (the compare exits 1
    only for its --fail-if condition that holds, after both runs)."""
    out, _, r = sector_compare
    assert r.returncode == 1 and "--fail-if wall_time_coupled_s>0.001 holds" in r.stderr, r.stderr[-3000:]
    assert "Traceback" not in r.stderr
    return out / "coupled"


@pytest.mark.getdp
def test_coupled_3d_case_runs_through_the_driver(coarse_run):
    out = coarse_run
    m = json.loads((out / "metrics.json").read_text())
    rows = list(csv.DictReader(open(out / "history.csv")))
    col = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    s = m["symmetry_factor"]   # 360 deg over the mesh's angular extent about the planes' common line
    assert s == pytest.approx(72.0, rel=1e-12) and m["status"] == "ok" and m["em_steps"] == 9
    # the 2D demo's metric names, the device's values = the sector's x 360/5
    for k in ("force_impulse_z_Ns", "force_peak_N", "coil_current_peak_kA",
              "conservation_error_rel", "plastic_work_J", "sheet_max_uz_mm"):
        assert k in m, k
    assert m["force_impulse_z_Ns"] == pytest.approx(s * m["sector_force_impulse_z_Ns"], rel=1e-15)
    assert m["sheet_max_uz_mm"] > 0   # the deflection (the sheet's largest |u_z|)
    # history.csv holds 10 significant digits
    assert m["force_peak_N"] == pytest.approx(s * np.abs(col["getdp_force_z_N"]).max(), rel=1e-9)
    # the impulse column: the device's Σ s ∫f_z dV dt of the held (BDF2 trapezoid) force = the loop's Σ F dt
    # of the nodal forces (equal up to the ledger, 1e-15)
    assert col["device_impulse_z_Ns"][-1] == pytest.approx(m["force_impulse_z_Ns"], rel=1e-9)
    assert m["conservation_error_rel"] < 1e-12
    assert col["capacitor_voltage_V"][0] == 6000.0 and col["force_z_N"][0] == 0.0
    # fields: the sheet's XDMF (3D tetrahedra) at the output times, the force density per tetrahedron
    xdmf = out / "fields" / "emf_sheet_bulge_3d_sheet.xdmf"
    with meshio.xdmf.TimeSeriesReader(xdmf) as reader:
        points, cells = reader.read_points_cells()
        times = [reader.read_data(k)[0] for k in range(reader.num_steps)]
    assert cells[0].type == "tetra" and points.shape[1] == 3
    assert np.allclose(times, [0.0, 1e-6, 2e-6, 3e-6], rtol=0, atol=1e-15)
    vtus = sorted((out / "fields" / "em3d").glob("sheet_em_*.vtu"))
    assert len(vtus) == 3 and (out / "fields" / "em3d" / "sheet_em.pvd").is_file()
    last = meshio.read(vtus[-1])
    f = last.cell_data["force_density_N_m3"][0]
    assert last.cells[0].type == "tetra" and len(f) == len(cells[0].data)
    peak = json.loads((out / "fields" / "em3d" / "em_peak_current.json").read_text())
    assert abs(peak["coil_current_A"]) == pytest.approx(1e3 * m["coil_current_peak_kA"], rel=1e-9)
    for name in ("em3d_force_density_peak_current.png", "deformed_von_mises.png", "deformed_plastic_strain.png",
                 "coil_current_A.png", "device_force_z_N.png"):
        assert (out / "plots" / name).is_file(), name


# slow (a repeated end-to-end run; covered in the default tier by the same SIGINT/--resume bitwise check of a 3D
# coupled case through the CLI:
# test_case_racetrack_remesh.py::test_sigint_after_the_remesh_then_resume_equals_the_uninterrupted_run; the 3D
# loop's checkpoint/resume: test_loop_fake3d.py)
def _interrupt_then_resume(out: Path, extra: list[str]) -> tuple[dict, dict]:
    """SIGINT the coarse run once its first checkpoint exists (the signal lands in some EM step, most often
    between output times), then ``--resume``; returns (the stopped run's, the resumed run's) metrics."""
    argv = [EXE, "run", CASE, "--out", str(out), "--quiet", *COARSE, "--set", "output.plots=false", *extra]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 300
    while not (out / "checkpoint.npz").exists():   # past the first output time (3 steps)
        assert proc.poll() is None and time.time() < deadline, proc.stderr.read() if proc.poll() is not None else ""
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "continue with --resume" in lines[0], err
    cut = json.loads((out / "metrics.json").read_text())
    assert cut["status"] == "interrupted" and 0 < cut["end_time_s"] < 3e-6
    r = subprocess.run(argv + ["--resume"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    return cut, json.loads((out / "metrics.json").read_text())


def _compared(ref: dict) -> list[str]:
    return [k for k in ref if k not in TIMERS and not k.startswith(("em_getdp", "em_mesh", "em_transfer", "em_res"))
            and k != "status"]


def _resumed_equals_bitwise(ref_dir: Path, out: Path, extra: list[str]) -> dict:
    """:func:`_interrupt_then_resume` into ``out``; every compared metric and the whole history equal the
    uninterrupted run's in ``ref_dir`` bit for bit. Returns the resumed run's metrics."""
    ref = json.loads((ref_dir / "metrics.json").read_text())
    cut, got = _interrupt_then_resume(out, extra)
    print(f"\ninterrupted at {cut['end_time_s']:.3g} s; resumed: deflection {got['sheet_max_uz_mm']!r} vs "
          f"{ref['sheet_max_uz_mm']!r} mm, impulse {got['force_impulse_z_Ns']!r} vs {ref['force_impulse_z_Ns']!r}")
    for k in _compared(ref):
        assert got[k] == ref[k], k   # bitwise
    h_ref = np.loadtxt(ref_dir / "history.csv", delimiter=",", skiprows=1)
    h_got = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1)
    assert h_got.shape == h_ref.shape and np.array_equal(h_got, h_ref)
    return got


@pytest.mark.slow
@pytest.mark.getdp
def test_sigint_then_resume_equals_the_uninterrupted_run(tmp_path):
    """With a factorisation per EM step (em.factor_reuse_tol = 0) the resumed run is the uninterrupted one bit
    for bit (reference (1)): every metric and the whole history."""
    fresh = ["--set", "em.factor_reuse_tol=0"]
    ref_dir = tmp_path / "ref"
    assert main(["run", CASE, "--out", str(ref_dir), "--quiet", *COARSE, "--set", "output.plots=false", *fresh]) == 0
    _resumed_equals_bitwise(ref_dir, tmp_path / "cut", fresh)


@pytest.mark.slow
@pytest.mark.getdp
def test_sigint_then_resume_with_kept_factors_equals_the_uninterrupted_run(coarse_run, tmp_path):
    """With kept LU factors (the default) a resume from a stop between output times is the uninterrupted run
    bit for bit too: the stop's checkpoint records which factors the next EM step uses (the nodes and gamma dt of
    the step that factorised: FactorRecord), and the resumed process rebuilds them before its first step
    (docs/getdp.md, Kept factors) -- every metric and the whole history. (Until issue 31's factor records the
    step after a stop between outputs factorised in the resumed run only: the two agreed to 6.3e-9.)"""
    got = _resumed_equals_bitwise(coarse_run, tmp_path / "cut", [])
    assert got["status"] == "ok"


# slow (a repeated end-to-end run; covered in the default tier by `pulseform sweep` of a 3D case file:
# tests/foundation/test_sweep.py::test_sweep_of_a_3d_case_plots_its_physics; the coarse sector through the driver:
# test_coupled_3d_case_runs_through_the_driver)
@pytest.mark.slow
@pytest.mark.getdp
def test_sweep_of_the_3d_case(tmp_path):
    """Two members (the bank charged to 3 kV and 6 kV) of the coarse sector: both run and sweep.csv holds
    the device metrics. Reference: the eddy-current problem is linear in the bank voltage on a fixed
    geometry, the force quadratic: over 3 µs the sheet moves ~1e-7 m against a 1.5 mm gap, so the
    impulse ratio is (3/6)² = 0.25 and the peak-current ratio 1/2 to far better than 1e-3 (1e-4 held)."""
    out = tmp_path / "sw"
    r = pulseform_cli(["sweep", CASE, "--out", str(out), "--jobs", "1", "--param",
                       "em.circuit.voltage=3000.0,6000.0", *COARSE, "--set", "output.plots=false"])
    assert r.returncode == 0, r.stderr[-3000:]
    rows = {row["em.circuit.voltage"]: row for row in csv.DictReader(open(out / "sweep.csv"))}
    a, b = (float(rows[k]["force_impulse_z_Ns"]) for k in ("3000.0", "6000.0"))
    ia, ib = (float(rows[k]["coil_current_peak_kA"]) for k in ("3000.0", "6000.0"))
    print(f"\nimpulse (device): 3 kV {a:.6g}, 6 kV {b:.6g} N s, ratio {a / b:.6f} (0.25); peak current ratio "
          f"{ia / ib:.6f} (0.5)")
    assert abs(a / b - 0.25) < 1e-3 and abs(ia / ib - 0.5) < 1e-4   # motion: ~1e-7 m / 1.5 mm
    assert all(float(rows[k]["sheet_max_uz_mm"]) > 0 for k in ("3000.0", "6000.0"))


BAD = [  # (--set overrides, text the one line must hold): what a user of the sector's geometry file can get wrong
    (["geometry.parameters.angle_deg=0.0"], "angle_deg must lie in (0, 180)"),   # the builder refuses
    (["geometry.parameters.angle_deg=180.0"], "angle_deg must lie in (0, 180)"),
    (["geometry.parameters.angle_deg=-5.0"], "angle_deg must lie in (0, 180)"),
    (["geometry.parameters.sheet_layer=2"], "unknown parameter 'sheet_layer'"),
    # the clamp beyond the sheet's rim (the old sector.clamp_rmin >= sheet radius): a box that holds no node
    (["bodies.sheet.fixed=[{where={rmin=0.07}, components=[0, 1, 2]}]"], "bodies[0].fixed[0].where"),
    (["bodies.sheet.fixed=[{where={rmin=0.05}, components=[3]}]"], "bodies[0].fixed[0].components"),
    (["mechanics.thickness=1.0"], "mechanics.thickness"),
    # one meridian plane only: the sheet then touches the outer boundary of the air; a second plane at another
    # angle than the builder's: no boundary face lies on it (refused as such since the field-shaper case's check)
    (["symmetry=[{normal=[0.0, 1.0, 0.0]}]"], "bodies[0].region"),
    ([planes(15.0)], "symmetry[1]: the plane"),
    (["geometry.die={cavity_radius=0.04, cavity_depth=0.01, outer_radius=0.06, height=0.02, gap=1e-4, "
      "mesh_size=2e-3}"], "geometry.die"),
    (["bodies.sheet.region=\"die\""], "bodies[0].region"),
    (["limits.max_cells=1e4"], "limits.max_cells"),
    (["geometry.on_mesh_break=\"refine\""], "geometry.on_mesh_break"),
    (["geometry.break_quality=1.5"], "geometry.break_quality"),
    (["coupling.load=\"pressure\""], "loads"),
]


@pytest.mark.parametrize("sets_,says", BAD, ids=[s[0].split("=")[0] + f"[{i}]" for i, (s, _) in enumerate(BAD)])
def test_bad_input_of_a_coupled_3d_case(capsys, sets_, says):
    print(one_line_refusal(capsys, CASE, MESH + sets_, says))


@pytest.mark.getdp
def test_too_many_em_steps_are_refused_before_the_first_step(tmp_path):
    """limits.max_em_steps below the run's EM steps (60 us / 0.45 us: 133): one line naming time.end, exit 2,
    found once the mesh's stable step is known (before any getdp run)."""
    r = pulseform_cli(["run", CASE, "--out", str(tmp_path / "x"), "--quiet", *sets(MESH),
                       "--set", "limits.max_em_steps=100"])
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1 and "limits.max_em_steps" in lines[0], r.stderr
    assert not (tmp_path / "x" / "em" / "getdp").exists() or not any((tmp_path / "x" / "em" / "getdp").iterdir())


def test_a_sector_mesh_too_large_for_the_memory_is_refused(tmp_path):
    """The memory guard after meshing (orchestrator/mesh/geometry3d.map_roles, orchestrator/case/memory.py): the
    coarse sector's mesh is refused in one line naming the key when the machine has one byte less than a run of
    it needs, and accepted with exactly that much."""
    from pulseform.orchestrator.case.io import load_case
    from pulseform.orchestrator.case.memory import memory_needed
    from pulseform.orchestrator.mesh.geometry3d import GeometryError, map_roles, mesh_file3d, plane_specs, read_groups

    case, _ = load_case(CASE, MESH)
    g = case.geometry
    raw = read_groups(mesh_file3d(g, tmp_path), "sector_geometry.py")
    need = memory_needed(len(raw.tets))
    args = (raw, g, [("bodies[0].region", "sheet")], plane_specs(case.symmetry), tmp_path / "em3d.msh", 72.0,
            "sector_geometry.py")
    with pytest.raises(GeometryError, match="GB are available") as e:
        map_roles(*args, available=need - 1.0)
    assert str(e.value).startswith("sector_geometry.py: geometry.mesh_sizes:")
    print(f"\n{len(raw.tets)} tetrahedra need ~{need / 1e9:.3g} GB: {e.value}")
    assert map_roles(*args, available=need).mesh.n_tets == len(raw.tets)


@pytest.mark.parametrize("sets,says", [(["geometry.parameters={angle_deg=5.0}"], "geometry.parameters"),
                                       (["mechanics.formulation=\"3d\""], "geometry.type")])
def test_3d_keys_refused_in_the_2d_demo_and_the_reverse(capsys, sets, says):
    args = ["check", str(REPO / "cases/emf_sheet_bulge")]
    for s in sets:
        args += ["--set", s]
    rc = main(args)
    _, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and says in lines[0], err
    print(lines[0])
