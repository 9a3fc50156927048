"""The racetrack case file (issue 20, case (b)) on the general 3D geometry path (issue 29: ``[geometry] type =
"geometry_3d"``, the gmsh builder ``cases/emf_racetrack_groove/racetrack_geometry.py``): ``pulseform run
cases/emf_racetrack_groove`` through the driver on a coarse, short run (sizes x 2, 3 µs), a stop signal then
``--resume``, the bad inputs a user of the geometry path can give this case (one line, exit 2) and, slow, the
whole case against the study's reference run.

References: (1) the conservation ledgers (Σ nodal forces vs Σ f V, per body and in total) are exact by
construction: round-off; (2) an independent computation: the fixed-mesh 3D EM solve of the same model, mesh and
steps (``solve_transient3d``, BDF2, one getdp process; the model and mesh built from the case as the run builds
them: ``em_model3d`` on ``build_geometry3d``): in 3 µs the sheet moves ~1e-7 m against a 1 mm gap, so the coupled
run's coil current and GetDP's per-body forces must equal it to far better than 1e-3; (3) Newton, until the clamp
reacts (~3 µs of wave travel): the sheet's momentum (history ``sheet_momentum_z_Ns``) = the impulse of the held
forces on its free nodes, rebuilt here from the run's EM snapshots (``fields/em3d/sheet_em_*.vtu``, one per EM
step: the held force density of a BDF2 step is the trapezoid of its start and end values, f V / 4 on each node);
(4) resume = the uninterrupted run bitwise (the checkpoint sits on an EM-step boundary and carries every double);
(5) the slow test: the case run against studies/emf_racetrack_groove/reference/racetrack_metrics.json (the
study's own runner on the same model and mesh).
"""

from __future__ import annotations

import csv
import json
import math
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
from .resume_check import assert_coupled3d_outputs_bitwise
from warm_cli import pulseform_cli

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))
CASE = str(REPO / "cases/emf_racetrack_groove")
#: the coarse mesh of the study's tests (the design's sizes x 2: 8.2k EM tets, sheet 1.6k, die 0.6k), 3 µs:
#: 3 EM steps of 27 mechanical steps, ~15 s
COARSE_SIZES = ["--set", "geometry.parameters.h_sheet=4e-3", "--set", "geometry.parameters.sheet_layers=2",
                "--set", "geometry.parameters.h_coil=6e-3", "--set", "geometry.parameters.h_die=8e-3"]
COARSE = COARSE_SIZES + ["--set", "time.end=3e-6", "--set", "output.field_interval=1e-6"]
#: the sheet's clamp of case.toml (its [[bodies.fixed]] boxes): the nodes at x >= 35 mm or y >= 45 mm
CLAMP_X, CLAMP_Y = 35e-3, 45e-3


def _run(out: Path, *extra: str) -> subprocess.CompletedProcess:
    return pulseform_cli(["run", CASE, "--out", str(out), "--quiet", *COARSE, *extra])


@pytest.fixture(scope="module")
def coarse_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("racetrack_case") / "run"
    r = _run(out)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


def _history(out: Path) -> dict[str, np.ndarray]:
    rows = list(csv.DictReader(open(out / "history.csv")))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def _reference_solve(out: Path, work: Path, t_end: float, steps: int):
    """(case, EM model, fixed-mesh result): the run's model and mesh built again from its resolved case.toml
    (the builder meshes again: the same nodes as the run's ``em/em3d.msh``, checked), solved on the fixed mesh
    with ``steps`` BDF2 steps to ``t_end`` (s)."""
    from pulseform.orchestrator.case.io import load_resolved_case
    from pulseform.orchestrator.em.model3d import em_model3d
    from pulseform.orchestrator.mesh.geometry3d import build_geometry3d
    from pulseform.solvers.getdp.mesh3d import read_msh22_tets
    from pulseform.solvers.getdp.solver3d import solve_transient3d

    case = load_resolved_case(out / "case.toml")
    geo = build_geometry3d(case, work / "mesh")
    assert np.array_equal(read_msh22_tets(out / "em" / "em3d.msh")[0], geo.mesh.points)
    assert geo.conductors == {"sheet": 1, "die": 2}   # GetDP's conductor rows: the sheet, then the die
    model = em_model3d(case, geo)
    ref = solve_transient3d(model, geo.mesh, t_end, steps, work / "fixed", time_scheme="bdf2", element_output="none")
    return case, model, ref


