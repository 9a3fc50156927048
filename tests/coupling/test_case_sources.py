"""Several coils on their own sources, from case files (``coaxial_coils``, ``[[em.sources]]``,
``[[em.coils]]``), run end to end by ``pulseform run`` (GetDP + DOLFINx).

References:
- the coil currents GetDP reports (history.csv, one column per coil) are the sources' formulas, evaluated
  here from the case's numbers: I0 e^(−β (t − t_on)) sin(2π f (t − t_on) + φ) after t_on, a direct
  current after t_on, the linear interpolation of a table's rows (numpy.interp) — to the 10 significant
  digits history.csv keeps of the current and of the time (GetDP itself: 1e-12, tests/getdp/test_sources.py);
- a table that tabulates a damped sine drives the same forces as the sine source, to the table's
  linear-interpolation error (measured here on a fine grid);
- on a fixed geometry the Lorentz force on the workpiece is a bilinear form of the coil currents (j and B
  are both linear in them, eddy currents included), so with coils A and B the parallelogram law
  F(A + B) + F(A − B) = 2 F(A) + 2 F(B) holds exactly; the runs differ only in coil B's ``sign`` and in
  switching a source on after the end (``t_on`` = 1 s) — the same mesh every time. The plate is clamped on
  its whole boundary and heavy so that it stays put (its motion is the only non-linearity).
"""
from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from pulseform.orchestrator.cli import main
from pulseform.orchestrator.run.history import History

REPO = Path(__file__).resolve().parents[2]
BASE = tomllib.loads((REPO / "cases/two_coils_plate/case.toml").read_text())
OFF = 1.0  # s: a t_on after the end switches a source off for the whole run


def _sine(t, amplitude, frequency, phase=0.0, decay=0.0, t_on=0.0):
    s = np.asarray(t, float) - t_on
    return np.where(s >= 0.0, amplitude * np.exp(-decay * s) * np.sin(2 * math.pi * frequency * s + phase), 0.0)


def _run(tmp_path: Path, name: str, edit, csv: dict[str, str] | None = None) -> History:
    data = copy.deepcopy(BASE)
    data["time"]["end"] = 8e-6
    data["output"] = {"field_interval": 8e-6, "plots": False}
    edit(data)
    folder = tmp_path / name
    folder.mkdir()
    for file, text in (csv or {}).items():
        (folder / file).write_text(text)
    (folder / "case.toml").write_text(tomli_w.dumps(data))
    assert main(["run", str(folder), "--out", str(folder / "out"), "--quiet"]) == 0
    return History.read(folder / "out" / "history.csv")


@pytest.mark.getdp
def test_coil_currents_equal_their_source_formulas(tmp_path):
    sine = {"name": "s", "type": "sine", "amplitude": 9e3, "frequency": 25e3, "phase": 0.4, "decay": 3e4,
            "t_on": 2e-6}
    dc = {"name": "d", "type": "dc", "current": 4e3, "t_on": 3e-6}
    rows = [(0.0, 0.0), (1e-6, 5e3), (2.5e-6, -2e3), (6e-6, 1e3)]  # held at 1 kA after 6 µs
    table = {"name": "t", "type": "table", "file": "current.csv"}

    def edit(d):
        d["geometry"]["coils"].append({"name": "third", "turns": 2, "windings": [[36e-3, -3e-3, 40e-3, 0.0]]})
        d["em"]["sources"] = [sine, dc, table]
        d["em"]["coils"] = [{"name": "inner", "source": "s"}, {"name": "outer", "source": "d", "sign": -1},
                            {"name": "third", "source": "t"}]

    text = "time_s,current_A\n# a comment\n" + "".join(f"{t!r},{i!r}\n" for t, i in rows)
    h = _run(tmp_path, "three", edit, {"current.csv": text})
    formulas = {"inner_current_A": lambda t: _sine(t, **{k: v for k, v in sine.items() if k not in ("name", "type")}),
                "outer_current_A": lambda t: -np.where(t >= dc["t_on"], dc["current"], 0.0),
                "third_current_A": lambda t: np.interp(t, *zip(*rows))}
    t = h.column("time_s")[1:]  # row 0 is the state at rest before the first step
    for col, formula in formulas.items():
        got, want = h.column(col)[1:], formula(t)
        # history.csv keeps 10 significant digits of the current and of the time: rounding budget
        slope = np.abs(formula(t + 1e-12) - formula(t - 1e-12)) / 2e-12
        budget = 5e-10 * (np.abs(want) + t * slope) + 1e-12 * np.abs(want).max()
        err = np.abs(got - want)
        print(f"\n{col}: {len(t)} EM steps, max |I - formula| = {err.max() / np.abs(want).max():.1e} of max|I|, "
              f"at most {(err / budget).max():.2f} of the CSV rounding budget")
        assert np.all(err <= budget), col
    assert (t < 2e-6).any() and (t > 6e-6).any()  # before a switch-on and past the table's last row
    # one BDF2 step per EM step: the largest |current| of the step is that of the coil with the largest at its end
    assert np.array_equal(h.column("coil_current_abs_max_A"), np.abs([h.column(c) for c in formulas]).max(axis=0))


