"""Convergence studies: a case on systematically refined meshes (or EM steps), the grid convergence
index of its headline metrics (:mod:`.gci`).

``pulseform converge CASE`` runs the case on ``levels`` (>= 3) meshes refined by a constant ``ratio``:
level 0 is the case as given, level k divides **every** element size of the case by ratio^k (the keys
named ``mesh_size*`` of ``[geometry]`` and its nested tables, and each body's ``mesh_size``; of a 3D geometry
file ``geometry.mesh_size_factor`` alone, which multiplies all its sizes), so the
meshes are refined alike everywhere, as the GCI procedure asks. With ``refine = "em_step"`` it
divides ``coupling.n`` instead (the EM step, the mechanical step fixed) -- or, for a 3D geometry file
with ``geometry.em_step`` (which sets n), that EM step (n = round(em_step / mechanical step) per level); when
every body is rigid (the EM step is a period of the source over ``coupling.steps_per_period``) it multiplies
``coupling.steps_per_period`` (and divides ``time.dt_max`` when given).
Each level is a ``pulseform run`` of its own (``jobs`` at a time, forked from the study's warm process, without
pictures of its own: as the members of a sweep, :mod:`..run.warm`). For each metric it computes,
on the three finest levels, the observed order, the Richardson-extrapolated value and the GCI
(Celik et al. 2008), and writes:

- ``converge.json``: the levels (their relative size h = ratio^−k, overrides, metrics) and per metric
  the values and the GCI result;
- ``report.md``: a table (metric, fine/medium/coarse values, observed order, extrapolated value, GCI
  of the finest level, convergence type);
- ``plots/converge_<metric>.png``: the values against h, the extrapolated value at h = 0 and the
  finest level's GCI band.
"""

from __future__ import annotations

import json
import logging
import math
import re
import tomllib
from pathlib import Path

from ..case.io import CaseError, case_to_toml, load_case
from ..case.model import STEPS_PER_PERIOD
from ..em.skin_depth import resolve_defaults
from ..run.results import ResultsFolder, atomic_write_text
from ..run.units import label
from ..run.warm import StudyInterrupted, import_in_background, run_all, warm_pool
from .gci import grid_convergence
from .sweep import Member, run_member

log = logging.getLogger(__name__)

__all__ = ["refinement_keys", "study_levels", "run_converge", "DEFAULT_METRICS", "default_metrics"]

#: the headline metrics a study reports when the caller names none (those the runs have; radial_load_impulse_Ns:
#: axisymmetric runs, the tubes' load)
DEFAULT_METRICS = ("force_peak_N", "force_impulse_Ns", "radial_load_impulse_Ns", "coil_current_peak_kA",
                   "max_deflection_mm", "max_radial_displacement_mm")


def default_metrics(metrics: dict[str, float]) -> list[str]:
    """The metrics a study reports when the caller names none: :data:`DEFAULT_METRICS` and each rigid body's
    largest translation ``<body>_max_position_<c>_mm`` (its first peak: what a coarse EM step moves most) among
    ``metrics``, one run's."""
    return list(DEFAULT_METRICS) + sorted(k for k in metrics if _RIGID_PEAK.fullmatch(k))


#: a rigid body's largest translation along a free component (orchestrator/mech/mixed.py, rigid_metrics)
_RIGID_PEAK = re.compile(r".+_max_position_[xyz]_mm")


class ConvergeError(ValueError):
    """A study that cannot be made (one line)."""


def refinement_keys(resolved: dict) -> dict[str, float]:
    """The element sizes (m) of a resolved case (the TOML of :func:`case_to_toml`), by ``--set`` key
    path: ``geometry.mesh_size*`` (also in nested tables such as ``geometry.die``) and
    ``bodies.<name>.mesh_size``; of a 3D geometry file only ``geometry.mesh_size_factor``, which scales all of
    its sizes (its ``geometry.mesh_sizes`` and a .geo's size parameters, even those named ``mesh_size*``)."""
    out: dict[str, float] = {}

    def number(v) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool)

    def walk(table: dict, path: str) -> None:
        for k, v in table.items():
            if isinstance(v, dict):
                walk(v, f"{path}.{k}")
            elif k.startswith("mesh_size") and number(v):
                out[f"{path}.{k}"] = float(v)

    geometry = resolved.get("geometry", {})
    if geometry.get("type") == "geometry_3d":
        # geometry.mesh_size_factor scales every size of the file (its own, geometry.mesh_sizes, a .geo's
        # parameters): refining anything else as well would refine those twice
        if number(geometry.get("mesh_size_factor")):
            out["geometry.mesh_size_factor"] = float(geometry["mesh_size_factor"])
    else:
        walk(geometry, "geometry")
    for b in resolved.get("bodies", []):
        if isinstance(b.get("mesh_size"), (int, float)):
            out[f"bodies.{b['name']}.mesh_size"] = float(b["mesh_size"])
    return out


