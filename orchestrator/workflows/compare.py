"""``pulseform compare``: a coupled case against its pressure-pulse approximation, side by side.

1. ``OUT/coupled/``: ``pulseform run CASE`` with the GetDP load.
2. The pulse: the coupled run's force on the workpiece over the loaded area A is a pressure history
   p(t) = F_z(t) / A (F_r for a tube); eq. (7) P0 e^(−βt) sin²(ωt) (or eq. (8) p0 e^(−t/T)) is
   fitted to it by least squares — with I(t) ∝ e^(−αt) sin(ω_d t) the Lorentz force is ∝ I², i.e.
   exactly eq. (7) with β = 2α, ω = ω_d — unless ``pressure_case`` gives the ``[[loads]]``.
   The loaded surface is the workpiece face towards the coil, over the coil's extent.
3. ``OUT/pressure/``: the same case with ``coupling.load = "pressure"`` and those loads, i.e. the
   same workpiece mesh and the same loop.
4. ``OUT/compare.json``: the pulse and the differences (max distance between the final workpiece
   shapes, max speeds, die stresses if there is a die, impulses, wall times); ``OUT/plots/``:
   pressure history with the fitted pulse, final shapes, deflection and speed histories.

A 3D model (``mechanics.formulation = "3d"``, a geometry file): the loaded surface is given (``surface``, a box
with 3D bounds, and ``body``: ``--surface`` / ``--body``); the force along its area vector over the area the
pressure run loads on the coupled run's mesh, the device's figures × the symmetry factor (:mod:`.compare3d`),
the 3D final positions, the loaded surface's profile.
"""

from __future__ import annotations

import json
import logging
import math
import operator
import re
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..case.io import CaseError, load_case, read_toml, resolve_case_file
from ..case.model import Case, FlatCoilSheet, PlanarCoilBlankDie, SolenoidTube
from ..mech.pulses import exp_pulse, sin2_pulse
from ..run.results import ResultsFolder, read_metrics
from ..run.warm import failure_report, member_run_argv, run_member_process, warm_pool
from .compare3d import loading_3d, nominal_area, plot_profile
from .compare_area import mesh_area
from .validate import write_json

log = logging.getLogger(__name__)
_COND = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(>=|<=|>|<)\s*([-+0-9.eE]+)\s*$")
_OPS = {">": operator.gt, "<": operator.lt, ">=": operator.ge, "<=": operator.le}
FORCE_COLUMNS = ("force_x_N", "force_y_N", "force_z_N")  # by the force component of the loaded surface


class CompareError(ValueError):
    """Bad input to compare (``run_failed`` False) or a run that failed (``run_failed`` True)."""

    def __init__(self, message: str, run_failed: bool = False) -> None:
        super().__init__(message)
        self.run_failed = run_failed


@dataclass(frozen=True)
class Condition:
    """A ``--fail-if`` condition ``metric OP value``."""

    text: str
    metric: str
    op: str
    value: float

    def holds(self, metrics: dict[str, float]) -> bool:
        v = metrics.get(self.metric)
        return v is not None and bool(_OPS[self.op](v, self.value))


def parse_conditions(texts: list[str]) -> list[Condition]:
    """``'metric>tol'`` strings -> conditions (one-line error naming the bad one)."""
    out = []
    for t in texts:
        m = _COND.match(t)
        if not m:
            raise CompareError(f"--fail-if {t!r}: expected METRIC>VALUE or METRIC<VALUE (also >=, <=), "
                               "e.g. shape_distance_max_mm>0.05")
        out.append(Condition(t, m.group(1), m.group(2), float(m.group(3))))
    return out


