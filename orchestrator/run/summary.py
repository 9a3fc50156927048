"""The headline figures of a finished run, as labelled values (the CLI prints them before the metrics).

Only the lines that apply to the case: the bank energy ½ C V0² of a capacitor circuit, the peak coil
current (coupled), the force impulse (loaded cases; in axisymmetry the axial one, and the radial load's
impulse where it is the larger: a tube), the largest deflection (or displacement) and
speed of the workpiece (or of any body), the peak von Mises stress of a die (or collar), and where
the energy went: the peak kinetic energy and the plastic work in % of the bank energy, of the
external work of the loads (pressure pulses, a prescribed coil current), or, for an impact without
loads, of the initial kinetic energy; under loads that take back what they put in (an AC coil
current), the peak kinetic energy in J and how far the loads' work swung; for a body whose material has a
forming limit curve, its least margin below the curve and the worst element (zone, time, place, strains).
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..mech.forming_limit import ZONES
from .history import History
from .units import time_axis

#: body regions (and, for mechanics cases, body names) whose peak stress is a die's
DIE_REGIONS = ("die", "outer_tube")


@dataclass(frozen=True)
class Headline:
    """One line of the summary: ``label``, ``value`` in ``unit``, and an optional ``note``."""

    label: str
    value: float
    unit: str
    note: str = ""

    def text(self, width: int = 28) -> str:
        """``label  value unit  note`` on one line."""
        note = f"  {self.note}" if self.note else ""
        value = f"{self.value:.3g}" if self.unit == "%" else f"{self.value:.4g}"
        return f"{self.label:<{width}}{value} {self.unit}{note}"


def energy_text(joules: float) -> str:
    """``"900 J"``, ``"1.12 MJ"``: an energy with 3 significant digits and a fitting prefix."""
    for factor, unit in ((1e9, "GJ"), (1e6, "MJ"), (1e3, "kJ")):
        if abs(joules) >= factor:
            return f"{joules / factor:.3g} {unit}"
    return f"{joules:.3g} J"


def headline(case, metrics: dict[str, float], history) -> list[Headline]:
    """The summary of a run of ``case`` from its metrics and :class:`~.history.History`."""
    cols = set(history.columns) if history is not None and history.rows else set()
    col = history.column if cols else None
    axis = time_axis(case.time.end)

    def at(column: str) -> str:
        """``at <time of the column's largest |value|>``."""
        if column not in cols:
            return ""
        t = col("time_s")[int(np.argmax(np.abs(col(column))))]
        return f"at {t * axis.scale:.4g} {axis.unit}"

    out: list[Headline] = []
    circuit = case.em.circuit if case.case.kind == "coupled" and case.em is not None else None
    bank = None
    if circuit is not None and case.coupling.load != "pressure":
        bank = 0.5 * circuit.capacitance * circuit.voltage ** 2
        out.append(Headline("bank energy", bank, "J",
                            f"½ C V0², {circuit.capacitance * 1e6:.4g} µF at {circuit.voltage / 1e3:.4g} kV"))
    if "coil_current_peak_kA" in metrics:
        peak = metrics["coil_current_peak_kA"]  # an AC coil of a few amperes in A, a pulse in kA
        out.append(Headline("peak coil current", *((peak, "kA") if peak >= 1.0 else (peak * 1e3, "A")),
                            at("coil_current_A")))
    if "force_impulse_Ns" in metrics:
        out.append(Headline("force impulse", metrics["force_impulse_Ns"], "N·s"))
    radial = metrics.get("radial_load_impulse_Ns")  # axisymmetric: the ring's radial load, shown when it dominates
    if radial is not None and abs(radial) > metrics.get("force_impulse_Ns", 0.0):
        out.append(Headline("radial load impulse", radial, "N·s",
                            f"summed round the ring, {'outward' if radial > 0 else 'inward'} (not a net force)"))

    workpiece = [b.name for b in case.bodies if b.region == "workpiece"]
    movers = workpiece or [b.name for b in case.bodies]
    if "max_deflection_mm" in metrics:
        out.append(Headline("max deflection", metrics["max_deflection_mm"], "mm", _whose(workpiece)))
    elif "max_radial_displacement_mm" in metrics:
        out.append(Headline("max radial displacement", metrics["max_radial_displacement_mm"], "mm", _whose(workpiece)))
    else:
        disp = {n: float(np.nanmax([metrics.get(f"{n}_max_u{c}_mm", np.nan) for c in "xyz"]))  # 3D: z too
                for n in movers if f"{n}_max_ux_mm" in metrics}
        if disp:
            name = max(disp, key=disp.get)
            out.append(Headline("max displacement", disp[name], "mm", f"({name})"))
    for b in case.bodies:  # a rigid body: its largest translation along each free component, and when
        for c in "xy":
            if f"{b.name}_max_travel_{c}_mm" in metrics:
                t = metrics[f"{b.name}_max_travel_{c}_time_s"] * axis.scale
                out.append(Headline(f"max travel in {'rz'[c == 'y'] if case.mechanics.formulation == 'axisymmetric' else c}",
                                    metrics[f"{b.name}_max_travel_{c}_mm"], "mm",
                                    f"at {t:.4g} {axis.unit} ({b.name}, rigid)"))
    speeds = {n: metrics[f"{n}_max_speed_m_s"] for n in movers if f"{n}_max_speed_m_s" in metrics}
    if speeds:
        name = max(speeds, key=speeds.get)
        when = at(f"{name}_max_speed_m_s")
        out.append(Headline("max speed", speeds[name], "m/s", f"{when} ({name})".strip()))

    for b in case.bodies:
        is_die = b.region in DIE_REGIONS or (b.region is None and b.name == "die")
        key = f"{b.name}_max_von_mises_MPa"
        if is_die and key in metrics:
            out.append(Headline(f"peak von Mises, {b.name}", metrics[key], "MPa", at(f"{b.name}_max_von_mises_Pa")))

    out.extend(_flc_lines(case, metrics, axis))
    out.extend(_energy_lines(bank, metrics, history, cols, axis))
    out.extend(_shot_lines(case, metrics))
    return out


def _shot_lines(case, metrics: dict[str, float]) -> list[Headline]:
    """Repeated shots (em.shots): per shot its peak coil current, with the coil's temperature at its end and each
    heated body's largest cell temperature then (shots.csv has the rest)."""
    out = []
    for n in range(1, int(metrics.get("shots", 0)) + 1):
        if f"shot{n}_peak_current_kA" not in metrics:
            continue
        note = [f"coil {metrics[f'shot{n}_coil_temperature_K']:.1f} K at its end"]
        note += [f"{b.name} max {metrics[k]:.1f} K" for b in case.bodies
                 if (k := f"shot{n}_{b.name}_temperature_max_K") in metrics]
        out.append(Headline(f"shot {n}, peak coil current", metrics[f"shot{n}_peak_current_kA"], "kA",
                            "; ".join(note)))
    return out


def _flc_lines(case, metrics: dict[str, float], axis) -> list[Headline]:
    """Per body with a forming limit curve: its least margin below the curve over the run (-) and where: the
    zone, time, cell (its index in the field file), deformed centroid (mm) and strains (ε2, ε1)."""
    out = []
    names = ("r", "z") if case.mechanics.formulation == "axisymmetric" else \
        ("x", "y", "z") if case.mechanics.formulation == "3d" else ("x", "y")
    for b in case.bodies:
        key = f"{b.name}_flc_"
        if f"{key}margin_min" not in metrics:
            continue
        at = ", ".join(f"{metrics[f'{key}worst_{c}_m'] * 1e3:.4g}" for c in ("x", "y", "z")[:len(names)])
        note = (f"{ZONES[int(metrics[f'{key}worst_zone'])]}: element {int(metrics[f'{key}worst_element'])} at "
                f"t = {metrics[f'{key}worst_time_s'] * axis.scale:.4g} {axis.unit}, ({', '.join(names)}) = ({at}) mm, "
                f"(ε2, ε1) = ({metrics[f'{key}worst_minor_strain']:.3g}, {metrics[f'{key}worst_major_strain']:.3g})")
        out.append(Headline(f"least FLC margin, {b.name}", metrics[f"{key}margin_min"], "-", note))
    return out


def summary_lines(case, metrics: dict[str, float], folder: Path, source: str = "CASE") -> list[str]:
    """The lines printed after a run: ``summary:`` and the :func:`headline` lines indented under it (none when
    no headline applies), from ``metrics`` and ``folder``'s history.csv (left out when it cannot be read), then
    the :func:`coarse_step_note` of the case (``source``: the case as the user named it, for the command)."""
    try:
        history = History.read(Path(folder) / "history.csv")
    except (OSError, ValueError):
        history = None
    lines = [h.text() for h in headline(case, metrics, history)]
    note = coarse_step_note(case, source)
    return (["summary:"] + ["  " + ln for ln in lines] if lines else []) + ([note] if note else [])


def coarse_step_note(case, source: str = "CASE") -> str | None:
    """The suggestion to check the time step of a run whose bodies are all rigid when it made fewer EM steps per
    period of its source than the default ``coupling.steps_per_period`` (:data:`~..case.model.STEPS_PER_PERIOD`,
    chosen by the jumping ring's first peak: +1.4 % at 40 steps, +0.57 % at 80, against 320); None otherwise."""
    from ..case.model import STEPS_PER_PERIOD
    from ..em.time_scale import steps_per_period

    steps = steps_per_period(case)
    if steps is None or steps >= STEPS_PER_PERIOD * (1.0 - 1e-9):
        return None
    return (f"note: {steps:.3g} EM steps per period of the source resolve the motion coarsely (the default is "
            f"{STEPS_PER_PERIOD}; at 40 the jumping ring's first peak is 1.4 % high): check the time step with "
            f"`pulseform converge {shlex.quote(source)} --refine em_step`")


def _whose(names: list[str]) -> str:
    return f"({names[0]})" if len(names) == 1 else ""


#: the external work falls this far (fraction of its largest value) below an earlier value: the loads take
#: energy back (an AC force), so its value is no measure of the energy put in
GIVEN_BACK = 0.05


def _energy_lines(bank: float | None, metrics: dict[str, float], history, cols: set[str], axis) -> list[Headline]:
    """Peak kinetic energy and plastic work in % of the energy put in (a 3D model's energies times its symmetry
    factor: the whole device's, as the bank's energy is); under loads that take back much of what they put in
    (AC forces: the external work falls by more than :data:`GIVEN_BACK` of its largest value), the peak kinetic
    energy in J and how far the loads' work swung, as no fraction of that work would mean anything."""
    if "energy_kinetic_J" not in cols:
        return []
    s = float(metrics.get("symmetry_factor", 1.0))
    ke = s * history.column("energy_kinetic_J")
    plastic = s * float(history.column("energy_plastic_J")[-1]) if "energy_plastic_J" in cols else \
        metrics.get("plastic_work_J", 0.0)
    external = s * float(history.column("energy_external_work_J")[-1]) if "energy_external_work_J" in cols else 0.0
    if bank is not None and bank > 0.0:
        ref, of = bank, "of the bank energy"
    elif external > 0.0 or "energy_external_work_J" in cols and _given_back(s * history.column("energy_external_work_J")):
        w = s * history.column("energy_external_work_J")
        if _given_back(w):
            k = int(np.argmax(ke))
            swing = "{:.3g} {}".format(*_small_energy(float(np.abs(w).max())))
            end = "{:.3g} {}".format(*_small_energy(float(w[-1])))
            out = [Headline("peak kinetic energy", *_small_energy(float(ke[k])),
                            f"at {history.column('time_s')[k] * axis.scale:.4g} {axis.unit}; the loads put in and "
                            f"took back work (up to {swing}, {end} at the end)")]
            if "energy_plastic_J" in cols:
                out.append(Headline("plastic work", *_small_energy(plastic)))
            return out
        ref, of = external, "of the external work"
    elif ke[0] > 0.0:  # an impact: the energy it starts with
        return [Headline("kinetic energy at the end", 100.0 * float(ke[-1]) / ke[0], "%",
                         f"of the initial {energy_text(ke[0])}"),
                Headline("plastic work", 100.0 * plastic / ke[0], "%",
                         f"of the initial kinetic energy ({energy_text(plastic)})")]
    else:
        return []
    out = [Headline("peak kinetic energy", 100.0 * float(ke.max()) / ref, "%", f"{of} ({energy_text(ke.max())})")]
    if "energy_plastic_J" in cols or "plastic_work_J" in metrics:  # not for rigid bodies alone
        out.append(Headline("plastic work", 100.0 * plastic / ref, "%", f"{of} ({energy_text(plastic)})"))
    return out


def _given_back(w: np.ndarray) -> bool:
    """The external work history ``w`` (J) falls by more than :data:`GIVEN_BACK` of its largest |value| below an
    earlier value."""
    top = float(np.abs(w).max()) if len(w) else 0.0
    return top > 0.0 and float((np.maximum.accumulate(w) - w).max()) > GIVEN_BACK * top


def _small_energy(joules: float) -> tuple[float, str]:
    """An energy (J) as (value, unit) in J, mJ, µJ or nJ."""
    for factor, unit in ((1.0, "J"), (1e-3, "mJ"), (1e-6, "µJ")):
        if abs(joules) >= factor:
            return joules / factor, unit
    return joules / 1e-9, "nJ"
