"""The validation registry: which run, which quantity, against which reference, with which tolerance.

An :class:`Entry` names a case (or a verification set-up), the quantity, its reference and a
tolerance. References are either :class:`Analytic` (a closed-form value or function, with its
source) or :class:`CsvCurve` (a curve ``cases/<case>/reference/<file>`` whose ``# key: value``
header gives its provenance: ``source``, ``figure``, ``units``, ``obtained``). Entries share
*runs* (one solver run feeds several quantities): :data:`RUNS` maps a run key to a function
``work_dir -> RunOutput`` that does the expensive part once per ``pulseform validate``.

Add an entry with :func:`register`; ``suites`` says whether it belongs to ``fast`` (the CI tier,
a minute or so here) and/or ``full``.
"""

from __future__ import annotations

import csv
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..run.results import read_metrics
from ..run.warm import failure_report, member_run_argv, run_member_process

log = logging.getLogger(__name__)

if TYPE_CHECKING:
    from .gci_band import GciBand

REPO = Path(__file__).resolve().parents[2]
PROVENANCE_KEYS = ("source", "figure", "units", "obtained")
MU0 = 4e-7 * math.pi


class ReferenceError_(ValueError):
    """A reference file is missing, malformed or lacks provenance (message names the file)."""


@dataclass
class RunOutput:
    """What one verification run hands to its entries: scalars and named curves (x, y)."""

    scalars: dict[str, float] = field(default_factory=dict)
    curves: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    labels: dict[str, tuple[str, str]] = field(default_factory=dict)  # curve -> (x label, y label)
    wall_time_s: float = 0.0


@dataclass(frozen=True)
class Analytic:
    """A closed-form reference: a scalar ``value`` or a function ``function(x) -> y``."""

    formula: str
    source: str
    value: float | None = None
    function: Callable[[np.ndarray], np.ndarray] | None = None
    from_run: Callable[[RunOutput], float] | None = None  # a balance whose other side the run reports

    def describe(self) -> str:
        return self.formula


@dataclass(frozen=True)
class CsvCurve:
    """A reference curve stored as ``cases/<case>/reference/<file>`` (two named columns); ``label``
    names it in the entries' pictures."""

    case: str
    file: str
    label: str = "reference"

    def path(self, root: Path) -> Path:
        return root / "cases" / self.case / "reference" / self.file

    def describe(self) -> str:
        return f"cases/{self.case}/reference/{self.file}"

    def load(self, root: Path) -> tuple[np.ndarray, np.ndarray, dict[str, str], list[str]]:
        """(x, y, provenance, column names); raises :class:`ReferenceError_` naming what is wrong."""
        p = self.path(root)
        if not p.is_file():
            raise ReferenceError_(f"{p}: reference file not found")
        prov: dict[str, str] = {}
        rows: list[list[str]] = []
        for line in p.read_text().splitlines():
            if line.startswith("#"):
                key, _, val = line[1:].partition(":")
                prov[key.strip()] = val.strip()
            elif line.strip():
                rows.append(next(csv.reader([line])))
        missing = [k for k in PROVENANCE_KEYS if not prov.get(k)]
        if missing:
            raise ReferenceError_(f"{p}: provenance header lacks {', '.join('# ' + k + ':' for k in missing)}")
        if len(rows) < 3 or len(rows[0]) < 2:
            raise ReferenceError_(f"{p}: expected a header row of two column names and >= 2 data rows")
        try:
            data = np.array([[float(v) for v in r[:2]] for r in rows[1:]])
        except ValueError as exc:
            raise ReferenceError_(f"{p}: non-numeric data ({exc})") from None
        if np.any(np.diff(data[:, 0]) < 0):
            raise ReferenceError_(f"{p}: the first column must be increasing")
        return data[:, 0], data[:, 1], prov, rows[0][:2]


