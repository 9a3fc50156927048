"""A study's answer: which parameters matter for each headline metric, a response surface, the best member.

For each headline metric (those the successful members report: :func:`headline_metrics`, or the ones the user
names) over the numeric parameters (a list of numbers or a range; others are left out of the answer):

- ``src`` and ``r2_linear``: standardised regression coefficients from the members and the linear fit's R²;
- ``surface``: the least-squares quadratic (linear with too few members) with its leave-one-out error
  ``loo_rmse`` (the metric's unit; what the surface's predictions of members it did not see are within, as an
  RMS) and ``loo_max``;
- ``sobol_first`` / ``sobol_total``: the Sobol indices of that surface over the parameters' box (independent,
  uniform), by :func:`.sensitivity.sobol_indices`; ``ranking``: the parameters by ``sobol_total``.

SRC are the members' own evidence (trust them when ``r2_linear`` is near 1); Sobol indices capture curvature
and interactions but only as far as the surface is right (see its ``loo_rmse``).

The best member (:func:`best_member`): the successful member that maximises or minimises the objective metric
(``max:NAME`` / ``min:NAME``) among those meeting every constraint (``NAME<LIMIT`` / ``NAME>LIMIT``).
"""

from __future__ import annotations

import logging
import math
import re

import numpy as np

from .designs import Param
from .sensitivity import QuadraticSurface, sobol_indices, standardised_regression

log = logging.getLogger(__name__)

__all__ = ["parse_objective", "parse_constraint", "headline_metrics", "analyse", "best_member", "report_markdown",
           "numeric_params", "json_ready", "summary_lines"]

_CONSTRAINT = re.compile(r"\s*([A-Za-z_][A-Za-z0-9_]*)\s*([<>])\s*(\S+)\s*")
#: wall-time metrics: a study's cost, not its physics (left out of the default headline)
_COST = re.compile(r".*_time_s$")


class AnswerError(ValueError):
    """A malformed ``--objective`` or ``--constraint`` (one line)."""


def parse_objective(text: str | None) -> tuple[str, str] | None:
    """``max:NAME`` or ``min:NAME`` -> (sense, metric); None for None."""
    if text is None:
        return None
    sense, _, name = text.partition(":")
    if sense not in ("max", "min") or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
        raise AnswerError(f"--objective {text}: expected max:METRIC or min:METRIC (a metrics.json key)")
    return sense, name


def parse_constraint(text: str) -> tuple[str, str, float]:
    """``NAME<LIMIT`` or ``NAME>LIMIT`` -> (metric, op, limit)."""
    m = _CONSTRAINT.fullmatch(text)
    try:
        limit = float(m.group(3)) if m else math.nan
    except ValueError:
        limit = math.nan
    if not m or not math.isfinite(limit):
        raise AnswerError(f"--constraint {text}: expected METRIC<LIMIT or METRIC>LIMIT with a finite number, e.g. "
                          "'die_max_von_mises_MPa<300'")
    return m.group(1), m.group(2), limit


def numeric_params(params: list[Param]) -> list[Param]:
    """The parameters with a numeric scale (ranges, lists of numbers that are not all equal)."""
    out = []
    for p in params:
        b = p.bounds()
        if b is not None and b[1] > b[0]:
            out.append(p)
    return out


def headline_metrics(ok: list) -> list[str]:
    """The metrics every successful member reports among the sweep's plotted ones and the convergence study's
    headline ones (:func:`.converge.default_metrics`), wall times left out."""
    from .converge import default_metrics
    from .sweep import main_metrics

    if not ok:
        return []
    names = [k for k in [*main_metrics(ok), *default_metrics(ok[0].metrics)] if not _COST.fullmatch(k)]
    return [k for k in dict.fromkeys(names) if all(k in m.metrics for m in ok)]