def _tet_volumes(x: np.ndarray, tets: np.ndarray) -> np.ndarray:
    p = x[tets]
    return np.abs(np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])) / 6


def sheet_momentum_vs_free_impulse(out: Path, h: dict[str, np.ndarray]) -> tuple[float, float]:
    """Reference (3) of the module docstring: (largest |momentum / free impulse - 1| over the EM steps, largest
    |rebuilt held force / history's sheet_force_z_N - 1|). The held force of EM step k is f_held V / 4 on each
    node of every sheet tetrahedron, f_held = (f(t_{k-1}) + f(t_k)) / 2 (f(0) = 0: no current), f(t_k) the
    force density of the snapshot at the end of step k; the free impulse sums it over the nodes outside the
    clamp, times the step (dt x substeps), less half a mechanical step of the first force (the explicit scheme's
    first velocity update is a half step)."""
    snaps = sorted((out / "fields" / "em3d").glob("sheet_em_*.vtu"))
    assert len(snaps) == len(h["time_s"]) - 1   # one snapshot per EM step (outputs every 1 µs = every step)
    prev, free, first, mom_err, total_err = None, 0.0, None, 0.0, 0.0
    for k, path in enumerate(snaps, start=1):
        m = meshio.read(path)
        x, tets, f = m.points, m.cells[0].data, m.cell_data["force_density_N_m3"][0]
        held = 0.5 * f if prev is None else 0.5 * (prev + f)
        prev = f
        nodal = np.zeros(len(x))
        np.add.at(nodal, tets.ravel(), np.repeat(held[:, 2] * _tet_volumes(x, tets) / 4, 4))
        total_err = max(total_err, abs(nodal.sum() / h["sheet_force_z_N"][k] - 1))
        free_nodes = (x[:, 0] < CLAMP_X * (1 - 1e-9)) & (x[:, 1] < CLAMP_Y * (1 - 1e-9))
        f_free = float(nodal[free_nodes].sum())
        if first is None:
            first = 0.5 * h["dt_s"][k] * f_free
        free += h["dt_s"][k] * h["substeps"][k] * f_free
        mom_err = max(mom_err, abs(h["sheet_momentum_z_Ns"][k] / (free - first) - 1))
    return mom_err, total_err