def study_levels(resolved: dict, ratio: float, levels: int, refine: str) -> list[dict[str, str]]:
    """The ``--set`` values of each level (level 0: the case as given), as TOML literals."""
    if refine == "mesh":
        keys = refinement_keys(resolved)
        if not keys:
            raise ConvergeError("the case has no element size to refine (no mesh_size key: a user deck's mesh is "
                                "its .geo's; refine its [geometry.parameters] with sweep)")
        return [{k: repr(v / ratio ** i) for k, v in keys.items()} for i in range(levels)]
    geometry = resolved.get("geometry", {})
    if geometry.get("type") == "geometry_3d" and isinstance(geometry.get("em_step"), (int, float)):
        # n = round(geometry.em_step / mechanical step) there: coupling.n is not used
        return [{"geometry.em_step": repr(float(geometry["em_step"]) / ratio ** i)} for i in range(levels)]
    if _all_rigid(resolved):
        return _rigid_step_levels(resolved, ratio, levels)
    n = int(resolved.get("coupling", {}).get("n", 10))
    out = []
    for i in range(levels):
        value = n / ratio ** i
        if abs(value - round(value)) > 1e-9 or round(value) < 1:
            raise ConvergeError(f"--refine em_step: coupling.n = {n} divided by {ratio:g}^{i} is {value:g}, not a whole "
                                "number >= 1; choose coupling.n and --ratio so that every level's n is whole")
        out.append({"coupling.n": str(int(round(value)))})
    return out


def _all_rigid(resolved: dict) -> bool:
    """A coupled case whose bodies are all rigid: its EM step is a period of the source over
    ``coupling.steps_per_period`` (capped by ``n`` times ``time.dt_max``), whatever ``coupling.n`` is."""
    bodies = resolved.get("bodies", [])
    return resolved.get("case", {}).get("kind") == "coupled" and bool(bodies) and all(b.get("rigid") for b in bodies)


def _rigid_step_levels(resolved: dict, ratio: float, levels: int) -> list[dict[str, str]]:
    """``--refine em_step`` of an all-rigid case: the EM step min(period / steps_per_period, n · dt_max) divided by
    ratio^k, i.e. ``coupling.steps_per_period`` times ratio^k (a whole number) and ``time.dt_max`` (if given)
    divided by it (dividing ``coupling.n`` would leave that step as it is)."""
    steps = int(resolved.get("coupling", {}).get("steps_per_period", STEPS_PER_PERIOD))
    dt_max = resolved.get("time", {}).get("dt_max")
    out = []
    for i in range(levels):
        value = steps * ratio ** i
        if abs(value - round(value)) > 1e-9:
            raise ConvergeError(f"--refine em_step: every body is rigid, so the EM step is the period over "
                                f"coupling.steps_per_period = {steps}, times {ratio:g}^{i} is {value:g}, not a whole "
                                "number; choose coupling.steps_per_period and --ratio so that every level's is whole")
        level = {"coupling.steps_per_period": str(int(round(value)))}
        if isinstance(dt_max, (int, float)):
            level["time.dt_max"] = repr(float(dt_max) / ratio ** i)
        out.append(level)
    return out


def run_converge(case: str, out: Path, *, ratio: float = 2.0, levels: int = 3, refine: str = "mesh",
                 metrics: list[str] | None = None, jobs: int = 1, force: bool = False,
                 overrides: list[str] | None = None) -> dict:
    """Run the study of ``case`` into ``out``; returns the ``converge.json`` content (see the module
    docstring). Raises :class:`ConvergeError` (or the loader's ``CaseError``) before anything runs for
    bad arguments or a level whose case is invalid; a level whose run fails leaves its metrics out."""
    if not (math.isfinite(ratio) and ratio >= 1.1):
        raise ConvergeError(f"--ratio: got {ratio:g}; must be >= 1.1 (Celik et al. recommend > 1.3)")
    if levels < 3:
        raise ConvergeError(f"--levels: got {levels}; the GCI needs at least 3")
    if refine not in ("mesh", "em_step"):
        raise ConvergeError(f"--refine: got {refine!r}; allowed: 'mesh', 'em_step'")
    base, file = load_case(case, list(overrides or []))
    base = resolve_defaults(base, file, list(overrides or []))  # level 0: conductor sizes left to the skin depth
    resolved = tomllib.loads(case_to_toml(base))
    plan = study_levels(resolved, ratio, levels, refine)
    results = ResultsFolder(out, force=force)
    members = [Member(i, values, results.root / f"level_{i}") for i, values in enumerate(plan)]
    for m in members:  # every level valid before anything runs (a finer mesh may exceed [limits])
        try:
            load_case(case, list(overrides or []) + m.overrides)
        except CaseError as exc:
            raise ConvergeError(f"level {m.index} (sizes / {ratio:g}^{m.index}): {exc}") from None
    sets = list(overrides or [])
    try:
        with warm_pool(results.root) as pool:
            figures = import_in_background("matplotlib.pyplot", after=pool)  # for the study's figures at the end
            run_all(lambda m: run_member(case, m, sets, pool=pool), members, jobs, pool)
    except StudyInterrupted as exc:
        write_report(results.root, summarise(members, ratio, metrics, refine), case)  # what the levels reached
        raise StudyInterrupted(exc.signum, f"converge {exc}; levels: {results.root / 'converge.json'}") from None
    except KeyboardInterrupt:
        write_report(results.root, summarise(members, ratio, metrics, refine), case)
        raise
    finally:
        results.release()
    report = summarise(members, ratio, metrics, refine)
    write_report(results.root, report, case)
    figures.join()
    plot_study(report, results.plots)
    return report


