"""Issue 14: units from a table, one time unit per run, the t = 0 history row, `pulseform plot`,
and the summary `pulseform run` prints (short runs of the demo, bar impact and the press fit)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.run.history import History
from pulseform.orchestrator.run.summary import headline
from pulseform.orchestrator.run.units import label, time_axis, unit_of
from warm_cli import pulseform_cli

REPO = Path(__file__).resolve().parents[2]
DEMO_SHORT = ["--set", "time.end=2e-6", "--set", "output.field_interval=1e-6"]
BAR_COARSE = ["--set", "bodies.left.mesh_size=0.25", "--set", "bodies.right.mesh_size=0.25"]


def _run(case: str, out: Path, *extra: str) -> subprocess.CompletedProcess:
    r = pulseform_cli(["run", str(REPO / "cases" / case), "--out", str(out), *extra])
    assert r.returncode == 0, r.stderr[-3000:]
    return r


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """The demo for 2 us, without pictures: its tests read the columns, history.csv and the printed summary
    (the pictures of a run and of `pulseform plot` are the bar's and the press fit's below)."""
    out = tmp_path_factory.mktemp("pictures") / "demo"
    return out, _run("emf_sheet_bulge", out, *DEMO_SHORT, "--set", "output.plots=false")


@pytest.fixture(scope="module")
def bar(tmp_path_factory):
    out = tmp_path_factory.mktemp("pictures") / "bar"
    return out, _run("bar_impact", out, *BAR_COARSE)


def _columns(out: Path) -> list[str]:
    return History.read(out / "history.csv").columns + list(json.loads((out / "metrics.json").read_text()))


# ------------------------------------------------------------------ units
def test_units_of_named_columns():
    assert unit_of("sheet_max_speed_m_s").shown == "m/s"
    assert unit_of("sheet_max_uy_m").shown == "mm" and unit_of("sheet_max_uy_m").scale == 1e3
    assert unit_of("contact_mid_contact_pressure_Pa").shown == "MPa"
    assert unit_of("conservation_error_rel").shown == "-"
    assert unit_of("em_mesh_min_quality").shown == "-"
    assert unit_of("dt_s").shown == "µs"
    assert unit_of("coil_current_peak_kA").shown == "kA"
    assert label("left_momentum_y_Ns") == "left_momentum_y_Ns [N·s]"
    assert label("some_new_column_xyz") == "some_new_column_xyz [?]"  # unknown: visible, not guessed


def test_one_time_unit_per_run_length():
    assert time_axis(60e-6).unit == "µs" and time_axis(60e-6).scale == 1e6
    assert time_axis(2.2e-3).unit == "µs"          # bar impact: a pulse too
    assert time_axis(16e-3).unit == "ms"
    assert time_axis(100.0).unit == "s"


@pytest.mark.getdp
def test_every_column_of_a_demo_run_has_a_unit(demo):
    unknown = [c for c in _columns(demo[0]) if not unit_of(c).known]
    assert not unknown, f"add these columns to orchestrator/run/units.RULES: {unknown}"


def test_every_column_of_a_mechanics_run_has_a_unit(bar, press_fit):
    """The bar impact, and the press fit with its analysis' columns and a pressure load."""
    unknown = [c for c in _columns(bar[0]) + _columns(press_fit) if not unit_of(c).known]
    assert not unknown, f"add these columns to orchestrator/run/units.RULES: {unknown}"


# ------------------------------------------------------------------ t = 0 row
@pytest.mark.getdp
def test_demo_t0_row_holds_the_charged_bank(demo):
    h = History.read(demo[0] / "history.csv")
    first = dict(zip(h.columns, h.rows[0]))
    assert first["time_s"] == 0.0
    assert first["capacitor_voltage_V"] == 6000.0         # charged to V0, not 0
    assert first["coil_current_A"] == 0.0 and first["force_y_N"] == 0.0 and first["magnetic_energy_J"] == 0.0
    q = h.column("em_mesh_min_quality")
    assert q[0] > 0.0 and q[0] == pytest.approx(q[1], rel=1e-3)  # the fresh mesh's quality, not 0
    vc = h.column("capacitor_voltage_V")
    assert np.all(np.diff(vc[:4]) < 0), "the bank discharges from V0 (no ramp up from 0)"


@pytest.fixture(scope="module")
def press_fit(tmp_path_factory):
    """The press fit for two steps, run with output.plots = false."""
    out = tmp_path_factory.mktemp("pictures") / "tpf"
    _run("tube_press_fit", out, "--quiet", "--set", "time.end=2e-7", "--set", "output.field_interval=1e-7",
         "--set", "output.history_every=1", "--set", "bodies.inner.mesh_size=1e-3",
         "--set", "bodies.outer.mesh_size=1e-3", "--set", "output.plots=false")
    return out


def test_pressure_t0_row_holds_the_pulse_at_t0(press_fit):
    """Eq. (8) starts at p0: the t = 0 row has p0 and its force, equal to the first step's (n = 1
    evaluates the pulse at the step's start)."""
    h = History.read(press_fit / "history.csv")
    p, fx = h.column("load0_pressure_Pa"), h.column("force_x_N")
    assert p[0] == 350e6
    assert fx[0] > 0.0 and fx[0] == pytest.approx(fx[1], rel=1e-12)


