"""Pulsed tube press fitting, paper sec. 6 / Figures 6-7 (cases/tube_press_fit).

References (paper sec. 6): with a small clearance (the Figure 6 example: 0.006 R0) both tubes unload
from about the same point and a residual contact pressure remains; the residual pressure falls as
the clearance grows, and beyond a critical clearance ("should not be more than 3 % of the inner
tube internal radius") the tubes unload from different points and no pressure is left.
"Near zero" here: below 2 % of the value at small clearance (studies/tube_press_fit/clearance_sweep.py uses
the zero-clearance value).
Default tier: 0.5 mm cells instead of 0.25 mm.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from .helpers import REPO, TUBE_COARSE, run_many, tube_clearance

VANISH = 0.02


@pytest.fixture(scope="module")
def small_and_large(tmp_path_factory):
    root = tmp_path_factory.mktemp("tube")
    return run_many({"c0.6": ("cases/tube_press_fit", TUBE_COARSE),  # the case file's own 0.006 R0
                     "c6": ("cases/tube_press_fit", [*TUBE_COARSE, *tube_clearance(6.0)])}, root)


def test_case_geometry_is_the_papers():
    import tomllib

    case = tomllib.loads((REPO / "cases/tube_press_fit/case.toml").read_text())
    inner, outer = case["bodies"]
    h0 = case["contact"][0]["h0"]
    r0 = inner["shape"]["origin"][0]
    assert 2 * (r0 + inner["shape"]["width"]) == pytest.approx(0.025)          # OD 25 mm
    assert inner["shape"]["width"] == pytest.approx(0.002)                      # wall 2 mm
    assert 2 * (outer["shape"]["origin"][0] + outer["shape"]["width"]) == pytest.approx(0.050)  # OD 50 mm
    clearance = outer["shape"]["origin"][0] - h0 - (r0 + inner["shape"]["width"])
    assert clearance / r0 == pytest.approx(0.006, rel=1e-3)                     # Figure 6's example


def test_residual_pressure_positive_at_small_clearance_and_gone_at_6_percent(small_and_large):
    m = small_and_large
    p06, p6 = (m[k]["residual_contact_pressure_MPa"] for k in ("c0.6", "c6"))
    assert p06 > 1.0                                      # MPa: a tight joint
    assert p6 < VANISH * p06                              # near zero beyond the critical clearance
    for r in m.values():
        assert r["final_kinetic_to_elastic"] < 1e-3       # relaxed: the vibration has decayed
        assert r["energy_error_rel"] < 0.02
        assert math.isfinite(r["max_radial_displacement_inner_mm"])
        assert (Path(r["_out"]) / "plots" / "press_fit_displacements.png").is_file()
    # the case's springback with contact kept (after the relaxation): the same residual pressure, none at 6 %
    assert m["c0.6"]["springback_residual_contact_pressure_MPa"] == pytest.approx(p06, rel=0.01)
    assert m["c6"]["springback_contact0_closed_nodes"] == 0.0
    # a larger clearance lets the inner tube fly further before it is stopped (mm)
    assert m["c6"]["max_radial_displacement_inner_mm"] > m["c0.6"]["max_radial_displacement_inner_mm"]


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """Full sweep 0 ... 6 % of R0 on the case's own mesh (two runs at a time; labels are folder names)."""
    cs = (0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    root = tmp_path_factory.mktemp("tube_sweep")
    m = {}
    for part in (cs[:4], cs[4:]):
        for pair in (part[:2], part[2:]):
            m.update(run_many({f"c{c:g}": ("cases/tube_press_fit", tube_clearance(c)) for c in pair}, root))
    return cs, np.array([m[f"c{c:g}"]["residual_contact_pressure_MPa"] for c in cs])


@pytest.mark.slow
def test_clearance_sweep_critical_clearance_a_few_percent(sweep):
    """Positive residual pressure up to a critical clearance of a few % of R0, none beyond
    (paper: 3 %; ours lies between 3 and 4 % on the 1 % sweep grid, docs/cases.md)."""
    from pulseform.orchestrator.run.analyses.tube_press_fit import critical_clearance_of_rows as critical_clearance

    cs, p = sweep
    assert p[0] > 1.0
    lo, hi = critical_clearance([{"clearance_percent": c, "ok": 1, "residual_contact_pressure_MPa": v}
                                 for c, v in zip(cs, p)])
    assert 1.0 <= lo < hi <= 6.0, (lo, hi)
    assert np.all(p[np.array(cs) <= lo] > VANISH * p[0]), p


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="known difference from the paper (docs/cases.md): below the critical "
                   "clearance our residual pressure is not monotonic (10.2, 6.4, 3.2, 10.4 MPa at 0, 1, 2, 3 %; the "
                   "same dip at 2 % on 0.5 mm cells): a few-micrometre interference set by the impact dynamics before "
                   "~90 us; the damping onset (100-250 us) and the contact layer (h0 halved) do not remove it")
