"""Repeated shots in 3D (issue 33, ``[em.shots]``): the 3D sector of the demo (cases/emf_sheet_bulge_3d, coarse).

* Bookkeeping (default tier, no getdp step): the 3D load's coil surface and heat capacity are the sector's (its
  boundary triangles less those on the symmetry planes, its tetrahedra's volume) -- times the symmetry factor the
  five revolved rectangular turns of the geometry's numbers (2π (r1 + r2) h + 2π (r2² − r1²) each; volume
  Σ 2π r_mid w h) to 1e-3 (the sector's straight chords); the sheet's outer surface the disk's 2 π R² + 2 π R t;
  the pause cools the coil and the sheet by exp(−h A t / (m c_p)) of those analytic A and m c_p, sets the sheet at
  rest and starts a fresh discharge at the next shot's voltage, whose bank and coil temperature a checkpoint keeps.
* The circuit (slow): three shots of the bank through the 5-turn coil whose resistivity grows linearly with its
  lumped temperature, the sheet at σ = 1 S/m (no eddy current worth the name), against the lumped R(T)-L-C ODE of
  tests/coupling/test_coil_shots.py (its :func:`ode_shots`; L = 2 s W / I² and R(T_ref) = Q_1 / (I_1² dt) from the
  history of GetDP's run, s the symmetry factor; m c_p and the coil's surface from the geometry's numbers): every
  shot's peak current and the coil's temperature rise at the end of every shot within 1 % (the 2D test's figure).
"""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from .sector_case import CASE, MESH, sets
from .test_coil_shots import ALPHA, CP, GAP, H, HT, PAUSE, R_IN, RHO, T_AMB, T_REF, TURNS, W, _turn_surface, ode_shots

EXE = str(Path(sys.executable).with_name("pulseform"))
C, V0, WINDOW, SHOTS = 50e-6, 8.0e3, 24e-6, 3
#: the circuit of the 2D shots test on the coarse 5 degree sector; the sheet without eddy currents
SHOTS3D = MESH + [
    "materials.al_blank.electrical_conductivity=1.0", "materials.al_blank.specific_heat=896.0",
    f"em.circuit={{capacitance={C}, voltage={V0}, resistance=0.0, inductance=2e-6}}",
    "em.coil_conductivity=1e7", f"em.coil_density={RHO}", f"em.coil_heat_capacity={CP}",
    f"em.coil_conductivity_curve={{type='linear_resistivity', temperature_coefficient={ALPHA}, "
    f"reference_temperature={T_REF}}}",
    f"em.shots={{count={SHOTS}, pause={PAUSE}, coil_heat_transfer={H}, ambient_temperature={T_AMB}, "
    "body_heat_transfer=20.0}"]


def _coil_volume() -> float:
    """The whole coil's volume (m³): five w × h rectangles revolved."""
    return sum(2 * math.pi * (R_IN + k * (W + GAP) + W / 2) * W * HT for k in range(TURNS))


@pytest.mark.getdp
def test_3d_shot_bookkeeping(tmp_path):
    from pulseform.orchestrator.case.io import load_case
    from pulseform.orchestrator.run.participants3d import participants_3d
    from pulseform.orchestrator.run.shots import ShotSequence, outer_surface

    case, _ = load_case(CASE, SHOTS3D)
    solver, _, load, _, geo = participants_3d(case, tmp_path / "em")
    s = float(load.model.symmetry_factor)
    area, mcp = load.coil_heat_paths()
    assert s == pytest.approx(72.0, rel=1e-12) and len(load.symmetry_planes) == 2
    assert s * area[0] == pytest.approx(_turn_surface(), rel=1e-3)
    assert s * mcp[0] == pytest.approx(RHO * CP * _coil_volume(), rel=1e-3)
    sheet = solver.bodies["sheet"]
    r, t = 60e-3, 1e-3
    a_sheet = outer_surface(sheet, load.symmetry_planes)
    assert s * a_sheet == pytest.approx(2 * math.pi * r * r + 2 * math.pi * r * t, rel=1e-3)
    assert outer_surface(sheet) > 1.1 * a_sheet   # with the faces on the planes: not the outer surface

    shots = ShotSequence.of_case(case)
    load.state = replace(load.state, t=WINDOW, coil_heat=[40.0 * mcp[0]])   # J in the sector: the coil 40 K warmer
    assert load.coil_temperatures()[0] == pytest.approx(T_REF + 40.0, rel=1e-12)
    sheet.temperature[:] = 400.0
    sheet.v[:] = 1.0
    shots.rows = [{"shot": 1.0, "peak_current_A": 1.0, "coil_temperature_end_K": T_REF + 40.0}]
    shots.begin(2, load, solver, tmp_path, write=True)
    m_sheet = case.materials["al_blank"].density * math.pi * r * r * t
    f_coil = math.exp(-H * _turn_surface() * PAUSE / (RHO * CP * _coil_volume()))
    f_sheet = math.exp(-20.0 * (2 * math.pi * r * r + 2 * math.pi * r * t) * PAUSE / (m_sheet * 896.0))
    assert load.model.coils[0].initial_temperature - T_AMB == pytest.approx(40.0 * f_coil, rel=1e-3)
    assert np.allclose(sheet.temperature - T_AMB, (400.0 - T_AMB) * f_sheet, rtol=1e-3) and not sheet.v.any()
    # a fresh discharge at shot 2's start: fields at rest, the bank at its voltage, the coil's heat from zero
    assert load.state.t == shots.start(2) and load.state.steps == 0 and load.state.circuit == (8e3, 0.0)
    assert load.coil_temperatures()[0] == load.model.coils[0].initial_temperature
    assert (tmp_path / "shots.csv").read_text().splitlines()[1].split(",")[6] == \
        repr(load.model.coils[0].initial_temperature)
    kept = load.shot_state()
    load.begin_shot(2 * WINDOW, 7e3, [500.0])
    assert load.model.circuit.V0 == 7e3 and load.state.circuit == (7e3, 0.0)
    load.load_shot_state(kept)
    assert load.model.circuit.V0 == 8e3 and load.model.coils[0].initial_temperature == kept["coil_t0"][0]
    load.close()


