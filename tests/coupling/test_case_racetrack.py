"""The racetrack case file (issue 20, case (b)): ``pulseform run cases/emf_racetrack_groove`` through the
driver on a coarse, short run (sizes x 2 as tests/coupling/test_coupled_racetrack.py, 3 µs), a stop signal
then ``--resume``, the bad inputs of a racetrack case (one line, exit 2) and, slow, the whole case against
the study's reference run.

References: (1) the conservation ledgers (Σ nodal forces vs Σ f V, per body and in total) are exact by
construction: round-off; (2) an independent computation: the fixed-mesh 3D EM solve of the same model,
mesh and steps (``solve_transient3d``, BDF2, one getdp process): in 3 µs the sheet moves ~1e-7 m against a
1 mm gap, so the coupled run's coil current and GetDP's per-body forces must equal it to far better than
1e-3; (3) Newton, until the clamp reacts (~3 µs of wave travel): the sheet's momentum = the impulse of the
held forces on its free nodes (RacetrackRecorder); (4) resume = the uninterrupted run bitwise (the
checkpoint sits on an EM-step boundary and carries every double); (5) the slow test: the case run against
studies/emf_racetrack_groove/reference/racetrack_metrics.json (run_racetrack on the same model and mesh).
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
from .resume_check import assert_racetrack_outputs_bitwise

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))
CASE = str(REPO / "cases/emf_racetrack_groove")
#: the coarse mesh of the study's tests (RACETRACK.scaled(2): 8.2k EM tets, sheet 1.6k, die 0.6k), 3 µs:
#: 3 EM steps of 27 mechanical steps, ~15 s
COARSE = ["--set", "racetrack.mesh_size_sheet=4e-3", "--set", "racetrack.sheet_layers=2",
          "--set", "racetrack.mesh_size_coil=6e-3", "--set", "racetrack.mesh_size_die=8e-3",
          "--set", "time.end=3e-6", "--set", "output.field_interval=1e-6"]


def _run(out: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, "run", CASE, "--out", str(out), "--quiet", *COARSE, *extra],
                          capture_output=True, text=True)


@pytest.fixture(scope="module")
def coarse_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("racetrack_case") / "run"
    r = _run(out)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


def _history(out: Path) -> dict[str, np.ndarray]:
    rows = list(csv.DictReader(open(out / "history.csv")))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


@pytest.mark.getdp
def test_racetrack_case_runs_through_the_driver(coarse_run, tmp_path):
    from pulseform.orchestrator.case.io import load_resolved_case
    from pulseform.orchestrator.run.racetrack_case import racetrack_options
    from pulseform.orchestrator.run.racetrack_design import em_model
    from pulseform.solvers.getdp.mesh3d import read_msh22_tets
    from pulseform.solvers.getdp.racetrack_mesh import racetrack_groove_mesh
    from pulseform.solvers.getdp.solver3d import solve_transient3d

    out = coarse_run
    m = json.loads((out / "metrics.json").read_text())
    h = _history(out)
    assert m["status"] == "ok" and m["em_steps"] == 3 and m["symmetry_factor"] == 4.0
    assert (m["em_tets"], m["sheet_tets"], m["die_tets"]) == (8214, 1620, 628)   # the study's coarse mesh
    # (1) ledgers at round-off; the bodies' nodal forces add up to the loop's resultant
    assert max(m["conservation_error_rel"], m["sheet_ledger_rel"], m["die_ledger_rel"]) < 1e-12
    np.testing.assert_allclose(h["sheet_force_z_N"][1:] + h["die_force_z_N"][1:], h["force_z_N"][1:], rtol=1e-9)
    # the device's figures: the quarter's x 4, two bookkeepings of the same impulse (load and loop)
    assert m["force_impulse_z_Ns"] == pytest.approx(4 * m["sector_force_impulse_z_Ns"], rel=1e-15)
    assert m["impulse_device_z_Ns"] == pytest.approx(m["force_impulse_z_Ns"], rel=1e-12)
    assert h["device_impulse_z_Ns"][-1] == pytest.approx(m["force_impulse_z_Ns"], rel=1e-9)
    assert m["max_deflection_mm"] == m["max_deflection_into_groove_mm"] > 0
    assert h["capacitor_voltage_V"][0] == 2500.0 and h["force_z_N"][0] == 0.0
    # (3) Newton on the sheet until the clamp reacts
    assert m["sheet_momentum_vs_impulse_rel"] < 1e-3
    # (2) the fixed-mesh solve of the same model and mesh (re-meshed: the same nodes, checked)
    opt = racetrack_options(load_resolved_case(out / "case.toml"))
    mesh = racetrack_groove_mesh(tmp_path / "fixed.msh", opt.geometry)
    assert np.array_equal(read_msh22_tets(out / "em" / "racetrack.msh")[0], mesh.points)
    ref = solve_transient3d(em_model(opt.geometry, opt.bank, sigma=opt.sigma), mesh, 3e-6, 3, tmp_path / "fixed",
                            time_scheme="bdf2", element_output="none")
    i_ref = ref.coil_current[:, 0]
    err_i = np.abs(h["coil_current_A"][1:] - i_ref).max() / np.abs(i_ref).max()
    errs = {n: np.abs(h[f"{n}_getdp_force_z_N"][1:] - ref.conductor_force[:, k, 2]).max()
            / np.abs(ref.conductor_force[:, k, 2]).max() for k, n in enumerate(("sheet", "die"))}
    print(f"\ncoarse racetrack case, 3 us: coil current vs fixed-mesh solve {err_i:.1e}, GetDP forces sheet "
          f"{errs['sheet']:.1e}, die {errs['die']:.1e}; ledger {m['conservation_error_rel']:.1e}; sheet momentum vs "
          f"free impulse {m['sheet_momentum_vs_impulse_rel']:.1e}; peak current {m['coil_current_peak_kA']:.4g} kA")
    assert err_i < 1e-4 and errs["sheet"] < 1e-3 and errs["die"] < 1e-3
    # outputs: both bodies' XDMF at the output times, the sheet's force density per tetrahedron, the peak
    # snapshot of both bodies, the racetrack's pictures and the history plots
    for body in ("sheet", "die"):
        with meshio.xdmf.TimeSeriesReader(out / "fields" / f"emf_racetrack_groove_{body}.xdmf") as reader:
            _, cells = reader.read_points_cells()
            times = [reader.read_data(k)[0] for k in range(reader.num_steps)]
        assert cells[0].type == "tetra" and len(cells[0].data) == m[f"{body}_tets"]
        assert np.allclose(times, [0.0, 1e-6, 2e-6, 3e-6], rtol=0, atol=1e-15)
    assert len(sorted((out / "fields" / "em3d").glob("sheet_em_*.vtu"))) == 3
    peak = meshio.read(out / "em" / "force_density_peak.vtu")
    assert sorted(np.unique(peak.cell_data["body_0sheet_1die"][0])) == [0.0, 1.0]
    assert len(peak.cells[0].data) == m["sheet_tets"] + m["die_tets"]
    for name in ("section_y0_von_mises.png", "force_density_peak.png", "coil_current_A.png", "energies.png",
                 "sheet_max_draw_m.png"):
        assert (out / "plots" / name).stat().st_size > 10_000, name


@pytest.mark.getdp
def test_sigint_then_resume_equals_the_uninterrupted_run(coarse_run, tmp_path):
    ref = json.loads((coarse_run / "metrics.json").read_text())
    out = tmp_path / "cut"
    proc = subprocess.Popen([EXE, "run", CASE, "--out", str(out), "--quiet", *COARSE, "--set", "output.plots=false"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 300
    while not (out / "checkpoint.npz").exists():   # past the first output time (1 EM step)
        assert proc.poll() is None and time.time() < deadline, proc.stderr.read() if proc.poll() is not None else ""
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    cut = json.loads((out / "metrics.json").read_text())
    assert cut["status"] == "interrupted" and 0 < cut["end_time_s"] < 3e-6
    r = _run(out, "--set", "output.plots=false", "--resume")
    assert r.returncode == 0, r.stderr[-3000:]
    got = json.loads((out / "metrics.json").read_text())
    print(f"\ninterrupted at {cut['end_time_s']:.3g} s; resumed: draw {got['max_deflection_into_groove_mm']!r} vs "
          f"{ref['max_deflection_into_groove_mm']!r} mm, impulse {got['impulse_device_z_Ns']!r} vs "
          f"{ref['impulse_device_z_Ns']!r} N s")
    assert_racetrack_outputs_bitwise(coarse_run, out)


BAD = [  # (--set overrides, text the one line must hold)
    (["racetrack.sheet_half_x=0.0"], "racetrack.sheet_half_x"),
    (["racetrack.turn_width=-3e-3"], "racetrack.turn_width"),
    (["racetrack.sheet_layers=0"], "racetrack.sheet_layers"),
    (["racetrack.sheet_half_x=0.015"], "racetrack.sheet_half_x"),        # the coil sticks out
    (["racetrack.groove_x1=0.036"], "wider than the sheet"),
    (["racetrack.coil_gap=0.0"], "racetrack.coil_gap"),                 # the coil would touch the sheet
    (["racetrack.coil_gap=-1e-3"], "racetrack.coil_gap"),
    (["racetrack.groove_depth=0.02"], "racetrack.groove_depth"),
    (["racetrack.air_radius=0.05"], "racetrack.air_radius"),
    (["racetrack.on_mesh_break=\"explode\""], "racetrack.on_mesh_break"),
    (["racetrack.mesh_size_sheet=0.05e-3"], "racetrack.mesh_size_sheet"),
    (["limits.max_em_steps=10"], "racetrack.em_step"),
    (["coupling.n=20"], "coupling.n"),
    (["em.getdp_process=\"per_step\""], "em.getdp_process"),
    (["em.remesh_quality=0.2"], "em.remesh_quality"),
    (["sector.angle_deg=5.0"], "sector"),
    (["geometry.type=\"flat_coil_sheet\""], "geometry"),
    (["symmetry=[{normal=[0.0, 1.0, 0.0]}]"], "symmetry"),
    (["bodies.sheet.fixed=[{where={xmin=0.03}}]"], "bodies[0].fixed"),
    (["bodies.die.rigid=true"], "bodies[1].rigid"),
    (["contact=[]"], "contact"),
    (["materials.tool_steel.electrical_conductivity=0.0"], "materials.tool_steel.electrical_conductivity"),
    (["em.current={amplitude=1e4, beta=1e3, omega=1e5}"], "em.current"),
    (["mechanics.formulation=\"axisymmetric\""], "racetrack"),
    (["racetrack.em_order=2"], "racetrack.on_mesh_break"),
    (["racetrack.em_order=3"], "racetrack.em_order"),
]


@pytest.mark.parametrize("sets,says", BAD, ids=[s[0].split("=")[0] + f"[{i}]" for i, (s, _) in enumerate(BAD)])
def test_bad_input_of_the_racetrack_case(capsys, sets, says):
    print(one_line_refusal(capsys, CASE, sets, says))


def test_the_racetrack_table_is_refused_in_the_2d_demo(capsys):
    rc = main(["check", str(REPO / "cases/emf_sheet_bulge"), "--set", "racetrack.turns=3"])
    _, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and "racetrack" in lines[0] and "remove [racetrack]" in lines[0], err


def test_a_racetrack_mesh_too_large_for_the_memory_is_refused_before_meshing():
    """The design mesh (gmsh: 26275 EM tets, the sheet 8910; metrics of the reference run) and the coarse
    one (8214 and 1620, the test above) are estimated below what gmsh makes (lower estimates: the guard
    must not refuse a mesh that fits) and above 0.3 of it (the coarse mesh's graded air is most of its
    tetrahedra: 0.36 of it estimated, the design's 0.70); the design is refused on a machine with 0.3 GB
    available, in one line naming the key."""
    from dataclasses import replace

    from pulseform.orchestrator.case.io import load_case
    from pulseform.orchestrator.case.racetrack3d import check_racetrack_resources, estimated_racetrack_tets
    from pulseform.orchestrator.case.schema import SchemaError

    case, _ = load_case(CASE)
    rt = case.racetrack
    coarse = replace(rt, mesh_size_sheet=4e-3, sheet_layers=2, mesh_size_coil=6e-3, mesh_size_die=8e-3)
    for r, (tets_gmsh, sheet_gmsh) in ((rt, (26275, 8910)), (coarse, (8214, 1620))):
        tets, sheet = estimated_racetrack_tets(r)
        print(f"\nestimate {tets:.0f} EM tets (gmsh {tets_gmsh}), sheet {sheet:.0f} (gmsh {sheet_gmsh})")
        assert 0.3 * tets_gmsh < tets < tets_gmsh and 0.5 * sheet_gmsh < sheet < sheet_gmsh
    with pytest.raises(SchemaError, match="GB available") as e:
        check_racetrack_resources(case, available=0.3e9)
    assert e.value.path == "racetrack.mesh_size_sheet"


#: figures of the slow comparison: the study's metric names (run_racetrack on the same model and mesh)
REFERENCE_KEYS = ("max_deflection_into_groove_mm", "sheet_min_uz_mm", "die_max_displacement_mm", "impulse_device_z_Ns",
                  "sheet_impulse_device_z_Ns", "die_impulse_device_z_Ns", "force_peak_device_z_N",
                  "die_force_peak_device_z_N", "coil_current_peak_kA", "t_peak_current_s", "contact_pressure_peak_Pa",
                  "first_contact_s", "max_sheet_speed_m_s", "sheet_momentum_vs_impulse_rel", "plastic_work_device_J",
                  "external_work_device_J", "em_mesh_frozen_at_s", "impulse_after_freeze_device_z_Ns")


@pytest.mark.slow
@pytest.mark.getdp
def test_the_case_reproduces_the_study_reference(tmp_path):
    """``pulseform run cases/emf_racetrack_groove`` (60 µs, the design mesh: ~4-7 min) against
    studies/emf_racetrack_groove/reference/racetrack_metrics.json, the same model and mesh run from Python
    (run_racetrack): the case's defaults are that design and the driver lands its EM steps on the same
    output times (every 10 µs), so the runs are the same to round-off (observed: <= 3e-13 relative, same
    EM and mechanical step counts, the EM mesh frozen at the same step)."""
    ref = json.loads((REPO / "studies/emf_racetrack_groove/reference/racetrack_metrics.json").read_text())
    out = tmp_path / "run"
    r = subprocess.run([EXE, "run", CASE, "--out", str(out), "--quiet", "--set", "output.plots=false"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads((out / "metrics.json").read_text())
    print("\n" + "\n".join(f"{k:36s} {m.get(k)!r:>24} {ref.get(k)!r:>24}" for k in REFERENCE_KEYS))
    for k in ("em_steps", "mech_steps", "n", "em_tets", "sheet_tets", "die_tets"):
        assert m[k] == ref[k], k
    for k in REFERENCE_KEYS:
        if k not in ref:   # a figure of a frozen EM mesh (the impulse after the freeze): neither run froze
            assert k not in m, k
            continue
        # the time of a freeze is NaN in both when neither froze (the study's json writes NaN, the case's null)
        got = float("nan") if m[k] is None else m[k]
        assert got == pytest.approx(ref[k], rel=1e-9, nan_ok=True), k
    assert max(m["conservation_error_rel"], m["sheet_ledger_rel"], m["die_ledger_rel"]) < 1e-12


def test_the_observer_state_round_trips_with_a_frozen_em_mesh():
    """A checkpoint after the EM mesh froze (a 3 µs test run never freezes: the design's freezes at 36 µs)
    restores the frozen mesh, its time and reason, the recorder's rows, sums and peak snapshot exactly
    (reference: the state written, array for array)."""
    from types import SimpleNamespace

    from pulseform.orchestrator.run.racetrack_case import RacetrackObserver

    rng = np.random.default_rng(7)

    def observer():
        load = SimpleNamespace(frozen_at=None, freeze_reason="", _last_valid=np.zeros((5, 3)))
        rm = SimpleNamespace(clamped={"sheet": np.zeros(4, bool), "die": np.zeros(3, bool)}, load=load, solver=None)
        return RacetrackObserver(rm, None, 42, Path("."))

    a = observer()
    a.rm.load.frozen_at, a.rm.load.freeze_reason = 3.6e-5, "tetrahedron 7 inverted"
    a.rm.load._last_valid = rng.random((5, 3))
    rec = a.rec
    rec.rows = [{"time_s": 1e-6 * k, "force_z_N": rng.random(), "em_mesh_frozen": float(k > 1)} for k in range(3)]
    rec.first_contact_s, rec.peak_current = 2e-6, 4.7e4
    for n in rec.impulse:
        rec.impulse[n], rec.clamp_impulse[n], rec.half_step[n] = rng.random(3), rng.random(3), rng.random(3)
    rec.peak = {"time_s": 2.2e-5, "points": rng.random((5, 3)), "tets": np.arange(8).reshape(2, 4),
                "force_density": rng.random((2, 3)), "coil_current_A": -4.7e4}
    state = a.state_dict()
    b = observer()
    b.load_state_dict({k: np.array(v) for k, v in state.items()})
    assert b.rm.load.frozen_at == 3.6e-5 and b.rm.load.freeze_reason == "tetrahedron 7 inverted"
    assert np.array_equal(b.rm.load._last_valid, a.rm.load._last_valid)
    assert b.rec.rows == rec.rows and (b.rec.first_contact_s, b.rec.peak_current) == (2e-6, 4.7e4)
    for n in rec.impulse:
        for what in ("impulse", "clamp_impulse", "half_step"):
            assert np.array_equal(getattr(b.rec, what)[n], getattr(rec, what)[n])
    assert b.rec.peak["time_s"] == 2.2e-5 and b.rec.peak["coil_current_A"] == -4.7e4
    for k in ("points", "tets", "force_density"):
        assert np.array_equal(b.rec.peak[k], rec.peak[k])


@pytest.mark.getdp
def test_the_case_with_second_order_edge_elements(coarse_run, tmp_path):
    """``racetrack.em_order = 2`` through the CLI (coarse mesh, 2 us, the air first order): GetDP's sheet and die
    forces equal a fixed-mesh order-2 solve of the same model and mesh (the sheet moves ~1e-7 m in 2 us), and
    they exceed the order-1 run's: order 1 underestimates the force on a coarse mesh (at the peak 35.8 vs 52.8 kN
    on the x 2 mesh, studies/emf_racetrack_groove/reference/em_convergence_order2.json), most at early times, when
    the skin depth (~0.25 mm at 2 us) is below the coarse sheet's layers (0.5 mm): 35 vs 313 N at 2 us here."""
    from dataclasses import replace

    from pulseform.orchestrator.case.io import load_resolved_case
    from pulseform.orchestrator.run.racetrack_case import racetrack_options
    from pulseform.orchestrator.run.racetrack_design import em_model
    from pulseform.solvers.getdp.racetrack_mesh import racetrack_groove_mesh
    from pulseform.solvers.getdp.solver3d import solve_transient3d

    out = tmp_path / "order2"
    r = _run(out, "--set", "racetrack.em_order=2", "--set", 'racetrack.on_mesh_break="freeze"',
             "--set", "time.end=2e-6", "--set", "output.plots=false")
    assert r.returncode == 0, r.stderr[-3000:]
    h, h1 = _history(out), _history(coarse_run)
    opt = racetrack_options(load_resolved_case(out / "case.toml"))
    assert opt.em_order == 2 and not opt.em_order2_air
    mesh = racetrack_groove_mesh(tmp_path / "fixed.msh", opt.geometry)
    model = replace(em_model(opt.geometry, opt.bank, sigma=opt.sigma), order=2, order2_air=False)
    ref = solve_transient3d(model, mesh, 2e-6, 2, tmp_path / "fixed", time_scheme="bdf2", element_output="none")
    for k, n in enumerate(("sheet", "die")):
        err = np.abs(h[f"{n}_getdp_force_z_N"][1:] - ref.conductor_force[:, k, 2]).max() \
            / np.abs(ref.conductor_force[:, k, 2]).max()
        ratio = h[f"{n}_getdp_force_z_N"][2] / h1[f"{n}_getdp_force_z_N"][2]
        print(f"\norder 2, {n}: GetDP force vs the fixed-mesh order-2 solve {err:.1e}; order 2 / order 1 at 2 us "
              f"{ratio:.4f}")
        assert err < 1e-3
        if n == "sheet":
            assert ratio > 1.05