@dataclass(frozen=True)
class Entry:
    """One validated quantity.

    ``kind``: ``"scalar"`` compares ``computed(out)`` with the reference's value (for a curve
    reference: ``metric`` applied to the reference curve, the same function that made the computed
    value); ``"curve"`` compares the run's curve ``curve`` with the reference curve at the
    computed abscissae, error = max |Δy| / max |y_ref|. ``error`` is relative (``rel``) or absolute.

    ``compare`` (scalar entries): ``"equal"`` passes when |computed − reference| <= tolerance;
    ``"below"`` / ``"above"`` test a claim that the computed value is lower / higher than the
    reference by at least the tolerance: the signed error (computed − reference, relative or
    absolute) must be <= −tolerance / >= +tolerance. ``reference_run``: the run whose output the
    reference's ``from_run`` reads (default: the entry's own run), e.g. "the four pulses load the
    die less than the single pulse". ``known_deviation``: why our result is known to differ from
    the reference (docs/cases.md); such an entry is expected to fail its comparison and is reported
    as "known deviation (xfail)"; if it passes, it is reported as XPASS and fails the suite
    (strict: the registry must then be updated). ``gci`` (scalar, "equal"): judged on the computed
    value's GCI band instead of ``tolerance`` (:mod:`.gci_band`). ``also``: further reference curves
    drawn in the entry's picture beside its own reference (not judged: e.g. the measured curve and an
    independent model of the same problem in each other's pictures).
    """

    name: str
    case: str
    quantity: str
    unit: str
    run: str
    reference: Analytic | CsvCurve
    tolerance: float
    kind: str = "scalar"
    computed: Callable[[RunOutput], float] | None = None
    metric: Callable[[np.ndarray, np.ndarray], float] | None = None
    curve: str | None = None
    error: str = "rel"
    suites: tuple[str, ...] = ("fast", "full")
    note: str = ""
    align_onset: bool = False  # plot only: shift the reference curve to the computed curve's first y > 0
    compare: str = "equal"  # "equal" | "below" | "above"
    reference_run: str | None = None
    known_deviation: str = ""
    gci: GciBand | None = None
    also: tuple[CsvCurve, ...] = ()


REGISTRY: dict[str, Entry] = {}
RUNS: dict[str, Callable[[Path], RunOutput]] = {}


def register(entry: Entry) -> Entry:
    if entry.name in REGISTRY:
        raise ValueError(f"validation entry {entry.name!r} registered twice")
    for key in (entry.run, entry.reference_run):
        if key is not None and key not in RUNS:
            raise ValueError(f"validation entry {entry.name!r}: unknown run {key!r}")
    if entry.compare not in ("equal", "below", "above"):
        raise ValueError(f"validation entry {entry.name!r}: compare must be equal, below or above")
    if entry.gci is not None and (entry.kind, entry.compare) != ("scalar", "equal"):
        raise ValueError(f"validation entry {entry.name!r}: a GCI band judges scalar 'equal' entries only")
    REGISTRY[entry.name] = entry
    return entry


def run(key: str) -> Callable[[Callable[[Path], RunOutput]], Callable[[Path], RunOutput]]:
    def deco(fn):
        RUNS[key] = fn
        return fn
    return deco


# ============================================================================ runs
def _bar_run(work: Path, formulation: str, nx: int, ny: int) -> RunOutput:
    from pulseform.solvers.dolfinx.verification import bar_impact

    r = bar_impact(nx=nx, ny=ny, formulation=formulation)
    out = RunOutput(scalars={k: float(v) for k, v in r["metrics"].items()})
    out.curves["contact_stress"] = (np.asarray(r["t"]), np.asarray(r["stress"]))
    out.labels["contact_stress"] = ("time (s)", "contact stress (Pa)")
    return out


@run("bar_impact_plane_stress_40x20")
def _bar_ps(work: Path) -> RunOutput:
    return _bar_run(work, "plane_stress", 40, 20)


@run("bar_impact_plane_strain_80x40")
def _bar_pe(work: Path) -> RunOutput:
    return _bar_run(work, "plane_strain", 80, 40)


