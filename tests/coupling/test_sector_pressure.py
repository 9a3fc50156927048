"""The coupled 3D sector driven by pressure pulses (``coupling.load = "pressure"`` with ``[[loads]]``): the
counterpart of its coupled run that ``pulseform compare`` uses, on the general 3D geometry-file path
(orchestrator/mech/pulses3d.py, the pressure branch of orchestrator/run/participants3d.py).

References: (1) the follower pressure's consistent nodal forces over a flat face sum to p × its area,
and the sector's lower face is the fan of its arc nodes about the apex: A = ½ R² Σ sin Δθ (exact for
the polygon; ½ α R² of the true sector up to the chord error); (2) a free sheet's internal forces
sum to zero along z and the sliding meridian planes have horizontal normals, so Σ m v_z is the
impulse central differences delivered: force F_s of substep s with weight (dt_{s−1} + dt_s)/2
(dt_{−1} = 0), rebuilt from history.csv (as tests/coupling/test_coupled_getdp.py does in 2D).
"""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from .sector_case import CASE, COARSE
from warm_cli import pulseform_cli

#: the 2D demo's loaded surface (compare.loaded_surface: the sheet's lower face over the coil, r in
#: [10, 34] mm at z = 1.5 mm) as a 3D box (rmin/rmax about the z-axis, z bounds) with an eq. (7) pulse of the
#: demo's discharge
PULSE = ('loads=[{type="pulse_sin2", body="sheet", surface={rmin=0.01, rmax=0.034, zmin=1.4999e-3, zmax=1.5001e-3}, '
         'amplitude=8.7e6, beta=8.9e3, omega=9.3e4, t_end=60e-6}]')


def _sets(*extra: str) -> list[str]:
    out = []
    for s in (*COARSE, 'coupling.load="pressure"', PULSE, *extra):
        out += ["--set", s]
    return out


def test_pressure_on_the_lower_face_sums_to_p_times_its_area(tmp_path):
    from pulseform.orchestrator.case.io import load_case
    from pulseform.orchestrator.case.model import Box
    from pulseform.orchestrator.mech.participants import DolfinxMechanics
    from pulseform.orchestrator.mech.pulses3d import PressurePulses3D, box_nodes
    from pulseform.orchestrator.run.participants3d import participants_3d

    case, _ = load_case(str(CASE), [*COARSE, 'coupling.load="pressure"', PULSE])
    solver, rigid, load, _, _ = participants_3d(case, tmp_path)
    assert rigid is None and isinstance(load, PressurePulses3D)
    body = solver.bodies["sheet"]
    g = case.geometry.parameters
    z0, R, alpha = g["coil_gap"], g["sheet_radius"], math.radians(g["angle_deg"])
    box = Box(rmax=R * (1 + 1e-9), zmin=z0 - 1e-7, zmax=z0 + 1e-7)   # the whole lower face
    marked = box_nodes(box, body.X0)
    p = 7.5e6
    f = DolfinxMechanics(solver).pressure_forces("sheet", marked, p)
    F = f[: body.n_owned].sum(axis=0)
    # the face's arc nodes (r = R, z = z0) about the apex: the fan's area
    X = body.X0
    arc = np.flatnonzero(marked & (np.abs(np.hypot(X[:, 0], X[:, 1]) - R) <= 1e-9 * R))
    theta = np.sort(np.arctan2(X[arc, 1], X[arc, 0]))
    fan = 0.5 * R ** 2 * float(np.sum(np.sin(np.diff(theta))))
    print(f"\nlower face: sum F_z = {F[2]:.12g} N, p A_fan = {p * fan:.12g} N ({len(arc)} arc nodes), "
          f"p alpha R^2 / 2 = {p * 0.5 * alpha * R ** 2:.12g} N; F_x, F_y = {F[0]:.3g}, {F[1]:.3g} N")
    assert theta[0] == pytest.approx(0.0, abs=1e-12) and theta[-1] == pytest.approx(alpha, rel=1e-12)
    assert F[2] == pytest.approx(p * fan, rel=1e-12)       # pushes into the sheet: +z on the lower face
    assert abs(F[0]) <= 1e-12 * F[2] and abs(F[1]) <= 1e-12 * F[2]   # a flat face: no in-plane resultant
    # the chords' area deficit of the true sector: (Δθ)² / 6 relative at most
    assert fan == pytest.approx(0.5 * alpha * R ** 2, rel=np.diff(theta).max() ** 2 / 6)
    # the upper face is not loaded by a box at the lower one
    assert not np.any(marked & (np.abs(X[:, 2] - (z0 + g["sheet_thickness"])) <= 1e-9))


