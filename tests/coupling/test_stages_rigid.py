"""``[[stages]]`` with rigid bodies (issue 34, item 5): a rigid body's position, velocity and end-stop state go from
stage to stage with the deformable bodies' state.

* The rigid participant alone (default tier): set at rest where it is, a body under a constant force F travels
  F t² / (2 m) and reaches F t / m after t, from either scheme (central differences start from rest with their half
  step, the held force is exact): to 1e-12; the change of scheme (explicit to implicit and back) keeps the position,
  the velocity at the present time and the totals.
* cases/emf_sheet_die with a free sheet and a free rigid die, no contact (tests/coupling/test_rigid_case.py's set-up),
  driven by the prescribed damped sine of cases/emf_fixed_disk (20 kA e^(−1e4 t) sin(1e5 t), a function of the run's
  time: a later pulse stage goes on with it, no new discharge), 6 us:
  - split into two pulse stages at 3 us (velocities kept) it equals the unsplit run bit for bit (history, physics
    metrics);
  - implicit, the second stage with its velocities zeroed: the die is at rest where the first stage left it, and
    from there its momentum m v is the impulse of its own force since the hand-over, Σ F dt (the held force is
    exact: history.csv's 10 digits), the sheet's momentum likewise restarts from zero; the ledger, what the
    hand-over took out counted, still closes;
  - explicit to 3 us, then implicit: the die's position and velocity carried, then m v grows by Σ F dt.
"""
from __future__ import annotations

import json
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from pulseform.orchestrator.mech.rigid import RigidMechanics
from pulseform.solvers.dolfinx.rigid import EndStop, RigidBody
from pulseform.solvers.dolfinx.rigid_held import HeldRigidBody
from warm_cli import pulseform_cli

from .resume_check import TIMER_PREFIXES_3D, TIMERS_3D, sigint_then_resume

REPO = Path(__file__).resolve().parents[2]


def _body(kind, velocity=(0.0, 3.0)):
    nodes = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    return kind("die", nodes, 2.0, free=(False, True), velocity=velocity, gravity=(0.0, -9.81),
                stops=(EndStop(1, -1.0, 1, 0.5),))


@pytest.mark.parametrize("kind", [RigidBody, HeldRigidBody])
def test_a_rigid_body_set_at_rest_restarts_as_from_rest(kind):
    m, f, dt, n = 2.0, np.array([0.0, 50.0]), 1e-4, 40
    b = _body(kind)
    b.advance(dt, 25, f)
    u0 = b.u.copy()
    b.rest()
    assert not b.velocity_now().any() and b.kinetic_energy() == 0.0
    b.advance(dt, n, f)
    a, t = 50.0 / m - 9.81, n * dt                      # F/m + g on the free axis
    assert b.u[1] - u0[1] == pytest.approx(0.5 * a * t * t, rel=1e-12)
    assert b.velocity_now()[1] == pytest.approx(a * t, rel=1e-12)
    assert b.u[0] == 0.0


def test_change_of_scheme_keeps_the_state():
    r = RigidMechanics([_body(RigidBody)], 1e-4)
    r.advance(1e-4, 30, {"die": np.array([[0.0, 20.0], [0.0, 0.0], [0.0, 0.0]])})
    b = r.bodies["die"]
    u, v, work = b.u.copy(), b.velocity_now(), b.work_J
    r.use_scheme(True)
    h = r.bodies["die"]
    assert type(h) is HeldRigidBody and h.stops == b.stops and h.time == b.time and h.step_count == b.step_count
    assert np.array_equal(h.u, u) and np.array_equal(h.velocity_now(), v) and h.work_J == work
    r.use_scheme(False)
    back = r.bodies["die"]
    assert type(back) is RigidBody and np.array_equal(back.u, u)
    assert np.allclose(back.velocity_now(), v, rtol=1e-14, atol=0.0)


TWO_PULSES = 'stages=[{name="a", kind="pulse", end=2e-6}, {name="b", kind="pulse", end=4e-6}]'


@pytest.mark.parametrize("case, sets, key, says", [
    ("jumping_ring", ["time.end=4e-6", "output.field_interval=1e-6"], "stages", "this case has none"),
    ("user_deck_sheet_bulge", ["time.end=4e-6", "output.field_interval=1e-6"], "stages[1].kind", "built-in deck"),
])
def test_what_stages_still_refuse_is_one_line(capsys, case, sets, key, says):
    """An all-rigid case (nothing for a springback or a hand-over to carry: a stage chain of rigid bodies alone is
    not done), a bank's second discharge from a user's deck (its circuit is the deck's)."""
    from pulseform.orchestrator.cli import main

    args = ["check", str(REPO / "cases" / case)] + [a for x in sets + [TWO_PULSES] for a in ("--set", x)]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert key in err and says in err and len(err.splitlines()) == 1, err