# ------------------------------------------------------------------ pulseform plot
def _plot(folder: Path) -> subprocess.CompletedProcess:
    return pulseform_cli(["plot", str(folder)])


def test_plot_redraws_the_pictures_of_a_run(bar, tmp_path):
    out = bar[0]
    drawn_by_run = {p.name for p in (out / "plots").glob("*.png")}
    assert {"energies.png", "time_step.png", "contact_mid_contact_pressure_Pa.png"} <= drawn_by_run
    for p in (out / "plots").glob("*.png"):
        p.unlink()
    r = _plot(out)
    assert r.returncode == 0, r.stderr
    assert {p.name for p in (out / "plots").glob("*.png")} == drawn_by_run
    assert f"pictures: {out / 'plots'}" in r.stdout and "energies.png" in r.stdout


def test_plot_draws_a_run_made_without_plots(press_fit):
    """output.plots = false: the run draws nothing; `pulseform plot` draws the history plots, the
    case analysis' pictures and the shapes from the field files."""
    assert not list((press_fit / "plots").glob("*.png"))
    r = _plot(press_fit)
    assert r.returncode == 0, r.stderr
    names = {p.name for p in (press_fit / "plots").glob("*.png")}
    assert {"energies.png", "load0_pressure_Pa.png", "press_fit_displacements.png"} <= names, names


def test_plot_refuses_a_folder_that_is_not_a_run(tmp_path):
    (tmp_path / "x").mkdir()
    for folder in (tmp_path / "x", tmp_path / "missing"):
        r = _plot(folder)
        err = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert r.returncode == 2 and len(err) == 1 and "not a results folder" in err[0], r.stderr


# ------------------------------------------------------------------ summary
def _summary(stdout: str) -> list[str]:
    """The lines between ``summary:`` and ``results:`` (which comes before the metrics)."""
    lines = stdout.splitlines()
    start, end = lines.index("summary:"), next(i for i, ln in enumerate(lines) if ln.startswith("results:"))
    assert start < end
    return [ln.strip() for ln in lines[start + 1:end]]


@pytest.mark.getdp
def test_demo_summary_before_the_metrics(demo):
    lines = _summary(demo[1].stdout)
    labels = [ln.split("  ")[0] for ln in lines]
    assert labels == ["bank energy", "peak coil current", "force impulse", "max deflection", "max speed",
                      "least FLC margin, sheet", "peak kinetic energy", "plastic work"], lines
    assert lines[0].split()[2:4] == ["900", "J"]           # ½ · 50 µF · (6 kV)²
    m = json.loads((demo[0] / "metrics.json").read_text())
    assert f"{m['coil_current_peak_kA']:.4g} kA" in lines[1]
    assert "% " in lines[6] and "of the bank energy" in lines[6]


def test_bar_summary_only_the_lines_that_apply(bar):
    lines = _summary(bar[1].stdout)
    text = "\n".join(lines)
    assert "bank energy" not in text and "coil current" not in text and "impulse" not in text
    assert lines[0].startswith("max displacement") and lines[1].startswith("max speed")
    assert "kinetic energy at the end" in text and "of the initial" in text


def test_summary_names_the_die_peak_stress():
    """A case with a die: its peak von Mises stress (from the run's metrics) is a line."""
    case, _ = load_case(REPO / "cases" / "corner_fill")
    h = History(Path("unused"))
    for t, ke in ((0.0, 0.0), (1e-5, 2.0), (2e-5, 1.0)):
        h.record({"time_s": t, "energy_kinetic_J": ke, "energy_plastic_J": 0.5 * t / 2e-5,
                  "energy_external_work_J": 4.0 * t / 2e-5, "die_max_von_mises_Pa": 3e8 * t / 2e-5})
    metrics = {"die_max_von_mises_MPa": 300.0, "blank_max_ux_mm": 0.1, "blank_max_uy_mm": 1.2,
               "blank_max_speed_m_s": 40.0, "die_max_ux_mm": 0.01, "die_max_uy_mm": 0.02, "die_max_speed_m_s": 1.0,
               "force_impulse_Ns": 0.3}
    lines = {h_.label: h_ for h_ in headline(case, metrics, h)}
    assert lines["peak von Mises, die"].value == 300.0 and lines["peak von Mises, die"].unit == "MPa"
    assert lines["peak kinetic energy"].value == pytest.approx(50.0)  # 2 J of 4 J external work
    assert lines["plastic work"].value == pytest.approx(12.5)
    assert "bank energy" not in lines


def test_summary_displacement_of_a_3d_body_counts_z():
    """A 3D sheet deflects along z: the summary's max displacement is its z-displacement, not the larger
    of x and y (the sector's 2.4 mm read 0.098 mm)."""
    case, _ = load_case(REPO / "cases" / "emf_sheet_bulge_3d")
    metrics = {"sheet_max_ux_mm": 0.0978, "sheet_max_uy_mm": 0.0021, "sheet_max_uz_mm": 2.389}
    lines = {h_.label: h_ for h_ in headline(case, metrics, None)}
    assert lines["max displacement"].value == pytest.approx(2.389)



