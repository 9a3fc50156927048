"""Repeated shots with a coil whose conductivity follows its temperature (issue 33, items 3 and 4).

Five discharges of a 50 µF bank through a five-turn flat coil (cases/emf_sheet_bulge's geometry, coarse) whose
resistivity grows linearly with temperature, ρ = ρ_ref (1 + α (T − T_ref)), cooled between the shots by Newton's law
(lumped). The sheet above the coil has σ = 1 S/m, so it carries no eddy current worth the name: only the circuit
matters, and it is a series R(T)-L-C circuit,

    C dV/dt = −I,   L dI/dt = V − (R_ext + R_coil(T)) I,   m c_p dT/dt = R_coil(T) I²,

with R_coil(T) = R_coil(T_ref) (1 + α (T − T_ref)) and, between the shots, T ← T_amb + (T − T_amb) exp(−h A t/(m c_p)).
This ODE (scipy's solve_ivp, DOP853, rtol 1e-10) is the reference. Its constants come from GetDP's run, not from
the code under test: L_coil = 2 W / I² (the magnetic energy and current of a step: coil in air, linear), R_coil at
T_ref from the first EM step's Joule heat (BDF2's trapezoid from rest: Q_1 = R I_1² dt / 2, σ evaluated at the
step's start, T_ref), m c_p from the history's temperature rise over heat; the coil's surface A is that of the five
rectangular turns revolved (2π (r1 + r2) h + 2π (r2² − r1²) each), from the geometry's numbers.

Tolerance: 1 % on every shot's peak current and on the coil temperature at the end of every shot (the issue's
figure); BDF2 with ~120 EM steps per period of the circuit is well inside it.
"""

from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = [pytest.mark.getdp, pytest.mark.slow]

EXE = str(Path(sys.executable).with_name("pulseform"))
C, V0, R_EXT, L_EXT = 50e-6, 8.0e3, 0.0, 2e-6
ALPHA, SIGMA_REF, T_REF = 3.9e-3, 1.0e7, 293.15
RHO, CP = 8960.0, 15.0
H, PAUSE, T_AMB = 80.0, 1.0, 293.15
WINDOW, SHOTS = 30e-6, 5
TURNS, R_IN, W, HT, GAP = 5, 10e-3, 4e-3, 3e-3, 1e-3

CASE = f"""
[case]
name = "coil_shots"
kind = "coupled"

[time]
end = {WINDOW}

[mechanics]
formulation = "axisymmetric"

[materials.plate]
density = 2700.0
shear_modulus = 25.9e9
bulk_modulus = 67.5e9
yield_stress = 300e6
electrical_conductivity = 1.0
specific_heat = 896.0

[[bodies]]
name = "sheet"
material = "plate"
region = "workpiece"
fixed = [{{ where = {{ xmin = 0.050 }}, components = [0, 1] }}]

[geometry]
type = "flat_coil_sheet"
turns = {TURNS}
coil_inner_radius = {R_IN}
turn_width = {W}
turn_height = {HT}
turn_gap = {GAP}
coil_gap = 1.5e-3
sheet_radius = 60e-3
sheet_thickness = 2e-3
air_radius = 0.15
shell_radius = 0.20
mesh_size_sheet = 2e-3
mesh_size_coil = 2e-3
mesh_size_air = 0.03

[em]
circuit = {{ capacitance = {C}, voltage = {V0}, resistance = {R_EXT}, inductance = {L_EXT} }}
time_scheme = "bdf2"
coil_conductivity = {SIGMA_REF}
coil_density = {RHO}
coil_heat_capacity = {CP}
coil_conductivity_curve = {{ type = "linear_resistivity", temperature_coefficient = {ALPHA}, reference_temperature = {T_REF} }}
shots = {{ count = {SHOTS}, pause = {PAUSE}, coil_heat_transfer = {H}, ambient_temperature = {T_AMB} }}

[coupling]
n = 8
em_substeps = 1

[output]
field_interval = {WINDOW}
plots = false
"""


def _turn_surface() -> float:
    """The coil's outer surface (m²): five w × h rectangles from r = R_IN, GAP apart, revolved."""
    area = 0.0
    for k in range(TURNS):
        r1 = R_IN + k * (W + GAP)
        r2 = r1 + W
        area += 2 * math.pi * (r1 + r2) * HT + 2 * math.pi * (r2 ** 2 - r1 ** 2)
    return area


def ode_shots(L: float, r_ref: float, mcp: float, times: np.ndarray, *, c: float = C, v0: float = V0,
              r_ext: float = R_EXT, l_ext: float = L_EXT, area: float | None = None, shots: int = SHOTS,
              window: float = WINDOW) -> tuple[list[float], list[float]]:
    """Peak |I| (at the history's step times of a shot, ``times``) and the coil temperature at the end of each of
    ``shots`` shots of ``window`` s of the lumped R(T)-L-C circuit (the module docstring's ODE): coil inductance ``L``
    (H), resistance ``r_ref`` at T_REF (Ω), heat capacity ``mcp`` (J/K) and outer surface ``area`` (m²; None: the
    five revolved turns, :func:`_turn_surface`), the bank ``c`` (F) at ``v0`` (V) with ``r_ext``, ``l_ext``; the
    law's ALPHA, T_REF and the cooling's H, PAUSE, T_AMB of this module (tests/coupling/test_coil_shots3d.py runs
    the same circuit in 3D)."""
    from scipy.integrate import solve_ivp

    def rhs(_t, y):
        v, i, temp = y
        r = r_ext + r_ref * (1 + ALPHA * (temp - T_REF))
        return [-i / c, (v - r * i) / (l_ext + L), r_ref * (1 + ALPHA * (temp - T_REF)) * i * i / mcp]

    decay = math.exp(-H * (_turn_surface() if area is None else area) * PAUSE / mcp)
    temp, peaks, ends = T_REF, [], []
    for _ in range(shots):
        sol = solve_ivp(rhs, (0.0, window), [v0, 0.0, temp], method="DOP853", rtol=1e-10, atol=1e-12,
                        dense_output=True)
        peaks.append(float(np.abs(sol.sol(times)[1]).max()))
        ends.append(float(sol.y[2, -1]))
        temp = T_AMB + (ends[-1] - T_AMB) * decay
    return peaks, ends


