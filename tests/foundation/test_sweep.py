"""`pulseform sweep`: full grid, parallel members, a bad member fails alone."""

import csv
from pathlib import Path
from warm_cli import pulseform_cli

REPO = Path(__file__).resolve().parents[2]


def test_sweep_grid_with_failing_members(tmp_path):
    out = tmp_path / "sw"
    r = pulseform_cli(["sweep", str(REPO / "cases/bar_impact"), "--out", str(out), "--jobs", "2",
                       "--param", "time.cfl=0.5,2.0",
                       "--param", "bodies.left.initial_velocity=[10.0, 0.0],[3000.0, 0.0]",
                       "--set", "bodies.left.mesh_size=0.25", "--set", "bodies.right.mesh_size=0.25",
                       "--set", "time.end=2e-4", "--set", "output.field_interval=1e-4",
                       "--set", "output.plots=false"])  # the members' own pictures: nothing here looks at them
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
    r = pulseform_cli(["sweep", str(REPO / "cases/bar_impact"), "--out", str(tmp_path / "x"),
                       "--param", "time.cfl"])
    assert r.returncode == 2 and "time.cfl" in r.stderr and "Traceback" not in r.stderr


def test_sweep_of_a_3d_case_plots_its_physics(tmp_path):
    """Issue 20 deliverable 6: `sweep` on a 3D case. The wall pressure of the quarter bar at 5 m/s is
    the paper's rho c v / 2 = 70 MPa (sec. 4) and the contact lasts 2 L / c = 1.6 ms, c = sqrt(E / rho):
    with the density 0.64 times the paper's, the stress is sqrt(0.64) = 0.8 times and the contact
    0.8 times as long (1D elastic bar theory; both members stay elastic)."""
    from pulseform.orchestrator.workflows.sweep import Member, main_metrics

    out = tmp_path / "sw3d"
    r = pulseform_cli(["sweep", str(REPO / "cases/bar_impact_3d"), "--out", str(out), "--jobs", "1",
                       "--param", "materials.paper_al.density=1792.0,2800.0",
                       "--set", "bodies.bar.mesh_size=0.25", "--set", "output.field_interval=1.4e-3"])
    assert r.returncode == 0, r.stderr
    rows = {row["materials.paper_al.density"]: row for row in csv.DictReader(open(out / "sweep.csv"))}
    light, paper = rows["1792.0"], rows["2800.0"]
    s_light, s_paper = (float(x["contact_stress_plateau_MPa"]) for x in (light, paper))
    d_light, d_paper = (float(x["contact_duration_ms"]) for x in (light, paper))
    assert abs(s_paper - 70.0) / 70.0 < 0.03          # the paper's 70 MPa within 3 % (as the 3D case)
    assert abs(s_light / s_paper - 0.8) < 0.02
    assert abs(d_light / d_paper - 0.8) < 0.03
    member = Member(index=0, values={}, out=out, metrics={k: float(v) for k, v in paper.items()
                                                          if k.endswith(("_MPa", "_ms", "_s")) and v})
    shown = main_metrics([member])
    assert shown[:3] == ["contact_stress_plateau_MPa", "contact_duration_ms", "bar_max_von_mises_MPa"], shown
    assert (out / "plots" / "sweep_materials_paper_al_density.png").is_file()
    assert "Traceback" not in r.stderr