@pytest.mark.getdp
def test_racetrack_case_runs_through_the_driver(coarse_run, tmp_path):
    out = coarse_run
    m = json.loads((out / "metrics.json").read_text())
    h = _history(out)
    assert m["status"] == "ok" and m["em_steps"] == 3 and m["symmetry_factor"] == 4.0
    assert (m["em_tets"], m["sheet_tets"], m["die_tets"]) == (8214, 1620, 628)   # the study's coarse mesh
    # (1) ledgers at round-off; the bodies' nodal forces add up to the loop's resultant
    assert max(m["conservation_error_rel"], m["sheet_ledger_rel"], m["die_ledger_rel"]) < 1e-12
    np.testing.assert_allclose(h["sheet_force_z_N"][1:] + h["die_force_z_N"][1:], h["force_z_N"][1:], rtol=1e-9)
    # the device's figures: the quarter's x 4; three bookkeepings of the same impulse (the loop's, the load's
    # Σ ∫f dV dt and the bodies' Σ nodal F dt)
    assert m["force_impulse_z_Ns"] == pytest.approx(4 * m["sector_force_impulse_z_Ns"], rel=1e-15)
    assert h["device_impulse_z_Ns"][-1] == pytest.approx(m["force_impulse_z_Ns"], rel=1e-9)
    assert m["sheet_impulse_z_Ns"] + m["die_impulse_z_Ns"] == pytest.approx(m["force_impulse_z_Ns"], rel=1e-12)
    # the draw: the largest |u_z| of the sheet over the history rows, in metrics.json
    assert m["sheet_max_uz_mm"] == pytest.approx(1e3 * h["sheet_max_uz_m"].max(), rel=1e-9) and m["sheet_max_uz_mm"] > 0
    assert h["capacitor_voltage_V"][0] == 2500.0 and h["force_z_N"][0] == 0.0
    # (3) Newton on the sheet until the clamp reacts (the rebuilt held force first checked against the history's)
    mom_err, total_err = sheet_momentum_vs_free_impulse(out, h)
    assert total_err < 1e-8   # history.csv's 10 digits
    assert mom_err < 1e-3
    # (2) the fixed-mesh solve of the same model and mesh
    _, _, ref = _reference_solve(out, tmp_path, 3e-6, 3)
    i_ref = ref.coil_current[:, 0]
    err_i = np.abs(h["coil_current_A"][1:] - i_ref).max() / np.abs(i_ref).max()
    errs = {n: np.abs(h[f"{n}_getdp_force_z_N"][1:] - ref.conductor_force[:, k, 2]).max()
            / np.abs(ref.conductor_force[:, k, 2]).max() for k, n in enumerate(("sheet", "die"))}
    print(f"\ncoarse racetrack case, 3 us: coil current vs fixed-mesh solve {err_i:.1e}, GetDP forces sheet "
          f"{errs['sheet']:.1e}, die {errs['die']:.1e}; ledger {m['conservation_error_rel']:.1e}; sheet momentum vs "
          f"free impulse {mom_err:.1e}; peak current {m['coil_current_peak_kA']:.4g} kA")
    assert err_i < 1e-4 and errs["sheet"] < 1e-3 and errs["die"] < 1e-3
    # outputs: both bodies' XDMF at the output times, the sheet's force density per tetrahedron, its snapshot at
    # the peak current (whose force density integrates to GetDP's sheet force at that step), the pictures
    for body in ("sheet", "die"):
        with meshio.xdmf.TimeSeriesReader(out / "fields" / f"emf_racetrack_groove_{body}.xdmf") as reader:
            _, cells = reader.read_points_cells()
            times = [reader.read_data(k)[0] for k in range(reader.num_steps)]
        assert cells[0].type == "tetra" and len(cells[0].data) == m[f"{body}_tets"]
        assert np.allclose(times, [0.0, 1e-6, 2e-6, 3e-6], rtol=0, atol=1e-15)
    assert len(sorted((out / "fields" / "em3d").glob("sheet_em_*.vtu"))) == 3
    peak = meshio.read(out / "fields" / "em3d" / "em_peak_current.vtu")
    meta = json.loads((out / "fields" / "em3d" / "em_peak_current.json").read_text())
    assert len(peak.cells[0].data) == m["sheet_tets"]
    k_peak = int(np.argmax(np.abs(h["coil_current_A"])))
    assert meta["time_s"] == pytest.approx(h["time_s"][k_peak], rel=1e-12)
    assert abs(meta["coil_current_A"]) == pytest.approx(1e3 * m["coil_current_peak_kA"], rel=1e-12)
    fz = peak.cell_data["force_density_N_m3"][0][:, 2] @ _tet_volumes(peak.points, peak.cells[0].data)
    assert fz == pytest.approx(h["sheet_getdp_force_z_N"][k_peak], rel=1e-6)
    for name in ("deformed_von_mises.png", "em3d_force_density_peak_current.png", "sheet_max_uz_m.png",
                 "coil_current_A.png", "energies.png", "section_y0_von_mises.png", "section_y0_plastic_strain.png"):
        assert (out / "plots" / name).stat().st_size > 10_000, name


