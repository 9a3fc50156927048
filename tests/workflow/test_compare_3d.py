"""`pulseform compare` on a 3D geometry file, the coupled 3D sector (cases/emf_sheet_bulge_3d): coupled GetDP load
vs the fitted eq. (7) pulse on the same sector mesh, the loaded surface given with --surface (the sheet's lower
face over the coil as a 3D box), and --fail-if.

Coarse and short (the 5 degree sector of tests/coupling/sector_case.py for 3 µs: 9 EM steps).
References: (1) the fitted pulse is a least-squares fit (P0 with β, ω from the discharge), not an
impulse-conserving one: by Cauchy–Schwarz its impulse on the coupled run's step grid differs from the
coupled impulse by at most A T × the fit's RMS residual (``fit_residual_rel`` × max p);
(2) the pressure run's impulse is the pulse evaluated where the loop evaluates it (t0 + (k − 1) dt / 2
of each EM step, held over the step) times the loaded area, and that sum differs from the closed-form
∫ p dt (mech.pulses.pulse_impulse_per_area) by the composite midpoint rule's Euler–Maclaurin term
−h²/24 (p'(T) − p'(0)) and the −dt/2 shift −dt/2 (p(T) − p(0)); (3) the loaded area from the coupled
run's field mesh (compare3d.py) against the pressure run's own (the solver's boundary triangles); (4) a flat
face's inward area vector is its area times its normal: exactly +z for the lower face.
"""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from pulseform.orchestrator.case.model import Box, PulseSin2
from pulseform.orchestrator.mech.pulses import pulse_impulse_per_area, sin2_pulse

from wf_helpers import REPO

import math

A = math.radians(5.0)
COARSE = ["--set", "geometry.parameters.angle_deg=5",
          "--set", f"symmetry=[{{normal=[0.0, 1.0, 0.0]}}, {{normal=[{-math.sin(A)!r}, {math.cos(A)!r}, 0.0]}}]",
          "--set", "geometry.parameters.h_sheet=1e-3", "--set", "geometry.parameters.sheet_layers=2",
          "--set", "geometry.parameters.h_coil=3e-3", "--set", "geometry.parameters.h_air=0.02",
          "--set", "time.end=3e-6", "--set", "output.field_interval=1e-6"]
#: the 2D demo's loaded surface (the sheet's lower face over the coil, r in [10, 34] mm at z = 1.5 mm) as a 3D box
from coupling.sector_case import COARSE as _SECTOR, SURFACE, sets  # noqa: E402

assert COARSE == sets(_SECTOR)   # the coarse sector of tests/coupling (the session's shared compare runs it)
CASE = str(REPO / "cases/emf_sheet_bulge_3d")


@pytest.fixture(scope="module")
def compared(sector_compare):
    """One compare run with a condition that cannot hold and one that must: exit 1 naming the second (the
    session's, tests/conftest.py: its coupled run is tests/coupling/test_case_3d_sector.py's too)."""
    return sector_compare


def _pulse(p, t_end: float) -> PulseSin2:
    return PulseSin2(type="pulse_sin2", body="sheet", surface=Box(), amplitude=p["amplitude"], beta=p["beta"],
                     omega=p["omega"], t_end=t_end)


@pytest.mark.getdp
def test_fail_if_on_the_3d_case(compared):
    _, rep, r = compared
    assert r.returncode == 1, r.stdout + r.stderr[-3000:]
    assert "--fail-if wall_time_coupled_s>0.001 holds" in r.stderr and "impulse_rel_diff>1e9" not in r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.getdp
def test_the_pulse_is_fitted_on_the_sectors_loaded_area(compared):
    out, rep, _ = compared
    p, mc, mp = rep["pulse"], rep["coupled_metrics"], rep["pressure_metrics"]
    s = p["symmetry_factor"]   # the coupled run's: 360 deg over the mesh's angular extent (round-off)
    assert s == pytest.approx(72.0, rel=1e-12) and s == mc["symmetry_factor"] == mp["symmetry_factor"]
    assert p["source"] == "fitted to the coupled run" and "circuit" in p["fit_method"] and p["body"] == "sheet"
    # the lower face is flat: its inward area vector is its area along +z
    assert p["direction"] == [0.0, 0.0, 1.0] and p["effective_area_m2"] == pytest.approx(p["model_area_m2"], rel=1e-12)
    # the same area from the coupled run's sheet mesh and from the pressure run's solver (round-off)
    assert p["model_area_m2"] == pytest.approx(mp["load0_area_m2"], rel=1e-12)
    assert p["area_m2"] == pytest.approx(s * p["model_area_m2"], rel=1e-15)
    # the mesh's loaded triangles lie inside the nominal annulus (those straddling r1, r2 are not loaded)
    assert 0.8 * p["nominal_area_m2"] < p["area_m2"] < p["nominal_area_m2"]
    # the fitted pulse's impulse on the coupled run's steps vs the coupled impulse: within the
    # Cauchy-Schwarz bound of the fit's residual (a least-squares fit does not conserve the impulse)
    h = np.genfromtxt(out / "coupled" / "history.csv", delimiter=",", names=True)
    t = h["time_s"]
    area = p["model_area_m2"]
    pressure = h["force_z_N"][1:] / area
    fitted = s * area * float(np.sum(sin2_pulse(0.5 * (t[1:] + t[:-1]), p["amplitude"], p["beta"], p["omega"])
                                     * np.diff(t)))
    coupled = mc["force_impulse_z_Ns"]
    bound = s * area * t[-1] * p["fit_residual_rel"] * np.abs(pressure).max()
    print(f"\nfitted pulse's impulse {fitted:.6g} vs coupled {coupled:.6g} N s ({fitted / coupled - 1:+.3%}); "
          f"bound {bound / coupled:.3%}; fit residual {p['fit_residual_rel']:.3%}")
    assert abs(fitted - coupled) <= bound
    assert coupled == pytest.approx(s * h["force_z_N"][1:] @ np.diff(t), rel=1e-9)


