"""Multi-pulse corner filling (paper sec. 5 / Figure 4) and preforming + restrike (paper conclusion 2).

References: sec. 5 — with four pulses of 5, 10, 15, 25 MPa "maximum value of J2(sigma) for the die
and the impact velocity of the blank ... are significantly lower than for a single pulse loading
when the blank filled the die cavity"; conclusion 2 — "static preforming ... combined with pulsed
restrike ... may substantially reduce the contact stresses on the die surface". The issue also asks
that both alternatives end filled. Compared with our single 30 MPa pulse on the same mesh (die cells
4 mm). These runs take several simulated milliseconds (rest phases, a 4 ms damped preform), so they
are in the slow tier even on the coarse die mesh.
"""

from __future__ import annotations

import pytest

from .helpers import CORNER_COARSE, run_many

FILLED = 0.999

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("sequences")
    m = run_many({"single30": ("cases/corner_fill", CORNER_COARSE),
                  "multi": ("cases/corner_fill_multipulse", CORNER_COARSE)}, root)
    m.update(run_many({"restrike": ("cases/corner_fill_restrike", CORNER_COARSE)}, root))
    return m


def test_four_pulses_lower_die_load_and_blank_speed(runs):
    single, multi = runs["single30"], runs["multi"]
    assert single["fill_fraction"] >= FILLED
    for k in range(1, 4):  # every pulse fired once the blank was at rest, after the previous window
        assert multi[f"pulse{k}_start_time_s"] > multi[f"pulse{k - 1}_start_time_s"] + 3.1e-4
    assert multi["die_mises_max_MPa"] < single["die_mises_max_MPa"]
    assert multi["die_contact_pressure_max_MPa"] < single["die_contact_pressure_max_MPa"]
    assert multi["blank_speed_max_m_s"] < single["blank_speed_max_m_s"]
    assert multi["blank_rms_speed_max_m_s"] < single["blank_rms_speed_max_m_s"]


@pytest.mark.xfail(strict=True, reason="known difference (docs/cases.md): our four pulses leave the corner "
                   "unfilled (fill 0.980 with die cells 4 mm, 0.936 with 2 mm; single 25 MPa from flat: 0.980 / "
                   "0.958): after three pulses the blank lies close to the die and the 25 MPa step has too short "
                   "a run-up to wrap the 130-degree corner")
def test_four_pulses_end_filled(runs):
    assert runs["multi"]["fill_fraction"] >= FILLED


def test_preform_is_quasi_static_at_the_top_of_the_ramp(runs):
    """Kinetic / (elastic + plastic) energy while the preform pressure is >= 90 % of P_pre (where the
    preformed shape is set): below the common 5 % guideline for quasi-static explicit analyses
    (measured 0.049 on this mesh: a narrow margin, docs/cases.md), and the preformed blank is at rest
    when the damping ends."""
    rs = runs["restrike"]
    assert rs["preform_kinetic_ratio_top_max"] < 5e-2
    assert rs["preform_kinetic_ratio_end"] < 1e-4


@pytest.mark.xfail(strict=True, reason="known shortfall (docs/cases.md): over the whole ramp (p >= 10 % of "
                   "P_pre) the slack blank moves with little internal energy, kinetic / internal reaches ~2; "
                   "a 1 % ratio throughout would need a ~10x slower ramp than the 4 ms we can afford")
def test_preform_is_quasi_static_over_the_whole_ramp(runs):
    assert runs["restrike"]["preform_kinetic_ratio_max"] < 1e-2


def test_restrike_lower_die_load(runs):
    single, rs = runs["single30"], runs["restrike"]
    assert rs["die_mises_max_MPa"] < single["die_mises_max_MPa"]
    assert rs["die_contact_pressure_max_MPa"] < single["die_contact_pressure_max_MPa"]


def test_restrike_fills(runs):
    assert runs["restrike"]["fill_fraction"] >= FILLED
