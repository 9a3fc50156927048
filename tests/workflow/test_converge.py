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


@pytest.mark.parametrize("args,key", [(["--levels", "2"], "--levels"), (["--ratio", "1.0"], "--ratio"),
                                      (["--refine", "em_step", "--ratio", "3"], "coupling.n")])
def test_bad_study_arguments(tmp_path, capsys, args, key):
    rc = main(["converge", CASE, "--out", str(tmp_path / "s"), *args])
    err = capsys.readouterr().err
    assert rc == 2 and key in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "s").exists()  # nothing started


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
