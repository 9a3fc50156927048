"""``pulseform validate``: run the registry's entries, compare with their references, write a report.

Writes into ``out``: ``report.md`` (case, quantity, reference, computed, error, tolerance, pass),
``report.json`` (the same plus provenance, runs and wall times), ``plots/<entry>.png`` (computed vs
reference overlays) and ``runs/<run>/`` (the runs' work folders). A run that raises makes each of its
entries fail with the error in the report; nothing stops the other runs.
"""

from __future__ import annotations

import hashlib
import logging
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import __version__
from ..run.results import ResultsFolder, atomic_write_text
from ..run.warm import warm_pool
from .gci_band import judge
from .info import collect
from . import registry_cases  # noqa: F401 - registers the shipped cases' entries against outside references
from .registry import REGISTRY, REPO, RUNS, Analytic, CsvCurve, Entry, ReferenceError_, RunOutput

log = logging.getLogger(__name__)
SUITES = ("fast", "full")


class SelectionError(ValueError):
    """Bad --suite / --only selection (no such entry)."""


@dataclass
class Outcome:
    """The result of one entry."""

    entry: Entry
    reference: float | None = None
    computed: float | None = None
    error: float | None = None
    passed: bool = False
    message: str = ""
    provenance: dict[str, str] = field(default_factory=dict)
    plot: str = ""
    met: bool = False  # the comparison itself succeeded (``passed`` also counts an expected known deviation)
    band: dict = field(default_factory=dict)  # a GCI-band entry's band and verdict (:mod:`.gci_band`)

    @property
    def status(self) -> str:
        """"pass", "known deviation (xfail)", "XPASS (known deviation no longer seen)" or "FAIL"."""
        if self.entry.known_deviation:
            return "XPASS (known deviation no longer seen)" if self.met else \
                ("known deviation (xfail)" if self.passed else "FAIL")
        return "pass" if self.passed else "FAIL"

    def row(self) -> dict:
        e = self.entry
        return {"name": e.name, "case": e.case, "quantity": e.quantity, "unit": e.unit, "kind": e.kind,
                "reference": e.reference.describe(), "reference_value": self.reference, "computed": self.computed,
                "error": self.error, "error_kind": "max|dy|/max|y_ref|" if e.kind == "curve" else e.error,
                "tolerance": e.tolerance, "compare": e.compare, "criterion": criterion(e), "pass": self.passed,
                "status": self.status, "known_deviation": e.known_deviation, "message": self.message,
                "provenance": self.provenance, "run": e.run, "reference_run": e.reference_run, "note": e.note,
                "plot": self.plot, "gci_band": self.band}


def criterion(e: Entry) -> str:
    """The pass condition on the error, as text."""
    if e.gci is not None:
        u = f"{100 * e.gci.uncertainty:g} %" if e.error == "rel" else f"{e.gci.uncertainty:g} {e.unit}"
        return f"reference within computed ± GCI ± {u}"
    return {"equal": f"|error| <= {e.tolerance:g}", "below": f"error <= -{e.tolerance:g}",
            "above": f"error >= {e.tolerance:g}"}[e.compare]


def select(suite: str, only: list[str] | None = None) -> list[Entry]:
    """Entries of ``suite``, optionally only those whose name starts with one of ``only``."""
    if suite not in SUITES:
        raise SelectionError(f"--suite: got {suite!r}; allowed: {', '.join(SUITES)}")
    entries = [e for e in REGISTRY.values() if suite in e.suites]
    if only:
        unknown = [o for o in only if not any(e.name.startswith(o) for e in entries)]
        if unknown:
            raise SelectionError(f"--only: no {suite!r} entry starts with {', '.join(map(repr, unknown))}; "
                                 f"entries: {', '.join(e.name for e in entries)}")
        entries = [e for e in entries if any(e.name.startswith(o) for o in only)]
    return entries


def run_validation(entries: list[Entry], out: Path, *, force: bool = False,
                   reference_root: Path = REPO) -> list[Outcome]:
    """Run every run the entries need (once each), compare, write the report. Returns the outcomes."""
    results = ResultsFolder(out, force=force)
    runs: dict[str, RunOutput | Exception] = {}
    with warm_pool(results.root):  # the runs through the CLI fork from one warm process (run/warm.py)
        for key in dict.fromkeys(k for e in entries for k in (e.run, e.reference_run) if k is not None):
            work = results.root / "runs" / key
            work.mkdir(parents=True, exist_ok=True)
            t0 = time.perf_counter()
            log.info("validation run %s ...", key)
            try:
                runs[key] = RUNS[key](work)
                runs[key].wall_time_s = time.perf_counter() - t0
                log.info("validation run %s done in %.1f s", key, runs[key].wall_time_s)
            except Exception as exc:  # a failed run fails its entries, not the suite
                log.warning("validation run %s failed: %s", key, exc)
                (work / "error.txt").write_text(traceback.format_exc())
                runs[key] = exc
    outcomes = [_evaluate(e, runs[e.run], reference_root, results.plots,
                          runs[e.reference_run] if e.reference_run else None) for e in entries]
    _write_report(outcomes, runs, results.root)
    return outcomes


