"""Rigid bodies in case files (issue 17): cases/emf_actuator_disk, a capacitor bank and a flat coil
launching a rigid aluminium disk.

- Momentum: the disk's momentum m v at the end equals the impulse of the held forces the loop handed
  it, as central differences deliver it, to round-off: any force lost or counted twice between
  GetDP's element forces, their transfer and the rigid body's resultant shows here.
- Mass: the disk's mass from density × the region's 2πr volume equals ρ π R² t (exact for
  triangles: r is linear on each).
- The rigid-body participant mixed with the driver's checkpoint keys restarts bit for bit.
- Bad input: one line naming the key, exit 2.
"""
from __future__ import annotations

import copy
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from pulseform.orchestrator.cli import main
from pulseform.orchestrator.mech.mixed import MixedMechanics, region_centroid, region_mass
from pulseform.orchestrator.mech.rigid import RigidMechanics
from pulseform.orchestrator.mesh.shared import ConductorMesh
from pulseform.solvers.dolfinx.rigid import EndStop, RigidBody

REPO = Path(__file__).resolve().parents[2]
CASE = REPO / "cases/emf_actuator_disk"
BASE = tomllib.loads((CASE / "case.toml").read_text())


def _delivered(hist, column: str = "force_y_N") -> float:
    """The impulse (N s) central differences deliver to the half-step velocity of the held resultants
    ``column`` (as the validation registry's free sheet, orchestrator/workflows/registry.py): the force
    held over mechanical step s enters with the weight (dt_(s-1) + dt_s) / 2, the first with dt_0 / 2."""
    f = np.repeat(hist[column], hist["substeps"].astype(int))
    d = np.repeat(hist["dt_s"], hist["substeps"].astype(int))
    return float(f @ np.concatenate([[0.5 * d[0]], 0.5 * (d[:-1] + d[1:])]))


def _v_half(hist, body: str, c: str) -> float:
    """The body's velocity (m/s) at the last half step: the history's velocity at the step's end less
    half a step of its acceleration."""
    return float(hist[f"{body}_velocity_{c}_m_s"][-1] - 0.5 * hist["dt_s"][-1] * hist[f"{body}_acceleration_{c}_m_s2"][-1])


@pytest.mark.getdp
def test_disk_momentum_equals_the_impulse_and_its_mass_the_volume(tmp_path, capsys):
    out = tmp_path / "run"
    rc = main(["run", str(CASE), "--out", str(out), "--quiet", "--set", "time.end=30e-6",
               "--set", "output.field_interval=15e-6", "--set", "output.plots=false",
               "--set", "mechanics.gravity=[0.0, 0.0]"])
    assert rc == 0, capsys.readouterr().err
    m = json.loads((out / "metrics.json").read_text())
    g = BASE["geometry"]
    mass = BASE["materials"]["al"]["density"] * math.pi * g["sheet_radius"] ** 2 * g["sheet_thickness"]
    assert m["disk_mass_kg"] == pytest.approx(mass, rel=1e-12)
    hist = np.genfromtxt(out / "history.csv", delimiter=",", names=True)[1:]
    delivered, v_half = _delivered(hist), _v_half(hist, "disk", "y")
    print(f"\nm v = {mass * v_half:.12g} N s, impulse delivered {delivered:.12g} N s, v = {v_half:.4g} m/s")
    assert v_half > 1.0  # it is launched
    assert mass * v_half == pytest.approx(delivered, rel=2e-9)  # history.csv holds 10 significant digits
    assert hist["disk_force_y_N"] == pytest.approx(hist["force_y_N"], rel=1e-12)  # the body got the resultant
    assert np.all(hist["disk_travel_y_m"] >= 0.0) and np.all(np.diff(hist["disk_travel_y_m"]) >= 0.0)
    assert m["disk_max_speed_m_s"] == pytest.approx(hist["disk_velocity_y_m_s"][-1], rel=1e-9)  # pushed away (10 digits)
    assert m["conservation_error_rel"] < 1e-12


def test_region_mass_of_a_ring_and_a_plane_plate():
    pts = np.array([[0.01, 0.0], [0.03, 0.0], [0.03, 0.002], [0.01, 0.002], [0.02, 0.001]])
    cells = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    sub = ConductorMesh(np.arange(4), np.arange(5), pts, cells)
    assert region_mass(sub, 2700.0, True) == pytest.approx(2700.0 * math.pi * (0.03 ** 2 - 0.01 ** 2) * 0.002,
                                                           rel=1e-13)
    assert region_mass(sub, 2700.0, False, thickness=0.5) == pytest.approx(2700.0 * 0.02 * 0.002 * 0.5, rel=1e-13)


def test_history_gives_the_reference_point_position_and_the_travel():
    """Issue 32 (item 8): ``<body>_position_<c>_m`` is the position of the body's reference point, the centroid
    of its region's section (here a rectangle 10..30 mm by 0..2 mm split into four triangles: (20, 1) mm), and
    ``<body>_travel_<c>_m`` the translation from the start; before, the position column was the travel."""
    pts = np.array([[0.01, 0.0], [0.03, 0.0], [0.03, 0.002], [0.01, 0.002], [0.025, 0.0015]])  # off-centre node
    cells = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    sub = ConductorMesh(np.arange(4), np.arange(5), pts, cells)
    assert region_centroid(sub) == pytest.approx([0.02, 0.001], rel=1e-13)
    assert not np.allclose(pts.mean(axis=0), [0.02, 0.001])  # not the mean of the nodes
    body = RigidBody("plate", pts, 0.01, free=(False, True), offset=(0.0, 0.5e-3), reference=tuple(region_centroid(sub)))
    body.advance(1e-4, 10, np.array([0.0, 0.2]))
    h = body.history()
    travel = 0.5e-3 + 0.5 * 20.0 * (1e-3) ** 2  # offset + a t²/2 (central differences are exact for it)
    assert h["plate_travel_y_m"] == pytest.approx(travel, rel=1e-12)
    assert h["plate_position_y_m"] == pytest.approx(0.001 + travel, rel=1e-12)
    assert "plate_position_x_m" not in h and "plate_travel_x_m" not in h  # axial motion only


def test_mixed_mechanics_restarts_bit_for_bit():
    nodes = np.array([[0.01, 0.001], [0.04, 0.001], [0.04, 0.003]])

    def make():
        body = RigidBody("disk", nodes, 0.027, gravity=(0.0, -9.81), stops=(EndStop(1, 0.0, 1, 0.3),))
        return MixedMechanics(None, RigidMechanics([body], 1e-6))

    a, b = make(), make()
    f = {"disk": np.array([[0.0, 3.0], [0.0, -1.0], [0.0, 2.0]])}
    for k in range(40):
        a.advance(1e-6, 3, {"disk": f["disk"] * math.sin(0.3 * k)})
        if k == 17:
            b.load_state_dict(copy.deepcopy(a.state_dict()))
        elif k > 17:
            b.advance(1e-6, 3, {"disk": f["disk"] * math.sin(0.3 * k)})
    assert a.state_dict().keys() == b.state_dict().keys()
    for key, value in a.state_dict().items():
        assert np.array_equal(value, b.state_dict()[key]), key
    assert a.time == b.time and a.step_count == b.step_count == 120
    assert np.array_equal(a.total_force(f), f["disk"].sum(axis=0))


BAD = [
    ("negative_mass", {"mass": -0.01}, "bodies[0].mass"),
    ("zero_mass", {"mass": 0.0}, "bodies[0].mass"),
    ("rigid_with_shape", {"region": None, "shape": {"type": "rectangle", "width": 0.01, "height": 0.001},
                          "mesh_size": 1e-3}, "bodies[0].rigid"),
    ("radial_motion_axisymmetric", {"moves": [0, 1]}, "bodies[0].moves"),
    ("stop_on_a_fixed_component", {"stops": [{"component": 0, "position": 0.0}]}, "bodies[0].stops[0].component"),
    ("offset_beyond_its_stop", {"offset": [0.0, -1e-3]}, "bodies[0].stops[0].position"),
    ("restitution_above_one", {"stops": [{"component": 1, "position": 0.0, "restitution": 1.5}]},
     "bodies[0].stops[0].restitution"),
    ("rigid_keys_on_a_deformable_body", {"rigid": False, "stops": [], "mass": 0.03}, "bodies[0].mass"),
    ("clamped_rigid_body", {"fixed": [{"where": {"xmin": 0.03}}]}, "bodies[0].fixed"),
]


@pytest.mark.parametrize("name,edits,key", BAD, ids=[b[0] for b in BAD])
def test_bad_rigid_body(tmp_path, capsys, name, edits, key):
    data = copy.deepcopy(BASE)
    for k, v in edits.items():
        if v is None:
            del data["bodies"][0][k]
        else:
            data["bodies"][0][k] = v
    file = tmp_path / "case.toml"
    file.write_text(tomli_w.dumps(data))
    rc = main(["check", str(file)])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert key in lines[0], lines[0]


def test_rigid_body_in_a_mechanics_case_is_refused(capsys):
    rc = main(["check", str(REPO / "cases/bar_impact"), "--set", "bodies.left.rigid=true"])
    err = capsys.readouterr().err
    assert rc == 2 and "bodies[0].rigid" in err and "coupled" in err, err


@pytest.mark.getdp
def test_deformable_sheet_and_rigid_die_share_the_impulse(tmp_path, capsys):
    """cases/emf_sheet_die with a free sheet (deformable) and a free rigid die, no contact, 6 µs: the
    two bodies' momenta add up to the impulse delivered (the die, behind the sheet, gets a push too)."""
    out = tmp_path / "run"
    rc = main(["run", str(REPO / "cases/emf_sheet_die"), "--out", str(out), "--quiet", "--set", "time.end=6e-6",
               "--set", "output.field_interval=3e-6", "--set", "output.plots=false", "--set", "contact=[]",
               "--set", "bodies.sheet.fixed=[]", "--set", "bodies.die.fixed=[]", "--set", "bodies.die.rigid=true"])
    assert rc == 0, capsys.readouterr().err
    m = json.loads((out / "metrics.json").read_text())
    hist = np.genfromtxt(out / "history.csv", delimiter=",", names=True)[1:]
    die = m["die_mass_kg"] * _v_half(hist, "die", "y")
    sheet = hist["sheet_momentum_y_Ns"][-1]
    print(f"\nsheet {sheet:.9g} + die {die:.9g} = {sheet + die:.9g} N s; delivered {_delivered(hist):.9g} N s")
    assert die > 1e-5 * sheet > 0.0  # 6e-5 of the total: far above the tolerance below
    assert sheet + die == pytest.approx(_delivered(hist), rel=2e-9)  # history.csv's 10 digits


def test_all_rigid_case_without_a_period_needs_dt_max(capsys):
    sets = ["bodies.plate.rigid=true", "bodies.plate.fixed=[]",
            'em.sources=[{name = "main", type = "dc", current = 100.0}, {name = "late", type = "dc", current = 50.0}]']
    args = ["check", str(REPO / "cases/two_coils_plate")] + [a for s in sets for a in ("--set", s)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "time.dt_max" in err and "rigid" in err and len(err.strip().splitlines()) == 1, err
    assert main(args + ["--set", "time.dt_max=1e-6"]) == 0


def test_all_rigid_case_too_long_for_its_source_is_refused(capsys):
    """400 s of the actuator at 120 EM steps per period of its ~0.1 ms bank: ~5e8 EM steps."""
    assert main(["check", str(CASE), "--set", "time.end=400.0"]) == 2
    err = capsys.readouterr().err
    assert "coupling.steps_per_period" in err and "limits.max" in err, err


@pytest.mark.slow
@pytest.mark.getdp
def test_planar_rigid_blank_moves_in_x_and_y_whatever_the_depth(tmp_path, capsys):
    """(Slow, ~6 s: two more runs of the planar corner fill at two depths. The default tier's companions: the
    same depth scaling with a deformable blank, tests/coupling/test_multibody.py::test_planar_forces_scale_with_the_depth,
    and a rigid body's momentum against the delivered impulse,
    test_disk_momentum_equals_the_impulse_and_its_mass_the_volume.) cases/emf_corner_fill (plane strain, per metre of depth) with its blank rigid and free in x and y,
    no contact, 6 µs: the forces and the mass both scale with mechanics.thickness, so the motion does not
    depend on it (1e-9); the blank's momentum in x and y equals the impulse delivered of its own resultant."""
    runs = {}
    for depth in (1.0, 0.5):
        out = tmp_path / f"d{depth}"
        rc = main(["run", str(REPO / "cases/emf_corner_fill"), "--out", str(out), "--quiet", "--set", "time.end=6e-6",
                   "--set", "output.field_interval=3e-6", "--set", "output.plots=false", "--set", "contact=[]",
                   "--set", "bodies.blank.fixed=[]", "--set", "bodies.blank.rigid=true",
                   "--set", "bodies.blank.moves=[0, 1]", "--set", f"mechanics.thickness={depth}", "--set", "analysis=[]"])
        assert rc == 0, capsys.readouterr().err
        runs[depth] = (json.loads((out / "metrics.json").read_text()),
                       np.genfromtxt(out / "history.csv", delimiter=",", names=True)[1:])
    (m1, h1), (m2, h2) = runs[1.0], runs[0.5]
    assert m2["blank_mass_kg"] == pytest.approx(0.5 * m1["blank_mass_kg"], rel=1e-12)
    for c in "xy":
        u1, u2 = h1[f"blank_travel_{c}_m"], h2[f"blank_travel_{c}_m"]
        assert np.abs(u1 - u2).max() <= 1e-9 * np.abs(u1).max(), c
        delivered, v_half = _delivered(h1, f"blank_force_{c}_N"), _v_half(h1, "blank", c)
        print(f"\n{c}: m v = {m1['blank_mass_kg'] * v_half:.9g} N s, delivered {delivered:.9g} N s")
        assert abs(v_half) > 0.0
        assert m1["blank_mass_kg"] * v_half == pytest.approx(delivered, rel=2e-9)


def test_compare_refuses_a_rigid_workpiece_before_running(tmp_path, capsys):
    out = tmp_path / "cmp"
    assert main(["compare", str(CASE), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "'disk' is rigid" in err and len(err.strip().splitlines()) == 1, err
    assert not (out / "coupled").exists()  # refused before the coupled run