# ------------------------------------------------------------------ issue 32: pictures and summary lines that apply
@pytest.mark.parametrize("case,left_out", [("jumping_ring", {"capacitor_voltage_V"}),      # a 50 Hz sine source
                                           ("emf_fixed_disk", {"capacitor_voltage_V"}),    # a prescribed current
                                           ("emf_sheet_bulge", set()),                     # a capacitor bank
                                           ("two_coils_plate", {"capacitor_voltage_V"}),   # two sine sources
                                           ("bar_impact", set())])                         # no EM at all
def test_no_capacitor_picture_without_a_capacitor(tmp_path, case, left_out):
    """Item 10: the capacitor_voltage_V column (0 without a bank) is not drawn for a case without a capacitor bank;
    the other columns are."""
    from pulseform.orchestrator.run.plots import columns_without_meaning, plot_probes

    c, _ = load_case(REPO / "cases" / case)
    assert columns_without_meaning(c) == left_out
    h = History(Path("unused"))
    for t in (0.0, 1e-3, 2e-3):
        h.record({"time_s": t, "capacitor_voltage_V": 0.0, "coil_current_A": 1e3 * t})
    drawn = {p.name for p in plot_probes(h, tmp_path, leave_out=columns_without_meaning(c))}
    assert drawn == {"coil_current_A.png"} | ({"capacitor_voltage_V.png"} - {f"{k}.png" for k in left_out})


def test_axisymmetric_radial_load_impulse_line_where_it_dominates():
    """Item 5: an axisymmetric run's force impulse is the axial one; the radial load's impulse (no net force) is a
    summary line only where it is the larger (a tube), so a sheet's summary stays as it was."""
    case, _ = load_case(REPO / "cases" / "emf_tube_expansion")
    tube = {h_.label: h_ for h_ in headline(case, {"force_impulse_Ns": 0.01, "radial_load_impulse_Ns": 1.7}, None)}
    assert tube["force impulse"].value == 0.01 and tube["radial load impulse"].value == 1.7
    assert "outward (not a net force)" in tube["radial load impulse"].note
    sheet = {h_.label for h_ in headline(case, {"force_impulse_Ns": 0.78, "radial_load_impulse_Ns": -0.01}, None)}
    assert "force impulse" in sheet and "radial load impulse" not in sheet


def test_impulse_metrics_per_formulation():
    """Item 5: the loop's impulse (Σ F Δt of the summed nodal forces) as metrics: planar and 3D the net force's
    magnitude; axisymmetric the axial one, the summed radial load (no net force) apart, signed."""
    from pulseform.orchestrator.run.impulse import impulse_metrics

    planar = impulse_metrics(np.array([0.3, -0.4]), "plane_strain")
    assert planar == {"force_impulse_Ns": pytest.approx(0.5, rel=1e-15), "force_impulse_z_Ns": -0.4}
    axi = impulse_metrics(np.array([1.7, -0.01]), "axisymmetric")
    assert axi == {"force_impulse_Ns": 0.01, "force_impulse_z_Ns": -0.01, "radial_load_impulse_Ns": 1.7}
    assert impulse_metrics(np.array([1.0, 2.0, 2.0]), "3d")["force_impulse_Ns"] == pytest.approx(3.0, rel=1e-15)


def test_springback_picture_of_a_3d_body(tmp_path):
    """``plots/springback_<body>.png`` of a 3D body (orchestrator/run/pictures_springback3d.py): the quarter bar of
    cases/bar_impact_3d, yielding (sigma_y 50 MPa under the paper's 70 MPa wave), released after 1.6 ms. Its
    springback (1.6 mm at most on a 4 m bar) is drawn x 100 (magnification: the power of ten that makes it 2 % of
    the body); the picture shows the springback colours (viridis' top, yellow, at the largest value) and the
    translucent grey surface before springback."""
    from PIL import Image

    from pulseform.orchestrator.run.pictures_springback import magnification

    assert magnification(4.0, 1.6e-3) == 100.0 and magnification(4.0, 0.03) == 1.0 and magnification(1.0, 0.0) == 1.0
    out = tmp_path / "bar3d"
    _run("bar_impact_3d", out, "--quiet", "--set", "bodies.bar.mesh_size=0.5", "--set", "time.end=1.6e-3",
         "--set", 'springback.supports="minimal"', "--set", "materials.paper_al.yield_stress=0.05e9")
    m = json.loads((out / "metrics.json").read_text())
    assert 1e-4 < m["bar_springback_max_m"] < 4.0 * 0.005  # drawn magnified
    img = np.asarray(Image.open(out / "plots" / "springback_bar.png").convert("RGB")).astype(int)
    yellow = (np.abs(img - [253, 231, 37]).sum(axis=2) < 60).sum()     # viridis at the largest springback
    dark = (np.abs(img - [68, 1, 84]).sum(axis=2) < 60).sum()          # ... and at zero (the colour bar at least)
    assert yellow > 500 and dark > 100, (yellow, dark)
