"""Validation entries of shipped cases against references from outside the project (see :mod:`.registry`):
the tube press-fit clearance sweep (the paper's Figures 6 and 7) and TEAM Workshop Problem 28 (the measured
levitation height and an independent filament model, full suite). Registered when :mod:`.registry` is imported."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .registry import REPO, Analytic, CsvCurve, Entry, RunOutput, register, run, run_case_cli


def _tube_clearances() -> tuple[float, ...]:
    return (0.0, 0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0)


@run("case_tube_press_fit_sweep")
def _tube_sweep(work: Path) -> RunOutput:
    """The case file (clearance 0.006 R0, Figure 6) and the clearance sweep 0 .. 6 % of R0 (Figure 7)."""
    r0, r1, r_out, h0 = 0.0105, 0.0125, 0.025, 5.0e-5
    m, _ = run_case_cli("tube_press_fit", work, [], folder="c_case")
    cs, ps = [], []
    for c in _tube_clearances():
        r2 = r1 + c / 100.0 * r0 + h0
        mc, _ = run_case_cli("tube_press_fit", work, [f"bodies.outer.shape.origin=[{r2:.9g}, 0.0]",
                                                      f"bodies.outer.shape.width={r_out - r2:.9g}"], folder=f"c_{c:g}")
        cs.append(c)
        ps.append(mc["residual_contact_pressure_MPa"])
    return tube_sweep_output(m["residual_contact_pressure_MPa"], cs, ps)


def tube_sweep_output(residual_case: float, cs: list[float], ps: list[float]) -> RunOutput:
    """The press-fit entries' scalars from the case file's residual pressure (MPa) and the sweep's
    clearances (% of R0) and residual pressures (MPa)."""
    from ..run.analyses.tube_press_fit import critical_clearance

    lo, hi = critical_clearance(list(zip(cs, ps)))
    p = np.array(ps)
    below = np.array(cs) <= lo
    out = RunOutput(scalars={"residual_case_MPa": float(residual_case), "residual_largest_MPa": float(p[-1]),
                             "residual_zero_clearance_MPa": float(p[0]), "critical_clearance_percent": 0.5 * (lo + hi),
                             "residual_largest_rise_rel": float(np.max(np.diff(p[below]), initial=0.0) / p[0])
                             if np.isfinite(lo) else float("nan")})
    out.curves["residual"] = (np.array(cs, dtype=float), p)
    out.labels["residual"] = ("initial radial clearance / R0 (%)", "residual contact pressure (MPa)")
    return out


_SEC6 = "paper sec. 6 (Figs. 6-7): "
register(Entry("tube_press_fit.residual_small_clearance", "tube_press_fit",
               "residual contact pressure at clearance 0.006 R0 (Figure 6's example)", "MPa", "case_tube_press_fit_sweep",
               Analytic("0 (no joint); the claim: above it by >= 1 % of the yield stress (3 MPa)", _SEC6 + "small "
                        "clearance: both tubes unload from about the same point, a residual contact pressure remains; "
                        "'positive' read as >= 1 % of sigma_s0 = 300 MPa", value=0.0), 3.0,
               computed=lambda o: o.scalars["residual_case_MPa"], compare="above",
               error="abs", suites=("full",), curve="residual"))
register(Entry("tube_press_fit.residual_6_percent", "tube_press_fit",
               "residual contact pressure at 6 % R0, relative to zero clearance", "-", "case_tube_press_fit_sweep",
               Analytic("0", _SEC6 + "beyond the critical clearance no residual pressure ('near zero': < 2 % of the "
                        "zero-clearance value, analyses/tube_press_fit.VANISH)", value=0.0), 0.02,
               computed=lambda o: o.scalars["residual_largest_MPa"] / o.scalars["residual_zero_clearance_MPa"],
               error="abs", suites=("full",), curve="residual"))
register(Entry("tube_press_fit.critical_clearance", "tube_press_fit", "critical clearance (middle of the sweep "
               "bracket)", "% of R0", "case_tube_press_fit_sweep",
               Analytic("3 % of R0", _SEC6 + "'the initial radial clearance should not be more than 3 % of the inner "
                        "tube internal radius'", value=3.0), 1.0,
               computed=lambda o: o.scalars["critical_clearance_percent"], error="abs", suites=("full",),
               curve="residual", note="tolerance = the sweep's 1 % grid spacing above 1 %"))
register(Entry("tube_press_fit.residual_falls_with_clearance", "tube_press_fit", "largest rise of the residual "
               "pressure from one sweep point to the next (below the critical clearance), relative to zero clearance",
               "-", "case_tube_press_fit_sweep",
               Analytic("0 (falls monotonically)", _SEC6 + "Fig. 7 and text: 'the larger is the initial clearance ... "
                        "the smaller is technological pressure'; a rise of up to 5 % of p(0) counted as flat", value=0.0),
               0.05, computed=lambda o: o.scalars["residual_largest_rise_rel"], error="abs", suites=("full",),
               curve="residual",
               known_deviation="below the critical clearance our residual pressure is an interference of a few "
               "micrometres left by the impact dynamics (plastic flow ends by ~90 us, before any damping); it dips at "
               "2 % and peaks again at 3 % on both meshes (0.25 and 0.5 mm cells), docs/cases.md"))


# --------------------------------------------------------------------------- TEAM Workshop Problem 28 (full suite)
# The electrodynamic levitation benchmark: cases/team28_levitation against the measured height of the problem
# description (Table I) and against the filament model of the same specification (docs/verification.md)
_T28 = "team28_levitation"
_T28_MEASURED = CsvCurve(_T28, "measured_height.csv", label="measured (TEAM 28, Table I)")
_T28_FILAMENTS = CsvCurve(_T28, "filament_model.csv", label="filament model (same spec)")
_T28_SETTLED_MS = 1200.0  # the settled plate: the mean height from 1.2 s on (the measured one varies by 0.3 mm)
_T28_FIRST_MS = 150.0  # the first rise and its peak: the measured first peak at 79-109 ms, its first minimum at 168 ms


@run("case_team28_levitation")
def _team28(work: Path) -> RunOutput:
    from ..case.io import load_case

    case, _ = load_case(REPO / "cases" / _T28)
    start = case.geometry.workpiece.box[1]  # the plate's lower face above the coils' top (z = 0) at rest
    m, h = run_case_cli(_T28, work, ["output.plots=false"])
    out = RunOutput(scalars={k: float(v) for k, v in m.items() if v is not None})
    out.curves["height"] = (h["time_s"] * 1e3, (start + h["plate_travel_y_m"]) * 1e3)
    out.labels["height"] = ("time (ms)", "levitation height z (mm)")
    return out


def _t28_settled(t_ms: np.ndarray, z_mm: np.ndarray) -> float:
    return float(np.mean(z_mm[t_ms >= _T28_SETTLED_MS]))


def _t28_first_peak(t_ms: np.ndarray, z_mm: np.ndarray) -> float:
    return float(np.max(z_mm[t_ms <= _T28_FIRST_MS]))


_T28_LEAD = ("the ideal problem switches the full 20 A on at t = 0 and its first rise leads the measurement by ~10 ms "
             "(the filament model of the same spec: first peak 19.29 mm at 77 ms, measured 18.2 mm at 79-109 ms)")
register(Entry(f"{_T28}.height_vs_measured", _T28, "levitation height z(t) over 1.7 s vs the measurement", "mm",
               "case_team28_levitation", _T28_MEASURED, 0.27, kind="curve", curve="height", suites=("full",),
               also=(_T28_FILAMENTS,),
               note="tolerance: " + _T28_LEAD + "; at the measured slope of up to 0.31 mm/ms the ideal problem's own "
               "distance to the measurement is 4.30 mm at 38 ms, 0.236 of the 18.2 mm peak (filament model, converged "
               "to 0.03 mm), plus 0.03 for this run's distance to the ideal problem (the entry height_vs_filament_model)"))
register(Entry(f"{_T28}.settled_height", _T28, "settled height: mean z from 1.2 s to the end", "mm",
               "case_team28_levitation", _T28_MEASURED, 0.06, metric=_t28_settled, curve="height", suites=("full",),
               also=(_T28_FILAMENTS,),
               note="tolerance 6 %: the ideal problem of the spec settles 2.6 % below the measured 11.32 mm (filament "
               "model 11.03 mm; Table I rounds to 0.1 mm, the spec gives sigma and the mass to 3 digits), plus 3 % "
               "for this run's distance to the ideal problem"))
register(Entry(f"{_T28}.first_peak", _T28, "first peak height (max z before 150 ms)", "mm",
               "case_team28_levitation", _T28_MEASURED, 0.09, metric=_t28_first_peak, curve="height", suites=("full",),
               also=(_T28_FILAMENTS,),
               note="tolerance 9 %: " + _T28_LEAD + "; the full current at once overshoots: 6.0 % above the measured "
               "peak in the filament model, plus 3 % for this run's distance to the ideal problem"))
register(Entry(f"{_T28}.height_vs_filament_model", _T28, "levitation height z(t) vs the filament model of the same "
               "spec", "mm", "case_team28_levitation", _T28_FILAMENTS, 0.03, kind="curve", curve="height",
               suites=("full",), also=(_T28_MEASURED,),
               note="the same ideal problem (rigid plate, the full current at t = 0) by another method: mutual "
               "inductances of 86 square filaments (orchestrator/em/filaments.py DrivenFilaments; "
               "studies/team28_levitation/filament_reference.py); 3 % of the max height as the jumping ring's "
               "lumped reference (docs/cases.md)"))
