"""cases/emf_sheet_die_steel (issue 35): the magnetisation of a 1010 steel die (FEMM's B–H curve, σ = 7e6 S/m)
changes the force on the aluminium sheet, compared with the same die at μ_r = 1 and with an ideal magnetic die.

Why the effect has this sign and size. The sheet (1 mm, skin depth 0.88 mm at the bank's ringing) shields the
die: the die sees only the field that diffuses through the sheet, and acts on the sheet through the field in the
0.2 mm gap between them. A non-magnetic conducting die squeezes that leaked flux into the gap (its own eddy
currents keep it out), which presses the sheet back towards the coil; a magnetised die takes the flux in (its
surface impedance grows like sqrt(μ_r)) and, in the limit μ → ∞, leaves no tangential field at its face: a
magnetic mirror whose image of the sheet's current pulls the sheet towards the die. So the sheet's force rises
with the die's permeability, and the curve's die lies between μ_r = 1 and the mirror (a linear μ_r = 1e4 die,
above the curve's largest B/μ0H ≈ 990): while the die's surface field stays below the curve's first point
(238.7 A/m, μ_r = 668: the first 20 µs) it acts as the mirror does; later the saturated surface takes less.

Measured (the whole 60 µs; the sheet's force is its Lorentz force, ``getdp_force_z_N``: the sheet is not
magnetic): the impulse on the sheet 0.75206 N s (μ_r = 1), 0.77512 (the curve, +3.07 %), 0.78175 (μ_r = 1e4,
+3.95 %); to 20 µs +0.219 % and +0.220 %; Newton's counts 1 .. 2 (the getdp runs per step, ~45 s), 70 s in all.
"""
from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from pulseform.orchestrator.cli import main

REPO = Path(__file__).resolve().parents[2]
CASE = REPO / "cases/emf_sheet_die_steel"


def _run(case: Path, out: Path, capsys) -> np.ndarray:
    """The run's history (its first row at t = 0)."""
    rc = main(["run", str(case), "--out", str(out), "--quiet", "--set", "output.plots=false"])
    assert rc == 0, capsys.readouterr().err
    return np.genfromtxt(out / "history.csv", delimiter=",", names=True)


def _impulse(h: np.ndarray, end: float) -> float:
    """∫ F dt (N s) of the sheet's force to ``end`` (s), trapezoids over the EM steps."""
    k = h["time_s"] <= end * (1 + 1e-12)
    return float(np.trapz(h["getdp_force_z_N"][k], h["time_s"][k]))


def _variant(tmp_path: Path, name: str, **steel) -> Path:
    """The case with the die's material's B–H curve replaced by ``steel`` keys."""
    data = tomllib.loads((CASE / "case.toml").read_text())
    mat = data["materials"]["steel_1010"]
    del mat["bh_curve"]
    mat.update(steel)
    p = tmp_path / f"{name}.toml"
    p.write_text(tomli_w.dumps(data))
    return p


@pytest.mark.slow
@pytest.mark.getdp
def test_steel_die_magnetisation_raises_the_run(tmp_path, capsys):
    curve = _run(CASE / "case.toml", tmp_path / "curve", capsys)
    vacuum = _run(_variant(tmp_path, "vacuum"), tmp_path / "vacuum", capsys)
    mirror = _run(_variant(tmp_path, "mirror", relative_permeability=1e4), tmp_path / "mirror", capsys)
    end = float(curve["time_s"][-1])
    i_c, i_v, i_m = (_impulse(h, end) for h in (curve, vacuum, mirror))
    e_c, e_v, e_m = (_impulse(h, 20e-6) for h in (curve, vacuum, mirror))
    newton = curve["em_newton_iterations"][1:]
    print(f"\nsheet impulse {i_v:.5f} (mu_r = 1), {i_c:.5f} (1010 curve, {i_c / i_v - 1:+.2%}), {i_m:.5f} (mu_r = 1e4, "
          f"{i_m / i_v - 1:+.2%}); to 20 us {e_c / e_v - 1:+.3%} and {e_m / e_v - 1:+.3%}; Newton "
          f"{newton.min():.0f} .. {newton.max():.0f}")
    assert np.array_equal(curve["time_s"], vacuum["time_s"])
    assert i_v < i_c < i_m                                    # towards the die, no more than the mirror
    assert abs(e_c - e_m) < 0.05 * (e_m - e_v)                # below the curve's first point: the mirror
    assert np.all((newton >= 1) & (newton <= 5))              # bounded Newton counts (max 30)