@pytest.mark.getdp
@pytest.mark.slow
def test_three_3d_shots_match_a_lumped_rlc_with_r_of_t(tmp_path):
    from pulseform.orchestrator.run.history import History

    out = tmp_path / "run"
    argv = [EXE, "run", str(CASE), "--out", str(out), "--quiet",
            *sets(SHOTS3D + [f"time.end={WINDOW}", f"output.field_interval={WINDOW}", "output.plots=false",
                             "geometry.em_step=0.5e-6"])]
    r = subprocess.run(argv, capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0, r.stderr[-3000:]
    h = History.read(out / "history.csv")
    t, i, w, heat = (h.column(k) for k in ("time_s", "coil_current_A", "magnetic_energy_J", "coil_joule_heat_J"))
    s = 72.0
    first = t <= WINDOW * (1 + 1e-12)
    k = int(np.argmax(np.abs(i) * first))
    L = 2 * s * w[k] / i[k] ** 2                          # the whole coil in air: W = L I² / 2
    r_ref = heat[1] / (i[1] ** 2 * (t[1] - t[0]))         # first step (implicit Euler from rest): Q = R I_1² dt at T_ref
    mcp = RHO * CP * _coil_volume()
    peaks, ends = ode_shots(L, r_ref, mcp, t[first], c=C, v0=V0, r_ext=0.0, l_ext=2e-6, shots=SHOTS, window=WINDOW)
    with open(out / "shots.csv") as fh:
        rows = list(csv.DictReader(fh))
    got_peak = np.array([float(row["peak_current_A"]) for row in rows])
    got_end = np.array([float(row["coil_temperature_end_K"]) for row in rows])
    print(f"\n3D: L_coil = {L * 1e6:.4f} uH, R_coil(T_ref) = {r_ref * 1e3:.4f} mOhm, m c_p = {mcp:.4f} J/K")
    for n in range(SHOTS):
        print(f"shot {n + 1}: peak {got_peak[n] / 1e3:.4f} kA (ODE {peaks[n] / 1e3:.4f}), coil end "
              f"{got_end[n]:.2f} K (ODE {ends[n]:.2f})")
    assert [int(row["shot"]) for row in rows] == list(range(1, SHOTS + 1))
    assert np.abs(got_peak / np.array(peaks) - 1).max() < 0.01
    assert np.abs((got_end - T_AMB) / (np.array(ends) - T_AMB) - 1).max() < 0.01
    assert got_end[-1] > got_end[0] + 50.0 and got_peak[1] < got_peak[0] * 0.997   # warmer, higher R, lower peak
    # the coil's resistance at T_ref: N² V / (σ S_c²) of the five rectangles (the sector's chords: 1e-3)
    assert r_ref == pytest.approx(TURNS ** 2 * _coil_volume() / (1e7 * (TURNS * W * HT) ** 2), rel=1e-3)


@pytest.mark.slow
@pytest.mark.getdp
def test_3d_shots_resume_bitwise(tmp_path):
    """Two 3D shots (the circuit above, 6 us windows, a checkpoint every 2 us), stopped by SIGINT in the second shot
    (after shot 1's row of shots.csv is written) and resumed: shots.csv, history.csv and every metric but the timers
    equal the uninterrupted run's bit for bit (the 3D checkpoint carries the shots so far, the bank and the coil's
    start temperature, as test_coil_shots.py::test_shots_resume_bitwise checks in 2D)."""
    import signal
    import time

    from .resume_check import assert_coupled3d_outputs_bitwise

    over = [s for s in SHOTS3D if not s.startswith("em.shots=")] + [
        f"em.shots={{count=2, pause={PAUSE}, coil_heat_transfer={H}, ambient_temperature={T_AMB}, "
        "body_heat_transfer=20.0}", "time.end=6e-6", "output.field_interval=2e-6", "output.plots=false",
        "geometry.em_step=0.5e-6"]
    ref, out = tmp_path / "ref", tmp_path / "out"
    argv = [EXE, "run", str(CASE), "--quiet", *sets(over)]
    r = subprocess.run(argv + ["--out", str(ref)], capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0, r.stderr[-3000:]
    proc = subprocess.Popen(argv + ["--out", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 600
    while not (out / "shots.csv").exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.005)
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == 130, err[-2000:]
    stopped = json.loads((out / "metrics.json").read_text())
    assert 6e-6 < stopped["end_time_s"] < 12e-6, stopped["end_time_s"]          # in the second shot
    resumed = subprocess.run(argv + ["--out", str(out), "--resume"], capture_output=True, text=True, timeout=1800)
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert (out / "shots.csv").read_bytes() == (ref / "shots.csv").read_bytes()
    assert_coupled3d_outputs_bitwise(ref, out)