def _evaluate(e: Entry, run: RunOutput | Exception, root: Path, plots: Path,
              ref_run: RunOutput | Exception | None = None) -> Outcome:
    """Compare one entry; ``ref_run``: the output of ``e.reference_run`` (if the entry names one)."""
    o = Outcome(e)
    for key, r in ((e.run, run), (e.reference_run, ref_run)):
        if isinstance(r, Exception):
            o.message = f"run {key} failed: {r}"
            return o
    ref_curve = None
    try:
        if isinstance(e.reference, CsvCurve):
            x, y, o.provenance, _ = e.reference.load(root)
            o.provenance["file"] = e.reference.describe()
            o.provenance["sha256"] = hashlib.sha256(e.reference.path(root).read_bytes()).hexdigest()
            ref_curve = (x, y)
        else:
            o.provenance = {"source": e.reference.source, "formula": e.reference.formula}
            if e.reference.function is not None and e.curve in run.curves:
                xc = run.curves[e.curve][0]
                ref_curve = (xc, e.reference.function(xc))
        if e.also:
            o.provenance["also drawn"] = ", ".join(c.describe() for c in e.also)
        if e.kind == "curve":
            xc, yc = run.curves[e.curve]
            yr = np.interp(xc, *ref_curve) if isinstance(e.reference, CsvCurve) else ref_curve[1]
            o.error = float(np.max(np.abs(yc - yr)) / np.max(np.abs(yr)))
            o.computed, o.reference = float(np.max(np.abs(yc))), float(np.max(np.abs(yr)))
        else:
            if e.metric is not None:
                o.computed = float(e.metric(*run.curves[e.curve]))
            else:
                o.computed = float(e.computed(run))
            o.reference = _scalar_reference(e, ref_run if e.reference_run else run, ref_curve)
            diff = o.computed - o.reference
            o.error = diff if e.error == "abs" else diff / abs(o.reference)
            if e.compare == "equal":
                o.error = abs(o.error)
        ok = {"equal": lambda x: x <= e.tolerance, "below": lambda x: x <= -e.tolerance,
              "above": lambda x: x >= e.tolerance}[e.compare if e.kind == "scalar" else "equal"]
        o.met = bool(np.isfinite(o.error) and ok(o.error))
        if e.gci is not None:  # the computed value's own error band instead of the tolerance
            verdict = judge(e.gci, run, o.reference, e.error)
            o.band = verdict.to_dict()
            o.met = verdict.met
            o.provenance["reference uncertainty"] = e.gci.uncertainty_source
        o.passed = o.met != bool(e.known_deviation)
        if not o.met:
            o.message = f"error {o.error:.3g} does not satisfy {criterion(e)}"
        if o.band:
            o.message = f"{o.message}: {verdict.text()}" if not o.met else verdict.text()
        if e.known_deviation:
            o.message = ("known deviation (xfail); " if not o.met else
                         "XPASS: the known deviation is no longer seen, update the registry (docs/cases.md); ") + o.message
    except ReferenceError_ as exc:
        o.message = str(exc)
    except Exception as exc:  # a quantity the run could not provide
        o.message = f"{type(exc).__name__}: {exc}"
    try:
        o.plot = _plot(e, run, ref_curve, plots, root)
    except Exception as exc:  # plots never decide a verdict
        log.warning("plot of %s failed: %s", e.name, exc)
    return o


def _scalar_reference(e: Entry, run: RunOutput, ref_curve) -> float:
    ref = e.reference
    if isinstance(ref, CsvCurve):
        if e.metric is None:
            raise ValueError(f"{e.name}: a scalar entry with a curve reference needs a metric")
        return float(e.metric(*ref_curve))
    if ref.from_run is not None:
        return float(ref.from_run(run))
    if ref.value is None:
        raise ValueError(f"{e.name}: analytic reference without a value")
    return float(ref.value)