def analyse(members: list, params: list[Param], metrics: list[str] | None = None,
            objective: tuple[str, str] | None = None, constraints: list[tuple[str, str, float]] = ()) -> dict:
    """The ``answer`` part of ``study.json`` (see the module docstring)."""
    ok = [m for m in members if m.returncode == 0 and m.metrics]
    num = numeric_params(params)
    names = list(metrics) if metrics else headline_metrics(ok)
    for extra in ([objective[1]] if objective else []) + [c[0] for c in constraints]:
        if extra not in names and any(extra in m.metrics for m in ok):
            names.append(extra)
    lo = np.array([p.bounds()[0] for p in num])
    hi = np.array([p.bounds()[1] for p in num])
    out: dict = {"parameters": [p.key for p in num], "left_out": [p.key for p in params if p not in num],
                 "members_ok": len(ok), "members": len(members), "metrics": {}}
    for name in names:
        rows = [m for m in ok if name in m.metrics and math.isfinite(m.metrics[name])]
        if not num:
            out["metrics"][name] = {"error": "no numeric parameter"}
            continue
        if len(rows) < len(num) + 2:
            out["metrics"][name] = {"error": f"{len(rows)} successful members report it; at least {len(num) + 2} "
                                             f"are needed for {len(num)} parameters"}
            continue
        x = np.array([[float(m.values[p.key]) for p in num] for m in rows])
        y = np.array([float(m.metrics[name]) for m in rows])
        out["metrics"][name] = _one_metric(x, y, lo, hi, [p.key for p in num])
    out["best"] = best_member(members, objective, constraints) if objective else None
    return out


def _one_metric(x: np.ndarray, y: np.ndarray, lo: np.ndarray, hi: np.ndarray, keys: list[str]) -> dict:
    src, r2 = standardised_regression(x, y)
    surf = QuadraticSurface.fit(x, y, lo, hi)
    s, st = sobol_indices(surf, lo, hi, n=2 ** 12)
    order = sorted(range(len(keys)), key=lambda i: -st[i])
    return {"n": int(len(y)), "mean": float(y.mean()), "std": float(y.std()), "min": float(y.min()),
            "max": float(y.max()), "src": dict(zip(keys, src.tolist())), "r2_linear": r2,
            "surface": {"kind": "quadratic" if surf.degree == 2 else "linear", "r2": surf.r2,
                        "loo_rmse": surf.loo_rmse, "loo_max": surf.loo_max,
                        "loo_rmse_rel_std": surf.loo_rmse / float(y.std()) if y.std() > 0 else math.nan,
                        "coefficients": surf.coef.tolist(), "lo": lo.tolist(), "hi": hi.tolist()},
            "sobol_first": dict(zip(keys, s.tolist())), "sobol_total": dict(zip(keys, st.tolist())),
            "ranking": [keys[i] for i in order]}


def best_member(members: list, objective: tuple[str, str], constraints: list[tuple[str, str, float]] = ()) -> dict:
    """The best successful member for ``objective`` (sense, metric) under ``constraints``; ``{"error": ...}`` when
    none qualifies."""
    sense, name = objective
    ok = [m for m in members if m.returncode == 0 and name in m.metrics and math.isfinite(m.metrics[name])]
    feasible = [m for m in ok if all(c in m.metrics and (m.metrics[c] < lim if op == "<" else m.metrics[c] > lim)
                                     for c, op, lim in constraints)]
    spec = {"objective": f"{sense}:{name}", "constraints": [f"{c}{op}{lim:g}" for c, op, lim in constraints],
            "candidates": len(ok), "feasible": len(feasible)}
    if not feasible:
        return {**spec, "error": f"no successful member {'reports ' + name if not ok else 'meets the constraints'}"}
    best = (max if sense == "max" else min)(feasible, key=lambda m: m.metrics[name])
    return {**spec, "index": best.index, "folder": best.out.name, "values": best.values, "value": best.metrics[name],
            "metrics": {k: best.metrics[k] for k in [name, *(c for c, _, _ in constraints)] if k in best.metrics}}