def test_clearance_sweep_residual_pressure_falls_monotonically(sweep):
    cs, p = sweep
    assert np.all(np.diff(p) <= 0.05 * p[0]), p


def _run_in_process(sets: list[str], out: Path):
    """Run cases/tube_press_fit in this process with ``--set``-style ``sets`` (without the ``--set`` words) into
    ``out``; returns the driver's run (its solver at time.end)."""
    from pulseform.orchestrator.case.io import load_case
    from pulseform.orchestrator.run.driver import run_case_loop
    from pulseform.orchestrator.run.results import ResultsFolder

    case, _ = load_case(REPO / "cases/tube_press_fit", sets)
    return case, run_case_loop(case, ResultsFolder(out, force=True), quiet=True)


@pytest.mark.slow
def test_springback_with_contact_kept_gives_the_relaxed_residual_pressure_and_lames(tmp_path):
    """The case (0.6 % R0, its 0.25 mm cells) run undamped to 150 us, past the end of plastic flow (docs/cases.md),
    and released by springback with contact kept: (1) the residual contact pressure equals the case's own damped
    dynamic relaxation to 300 us within 1 % (the equilibrium of two elastic rings with frozen plastic strain is
    unique; measured 9.128 MPa against 9.13); (2) it is within 2 % of the Lame shrink-fit pressure of the
    interference measured on the tubes released from each other (tests/shrink_fit.py; measured +0.99 %; on
    0.125 mm cells -0.40 %; on 0.5 mm cells, 4 cells through the inner wall, -9.8 %); (3) that last release is
    elastic (Lame applies)."""
    from pulseform.orchestrator.mech.model import solver_material
    from pulseform.solvers.dolfinx.springback import springback
    from shrink_fit import released_interference_check

    from pulseform.orchestrator.run.analyses.tube_press_fit import H0, R0, R1, R_OUT

    sets = [s for s in tube_clearance(0.6) if s != "--set"]
    case, relaxed = _run_in_process(sets, tmp_path / "relaxed")
    p_relaxed = relaxed.metrics["residual_contact_pressure_MPa"] * 1e6
    case, run = _run_in_process([*sets, "time.end=1.5e-4"], tmp_path / "undamped")
    sb = springback(run.solver, contact="kept")
    k = case.contact[0].stiffness
    p, lame, added, closed = released_interference_check(sb, R0, R1, R_OUT,
                                                         solver_material(case.materials["stainless"]), k, H0)
    print(f"damped relaxation {p_relaxed / 1e6:.4f} MPa; springback at 150 us {p / 1e6:.4f} MPa "
          f"({100 * (p / p_relaxed - 1):+.3f} %) on {closed} nodes; Lame {lame / 1e6:.4f} MPa "
          f"({100 * (p / lame - 1):+.3f} %); plastic strain added by the release {added:.1e}")
    assert p > 1e6
    assert p == pytest.approx(p_relaxed, rel=0.01)
    assert added < 1e-9
    assert p == pytest.approx(lame, rel=0.02)