def test_five_shots_match_a_lumped_rlc_with_r_of_t(tmp_path):
    from pulseform.orchestrator.run.history import History

    (tmp_path / "case.toml").write_text(CASE)
    out = tmp_path / "run"
    r = subprocess.run([EXE, "run", str(tmp_path / "case.toml"), "--out", str(out), "--quiet"],
                       capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0, r.stderr[-3000:]
    h = History.read(out / "history.csv")
    t, i, w = h.column("time_s"), h.column("coil_current_A"), h.column("magnetic_energy_J")
    heat, rise = h.column("coil_joule_heat_J"), h.column("coil_temperature_rise_K")
    first = t <= WINDOW * (1 + 1e-12)
    k = int(np.argmax(np.abs(i) * first))
    L = 2 * w[k] / i[k] ** 2                                  # coil in air: W = L I² / 2
    r_ref = 2 * heat[1] / (i[1] ** 2 * (t[1] - t[0]))           # first BDF2 step from rest, σ at T_ref
    mcp = heat[k] / rise[k]
    times = t[first]
    peaks, ends = ode_shots(L, r_ref, mcp, times)
    with open(out / "shots.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [int(row["shot"]) for row in rows] == list(range(1, SHOTS + 1))
    got_peak = np.array([float(row["peak_current_A"]) for row in rows])
    got_end = np.array([float(row["coil_temperature_end_K"]) for row in rows])
    print(f"\nL_coil = {L * 1e6:.4f} uH, R_coil(T_ref) = {r_ref * 1e3:.4f} mOhm, m c_p = {mcp:.4f} J/K")
    for n in range(SHOTS):
        print(f"shot {n + 1}: peak {got_peak[n] / 1e3:.4f} kA (ODE {peaks[n] / 1e3:.4f}), coil end "
              f"{got_end[n]:.2f} K (ODE {ends[n]:.2f})")
    assert np.abs(got_peak / np.array(peaks) - 1).max() < 0.01
    assert np.abs((got_end - T_AMB) / (np.array(ends) - T_AMB) - 1).max() < 0.01
    # the shots differ: the coil starts every shot warmer, its resistance is higher and the peak lower
    assert got_end[-1] > got_end[0] + 50.0
    assert got_peak[-1] < got_peak[0] * 0.995
    # shot 1 starts from T_ref, so its first step's σ is SIGMA_REF: the coil's (constant-σ) resistance
    # N² ∫ 2π r dA / (σ S_c²) of the five rectangles
    vol = sum(2 * math.pi * (R_IN + k * (W + GAP) + W / 2) * W * HT for k in range(TURNS))
    sc = TURNS * W * HT
    assert r_ref == pytest.approx(TURNS ** 2 * vol / (SIGMA_REF * sc ** 2), rel=1e-6)


def test_shots_resume_bitwise(tmp_path):
    """Three shots of the same circuit above a conducting sheet with its own σ(T) and body cooling, stopped by
    SIGINT after a checkpoint and resumed: history.csv, shots.csv and the metrics equal the uninterrupted run's
    bit for bit (the checkpoint keeps the shots so far, the bank's voltage and the coil's start temperature)."""
    import json

    from .resume_check import sigint_then_resume

    case = (CASE.replace(f"end = {WINDOW}", "end = 6e-6").replace(f"field_interval = {WINDOW}", "field_interval = 2e-6")
            .replace("electrical_conductivity = 1.0", "electrical_conductivity = 2.5e7\n"
                     "conductivity_curve = { type = 'linear_resistivity', temperature_coefficient = 4e-3 }")
            .replace(f"count = {SHOTS}", "count = 3, voltages = [8e3, 6e3, 7e3], body_heat_transfer = 20.0"))
    (tmp_path / "case.toml").write_text(case)
    ref, out = tmp_path / "ref", tmp_path / "out"
    r = subprocess.run([EXE, "run", str(tmp_path / "case.toml"), "--out", str(ref), "--quiet"],
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    proc, err, _, resumed = sigint_then_resume([EXE, "run", str(tmp_path / "case.toml"), "--out", str(out),
                                                "--quiet"], out, delay=0.05)
    assert proc.returncode == 130, err[-2000:]
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert (out / "history.csv").read_bytes() == (ref / "history.csv").read_bytes()
    assert (out / "shots.csv").read_bytes() == (ref / "shots.csv").read_bytes()
    want, got = (json.loads((p / "metrics.json").read_text()) for p in (ref, out))
    for k, v in want.items():
        if k.startswith("shot"):
            assert got[k] == v, k
    rows = (ref / "shots.csv").read_text().splitlines()
    assert len(rows) == 4 and float(rows[2].split(",")[3]) == 6e3     # the second shot at its own voltage