# slow (a repeated end-to-end run; covered in the default tier by the same SIGINT/--resume bitwise check of a 3D
# coupled run through the CLI:
# test_case_racetrack_remesh.py::test_sigint_after_the_remesh_then_resume_equals_the_uninterrupted_run; the 3D
# loop's checkpoint/resume: test_loop_fake3d.py)
@pytest.mark.slow
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
    print(f"\ninterrupted at {cut['end_time_s']:.3g} s; resumed: draw {got['sheet_max_uz_mm']!r} vs "
          f"{ref['sheet_max_uz_mm']!r} mm, impulse {got['force_impulse_z_Ns']!r} vs {ref['force_impulse_z_Ns']!r} N s")
    assert_coupled3d_outputs_bitwise(coarse_run, out)


BAD = [  # (--set overrides, text the one line must hold): what a user of the geometry path can get wrong here
    # the builder's own checks (its ValueError lines come back as a GeometryError: `pulseform check` meshes)
    (["geometry.parameters.sheet_half_x=0.015"], "sheet_half_x must exceed the coil's outer half width"),
    (["geometry.parameters.turn_width=-3e-3"], "turn_width must be a positive number"),
    (["geometry.parameters.sheet_layers=0"], "sheet_layers must be a positive number"),
    (["geometry.parameters.groove_x1=0.036"], "groove_x1"),
    (["geometry.parameters.coil_gap=0.0"], "coil_gap must be a positive number"),   # the coil would touch the sheet
    (["geometry.parameters.groove_depth=0.02"], "groove_depth must be below die_height"),
    (["geometry.parameters.air_radius=0.05"], "air_radius must enclose"),
    (["geometry.parameters.sheet_thicknes=1e-3"], "unknown parameter 'sheet_thicknes'"),
    # the geometry table and the role map
    (["geometry.on_mesh_break=\"explode\""], "geometry.on_mesh_break"),
    (["geometry.em_order=2"], "geometry.em_order"),                    # order 2 cannot remesh
    (["geometry.em_order=3"], "geometry.em_order"),
    (["geometry.em_step=0.0"], "geometry.em_step"),
    (["geometry.break_quality=1.5"], "geometry.break_quality"),
    (["geometry.shell_radii=[0.15, 0.12]"], "geometry.shell_radii"),
    (["geometry.file=\"missing.py\""], "geometry.file"),
    (["geometry.allow_system_calls=false"], "geometry.allow_system_calls"),
    (["geometry.air=\"sheet\""], "a physical group has one role"),
    (["geometry.coils[0].group=\"die\""], "a physical group has one role"),
    (["geometry.coils[0].terminals=[\"coil_in\", \"coil_in\"]"], "geometry.coils[0].terminals"),
    (["bodies.die.region=\"nope\""], "bodies[1].region: got 'nope', not a physical volume group of the mesh; its "
                                     "groups: volumes 'air'"),   # the listing (shortened in the middle)
    (["bodies.sheet.fixed=[{group=\"nope\", components=[0, 1, 2]}]"], "bodies[0].fixed[0].group"),
    (["limits.max_cells=5000"], "limits.max_cells"),                   # the mesh's cells, checked once meshed
    (["symmetry=[{normal=[0.0, 1.0, 0.0]}]"], "touches the outer boundary"),   # the plane x = 0 taken away
    (["sector.angle_deg=5.0"], "sector"),
    (["geometry.type=\"flat_coil_sheet\""], "geometry"),
    (["bodies.die.rigid=true"], "bodies[1]"),
    (["contact[0].slave=\"nope\""], "contact[0].slave"),
    (["materials.tool_steel.electrical_conductivity=0.0"], "materials.tool_steel.electrical_conductivity"),
    (["em.current={amplitude=1e4, beta=1e3, omega=1e5}"], "em.current"),
    (["mechanics.formulation=\"axisymmetric\""], "symmetry"),
]