def report_markdown(study: dict, case: str) -> str:
    """``report.md``: the design, the members, per metric the parameters ranked with SRC and Sobol indices and
    the surface's error, the best member."""
    d, a = study["design"], study["answer"]
    kind = "full grid" if d["design"] == "grid" else f"{d['design'].upper()} sample of {d['sample']} (seed {d['seed']})"
    failed = [m for m in study["members"] if m["returncode"] not in (0, None)]
    lines = [f"# Study of {case}", "",
             f"{kind} over {', '.join(p['key'] for p in d['params'])}: {len(study['members'])} members, "
             f"{a['members_ok']} succeeded, {len(failed)} failed, "
             f"{sum(m['returncode'] is None for m in study['members'])} not run.", ""]
    if a["left_out"]:
        lines += [f"Left out of the sensitivities (not numeric): {', '.join(a['left_out'])}.", ""]
    lines += ["SRC: standardised regression coefficients from the members (linear fit, its R²). S, S_T: first-order "
              "and total Sobol indices of the response surface (Saltelli 2010 / Jansen 1999 estimators); trust them "
              "as far as the surface's leave-one-out error allows.", ""]
    for name, r in a["metrics"].items():
        lines.append(f"## {name}")
        if "error" in r:
            lines += ["", r["error"], ""]
            continue
        s = r["surface"]
        lines += ["", f"{r['n']} members: mean {r['mean']:.6g}, std {r['std']:.6g}, range {r['min']:.6g} to "
                      f"{r['max']:.6g}. Linear fit R² = {r['r2_linear']:.3f}; {s['kind']} surface R² = {s['r2']:.4f}, "
                      f"leave-one-out RMS error {s['loo_rmse']:.3g} ({100 * s['loo_rmse_rel_std']:.2g} % of the std), "
                      f"largest {s['loo_max']:.3g}.", "",
                  "| rank | parameter | SRC | S | S_T |", "|---|---|---|---|---|"]
        for i, key in enumerate(r["ranking"], 1):
            lines.append(f"| {i} | {key} | {r['src'][key]:+.3f} | {r['sobol_first'][key]:.3f} | "
                         f"{r['sobol_total'][key]:.3f} |")
        lines.append("")
    best = a.get("best")
    if best:
        lines += ["## Best member", "", f"{best['objective']}" + (f" subject to {', '.join(best['constraints'])}"
                                                                  if best["constraints"] else "") +
                  f": {best['feasible']} of {best['candidates']} members qualify."]
        if "error" in best:
            lines.append(best["error"])
        else:
            vals = ", ".join(f"{k} = {v}" for k, v in best["values"].items())
            lines.append(f"Member {best['index']} ({best['folder']}): {vals}; "
                         + ", ".join(f"{k} = {v:.6g}" for k, v in best["metrics"].items()) + ".")
        lines.append("")
    for m in failed:
        lines.append(f"member {m['index']} ({m['folder']}) failed: {m['error']}")
    return "\n".join(lines) + "\n"


def json_ready(obj):
    """``obj`` with every non-finite float as None (JSON has no NaN), recursively."""
    if isinstance(obj, dict):
        return {k: json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_ready(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def summary_lines(members: list, out) -> list[str]:
    """The terminal's summary of a study: one line per member (values, status, main metrics), the parameters
    ranked per metric and the best member (from ``out/study.json``), the report's path."""
    import json
    from pathlib import Path

    keys = list(members[0].values) if members else []
    shown = ("max_deflection_mm", "force_impulse_Ns", "em_time_s", "mech_time_s", "wall_time_s")
    lines = ["  ".join(f"{k:>14}" for k in keys + ["status", *shown])]
    for m in members:
        status = "ok" if m.returncode == 0 else "not run" if m.returncode is None else f"FAILED({m.returncode})"
        vals = [f"{m.metrics[k]:14.6g}" if k in m.metrics else f"{'-':>14}" for k in shown]
        lines.append("  ".join([f"{m.values[k]:>14}" for k in keys] + [f"{status:>14}"] + vals))
    try:
        answer = json.loads((Path(out) / "study.json").read_text())["answer"]
    except (OSError, ValueError, KeyError):
        return lines
    for name, r in answer["metrics"].items():
        if "error" in r:
            continue
        ranked = ", ".join(f"{k.split('.')[-1]} {r['sobol_total'][k]:.2f}" for k in r["ranking"])
        loo = r["surface"]["loo_rmse"]
        lines.append(f"{name}: S_T {ranked}; linear R² {r['r2_linear']:.3f}; {r['surface']['kind']} surface "
                     f"LOO RMS {'-' if loo is None else f'{loo:.3g}'}")
    best = answer.get("best")
    if best:
        lines.append(f"best ({best['objective']}{', ' + ', '.join(best['constraints']) if best['constraints'] else ''}"
                     "): " + (best["error"] if "error" in best else
                              f"member {best['index']} {' '.join(f'{k}={v}' for k, v in best['values'].items())}: "
                              f"{best['value']:.6g}"))
    lines.append(f"report: {Path(out) / 'report.md'}")
    return lines