# --------------------------------------------------------------------------- loaded surface
def loaded_surface(case: Case) -> tuple[dict[str, float], float, int, float]:
    """(Box of the workpiece face towards the coil over the coil's extent, its area (m²), force
    component that pushes on it: 1 = z for a sheet, 0 = r for a tube, 1 = y for a planar blank,
    and the sign that makes that force component a positive pressure)."""
    g = case.geometry
    eps = 1e-6 * max(getattr(g, "air_radius", 1.0), 1e-3)
    if isinstance(g, FlatCoilSheet):
        r1 = g.coil_inner_radius
        r2 = min(g.coil_inner_radius + g.turns * g.turn_width + (g.turns - 1) * g.turn_gap, g.sheet_radius)
        z = g.coil_gap
        return {"xmin": r1, "xmax": r2, "ymin": z - eps, "ymax": z + eps}, math.pi * (r2 ** 2 - r1 ** 2), 1, 1.0
    if isinstance(g, SolenoidTube):
        half = 0.5 * min(g.turns * (g.turn_height + g.turn_gap) - g.turn_gap, g.tube_length)
        r = g.tube_inner_radius
        return {"xmin": r - eps, "xmax": r + eps, "ymin": -half, "ymax": half}, 2 * math.pi * r * 2 * half, 0, 1.0
    if isinstance(g, PlanarCoilBlankDie):  # the blank's upper face under the coil, pushed down (−y)
        x1 = g.coil_inner_x
        x2 = min(g.coil_inner_x + g.turns * g.turn_width + (g.turns - 1) * g.turn_gap, g.blank_half_width)
        y = g.blank_thickness
        return {"xmin": x1, "xmax": x2, "ymin": y - eps, "ymax": y + eps}, (x2 - x1) * case.mechanics.thickness, 1, -1.0
    raise CompareError(f"compare: geometry type {getattr(g, 'type', None)!r} has no known loaded surface")


# --------------------------------------------------------------------------- fits
def fit_pulse(t: np.ndarray, p: np.ndarray, kind: str = "sin2") -> dict[str, float]:
    """Least-squares eq. (7) (``sin2``: P0, β, ω) or eq. (8) (``exp``: p0, T) fit of p(t) (Pa).

    Returns the parameters and the fit's relative RMS residual (of max |p|)."""
    from scipy.optimize import curve_fit

    t, p = np.asarray(t, float), np.asarray(p, float)
    i_pk = int(np.argmax(p))
    t_pk, p_pk = max(float(t[i_pk]), 1e-12), float(p[i_pk])
    if p_pk <= 0:
        raise CompareError("compare: the coupled run's pressure on the workpiece is never positive", run_failed=True)
    if kind == "sin2":
        peaked = i_pk < len(t) - 1  # a maximum inside the run: ω from the first peak
        omega0 = math.pi / (2 * t_pk) if peaked else math.pi / (4 * t[-1])
        guess = [p_pk / max(math.sin(omega0 * t_pk) ** 2, 1e-3), 1e4, omega0]
        try:
            par, _ = curve_fit(sin2_pulse, t, p, p0=guess, bounds=([0, 0, 1e2], [np.inf, 1e8, 1e9]), maxfev=20000)
        except (RuntimeError, ValueError) as exc:
            log.warning("eq. (7) fit did not converge (%s); using the first-peak estimate", exc)
            par = np.array(guess)
        res = p - sin2_pulse(t, *par)
        out = {"amplitude": float(par[0]), "beta": float(par[1]), "omega": float(par[2])}
    else:
        guess = [p_pk, max(t[-1] - t_pk, t[-1]) / 2]
        try:
            par, _ = curve_fit(exp_pulse, t, p, p0=guess, bounds=([0, 1e-9], [np.inf, 1.0]), maxfev=20000)
        except (RuntimeError, ValueError) as exc:
            log.warning("eq. (8) fit did not converge (%s); using the peak estimate", exc)
            par = np.array(guess)
        res = p - exp_pulse(t, *par)
        out = {"amplitude": float(par[0]), "decay_time": float(par[1])}
    out["fit_residual_rel"] = float(np.sqrt(np.mean(res ** 2)) / np.max(np.abs(p)))
    return out