def run_case_cli(case: str, work: Path, sets: list[str], folder: str = "run") -> tuple[dict[str, float], np.ndarray]:
    """``pulseform run cases/<case>`` into ``work/<folder>`` (the user's path: case file, CLI, results
    folder); returns (metrics, history)."""
    out_dir = work / folder
    r = run_member_process(member_run_argv(REPO / "cases" / case, out_dir, sets))  # validate's warm process
    if r.returncode != 0:
        error, tail = failure_report(r, out_dir)
        log.warning("pulseform run %s failed: %s%s", out_dir, error, "".join(f"\n  {ln}" for ln in tail.splitlines()))
        raise RuntimeError(f"pulseform run failed ({r.returncode}): {error}")
    return read_metrics(out_dir / "metrics.json"), np.genfromtxt(out_dir / "history.csv", delimiter=",", names=True)


@run("case_bar_impact_wall")
def _bar_wall(work: Path) -> RunOutput:
    m, h = run_case_cli("bar_impact_wall", work, [])
    out = RunOutput(scalars={k: float(v) for k, v in m.items() if v is not None})
    out.curves["contact_stress"] = (h["time_s"], h["wall_mid_wall_pressure_Pa"])
    out.labels["contact_stress"] = ("time (s)", "wall pressure at the middle of the face (Pa)")
    return out


DIFF_SIGMA, DIFF_H0, DIFF_T, DIFF_LEN = 3.5e7, 1e5, 20e-6, 4e-3


def _diffusion_run(work: Path, h: float, steps: int) -> RunOutput:
    from pulseform.solvers.getdp import Conductor, EMModel, GetDPSolver, slab_mesh

    mesh = slab_mesh(DIFF_LEN, h)
    solver = GetDPSolver(EMModel(False, conductors=[Conductor(DIFF_SIGMA)], h0_step=DIFF_H0), work)
    res, _ = solver.step(mesh, solver.initial_state(), DIFF_T, steps, run_name="diffusion")
    x = mesh.points[mesh.triangles[res.elements]][:, :, 0].mean(axis=1)
    hy = res.flux_density[-1][:, 1] / MU0
    order = np.argsort(x)
    area = np.abs(mesh.areas()[res.elements])
    pressure = float((res.force_density[-1][:, 0] * area).sum() / h)
    out = RunOutput(scalars={"magnetic_pressure_Pa": pressure})
    out.curves["H"] = (x[order], hy[order])
    out.labels["H"] = ("depth x (m)", "H_y (A/m)")
    return out


@run("getdp_diffusion_h0.05mm")
def _diff_fast(work: Path) -> RunOutput:
    return _diffusion_run(work, 0.05e-3, 100)


@run("getdp_diffusion_h0.0125mm")
def _diff_full(work: Path) -> RunOutput:
    return _diffusion_run(work, 0.0125e-3, 400)


def _coupled_free_sheet(work: Path, end: float) -> RunOutput:
    m, h = run_case_cli("emf_sheet_bulge", work, [f"time.end={end}", f"output.field_interval={end / 2}",
                                                  "bodies.sheet.fixed=[]"])
    # impulse central differences delivered: the force held over substep s acts from that substep on
    # (no lag since the solver change 98cfbf8) and enters the half-step velocity with weight
    # (dt_{s-1} + dt_s) / 2, the first one with dt_0 / 2 (tests/mechanics/test_solver_api.py)
    forces, dts, ends = [], [], [0]
    for row in h[1:]:
        k = int(row["substeps"])
        forces += [row["force_y_N"]] * k
        dts += [row["dt_s"]] * k
        ends.append(len(forces))
    f, d = np.array(forces), np.array(dts)
    weights = np.concatenate([[0.5 * d[0]], 0.5 * (d[:-1] + d[1:])])
    cumulative = np.concatenate([[0.0], np.cumsum(f * weights)])
    delivered = float(cumulative[-1])
    out = RunOutput(scalars={"momentum_y_Ns": float(h["sheet_momentum_y_Ns"][-1]), "impulse_delivered_Ns": delivered,
                             "conservation_error_rel": float(m["conservation_error_rel"])})
    out.curves["momentum"] = (h["time_s"], h["sheet_momentum_y_Ns"])
    out.curves["momentum_reference"] = (h["time_s"], cumulative[np.array(ends)])  # impulse up to each row
    out.labels["momentum"] = ("time (s)", "sheet momentum z (N s)")
    return out