@pytest.mark.parametrize("sets,says", BAD, ids=[s[0].split("=")[0] + f"[{i}]" for i, (s, _) in enumerate(BAD)])
def test_bad_input_of_the_racetrack_case(capsys, sets, says):
    print(one_line_refusal(capsys, CASE, sets, says))


def test_a_racetrack_table_is_refused_in_the_2d_demo(capsys):
    """A ``racetrack`` key is not a key of the 2D demo: one line naming it, exit 2."""
    rc = main(["check", str(REPO / "cases/emf_sheet_bulge"), "--set", "racetrack.turns=3"])
    _, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and "racetrack" in lines[0], err


#: figures of the slow comparison: (the study's metric name, the run's: a metrics.json key, or a function of
#: the metrics and the history computing the study's figure from the run's outputs)
REFERENCE = {
    "max_deflection_into_groove_mm": "sheet_max_uz_mm",   # the draw: max u_z = max |u_z| (never below its start)
    "impulse_device_z_Ns": "force_impulse_z_Ns",
    "sheet_impulse_device_z_Ns": "sheet_impulse_z_Ns",
    "die_impulse_device_z_Ns": "die_impulse_z_Ns",
    "force_peak_device_z_N": lambda m, h: 4 * float(np.abs(h["force_z_N"]).max()),
    "die_force_peak_device_z_N": lambda m, h: 4 * float(np.abs(h["die_force_z_N"]).max()),
    "coil_current_peak_kA": "coil_current_peak_kA",
    "t_peak_current_s": lambda m, h: float(h["time_s"][np.argmax(np.abs(h["coil_current_A"]))]),
    "contact_pressure_peak_Pa": "contact_pressure_peak_Pa",
    "first_contact_s": "first_contact_s",
    "max_sheet_speed_m_s": "sheet_max_speed_m_s",
    "plastic_work_device_J": "plastic_work_J",
    "external_work_device_J": lambda m, h: 4 * float(h["energy_external_work_J"][-1]),
    # the study's definition, the balance over the external work at the end (the run's energy_error_rel is
    # relative to the largest external work over the run since issue 32: 0.3 % larger here)
    "energy_balance_error_rel": lambda m, h: float(h["energy_balance_error_J"][-1] / h["energy_external_work_J"][-1]),
    "em_mesh_frozen_at_s": "em_mesh_frozen_at_s",
    "impulse_after_freeze_device_z_Ns": "impulse_after_freeze_device_z_Ns",
}
#: counts of the slow comparison: (the study's name, the run's)
REFERENCE_COUNTS = (("em_steps", "em_steps"), ("mech_steps", "mech_steps"), ("n", "n_final"), ("em_tets", "em_tets"),
                    ("sheet_tets", "sheet_tets"), ("die_tets", "die_tets"))