@pytest.fixture(scope="module")
def free_sheet(tmp_path_factory) -> Path:
    """The coarse sector without its clamp (a free sheet), 3 µs of the eq. (7) pulse."""
    out = tmp_path_factory.mktemp("free3d") / "run"
    r = pulseform_cli(["run", str(CASE), "--out", str(out), "--quiet", *_sets("bodies.sheet.fixed=[]"),
                       "--set", "output.plots=false"])
    assert r.returncode == 0, r.stderr[-3000:]
    return out


def test_momentum_equals_the_impulse_of_the_held_pressure_forces(free_sheet):
    h = np.genfromtxt(free_sheet / "history.csv", delimiter=",", names=True)
    m = json.loads((free_sheet / "metrics.json").read_text())
    forces, dts = [], []
    for row in h[1:]:
        k = int(row["substeps"])
        forces += [row["force_z_N"]] * k
        dts += [row["dt_s"]] * k
    forces, dts = np.array(forces), np.array(dts)
    expected = float(np.sum(forces * 0.5 * (np.concatenate([[0.0], dts[:-1]]) + dts)))
    got = h["sheet_momentum_z_Ns"][-1]
    print(f"\nfree sector sheet: sum m v_z = {got!r}, rebuilt impulse {expected!r} N s "
          f"({got / expected - 1:.2e}); loop impulse {m['sector_force_impulse_z_Ns']!r}")
    assert got == pytest.approx(expected, rel=1e-9)
    # the loop's impulse Σ F (t1 − t0), and the device's (× 360 / 5) under the 2D names
    assert m["sector_force_impulse_z_Ns"] == pytest.approx(np.sum(forces * dts), rel=1e-12)
    s = m["symmetry_factor"]   # 360 deg over the mesh's angular extent (round-off)
    assert s == pytest.approx(72.0, rel=1e-12)
    assert m["force_impulse_z_Ns"] == pytest.approx(s * m["sector_force_impulse_z_Ns"], rel=1e-15)
    assert h["device_impulse_z_Ns"][-1] == pytest.approx(m["force_impulse_z_Ns"], rel=1e-9)
    assert m["load0_area_m2"] > 0 and m["sheet_max_uz_mm"] > 0 and m["em_steps"] == 9
    assert not (free_sheet / "em" / "getdp").exists()   # no getdp run


def _main(capsys, *args: str) -> subprocess.CompletedProcess:
    """``pulseform *args`` through the CLI's ``main`` in this process (no interpreter start), as a finished
    process: exit code, stdout, stderr."""
    from pulseform.orchestrator.cli import main

    capsys.readouterr()
    rc = main(list(args))
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(["pulseform", *args], rc, out, err)


def _check(capsys, *sets: str) -> subprocess.CompletedProcess:
    args = ["check", str(CASE)]
    for s in (*COARSE, *sets):
        args += ["--set", s]
    return _main(capsys, *args)


def test_loads_and_coupling_keys_of_a_3d_geometry_file(capsys):
    """[[loads]] need coupling.load = 'pressure' and the reverse; damping acts only with the pulses."""
    r = _check(capsys, PULSE)
    assert r.returncode == 2 and "coupling.load = 'pressure'" in r.stderr, r.stderr
    r = _check(capsys, 'coupling.load="pressure"')
    assert r.returncode == 2 and "loads" in r.stderr, r.stderr
    r = _check(capsys, "mechanics.mass_damping=1e3")
    assert r.returncode == 2 and "mechanics.mass_damping" in r.stderr, r.stderr
    assert _check(capsys, 'coupling.load="pressure"', PULSE).returncode == 0
    assert _check(capsys, 'coupling.load="pressure"', PULSE, "mechanics.mass_damping=1e3").returncode == 0


def test_a_box_that_loads_nothing_is_named(tmp_path, capsys):
    """A 2D-style box (x, y bounds read as the axisymmetric case's r, z: here y in a 0.2 um slab) loads no
    triangle of the 3D sheet: the run stops before its first step with one line naming the load, exit 2."""
    bad = PULSE.replace("rmin=0.01, rmax=0.034, zmin=1.4999e-3, zmax=1.5001e-3", "xmin=0.01, xmax=0.034, "
                        "ymin=1.4999e-3, ymax=1.5001e-3")
    r = _main(capsys, "run", str(CASE), "--out", str(tmp_path / "x"), "--quiet", *_sets(bad))
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1 and "loads[0].surface" in lines[0] and "rmin/rmax" in lines[0], r.stderr
    print(lines[-1])