@run("emf_free_sheet_4us")
def _coupled_fast(work: Path) -> RunOutput:
    return _coupled_free_sheet(work, 4e-6)


@run("emf_free_sheet_10us")
def _coupled_full(work: Path) -> RunOutput:
    return _coupled_free_sheet(work, 10e-6)


# ============================================================================ entries
def _plateau(t: np.ndarray, s: np.ndarray) -> float:
    from pulseform.solvers.dolfinx.analysis import contact_stress_metrics

    return contact_stress_metrics(t, s)["contact_stress_plateau_MPa"]


def _duration(t: np.ndarray, s: np.ndarray) -> float:
    from pulseform.solvers.dolfinx.analysis import contact_stress_metrics

    return contact_stress_metrics(t, s)["contact_duration_ms"]


_BAR_CSV = CsvCurve("bar_impact", "contact_stress_1d_bar.csv")
_PAPER4 = "paper sec. 4, eq. (6): 1D bar, c = sqrt(E/rho)"


def _bar_entries(run_key: str, suites: tuple[str, ...], label: str, plateau_ref) -> None:
    register(Entry(f"bar_impact.{label}.plateau", "bar_impact", f"contact stress plateau ({label})", "MPa", run_key,
                   plateau_ref, 0.03, kind="scalar", metric=_plateau, curve="contact_stress", suites=suites,
                   note="mean over the middle half of the contact episode at the middle of the contact surface"))
    register(Entry(f"bar_impact.{label}.duration", "bar_impact", f"contact duration ({label})", "ms", run_key,
                   _BAR_CSV, 0.04, kind="scalar", metric=_duration, curve="contact_stress", suites=suites,
                   note="first to last sample with stress > 0 (soft contact, h0 = 0.01 m)"))


_bar_entries("bar_impact_plane_stress_40x20", ("fast", "full"), "plane_stress", _BAR_CSV)
# the paper's rigid-wall variant through its case file (cases/bar_impact_wall, 5 m/s onto a frictionless
# wall = the symmetry plane of the two-body impact): the same curve, shifted by the 1 ms approach, which
# neither the plateau nor the duration metric sees
register(Entry("bar_impact_wall.plateau", "bar_impact_wall", "wall pressure plateau (rigid wall, 5 m/s)", "MPa",
               "case_bar_impact_wall", _BAR_CSV, 0.02, metric=_plateau, curve="contact_stress",
               note="pulseform run cases/bar_impact_wall; the case file claims the two-body plateau within 2 %",
               align_onset=True))
register(Entry("bar_impact_wall.duration", "bar_impact_wall", "wall contact duration", "ms",
               "case_bar_impact_wall", _BAR_CSV, 0.04, metric=_duration, curve="contact_stress",
               note="pulseform run cases/bar_impact_wall", align_onset=True))
_RHO, _G, _K = 2800.0, 26.5e9, 65.1e9
_E, _NU = 9 * _K * _G / (3 * _K + _G), (3 * _K - 2 * _G) / (2 * (3 * _K + _G))
_bar_entries("bar_impact_plane_strain_80x40", ("full",), "plane_strain",
             Analytic("rho c v / 2, c = sqrt(E / (rho (1 - nu^2))) (plane-strain bar)",
                      _PAPER4 + " with the plane-strain modulus E/(1-nu^2) (SOLVER_NOTES)",
                      value=_RHO * math.sqrt(_E / (_RHO * (1 - _NU ** 2))) * 10.0 / 2 / 1e6))