@pytest.mark.slow
@pytest.mark.getdp
def test_the_case_reproduces_the_study_reference(tmp_path):
    """``pulseform run cases/emf_racetrack_groove`` (60 µs, the design mesh: ~4-7 min) against
    studies/emf_racetrack_groove/reference/racetrack_metrics.json, the same model and mesh run by the study's own
    runner (studies/emf_racetrack_groove/racetrack_run.py): the case's builder meshes that design and the driver
    lands its EM steps on the same output times (every 10 µs), so with a factorisation per EM step the runs are the
    same to round-off (observed: <= 2e-14 relative, same EM and mechanical step counts). The case runs with kept LU
    factors (the default em.factor_reuse_tol = 1e-10: each EM step's system solved to that relative residual,
    docs/getdp.md) and is held to the issue's bound, 1e-6 relative (measured: <= 5.7e-9 against a factorisation per
    step). Figures the general path does not write are computed from its history (10 digits)."""
    ref = json.loads((REPO / "studies/emf_racetrack_groove/reference/racetrack_metrics.json").read_text())
    out = tmp_path / "run"
    r = pulseform_cli(["run", CASE, "--out", str(out), "--quiet", "--set", "output.plots=false"])
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads((out / "metrics.json").read_text())
    h = _history(out)
    got = {k: (m.get(v) if isinstance(v, str) else v(m, h)) for k, v in REFERENCE.items()}
    print("\n" + "\n".join(f"{k:36s} {got[k]!r:>24} {ref.get(k)!r:>24}" for k in REFERENCE))
    for k, mine in REFERENCE_COUNTS:
        assert m[mine] == ref[k], k
    for k, v in REFERENCE.items():
        if k not in ref:   # a figure of a frozen EM mesh (the impulse after the freeze): neither run froze
            assert isinstance(v, str) and v not in m, k
            continue
        # the time of a freeze is NaN in both when neither froze (the study's json writes NaN, the case's null)
        value = float("nan") if got[k] is None else got[k]
        assert value == pytest.approx(ref[k], rel=1e-6, nan_ok=True), k
    # the die's largest displacement: the study's is |u| of a node, the run's the largest component of each
    assert max(m[f"die_max_u{c}_mm"] for c in "xyz") <= ref["die_max_displacement_mm"] * (1 + 1e-9)
    assert max(m[f"die_max_u{c}_mm"] for c in "xyz") >= ref["die_max_displacement_mm"] / math.sqrt(3)
    assert max(m["conservation_error_rel"], m["sheet_ledger_rel"], m["die_ledger_rel"]) < 1e-12


# slow (a repeated end-to-end run; covered in the default tier by order-2 edge elements in the coupled loop vs a
# fixed-mesh order-2 solve:
# test_coupled_racetrack.py::test_order2_em_in_the_coupled_loop_freezes_instead_of_remeshing; order 2 vs order 1:
# tests/getdp/test_em3d_order2.py)
@pytest.mark.slow
@pytest.mark.getdp
def test_the_case_with_second_order_edge_elements(coarse_run, tmp_path):
    """``geometry.em_order = 2`` through the CLI (coarse mesh, 2 us, the air first order): GetDP's sheet and die
    forces equal a fixed-mesh order-2 solve of the same model and mesh (the sheet moves ~1e-7 m in 2 us), and
    they exceed the order-1 run's: order 1 underestimates the force on a coarse mesh (at the peak 35.8 vs 52.8 kN
    on the x 2 mesh, studies/emf_racetrack_groove/reference/em_convergence_order2.json), most at early times, when
    the skin depth (~0.25 mm at 2 us) is below the coarse sheet's layers (0.5 mm): 35 vs 313 N at 2 us here."""
    out = tmp_path / "order2"
    r = _run(out, "--set", "geometry.em_order=2", "--set", 'geometry.on_mesh_break="freeze"',
             "--set", "time.end=2e-6", "--set", "output.plots=false")
    assert r.returncode == 0, r.stderr[-3000:]
    h, h1 = _history(out), _history(coarse_run)
    case, model, ref = _reference_solve(out, tmp_path, 2e-6, 2)
    assert case.geometry.em_order == 2 and model.order == 2 and not model.order2_air
    for k, n in enumerate(("sheet", "die")):
        err = np.abs(h[f"{n}_getdp_force_z_N"][1:] - ref.conductor_force[:, k, 2]).max() \
            / np.abs(ref.conductor_force[:, k, 2]).max()
        ratio = h[f"{n}_getdp_force_z_N"][2] / h1[f"{n}_getdp_force_z_N"][2]
        print(f"\norder 2, {n}: GetDP force vs the fixed-mesh order-2 solve {err:.1e}; order 2 / order 1 at 2 us "
              f"{ratio:.4f}")
        assert err < 1e-3
        if n == "sheet":
            assert ratio > 1.05