def circuit_shape(t: np.ndarray, vc: np.ndarray, current: np.ndarray) -> tuple[float, float]:
    """(α, ω_d) of the bank's discharge from the coupled run's (capacitor voltage, current) samples.

    A series RLC circuit is a linear 2-state system: consecutive samples obey x_{k+1} = A x_k for a
    fixed step; A is fitted by least squares and its eigenvalues exp((−α ± iω_d) dt) give α and ω_d.
    This works on any window, also one that ends before the current's first peak."""
    x = np.vstack([vc, current])
    steps = np.diff(t)
    dt = float(np.median(steps)) if len(steps) else 0.0
    pairs = np.flatnonzero(np.abs(steps - dt) <= 1e-3 * dt)  # steps of the common length only
    if len(pairs) < 2:  # (output milestones shorten the step that reaches them)
        raise CompareError("compare: fewer than 2 equal EM steps; cannot identify the discharge")
    scale = np.abs(x).max(axis=1, keepdims=True)
    xs = x / np.where(scale > 0, scale, 1.0)
    a, *_ = np.linalg.lstsq(xs[:, pairs].T, xs[:, pairs + 1].T, rcond=None)
    mu = np.linalg.eigvals(a.T).astype(complex)
    lam = np.log(mu[np.argmax(np.abs(mu.imag))]) / dt
    return float(-lam.real), float(abs(lam.imag))


def fit_pulse_shaped(t: np.ndarray, p: np.ndarray, beta: float, omega: float) -> dict[str, float]:
    """Eq. (7) with β and ω given (from the current: F ∝ I² ⇒ β = 2α, ω = ω_d); P0 by linear least squares."""
    basis = sin2_pulse(t, 1.0, beta, omega)
    p0 = float(basis @ p / (basis @ basis))
    res = p - p0 * basis
    return {"amplitude": p0, "beta": beta, "omega": omega,
            "fit_residual_rel": float(np.sqrt(np.mean(res ** 2)) / np.max(np.abs(p)))}


def _inline(v) -> str:
    """A TOML inline literal (numbers, strings, booleans, tables, arrays)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        if isinstance(v, float) and math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_inline(x)}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_inline(x) for x in v) + "]"
    raise TypeError(type(v))


# --------------------------------------------------------------------------- runs
def _run(case: str, out: Path, sets: list[str]) -> dict[str, float]:
    """``pulseform run`` of one side (a study's member: :func:`..run.warm.member_run_argv`, no pictures of its
    own unless ``sets`` say so); its metrics and its wall time as this process saw it."""
    t0 = time.perf_counter()
    r = run_member_process(member_run_argv(case, out, sets))
    if r.returncode != 0:
        error, tail = failure_report(r, out)
        log.warning("compare: run %s failed: %s%s", out.name, error, "".join(f"\n  {ln}" for ln in tail.splitlines()))
        raise CompareError(f"compare: run {out.name} failed (exit {r.returncode}): {error}",
                           run_failed=r.returncode == 1)
    m = read_metrics(out / "metrics.json")
    m["process_wall_s"] = time.perf_counter() - t0
    return m


def _history(folder: Path) -> np.ndarray:
    return np.genfromtxt(folder / "history.csv", delimiter=",", names=True)


def final_shape(folder: Path, case_name: str, body: str) -> tuple[np.ndarray, np.ndarray, dict[float, np.ndarray]]:
    """(reference coordinates (N, 2), final displacement (N, 2); (N, 3) of a 3D body, {time: von Mises per cell}) of ``body``
    (m, m, Pa) from the run's field files; ``case_name`` is kept for the callers (the files name it)."""
    from ..run.mech_fields import FieldFileError, read_fields

    try:
        bodies = read_fields(folder)
    except FieldFileError as exc:
        raise CompareError(f"compare: {exc}", run_failed=True) from None
    if body not in bodies:
        raise CompareError(f"compare: no field file for body {body!r} in {folder / 'fields'}", run_failed=True)
    bf = bodies[body]
    vm = {float(t): bf.read(k, ("von_mises_Pa",))["von_mises_Pa"] for k, t in enumerate(bf.times)}
    if bf.solid:  # a 3D body: (N, 3)
        return bf.points, bf.read(len(bf.times) - 1, ("displacement_m",))["displacement_m"], vm
    return bf.points[:, :2], bf.displacement(len(bf.times) - 1), vm