def write_report(root: Path, report: dict, case: str) -> None:
    """``converge.json`` and ``report.md`` (atomically)."""
    atomic_write_text(root / "converge.json", json.dumps(report, indent=1) + "\n")
    atomic_write_text(root / "report.md", report_markdown(report, case))


def summarise(members: list[Member], ratio: float, metrics: list[str] | None, refine: str) -> dict:
    """The study's record: the levels and, per metric present in every level's run, the GCI of the
    three finest levels."""
    ok = [m for m in members if m.returncode == 0 and m.metrics]
    names = list(metrics) if metrics else [k for k in default_metrics(ok[0].metrics if ok else {})
                                           if all(k in m.metrics for m in ok)]
    out = {"refine": refine, "ratio": ratio,
           "levels": [{"level": m.index, "h_rel": ratio ** -m.index, "overrides": m.values, "returncode": m.returncode,
                       "error": m.error, "log_tail": m.log_tail, "metrics": m.metrics} for m in members],
           "metrics": {}}
    fine = sorted(ok, key=lambda m: m.index)[-3:][::-1]  # finest first
    for name in names:
        if len(fine) < 3 or not all(name in m.metrics for m in fine):
            out["metrics"][name] = {"error": "not in the runs of the three finest levels"}
            continue
        h = [ratio ** -m.index for m in fine]
        phi = [float(m.metrics[name]) for m in fine]
        out["metrics"][name] = {"values": phi, "h_rel": h, **grid_convergence(h, phi).to_dict()}
    return out


def report_markdown(report: dict, case: str) -> str:
    """``report.md``: one row per metric."""
    keys = {k for lv in report["levels"] for k in lv["overrides"]}
    what = "element sizes" if report["refine"] == "mesh" else \
        "EM step (geometry.em_step)" if "geometry.em_step" in keys else \
        "EM step (the period over coupling.steps_per_period)" if "coupling.steps_per_period" in keys else \
        "EM step (coupling.n)"
    lines = [f"# Convergence study of {case}", "",
             f"{len(report['levels'])} levels, {what} divided by {report['ratio']:g} per level; the GCI of the "
             "three finest (Celik et al., J. Fluids Eng. 130 (2008) 078001; safety factor 1.25).", "",
             "| metric | fine | medium | coarse | observed order | extrapolated | GCI fine | convergence |",
             "|---|---|---|---|---|---|---|---|"]
    for name, r in report["metrics"].items():
        if "error" in r:
            lines.append(f"| {name} | - | - | - | - | - | - | {r['error']} |")
            continue
        v = r["values"]
        lines.append(f"| {name} | {v[0]:.6g} | {v[1]:.6g} | {v[2]:.6g} | {r['order']:.3g} | {r['extrapolated']:.6g} "
                     f"| {100 * r['gci_fine']:.3g} % | {r['convergence']} |")
    failed = [lv for lv in report["levels"] if lv["returncode"] != 0]
    for lv in failed:
        lines.append(f"\nlevel {lv['level']} failed: {lv['error']}")
    return "\n".join(lines) + "\n"


def plot_study(report: dict, folder: Path) -> list[Path]:
    """``converge_<metric>.png``: values vs relative size h, the extrapolated value at h = 0 and the
    finest level's GCI band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    for name, r in report["metrics"].items():
        if "error" in r:
            continue
        fig, ax = plt.subplots(figsize=(6.5, 4))
        ax.plot(r["h_rel"], r["values"], "o-", label="runs (three finest)")
        if math.isfinite(r["extrapolated"]):
            ax.plot([0.0], [r["extrapolated"]], "*", ms=12, label=f"extrapolated, p = {r['order']:.2f}")
            band = r["gci_fine"] * abs(r["values"][0])
            ax.errorbar([r["h_rel"][0]], [r["values"][0]], yerr=[band], fmt="none", capsize=5,
                        label=f"GCI fine {100 * r['gci_fine']:.2g} %")
        ax.set_xlim(left=0.0)
        ax.set_xlabel("relative size h (finest refined level: smallest)")
        ax.set_ylabel(label(name))
        ax.set_title(f"{name}: {r['convergence']} convergence")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        path = folder / f"converge_{name}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths
