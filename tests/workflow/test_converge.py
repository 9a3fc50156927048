"""``pulseform converge`` (orchestrator/workflows/converge.py) on cases/emf_fixed_disk, the mesh-convergence
configuration of issue 19 (fixed Al disk 1 mm over a flat 5-turn coil, 20 kA e^(−1e4 t) sin(1e5 t); peak
force 15.18 kN at 14.5 µs, computed independently before: /work/shared/SOLVER_NOTES.md).

Default tier: a coarse, short study (sizes 1, 0.5, 0.25 mm in the disk, 4 µs): every level's element sizes
are the case's divided by 2^k, converge.json holds each level's metrics as its run wrote them and the GCI
of grid_convergence on those values, report.md and the plots exist; bad arguments are one line, exit 2.
Slow tier: the issue's study (0.5, 0.25, 0.125 mm, 30 µs): extrapolated peak force within 0.5 % of
15.18 kN, an observed order between 1.5 and 3.5 (P1 elements: a force, a functional of the field,
converges at about second order; measured 2.89, 15219 N, GCI 0.066 %).
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from pulseform.orchestrator.cli import main
from pulseform.orchestrator.workflows.gci import grid_convergence

REPO = Path(__file__).resolve().parents[2]
CASE = str(REPO / "cases/emf_fixed_disk")


@pytest.mark.getdp
def test_converge_writes_the_study(tmp_path, capsys):
    out = tmp_path / "study"
    rc = main(["converge", CASE, "--out", str(out), "--set", "time.end=4e-6", "--set", "output.field_interval=4e-6",
               "--set", "geometry.mesh_size_sheet=1e-3", "--set", "geometry.mesh_size_coil=2e-3",
               "--set", "geometry.mesh_size_air=0.04", "--jobs", "2"])
    printed = capsys.readouterr()
    assert rc == 0, printed.err
    report = json.loads((out / "converge.json").read_text())
    assert [lv["level"] for lv in report["levels"]] == [0, 1, 2]
    for lv in report["levels"]:
        k = lv["level"]
        assert float(lv["overrides"]["geometry.mesh_size_sheet"]) == pytest.approx(1e-3 / 2 ** k, rel=1e-15)
        assert float(lv["overrides"]["geometry.mesh_size_air"]) == pytest.approx(0.04 / 2 ** k, rel=1e-15)
        written = json.loads((out / f"level_{k}" / "metrics.json").read_text())
        assert lv["metrics"] == {n: v for n, v in written.items() if n != "status"}  # the numbers as the run wrote them
    r = report["metrics"]["force_peak_N"]
    values = [report["levels"][k]["metrics"]["force_peak_N"] for k in (2, 1, 0)]  # finest first
    assert r["values"] == values
    assert r == {"values": values, "h_rel": [0.25, 0.5, 1.0], **grid_convergence([0.25, 0.5, 1.0], values).to_dict()}
    assert report["metrics"]["coil_current_peak_kA"]["convergence"] == "constant"  # a prescribed current
    assert "| force_peak_N |" in (out / "report.md").read_text()
    assert (out / "plots" / "converge_force_peak_N.png").is_file()
    assert "force_peak_N" in printed.out


#: (arguments, the key the one-line error names, case): the fixed disk is all rigid, so its EM step is refined through
#: coupling.steps_per_period (120 x 1.3 is whole, x 1.3^2 is not); the sheet bulge's n = 20 / 3 is not whole
BAD_STUDIES = [(["--levels", "2"], "--levels", CASE), (["--ratio", "1.0"], "--ratio", CASE),
               (["--refine", "em_step", "--ratio", "1.3"], "coupling.steps_per_period", CASE),
               (["--refine", "em_step", "--ratio", "3"], "coupling.n", str(REPO / "cases/emf_sheet_bulge"))]


@pytest.mark.parametrize("args,key,case", BAD_STUDIES)
def test_bad_study_arguments(tmp_path, capsys, args, key, case):
    rc = main(["converge", case, "--out", str(tmp_path / "s"), *args])
    err = capsys.readouterr().err
    assert rc == 2 and key in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "s").exists()  # nothing started


@pytest.mark.parametrize("sets", [[], ["time.dt_max=1e-8"]], ids=["period", "dt_max"])
def test_all_rigid_em_step_is_refined_through_the_period(sets):
    """Issue 32, item 7: when every body is rigid the EM step is min(period / steps_per_period, n · dt_max), so
    --refine em_step multiplies coupling.steps_per_period (and divides time.dt_max when given) by ratio^k; dividing
    coupling.n, as for deformable bodies, would run the same step three times. Each level's EM step, as the
    driver computes it (orchestrator/em/time_scale.py), is the case's divided by ratio^k."""
    import tomllib

    from pulseform.orchestrator.case.io import case_to_toml, load_case
    from pulseform.orchestrator.em.time_scale import source_period, steps_per_period
    from pulseform.orchestrator.workflows.converge import study_levels

    base, _ = load_case(CASE, sets)
    resolved = tomllib.loads(case_to_toml(base))
    levels = study_levels(resolved, 2.0, 3, "em_step")
    assert [int(lv["coupling.steps_per_period"]) for lv in levels] == [120, 240, 480]
    assert all(("time.dt_max" in lv) == bool(sets) for lv in levels)
    period = source_period(base)
    em_step = [period / steps_per_period(load_case(CASE, sets + [f"{k}={v}" for k, v in lv.items()])[0])
               for lv in levels]
    assert em_step == pytest.approx([em_step[0], em_step[0] / 2, em_step[0] / 4], rel=1e-12)
    if sets:  # n · dt_max = 1e-8 s binds (the period over 120 is 0.52 us)
        assert em_step[0] == pytest.approx(1e-8, rel=1e-12)


def test_default_metrics_add_the_rigid_bodies_peaks():
    """A study of an all-rigid case reports each rigid body's largest translation (the first peak: what a coarse EM
    step moves most) beside the headline metrics."""
    from pulseform.orchestrator.workflows.converge import DEFAULT_METRICS, default_metrics

    run = {"force_peak_N": 1.0, "ring_max_position_y_mm": 14.7, "ring_max_position_y_time_s": 0.067,
           "ring_min_position_y_mm": 0.0, "sheet_max_uy_mm": 1.0}
    assert default_metrics(run) == [*DEFAULT_METRICS, "ring_max_position_y_mm"]


@pytest.mark.slow
@pytest.mark.getdp
def test_fixed_disk_peak_force_converges_to_the_reference(tmp_path, capsys):
    out = tmp_path / "study"
    assert main(["converge", CASE, "--out", str(out), "--jobs", "2"]) == 0, capsys.readouterr().err
    r = json.loads((out / "converge.json").read_text())["metrics"]["force_peak_N"]
    print(f"\npeak force {r['values']} N, order {r['order']:.3g}, extrapolated {r['extrapolated']:.6g} N, "
          f"GCI {100 * r['gci_fine']:.3g} %")
    assert r["convergence"] == "monotone" and 1.5 < r["order"] < 3.5
    assert r["extrapolated"] == pytest.approx(15.18e3, rel=0.005)


def test_geometry_3d_sizes_are_refined():
    """A 3D geometry-file case (cases/emf_tube_field_shaper): geometry.mesh_size_factor alone is divided by
    ratio^k; it scales every size of the file, so neither geometry.mesh_sizes nor the .geo's parameters named
    mesh_size* (field_shaper.geo's mesh_size_air, mesh_size_shell) are refined as well (that would refine them
    twice); a level's overrides load."""
    import tomllib

    from pulseform.orchestrator.case.io import case_to_toml, load_case
    from pulseform.orchestrator.workflows.converge import refinement_keys, study_levels

    case = str(REPO / "cases/emf_tube_field_shaper")
    resolved = tomllib.loads(case_to_toml(load_case(case, ["geometry.mesh_size_factor=1.5"])[0]))
    assert "mesh_size_air" in resolved["geometry"]["parameters"] and resolved["geometry"]["mesh_sizes"]
    assert refinement_keys(resolved) == {"geometry.mesh_size_factor": 1.5}
    levels = study_levels(resolved, 1.5, 3, "mesh")
    assert [float(lv["geometry.mesh_size_factor"]) for lv in levels] == pytest.approx([1.5, 1.0, 1.0 / 1.5], rel=1e-15)
    c, _ = load_case(case, [f"{k}={v}" for k, v in levels[2].items()])
    assert c.geometry.mesh_size_factor == pytest.approx(1.0 / 1.5, rel=1e-15)
    assert c.geometry.mesh_sizes == load_case(case, [])[0].geometry.mesh_sizes


def test_geometry_3d_em_step_is_refined():
    """--refine em_step on a 3D geometry file whose geometry.em_step sets n divides that EM step (coupling.n is
    not used there: dividing it would run the same case three times)."""
    import tomllib

    from pulseform.orchestrator.case.io import case_to_toml, load_case
    from pulseform.orchestrator.workflows.converge import study_levels

    resolved = tomllib.loads(case_to_toml(load_case(str(REPO / "cases/emf_tube_field_shaper"), [])[0]))
    em_step = resolved["geometry"]["em_step"]
    levels = study_levels(resolved, 2.0, 3, "em_step")
    assert [float(lv["geometry.em_step"]) for lv in levels] == [em_step, em_step / 2, em_step / 4]
    assert all(list(lv) == ["geometry.em_step"] for lv in levels)