def shape_distance(xa, ua, xb, ub) -> float:
    """Max distance (m) between the final positions of the same material points of two runs; nodes
    are matched by reference coordinates (same mesh), otherwise each deformed node is measured to
    the nearest deformed node of the other run (symmetric Hausdorff distance)."""
    from scipy.spatial import cKDTree

    scale = float(np.abs(xa).max())
    d, idx = cKDTree(xb).query(xa)
    if len(xa) == len(xb) and d.max() <= 1e-9 * scale:
        return float(np.linalg.norm((xa + ua) - (xb[idx] + ub[idx]), axis=1).max())
    ya, yb = xa + ua, xb + ub
    return float(max(cKDTree(yb).query(ya)[0].max(), cKDTree(ya).query(yb)[0].max()))


def _loaded_body(case: Case, case_path: str, body: str | None):
    """The loaded body: ``body`` (``--body``), else the workpiece of a built-in geometry, else the only
    deformable body of a 3D model."""
    names = [b.name for b in case.bodies]
    if body is not None:
        if body not in names:
            raise CompareError(f"{case_path}: --body {body!r}: not a body of the case; its bodies: "
                               + ", ".join(repr(n) for n in names))
        return case.body(body)
    work = [b for b in case.bodies if b.region == "workpiece"]
    if work:
        return work[0]
    if len(case.bodies) == 1:
        return case.bodies[0]
    raise CompareError(f"{case_path}: give the loaded body with --body (the case's bodies: "
                       + ", ".join(repr(n) for n in names) + ")")