def _erfc_profile(x: np.ndarray) -> np.ndarray:
    from scipy.special import erfc

    return DIFF_H0 * erfc(np.asarray(x) / (2 * math.sqrt(DIFF_T / (MU0 * DIFF_SIGMA))))


_ERFC = Analytic("H0 erfc(x / (2 sqrt(t / (mu0 sigma)))), t = 20 us", "Carslaw & Jaeger, step field on a "
                 "conducting half-space (1D diffusion); H0 = 1e5 A/m, sigma = 3.5e7 S/m", function=_erfc_profile)
_PRESSURE = Analytic("B0^2 / (2 mu0)", "Ampere + Lorentz on a half-space: int J x B dx = mu0 H0^2 / 2",
                     value=MU0 * DIFF_H0 ** 2 / 2)
for _key, _suites, _tol in (("getdp_diffusion_h0.05mm", ("fast",), 0.02), ("getdp_diffusion_h0.0125mm", ("full",), 0.01)):
    _tag = _key.split("_")[-1]
    register(Entry(f"getdp_diffusion.{_tag}.H_profile", "getdp_diffusion", f"H_y(x) at 20 us ({_tag})", "A/m", _key,
                   _ERFC, _tol, kind="curve", curve="H", suites=_suites,
                   note="element-centroid values of the planar slab (slab_mesh, 4 mm); error = max|dH| / H0"))
    register(Entry(f"getdp_diffusion.{_tag}.pressure", "getdp_diffusion", f"magnetic pressure ({_tag})", "Pa", _key,
                   _PRESSURE, 0.01, computed=lambda o: o.scalars["magnetic_pressure_Pa"], suites=_suites))

for _key, _suites in (("emf_free_sheet_4us", ("fast",)), ("emf_free_sheet_10us", ("full",))):
    _tag = _key.split("_")[-1]
    register(Entry(f"emf_sheet_bulge.free.{_tag}.momentum", "emf_sheet_bulge", f"free-sheet momentum ({_tag})", "N s",
                   _key, Analytic("sum over substeps of F_s (dt_s-1 + dt_s) / 2, first dt_0 / 2 (impulse of the held forces)",
                                  "Newton's second law on a free body (internal forces cancel)",
                                  from_run=lambda o: o.scalars["impulse_delivered_Ns"]),
                   1e-9, computed=lambda o: o.scalars["momentum_y_Ns"], curve="momentum", suites=_suites,
                   note="the reference value comes from the same run's force history"))
    register(Entry(f"emf_sheet_bulge.free.{_tag}.ledger", "emf_sheet_bulge", f"force-transfer ledger ({_tag})", "-",
                   _key, Analytic("sum of nodal forces == sum f_e V_e of GetDP's elements", "conservative transfer on "
                                  "shared nodes (ARCHITECTURE: conservation ledger)", value=0.0),
                   1e-10, computed=lambda o: o.scalars["conservation_error_rel"], error="abs", suites=_suites))



# --------------------------------------------------------------------------- paper section 5 (full suite)
@run("case_corner_fill_30MPa")
def _corner_fill_30(work: Path) -> RunOutput:
    m, _ = run_case_cli("corner_fill", work, ["loads[0].amplitude=30e6"])
    return RunOutput(scalars={k: float(v) for k, v in m.items() if v is not None})


register(Entry("corner_fill.P0_30MPa.fill_fraction", "corner_fill", "fill fraction of the die profile, P0 = 30 MPa",
               "-", "case_corner_fill_30MPa",
               Analytic("1 (the die cavity is filled)", "paper sec. 5: a single 30 MPa pulse fills the die "
                        "(P0* between 25 and 30 MPa); cases/corner_fill/reference/paper.md", value=1.0),
               1e-3, computed=lambda out: out.scalars["fill_fraction"], error="abs", suites=("full",),
               note="pulseform run cases/corner_fill (die depth chosen so that P0* lies in 25-30 MPa, docs/cases.md)"))