def _plot(e: Entry, run: RunOutput, ref_curve, folder: Path, root: Path = REPO) -> str:
    if e.curve is None or e.curve not in run.curves:
        return ""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xc, yc = run.curves[e.curve]
    fig, ax = plt.subplots(figsize=(6, 3.4))
    ax.plot(xc, yc, "-", lw=1.2, label="computed")
    if ref_curve is None and f"{e.curve}_reference" in run.curves:  # a balance's other side, from the run
        ref_curve = run.curves[f"{e.curve}_reference"]
    if ref_curve is not None:
        rx, ry = ref_curve
        label = e.reference.label if isinstance(e.reference, CsvCurve) else "reference"
        if e.align_onset and (yc > 0).any() and (ry > 0).any():
            shift = float(xc[np.argmax(yc > 0)] - rx[np.argmax(ry > 0)])
            rx, label = rx + shift, f"reference (shifted by {shift:.4g})"
        ax.plot(rx, ry, "--", lw=1.5, label=label)
    elif isinstance(e.reference, Analytic) and e.reference.value is not None and e.kind == "scalar" \
            and e.metric is None and e.error == "rel":
        ax.axhline(e.reference.value, ls="--", color="k", label="reference")
    for other in e.also:
        ox, oy, _, _ = other.load(root)
        ax.plot(ox, oy, ":", lw=1.5, label=other.label)
    xl, yl = run.labels.get(e.curve, ("x", "y"))
    ax.set(xlabel=xl, ylabel=yl, title=e.name)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = folder / f"{e.name}.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return f"plots/{path.name}"


def _fmt(v: float | None) -> str:
    return "-" if v is None else f"{v:.6g}"


def _write_report(outcomes: list[Outcome], runs: dict, root: Path) -> None:
    n_ok = sum(o.passed for o in outcomes)
    n_xfail = sum(o.passed and not o.met for o in outcomes)
    env = _environment()
    lines = ["# pulseform validation report", "",
             f"{n_ok} of {len(outcomes)} passed" + (f" ({n_xfail} of them known deviations, xfail)" if n_xfail else "")
             + ("" if n_ok == len(outcomes) else " — FAILED"), "",
             "Environment: " + ", ".join(f"{k} {v}" for k, v in env.items()), "",
             "| case | quantity | reference | reference value | computed | error | tolerance | pass |",
             "|---|---|---|---|---|---|---|---|"]
    for o in outcomes:
        e = o.entry
        err = _fmt(o.error) + ("" if o.error is None else (" (abs)" if e.error == "abs" and e.kind != "curve" else " (rel)"))
        tol = f"{e.tolerance:g}" if e.compare == "equal" and e.gci is None else criterion(e)
        lines.append(f"| {e.case} | {e.quantity} [{e.unit}] | {e.reference.describe()} | {_fmt(o.reference)} | "
                     f"{_fmt(o.computed)} | {err} | {tol} | {o.status} |")
    lines += ["", "## Details", ""]
    for o in outcomes:
        e = o.entry
        lines.append(f"### {e.name}: {o.status}")
        if o.message:
            lines.append(f"- **{o.message}**")
        lines.append(f"- run `{e.run}`" + (f" ({runs[e.run].wall_time_s:.1f} s)" if isinstance(runs[e.run], RunOutput) else "")
                     + (f"; reference from run `{e.reference_run}`" if e.reference_run else ""))
        if e.known_deviation:
            lines.append(f"- known deviation: {e.known_deviation}")
        for k, v in o.provenance.items():
            lines.append(f"- {k}: {v}")
        if e.note:
            lines.append(f"- note: {e.note}")
        if o.plot:
            lines.append(f"\n![{e.name}]({o.plot})")
        lines.append("")
    atomic_write_text(root / "report.md", "\n".join(lines))
    write_json(root / "report.json", {
        "passed": n_ok == len(outcomes), "n_entries": len(outcomes), "n_passed": n_ok, "n_known_deviations": n_xfail,
        "entries": [o.row() for o in outcomes],
        "runs": {k: ({"wall_time_s": v.wall_time_s} if isinstance(v, RunOutput) else {"error": str(v)})
                 for k, v in runs.items()},
        "environment": env})


def _environment() -> dict[str, str]:
    """Versions of pulseform and the programs it ran (as ``pulseform info``), next to the results."""
    env = {"pulseform": __version__}
    try:
        env.update({c.name: c.version for c in collect()})
    except Exception as exc:  # never lose a report over a version query
        env["error"] = str(exc)
    return env


def _clean(v):
    if isinstance(v, dict):
        return {str(k): _clean(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_clean(x) for x in v]
    if hasattr(v, "item"):
        v = v.item()
    if isinstance(v, float) and not np.isfinite(v):
        return None
    return v


def write_json(path: Path, data: dict) -> None:
    """Nested JSON, atomically; non-finite numbers become null."""
    import json

    atomic_write_text(path, json.dumps(_clean(data), indent=2) + "\n")