@pytest.mark.getdp
def test_a_table_of_the_sine_gives_the_sine_forces(tmp_path):
    main_src = next(s for s in BASE["em"]["sources"] if s["name"] == "main")
    args = {k: v for k, v in main_src.items() if k not in ("name", "type")}
    times = np.arange(0.0, 10e-6 + 1e-12, 0.2e-6)
    text = "".join(f"{t!r},{i!r}\n" for t, i in zip(times, _sine(times, **args)))
    fine = np.linspace(0.0, 8e-6, 20001)  # the run's 8 µs
    exact = _sine(fine, **args)
    interp_err = np.abs(np.interp(fine, times, _sine(times, **args)) - exact).max() / np.abs(exact).max()

    def as_table(d):
        d["em"]["sources"][0] = {"name": "main", "type": "table", "file": "main.csv"}

    f_sine = _run(tmp_path, "sine", lambda d: None).column("force_y_N")
    f_table = _run(tmp_path, "table", as_table, {"main.csv": text}).column("force_y_N")
    diff = np.abs(f_table - f_sine).max() / np.abs(f_sine).max()
    print(f"\ntable (0.2 µs rows) vs sine: interpolation error {interp_err:.2e} of the run's largest current, "
          f"force_y_N differs by {diff:.2e} of its peak ({diff / interp_err:.2f} times)")
    # the force is quadratic in the currents: a relative current error e changes it by about 2 e
    assert 0.1 * interp_err <= diff <= 3.0 * interp_err


@pytest.mark.getdp
def test_two_coils_forces_obey_the_parallelogram_law(tmp_path):
    def setup(d, sign: int, a_on: bool = True, b_on: bool = True):
        d["materials"]["al"]["density"] = 1e5  # heavy and clamped all round: the geometry stays (see the docstring)
        d["bodies"][0]["fixed"] = [{"where": {}, "components": [0, 1]}]
        d["em"]["sources"][1]["t_on"] = 0.0
        if not a_on:
            d["em"]["sources"][0]["t_on"] = OFF
        if not b_on:
            d["em"]["sources"][1]["t_on"] = OFF
        d["em"]["coils"][1]["sign"] = sign

    plus = _run(tmp_path, "plus", lambda d: setup(d, 1))
    minus = _run(tmp_path, "minus", lambda d: setup(d, -1))
    a = _run(tmp_path, "a", lambda d: setup(d, 1, b_on=False))
    b = _run(tmp_path, "b", lambda d: setup(d, 1, a_on=False))
    moved = max(h.column("plate_max_uy_m").max() for h in (plus, minus, a, b))
    for col in ("force_y_N", "getdp_force_z_N"):
        fp, fm, fa, fb = (h.column(col) for h in (plus, minus, a, b))
        err = np.abs(fp + fm - 2 * fa - 2 * fb).max() / np.abs(fp).max()
        cross = np.abs(fp - fm).max() / np.abs(fp).max()
        print(f"\n{col}: |F(A+B) + F(A-B) - 2F(A) - 2F(B)| / max|F(A+B)| = {err:.1e}; cross term "
              f"|F(A+B) - F(A-B)| / max|F(A+B)| = {cross:.2f}; plate moved {moved * 1e9:.2f} nm")
        assert cross > 0.05  # the coils interact: the sign changes the force
        assert err < 1e-8
    assert np.all(plus.column("outer_current_A") == -minus.column("outer_current_A"))


@pytest.mark.getdp
def test_two_coils_in_series_on_a_bank(tmp_path):
    """Both coils on one bank, the outer one reversed: one series current (the outer coil's is its negative,
    exactly: the deck connects it the other way round), and the bank's charge goes into the discharge."""
    def on_bank(d):
        d["em"]["sources"] = [{"name": "bank", "type": "bank", "capacitance": 20e-6, "voltage": 3e3,
                               "resistance": 5e-3, "inductance": 0.5e-6}]
        d["em"]["coils"] = [{"name": "inner", "source": "bank"}, {"name": "outer", "source": "bank", "sign": -1}]

    h = _run(tmp_path, "bank", on_bank)
    inner, outer, vc = h.column("inner_current_A"), h.column("outer_current_A"), h.column("capacitor_voltage_V")
    assert np.array_equal(inner, -outer) and np.abs(inner).max() > 1e3
    assert vc[0] == 3e3 and vc[-1] < 3e3  # charged to V0, discharging