@pytest.mark.getdp
def test_the_pressure_runs_impulse_is_the_pulses(compared):
    out, rep, _ = compared
    p, m, mp = rep["pulse"], rep["metrics"], rep["pressure_metrics"]
    s, area = p["symmetry_factor"], mp["load0_area_m2"]
    h = np.genfromtxt(out / "pressure" / "history.csv", delimiter=",", names=True)
    t0, t1 = h["time_s"][:-1], h["time_s"][1:]
    k, dt = h["substeps"][1:], h["dt_s"][1:]
    t_mid = t0 + 0.5 * (k - 1) * dt
    pulse = lambda x: sin2_pulse(x, p["amplitude"], p["beta"], p["omega"])  # noqa: E731
    held = s * area * float(np.sum(pulse(t_mid) * (t1 - t0)))
    got = mp["force_impulse_z_Ns"]
    # closed form over [0, T] with the step rule's leading terms (equal EM steps h, mechanical step dt)
    T, hh, d, eps = t1[-1], t1[0] - t0[0], 0.5 * dt[0], 1e-11
    slope = lambda x: (pulse(x + eps) - pulse(x - eps)) / (2 * eps)  # noqa: E731
    closed = s * area * pulse_impulse_per_area(_pulse(p, T))
    predicted = closed - s * area * (hh ** 2 / 24 * (slope(T) - slope(0.0)) + d * (pulse(T) - pulse(0.0)))
    print(f"\npressure run: impulse {got:.8g}, held pulse {held:.8g} ({got / held - 1:.2e}), closed form "
          f"{closed:.8g} ({got / closed - 1:+.3%}), with the step rule's terms {predicted:.8g} ({got / predicted - 1:.2e})")
    assert np.all(np.abs(np.diff(t1 - t0)) <= 1e-6 * hh) and np.all(k == k[0])   # equal steps (10 digits in history.csv)
    # the follower pressure's area changes with the motion (1e-7 m here): a few 1e-7
    assert got == pytest.approx(held, rel=1e-5)
    assert got == pytest.approx(predicted, rel=1e-4)
    assert m["impulse_pressure_Ns"] == mp["force_impulse_Ns"] and m["impulse_coupled_Ns"] > 0
    assert m["impulse_rel_diff"] == pytest.approx(abs(m["impulse_pressure_Ns"] / m["impulse_coupled_Ns"] - 1), rel=1e-12)


@pytest.mark.getdp
def test_shapes_compared_on_the_same_nodes_in_3d(compared):
    from pulseform.orchestrator.run.mech_fields import read_fields
    from pulseform.orchestrator.workflows.compare import final_shape, shape_distance

    out, rep, _ = compared
    a, b = read_fields(out / "coupled")["sheet"], read_fields(out / "pressure")["sheet"]
    assert a.solid and np.array_equal(a.points, b.points) and np.array_equal(a.triangles, b.triangles)
    (xc, uc, _), (xp, up, _) = (final_shape(out / r, "", "sheet") for r in ("coupled", "pressure"))
    assert xc.shape[1] == 3 and uc.shape == xc.shape
    d = float(np.linalg.norm((xc + uc) - (xp + up), axis=1).max())   # the same material points
    assert rep["metrics"]["shape_distance_max_mm"] == pytest.approx(1e3 * d, rel=1e-12) and d > 0
    assert shape_distance(xc, uc, xp, up) == d
    m = rep["metrics"]
    assert m["sheet_max_uz_mm_coupled"] > 0 and m["sheet_max_uz_mm_pressure"] > 0
    for name in ("compare_pressure.png", "compare_shapes.png", "compare_histories.png"):
        assert (out / "plots" / name).stat().st_size > 5000, name
    assert (out / "pressure" / "case.toml").read_text().count('load = "pressure"') == 1


def _in_process(capsys, *args: str) -> subprocess.CompletedProcess:
    """``pulseform *args`` through the CLI's ``main`` in this process, as a finished process (exit code, stdout,
    stderr) for ``one_line_error``."""
    from pulseform.orchestrator.cli import main

    capsys.readouterr()
    rc = main(list(args))
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(["pulseform", *args], rc, out, err)


@pytest.mark.parametrize("args,says", [
    ((), "--surface"),   # a geometry file does not know its loaded surface
    (("--surface", "{rmin = 0.01"), "not a TOML inline table"),
    (("--surface", "{r = 0.01}"), "unknown bound 'r'"),
    (("--surface", "{zmin = 2e-3, zmax = 1e-3}"), "--surface.zmax"),
    (("--surface", SURFACE, "--body", "coil"), "--body 'coil'"),
])
def test_bad_compare_inputs_of_a_3d_geometry_file(tmp_path, capsys, args, says):
    """One line, exit 2, before any run (the CLI's ``main`` in this process: no interpreter start per input)."""
    from wf_helpers import one_line_error

    r = _in_process(capsys, "compare", CASE, "--out", str(tmp_path / "c"), *COARSE, *args)
    line = one_line_error(r)
    assert r.returncode == 2 and says in line, line
    assert not (tmp_path / "c" / "coupled").exists()


def test_a_surface_is_refused_on_a_2d_case(tmp_path, capsys):
    from wf_helpers import one_line_error

    r = _in_process(capsys, "compare", str(REPO / "cases/emf_sheet_bulge"), "--out", str(tmp_path / "c"), "--surface", SURFACE)
    line = one_line_error(r)
    assert r.returncode == 2 and "--surface is for 3D models" in line, line