def run_compare(case_path: str, out: Path, *, overrides: list[str] | None = None, pulse: str = "sin2",
                pressure_case: str | None = None, force: bool = False, surface: dict | None = None,
                body: str | None = None) -> dict:
    """Run both and write ``compare.json`` + plots; returns the report dict (see module docstring).
    ``surface`` the loaded surface of a 3D model (a box with 3D bounds, m: ``--surface``), ``body`` the loaded
    body (``--body``)."""
    overrides = list(overrides or [])
    case, _ = load_case(case_path, overrides)
    if case.case.kind != "coupled" or case.coupling.load != "getdp":
        raise CompareError(f"{case_path}: compare needs a coupled case with coupling.load = 'getdp' "
                           f"(got kind {case.case.kind!r}, load {case.coupling.load!r})")
    rigid = [b.name for b in case.bodies if b.rigid]
    if rigid:  # the pressure pulses act on deformable bodies (a rigid body's motion is the force's alone)
        raise CompareError(f"{case_path}: compare loads deformable bodies with pressure pulses; {rigid[0]!r} is "
                           "rigid (its motion follows from the force history in history.csv)")
    three_d = case.mechanics.formulation == "3d"  # a 3D model: the force along the given surface's area vector
    if surface is not None and not three_d:
        raise CompareError(f"{case_path}: --surface is for 3D models (mechanics.formulation = '3d'); a 2D built-in "
                           "geometry knows its loaded surface, a user deck takes --pressure-case FILE")
    work = _loaded_body(case, case_path, body)
    dies = [b.name for b in case.bodies if b.name != work.name]  # own shapes, or the EM die/collar
    given = _given_loads(pressure_case) if pressure_case else None
    direction = None   # the unit area vector of a 3D model's loaded surface
    if three_d:
        if surface is None and given is None:
            raise CompareError(f"{case_path}: a 3D model has no known loaded surface to fit a pulse on: give it with "
                               "--surface '{rmin = ..., rmax = ..., zmin = ..., zmax = ...}' (a box, m; and --body) "
                               "or the pulses with --pressure-case FILE")
        box, area, comp, sign = surface, 1.0, 2, 1.0
    else:
        try:
            box, area, comp, sign = loaded_surface(case)
        except CompareError:
            if given is None:
                raise CompareError(f"{case_path}: geometry type {case.geometry.type!r} has no known loaded surface "
                                   "to fit a pulse on; give the pulses with --pressure-case FILE") from None
            box, area, comp, sign = None, 1.0, 1, 1.0  # given pulses: histories shown as force (N) along z
    results = ResultsFolder(out, force=force)
    root = results.root

    with warm_pool(root):  # both runs forked from one warm process: the second pays no imports
        log.info("compare: coupled run")
        mc = _run(str(case_path), root / "coupled", overrides)
        hc = _history(root / "coupled")
        t = hc["time_s"]
        sym = float(mc.get("symmetry_factor", 1.0)) if three_d else 1.0
        if three_d and box is not None:  # the area the pressure run loads on the coupled run's mesh (compare3d.py)
            area, s_vec = loading_3d(root / "coupled", work.name, box)
            effective = float(np.linalg.norm(s_vec))
            direction = s_vec / effective
            comp = int(np.argmax(np.abs(direction)))
            log.info("compare: loaded area %.6g cm^2 of the model (x %g: the device's %.6g cm^2), direction %s",
                     area * 1e4, sym, area * sym * 1e4, np.array2string(direction, precision=4))
        nominal = area
        if not three_d and box is not None:  # the area the pressure run loads on this mesh (compare_area.py)
            area = mesh_area(case, root / "coupled", work.name, box, area)
        if direction is not None:   # p = F.S / |S|^2: the pressure that pushes the model's force along S
            force_col = sum(direction[c] * hc[FORCE_COLUMNS[c]] for c in range(3)) * (area / effective)
        else:
            force_col = hc[FORCE_COLUMNS[comp]]
        p_hist = sign * force_col / area
        if given is None:
            # each history row holds the force held over the EM step that ends there (the mean of GetDP's
            # sub-steps): it belongs at the step's mid-time; the first row is t = 0 before any step
            t_mid = 0.5 * (t[1:] + t[:-1])
            par = _fit(case, hc, t, t_mid, p_hist[1:], pulse)
            load = {"type": "pulse_sin2" if pulse == "sin2" else "pulse_exp", "body": work.name, "surface": box,
                    "amplitude": par["amplitude"], "t_end": case.time.end}
            if pulse == "sin2":
                load.update(beta=par["beta"], omega=par["omega"])
                desc = (f"eq. (7) fitted: P0 = {par['amplitude'] / 1e6:.4g} MPa, beta = {par['beta']:.4g} 1/s, "
                        f"omega = {par['omega']:.4g} rad/s on {area * 1e4:.4g} cm^2 (fit residual "
                        f"{100 * par['fit_residual_rel']:.2g} % of the peak; {par['fit_method']})")
            else:
                load.update(decay_time=par["decay_time"])
                desc = (f"eq. (8) fitted: p0 = {par['amplitude'] / 1e6:.4g} MPa, T = {par['decay_time']:.4g} s on "
                        f"{area * 1e4:.4g} cm^2 (fit residual {100 * par['fit_residual_rel']:.2g} % of the peak)")
            loads = [load]
            pulse_info = {"source": "fitted to the coupled run", "kind": pulse, **par, "area_m2": area * sym,
                          "surface": box, "description": desc}
            if not three_d and box is not None:
                pulse_info["nominal_area_m2"] = nominal
            if three_d:  # the device's area: the model's loaded triangles x the symmetry factor (compare3d.py)
                pulse_info.update(model_area_m2=area, effective_area_m2=effective, direction=direction.tolist(),
                                  symmetry_factor=sym, body=work.name)
                annulus = nominal_area(box, direction)
                if annulus is not None:
                    pulse_info["nominal_area_m2"] = annulus
                pulse_info["description"] = desc.replace(
                    f"on {area * 1e4:.4g} cm^2", f"on {area * sym * 1e4:.4g} cm^2 (the model's loaded triangles x {sym:.6g}"
                    + (f"; nominal {annulus * 1e4:.4g} cm^2)" if annulus is not None else ")"))
        else:
            loads = given
            pulse_info = {"source": f"given: {pressure_case}", "loads": given, "area_m2": area,
                          "description": f"[[loads]] of {pressure_case}"}
        sets = overrides + ["coupling.load=pressure", f"loads={_inline(loads)}"]
        try:
            load_case(case_path, sets)
        except CaseError as exc:
            raise CompareError(f"compare: the pressure case is invalid: {exc}") from None
        log.info("compare: pressure run")
        mp = _run(str(case_path), root / "pressure", sets)
        hp = _history(root / "pressure")

        xc, uc, vmc = final_shape(root / "coupled", case.case.name, work.name)
        xp, up, vmp = final_shape(root / "pressure", case.case.name, work.name)
        metrics = {
            "shape_distance_max_mm": 1e3 * shape_distance(xc, uc, xp, up),
            "max_speed_coupled_m_s": mc[f"{work.name}_max_speed_m_s"],
            "max_speed_pressure_m_s": mp[f"{work.name}_max_speed_m_s"],
            "impulse_coupled_Ns": mc["force_impulse_Ns"],
            "impulse_pressure_Ns": mp["force_impulse_Ns"],
            "wall_time_coupled_s": mc["process_wall_s"],
            "wall_time_pressure_s": mp["process_wall_s"],
        }
        metrics["max_speed_rel_diff"] = abs(metrics["max_speed_pressure_m_s"] / metrics["max_speed_coupled_m_s"] - 1)
        metrics["impulse_rel_diff"] = abs(metrics["impulse_pressure_Ns"] / metrics["impulse_coupled_Ns"] - 1)
        metrics["wall_time_ratio"] = metrics["wall_time_coupled_s"] / metrics["wall_time_pressure_s"]
        for key in ("max_deflection_mm", "max_radial_displacement_mm") + tuple(f"{work.name}_max_u{c}_mm" for c in "xyz"):
            if key in mc and key in mp:
                metrics[f"{key}_coupled"], metrics[f"{key}_pressure"] = mc[key], mp[key]
                metrics[f"{key}_rel_diff"] = abs(mp[key] / mc[key] - 1) if mc[key] else float("nan")
        for die in dies:
            vc = max(float(v.max()) for v in final_shape(root / "coupled", case.case.name, die)[2].values())
            vp = max(float(v.max()) for v in final_shape(root / "pressure", case.case.name, die)[2].values())
            metrics[f"die_von_mises_max_coupled_MPa"] = max(metrics.get("die_von_mises_max_coupled_MPa", 0), vc / 1e6)
            metrics[f"die_von_mises_max_pressure_MPa"] = max(metrics.get("die_von_mises_max_pressure_MPa", 0), vp / 1e6)
        if dies:
            metrics["die_von_mises_rel_diff"] = abs(metrics["die_von_mises_max_pressure_MPa"]
                                                    / metrics["die_von_mises_max_coupled_MPa"] - 1)
        report = {"case": str(case_path), "overrides": overrides, "workpiece": work.name, "dies": dies,
                  "pulse": pulse_info, "metrics": metrics,
                  "runs": {"coupled": str(root / "coupled"), "pressure": str(root / "pressure")},
                  "coupled_metrics": mc, "pressure_metrics": mp}
        write_json(root / "compare.json", report)
        try:
            _plots(root, hc, hp, comp, sign * area, loads, (xc, uc), (xp, up), work.name, box, direction)
        except Exception as exc:  # plots never decide the result
            log.warning("compare plots failed: %s", exc)
        return report


def _fit(case: Case, hc, t, t_mid, p, pulse: str) -> dict[str, float]:
    """The pulse parameters. eq. (8): free least-squares fit. eq. (7): β and ω from the current
    (F ∝ I²: β = 2α, ω = ω_d; α, ω_d of the prescribed current, or identified from the circuit's
    history), P0 by least squares; when the window holds the force's first peak, a free
    3-parameter fit started there is kept if it fits better with ω within a factor 2."""
    if pulse != "sin2":
        return {**fit_pulse(t_mid, p, pulse), "fit_method": "eq. (8) least squares (p0, T)"}
    em = case.em
    if em.current is not None:
        alpha, omega_d, how = em.current.beta, em.current.omega, "the prescribed current"
    else:
        alpha, omega_d = circuit_shape(t[1:], hc["capacitor_voltage_V"][1:], hc["coil_current_A"][1:])
        how = "the circuit's (V_C, I) history"
    par = fit_pulse_shaped(t_mid, p, 2 * alpha, omega_d)
    par["fit_method"] = f"beta = 2 alpha, omega = omega_d from {how}; P0 by least squares"
    if 0 < int(np.argmax(p)) < len(p) - 1:  # the first force peak lies inside the window
        try:
            free = fit_pulse(t_mid, p, "sin2")
        except CompareError:
            free = None
        if free and free["fit_residual_rel"] < par["fit_residual_rel"] and 0.5 < free["omega"] / omega_d < 2:
            par = {**free, "fit_method": "free least squares (P0, beta, omega) started from the current's shape"}
    par["current_alpha"], par["current_omega_d"] = alpha, omega_d
    return par


def _given_loads(path: str) -> list[dict]:
    file = resolve_case_file(path)
    data = read_toml(file)
    loads = data.get("loads")
    if not isinstance(loads, list) or not loads:
        raise CompareError(f"{file}: loads: --pressure-case needs at least one [[loads]] table")
    return loads


def _plots(root: Path, hc, hp, comp: int, area: float, loads: list[dict], shape_c, shape_p, body: str,
           box: dict | None = None, direction: np.ndarray | None = None) -> None:
    """``compare_pressure.png`` (F / A of both runs: F along ``direction``, a 3D model's unit area vector, else
    component ``comp``), ``compare_shapes.png`` (a 3D model: the profile of the loaded surface ``box``) and
    ``compare_histories.png`` in ``root / "plots"``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt


    plots = root / "plots"
    def along(h):
        if direction is None:
            return h[FORCE_COLUMNS[comp]]
        return sum(direction[c] * h[FORCE_COLUMNS[c]] for c in range(3))

    fig, ax = plt.subplots(figsize=(6, 3.4))
    ax.plot(hc["time_s"] * 1e6, along(hc) / area / 1e6, "o-", ms=3, label="coupled: F / A")
    ax.plot(hp["time_s"] * 1e6, along(hp) / area / 1e6, "--", label="pressure run: F / A")
    ax.set(xlabel="time (µs)", ylabel="pressure on the workpiece (MPa)", title="coupled vs pressure pulse")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(plots / "compare_pressure.png", dpi=100)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 3.4))
    if direction is not None:  # a 3D model: the profile of its loaded surface
        plot_profile(ax, shape_c, shape_p, box, direction)
        ax.set(title=f"final shape of {body} (the loaded surface)")
    else:
        for (x, u), lab, st in ((shape_c, "coupled", "."), (shape_p, "pressure", "x")):
            y = x + u
            ax.plot(y[:, 0] * 1e3, y[:, 1] * 1e3, st, ms=2, label=lab)
        ax.set(xlabel="r (mm)", ylabel="z (mm)", title=f"final shape of {body}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(plots / "compare_shapes.png", dpi=100)
    plt.close(fig)

    fig, axes = plt.subplots(2, 1, figsize=(6, 5), sharex=True)
    key = f"{body}_max_u{'xyz'[comp]}_m"
    for h, lab, st in ((hc, "coupled", "-"), (hp, "pressure", "--")):
        axes[0].plot(h["time_s"] * 1e6, h[key] * 1e3, st, label=lab)
        axes[1].plot(h["time_s"] * 1e6, h[f"{body}_max_speed_m_s"], st, label=lab)
    axes[0].set_ylabel("max displacement (mm)")
    axes[1].set(xlabel="time (µs)", ylabel="max speed (m/s)")
    for a in axes:
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(plots / "compare_histories.png", dpi=100)
    plt.close(fig)