def test_stages_of_a_coupled_3d_case_and_a_rigid_body_are_accepted(capsys):
    """The refusals lifted (coupled 3D cases; rigid bodies beside deformable ones): ``pulseform check`` passes."""
    from pulseform.orchestrator.cli import main

    for case, extra in (("emf_sheet_bulge_3d", []),
                        ("emf_sheet_die", ["bodies.die.rigid=true", "bodies.die.fixed=[]", "contact=[]"])):
        over = ["time.end=4e-6", "output.field_interval=1e-6", TWO_PULSES] + extra
        args = ["check", str(REPO / "cases" / case)] + [a for x in over for a in ("--set", x)]
        assert main(args) == 0, capsys.readouterr().err


def _sheet_die(stages, implicit: bool) -> dict:
    case = tomllib.loads((REPO / "cases/emf_sheet_die/case.toml").read_text())
    case["time"]["end"] = 6e-6
    case["output"] = {**case.get("output", {}), "plots": False, "field_interval": 3e-6}
    case.pop("contact")
    for b in case["bodies"]:
        b["fixed"] = []
    case["bodies"][1]["rigid"] = True
    del case["em"]["circuit"]
    case["em"]["current"] = {"amplitude": 20e3, "beta": 1e4, "omega": 1e5}   # cases/emf_fixed_disk's
    if implicit:   # tests/coupling/test_rigid_implicit.py's steps
        case["mechanics"].update({"integrator": "implicit", "implicit": {"dt": 2e-7}})
        case["coupling"]["n"] = 1
    if stages:
        case["stages"] = stages
    return case


def _run(tmp_path: Path, name: str, case: dict) -> tuple[Path, dict]:
    (tmp_path / name).mkdir()
    file = tmp_path / name / "case.toml"
    file.write_text(tomli_w.dumps(case))
    out = tmp_path / name / "out"
    r = pulseform_cli(["run", str(file), "--out", str(out), "--quiet"])
    assert r.returncode == 0, r.stderr[-3000:]
    return out, json.loads((out / "metrics.json").read_text())


def _history(out: Path) -> tuple[list[str], np.ndarray]:
    cols = (out / "history.csv").read_text().splitlines()[0].split(",")
    return cols, np.loadtxt(out / "history.csv", delimiter=",", skiprows=1)




@pytest.mark.slow
@pytest.mark.getdp
def test_two_pulse_stages_with_a_rigid_die_equal_the_unsplit_run(tmp_path):
    stages = [{"name": "a", "kind": "pulse", "end": 3e-6}, {"name": "b", "kind": "pulse", "end": 6e-6}]
    ref, want = _run(tmp_path, "plain", _sheet_die(None, False))
    out, got = _run(tmp_path, "staged", _sheet_die(stages, False))
    cols_ref, h_ref = _history(ref)
    cols, h = _history(out)
    stage = h[:, cols.index("stage")]
    assert not h[:, cols.index("energy_stage_released_J")].any()   # nothing taken out: velocities kept
    h = np.delete(h, [cols.index("stage"), cols.index("energy_stage_released_J")], axis=1)
    assert [c for c in cols if c not in ("stage", "energy_stage_released_J")] == cols_ref
    start_b = int(np.flatnonzero(stage == 2.0)[0])      # the row the second stage records at its start
    assert h[start_b, 0] == h[start_b - 1, 0] == pytest.approx(3e-6, rel=1e-12)
    h = np.delete(h, start_b, axis=0)
    print(f"\ndie at 3 us: {h_ref[start_b - 1, cols_ref.index('die_velocity_y_m_s')]:.6g} m/s; rows {len(h_ref)}")
    assert h_ref[start_b - 1, cols_ref.index("die_velocity_y_m_s")] != 0.0    # the die moves across the split
    assert np.array_equal(h, h_ref)
    differ = [k for k, v in want.items() if k not in TIMERS_3D and not k.startswith(TIMER_PREFIXES_3D) and got[k] != v]
    assert set(got) - set(want) == {"stages"} | {k for k in got if k.startswith(("stage_a_", "stage_b_"))}
    assert not differ, differ


@pytest.mark.slow
@pytest.mark.getdp
@pytest.mark.parametrize("between", ["zeroed", "springback"])
def test_zeroed_velocities_restart_the_rigid_die_from_rest(tmp_path, between):
    """``between``: the second pulse zeroes the velocities, or a springback stage comes between the pulses (it leaves
    the die where it is, at rest)."""
    second = {"name": "b", "kind": "pulse", "end": 6e-6}
    stages = [{"name": "a", "kind": "pulse", "end": 3e-6}] + (
        [dict(second, velocities="zeroed")] if between == "zeroed"
        else [{"name": "r", "kind": "springback", "springback": {"supports": "minimal"}}, second])   # a free sheet
    out, m = _run(tmp_path, between, _sheet_die(stages, True))
    cols, h = _history(out)
    col = {c: h[:, i] for i, c in enumerate(cols)}
    k = int(np.flatnonzero(col["stage"] == 2.0)[0])     # the hand-over's row (3 us; the springback's)
    assert col["time_s"][k] == col["time_s"][k - 1] == pytest.approx(3e-6, rel=1e-12)
    assert col["die_velocity_y_m_s"][k - 1] != 0.0 and col["die_velocity_y_m_s"][k] == 0.0
    assert col["die_position_y_m"][k] == col["die_position_y_m"][k - 1]
    assert col["sheet_momentum_y_Ns"][k] == 0.0
    released = col["energy_stage_released_J"]
    assert released[k] > 0.0 and released[k - 1] == 0.0
    k += between == "springback"                        # the second pulse's own first row
    assert col["die_velocity_y_m_s"][k] == 0.0 and col["time_s"][k] == col["time_s"][k - 1]
    after = slice(k + 1, None)
    impulse = float(col["die_force_y_N"][after] @ col["dt_s"][after])   # the held force over each step
    mv = m["die_mass_kg"] * col["die_velocity_y_m_s"][-1]
    delivered = float(col["force_y_N"][after] @ col["dt_s"][after])
    sheet = col["sheet_momentum_y_Ns"][-1]
    print(f"\ndie m v = {mv:.9g} N s, its impulse since 3 us {impulse:.9g} N s; sheet + die {sheet + mv:.9g} of "
          f"{delivered:.9g} N s; released {col['energy_stage_released_J'][k]:.6g} J; energy_error_rel "
          f"{m['energy_error_rel']:.2e}")
    assert mv == pytest.approx(impulse, rel=2e-9) and mv > 0.0
    assert sheet + mv == pytest.approx(delivered, rel=2e-9)
    assert m["energy_error_rel"] < 1e-6


@pytest.mark.slow
@pytest.mark.getdp
def test_rigid_die_goes_on_from_an_explicit_to_an_implicit_stage(tmp_path):
    """Explicit to 3 us, implicit (0.2 us steps) to 6 us, one mechanical step per EM step: at the hand-over the die
    keeps its position and its velocity at the present time (the central differences' v + dt/2 a becomes the held
    force's full-step velocity), and from there, stepped under the held force, m v grows by the impulse of its own
    force, Σ F dt (exact: history.csv's 10 digits). Stopped by SIGINT in the implicit stage and resumed: history
    and metrics (timers aside) bit for bit."""
    case = _sheet_die([{"name": "a", "kind": "pulse", "end": 3e-6},
                       {"name": "b", "kind": "pulse", "end": 6e-6, "integrator": "implicit"}], False)
    case["mechanics"]["implicit"] = {"dt": 2e-7}
    case["coupling"]["n"] = 1
    out, m = _run(tmp_path, "switch", case)
    cols, h = _history(out)
    col = {c: h[:, i] for i, c in enumerate(cols)}
    k = int(np.flatnonzero(col["stage"] == 2.0)[0])
    v = col["die_velocity_y_m_s"]
    assert col["time_s"][k] == pytest.approx(3e-6, rel=1e-12) and v[k - 1] > 0.0
    assert v[k] == pytest.approx(v[k - 1], rel=1e-12) and col["die_position_y_m"][k] == col["die_position_y_m"][k - 1]
    after = slice(k + 1, None)
    assert col["dt_s"][after].sum() == pytest.approx(3e-6, rel=1e-12)     # a row per step (the loop's own steps)
    impulse = float(col["die_force_y_N"][after] @ col["dt_s"][after])
    mass = m["die_mass_kg"]
    print(f"\ndie: m v at 3 us {mass * v[k]:.9g} N s + impulse {impulse:.9g} N s = {mass * (v[k]) + impulse:.9g}; "
          f"m v at 6 us {mass * v[-1]:.9g} N s; energy_error_rel {m['energy_error_rel']:.2e}")
    assert mass * v[-1] == pytest.approx(mass * v[k] + impulse, rel=2e-9)

    # stopped by SIGINT in the implicit stage and resumed: the die's scheme is the stage's again, bit for bit
    cut = tmp_path / "switch" / "cut"
    args = [str(Path(sys.executable).with_name("pulseform")), "run", str(tmp_path / "switch" / "case.toml"),
            "--out", str(cut), "--quiet"]
    proc, err, stopped, resumed = sigint_then_resume(args, cut, delay=1.0)
    assert proc.returncode == 130, err[-2000:]
    assert 3e-6 < stopped["end_time_s"] < 6e-6, stopped["end_time_s"]      # in the implicit stage
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    assert np.array_equal(_history(cut)[1], h)
    got = json.loads((cut / "metrics.json").read_text())
    differ = [k for k, v in m.items() if k not in TIMERS_3D and not k.startswith(TIMER_PREFIXES_3D) and got[k] != v]
    assert not differ, differ