# --------------------------------------------------------------------------- paper sec. 5 and 6: the other claims
# (full suite; case meshes; docs/cases.md gives the figures and the explanations of the known deviations)
@run("case_corner_fill_multipulse")
def _corner_fill_multi(work: Path) -> RunOutput:
    m, _ = run_case_cli("corner_fill_multipulse", work, [])
    return RunOutput(scalars={k: float(v) for k, v in m.items() if v is not None})


@run("case_corner_fill_restrike")
def _corner_fill_restrike(work: Path) -> RunOutput:
    m, _ = run_case_cli("corner_fill_restrike", work, [])
    return RunOutput(scalars={k: float(v) for k, v in m.items() if v is not None})


_FILLED = Analytic("1 (the die cavity is filled)", "", value=1.0)
_SEC5 = "paper sec. 5, last paragraph (Fig. 4 vs Fig. 3): "
_CONCL2 = "paper sec. 7, conclusion 2: "
# "significantly lower" / "substantially reduce": read as lower by at least 10 % (more than the 2-4 %
# our verification entries accept as agreement), fixed before the comparison was run
_LOWER = 0.10
_VM_CAPPED = ("the die yields (sigma_0 = 620 MPa) under every loading from P0 = 10 MPa on, so its von Mises "
              "maximum is capped near 620-660 MPa and hardly separates the loadings; the contact stress, the "
              "die's plastic strain and how much of it yields do (die_yielded_volume_fraction, case meshes: "
              "single 30 MPa 0.21, four pulses 0.014, preform + restrike 0.0007; docs/cases.md)")


def _vs_single(key: str, why: str) -> Analytic:
    return Analytic(f"{key} of the single 30 MPa pulse (run case_corner_fill_30MPa)", why,
                    from_run=lambda o: o.scalars[key])


def _corner_entries(tag: str, run_key: str, paper: str, fill_known: str, vm_known: str) -> None:
    case = f"corner_fill_{tag}"
    register(Entry(f"{case}.fill_fraction", case, "fill fraction of the die profile", "-", run_key,
                   Analytic(_FILLED.formula, paper + "the blank ends filled; cases/" + case + "/reference/paper.md",
                            value=1.0), 1e-3, computed=lambda o: o.scalars["fill_fraction"], error="abs",
                   suites=("full",), known_deviation=fill_known,
                   note="profile sampled every 0.1 mm, touched within 2 h0 at some time (analyses/corner_fill.py)"))
    for key, label, claim, known in (
            ("die_mises_max_MPa", "die von Mises max", "maximum J2(sigma) of the die", vm_known),
            ("die_contact_pressure_max_MPa", "die contact stress max", "contact stresses on the die surface", ""),
            ("blank_speed_max_m_s", "blank max speed", "impact velocity of the blank", "")):
        if tag == "restrike" and key == "blank_speed_max_m_s":
            continue  # conclusion 2 speaks of the die's contact stresses only
        register(Entry(f"{case}.{key}_vs_single", case, f"{label}, relative to the single 30 MPa pulse", "-", run_key,
                       _vs_single(key, paper + f"{claim} lower than with the single pulse that fills"),
                       _LOWER, computed=lambda o, k=key: o.scalars[k], compare="below",
                       reference_run="case_corner_fill_30MPa", suites=("full",), known_deviation=known,
                       note="lower by >= 10 % ('significantly'), same die mesh as the single pulse"))


_corner_entries("multipulse", "case_corner_fill_multipulse", _SEC5 + "four pulses 5, 10, 15, 25 MPa: ",
                "with the case file's rest damping (2e4 1/s between pulses) the last 25 MPa pulse starts from a "
                "blank resting 2.4 mm from the corner, brings 144 J there and stops 0.59 mm short (> 2 h0); the "
                "fill moves with that damping but stays below 1 (1e3: 0.972, 2.5e3: 0.997, 5e3: 0.974; die 4 mm, "
                "docs/cases.md)", _VM_CAPPED)
_corner_entries("restrike", "case_corner_fill_restrike", _CONCL2 + "static preforming + pulsed restrike: ",
                "", _VM_CAPPED)
