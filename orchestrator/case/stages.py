"""The case's ``[[stages]]`` (issue 34, item 5): a run as a chain of stages — a quasi-static preform, pulses,
springbacks — in one results folder with one history.

A timed stage (``"pulse"``, ``"quasi_static"``) integrates from the previous timed stage's end to its own ``end``
on the run's one time axis; a ``"springback"`` stage takes no time (a static release of the state the stage before
it left). The state (positions, stress, plastic strain, temperature, contact) is carried from stage to stage; what
runs it: :mod:`pulseform.orchestrator.run.stages`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from .names import check_file_name
from .schema import SchemaError, spec
from .springback import SpringbackTable

__all__ = ["StageTable", "check_stages", "check_implicit_reach", "check_adaptive", "stage_integrator", "discharges",
           "TIMED"]

#: the stage kinds that take time
TIMED = ("pulse", "quasi_static")


@dataclass(frozen=True, kw_only=True)
class StageTable:
    """One stage of a chained run."""

    name: str = spec(doc="stage name (fields/<case>_<stage>_<body>.xdmf, stage_<stage>_* metrics): 1 to 100 ASCII "
                         "letters, digits, '.', '_', '-'")
    kind: Literal["pulse", "quasi_static", "springback"] = spec(
        doc="'pulse': the case's loads (pressure [[loads]], the EM sources on the run's time axis, or the bank's "
            "discharge: a fresh one from the second pulse on) over the stage with the dynamic integrator; "
            "'quasi_static': implicit static steps under the pressure [[loads]] (a preform); "
            "'springback': a static release of the state the previous stage left (no time passes)")
    end: float | None = spec(None, unit="s", gt=0.0,
                             doc="end of a timed stage on the run's time axis (required for 'pulse' and "
                                 "'quasi_static'; increasing from stage to stage, the last one time.end)")
    integrator: Literal["explicit", "implicit"] | None = spec(
        None, doc="'pulse' only: its integrator (default mechanics.integrator); 'quasi_static' is implicit static")
    dt: float | None = spec(None, unit="s", gt=0.0,
                            doc="implicit step of an implicit 'pulse' or a 'quasi_static' stage (default "
                                "mechanics.implicit.dt)")
    velocities: Literal["kept", "zeroed"] | None = spec(
        None, doc="'pulse' only: the velocities at its start (deformable and rigid bodies), kept from the stage "
                  "before (default) or set to rest (after a springback stage they are at rest either way)")
    voltage: float | None = spec(None, unit="V", gt=0.0,
                                 doc="coupled cases with a capacitor bank, a 'pulse' stage after the first: its "
                                     "discharge's charging voltage (default: the bank's own)")
    field_interval: float | None = spec(None, unit="s", gt=0.0,
                                        doc="timed stages: field output interval in the stage (default "
                                            "output.field_interval, else the stage's duration / 20)")
    springback: SpringbackTable | None = spec(
        None, doc="'springback' only: how the bodies are released (the keys of [springback]; default its defaults)")


def stage_integrator(case, stage: StageTable) -> str:
    """The integrator of a timed ``stage`` of ``case``: ``"implicit"`` or ``"explicit"``."""
    if stage.kind == "quasi_static":
        return "implicit"
    return stage.integrator or case.mechanics.integrator


def check_implicit_reach(case, where: str = "", remedy: str = "mechanics.integrator = 'explicit'") -> None:
    """The implicit integrator's present reach (raise :class:`SchemaError` otherwise): deformable bodies, rigid
    bodies (not in static steps), contact pairs with the elastic law of eq. (5) only (no friction or viscosity),
    rigid walls. ``where``: the stage that
    asks for it (a prefix of the message), ``remedy``: what to set instead."""
    for i, c in enumerate(case.contact):
        for key in ("friction", "viscosity"):
            if getattr(c, key) > 0:
                raise SchemaError(f"contact[{i}].{key}", f"got {getattr(c, key)!r}; {where}the implicit integrator "
                                  f"has the elastic law of eq. (5) only: set 0 or use {remedy}")
    if case.mechanics.implicit.scheme == "static":
        for i, b in enumerate(case.bodies):
            if b.rigid:
                raise SchemaError(f"bodies[{i}].rigid", f"{where}a rigid body has no static equilibrium under its "
                                  "forces: with rigid bodies use mechanics.implicit.scheme = 'trapezoidal' or 'hht'")


def check_adaptive(case) -> None:
    """``mechanics.implicit.adaptive`` with the rest of ``case`` (raise :class:`SchemaError` otherwise): the step
    chooses the EM step too, one mechanical step per EM step (coupling.n = 1, not coupling.adaptive), and
    time.dt_max (the largest step) not below the first step."""
    im = case.mechanics.implicit
    if case.mechanics.integrator != "implicit" or not im.adaptive:
        return
    if all(b.rigid for b in case.bodies):
        raise SchemaError("mechanics.implicit.adaptive", "got true; the adaptive step is chosen from the deformable "
                          "bodies' error (rigid bodies move exactly): this case has none, set false")
    if case.case.kind == "coupled":
        if case.coupling.n != 1:
            raise SchemaError("coupling.n", f"got {case.coupling.n}; adaptive implicit steps take one mechanical "
                              "step per EM step: set 1")
        if case.coupling.adaptive:
            raise SchemaError("coupling.adaptive", "got true; with mechanics.implicit.adaptive the mechanics "
                              "chooses the step: set false")
    if case.time.dt_max is not None and case.time.dt_max < im.dt:
        raise SchemaError("time.dt_max", f"got {case.time.dt_max!r} s; the largest adaptive step must not be below "
                          f"the first, mechanics.implicit.dt = {im.dt!r} s")


def check_stages(case) -> None:
    """Cross-checks of ``case.stages`` (one :class:`SchemaError` naming the key)."""
    stages = case.stages
    if not stages:
        return
    for key, given in (("springback", case.springback is not None),
                       ("em.shots", case.em is not None and getattr(case.em, "shots", None) is not None)):
        if given:
            raise SchemaError(key, f"[{key}] and [[stages]] do not go together: give it as a stage "
                              + ("(kind = 'springback')" if key == "springback" else "(one 'pulse' stage per shot)"))
    if all(b.rigid for b in case.bodies):
        raise SchemaError("stages", "stages carry deformable bodies: this case has none")
    getdp = case.case.kind == "coupled" and case.coupling.load == "getdp"
    names: list[str] = []
    last_end, last_kind, pulses = 0.0, None, 0
    for i, s in enumerate(stages):
        path = f"stages[{i}]"
        check_file_name(s.name, f"{path}.name", "fields/<case>_<stage>_<body>.xdmf and stage_<stage>_* metrics")
        if s.name in names:
            raise SchemaError(f"{path}.name", f"got {s.name!r}; stage names must be unique")
        names.append(s.name)
        if s.kind == "springback":
            _check_springback_stage(case, s, path, i, last_kind)
        else:
            _check_timed_stage(case, s, path, i, last_end, getdp, pulses)
            last_end = s.end
            pulses += s.kind == "pulse"
        last_kind = s.kind
    if abs(last_end - case.time.end) > 1e-12 * case.time.end:
        i = max(i for i, s in enumerate(stages) if s.kind in TIMED)
        raise SchemaError(f"stages[{i}].end", f"got {last_end:g}; the last timed stage ends the run: it must be "
                          f"time.end = {case.time.end:g} (s)")


def _refuse(s: StageTable, path: str, keys: tuple[str, ...], why: str) -> None:
    for key in keys:
        if getattr(s, key) is not None:
            raise SchemaError(f"{path}.{key}", f"{why}; remove it")


def _check_springback_stage(case, s: StageTable, path: str, i: int, last_kind: str | None) -> None:
    if last_kind is None:
        raise SchemaError(f"{path}.kind", "got 'springback' as the first stage: a springback releases what a stage "
                          "before it formed; start with a 'pulse' or 'quasi_static' stage")
    if last_kind == "springback":
        raise SchemaError(f"{path}.kind", f"got 'springback' right after the springback stages[{i - 1}]: nothing "
                          "moved in between; remove one")
    _refuse(s, path, ("end", "integrator", "dt", "velocities", "voltage", "field_interval"),
            "a 'springback' stage takes no time (a static release at the previous stage's end)")
    deformable = [b.name for b in case.bodies if not b.rigid]
    for j, n in enumerate(s.springback.bodies if s.springback else ()):
        if n not in deformable:
            raise SchemaError(f"{path}.springback.bodies[{j}]", f"got {n!r}; allowed: "
                              + ", ".join(repr(b) for b in deformable))


def _check_timed_stage(case, s: StageTable, path: str, i: int, last_end: float, getdp: bool, pulses: int) -> None:
    if s.end is None:
        raise SchemaError(f"{path}.end", f"missing; a {s.kind!r} stage needs its end time on the run's time axis (s)")
    if s.end <= last_end * (1.0 + 1e-12):
        raise SchemaError(f"{path}.end", f"got {s.end:g}; stage times must increase: must be > {last_end:g} (s), "
                          "the end of the timed stage before it")
    if s.end > case.time.end * (1.0 + 1e-12):
        raise SchemaError(f"{path}.end", f"got {s.end:g}; must be <= time.end = {case.time.end:g} (s)")
    if s.springback is not None:
        raise SchemaError(f"{path}.springback", f"a {s.kind!r} stage has no release; give it to a stage of kind "
                          "'springback'")
    if s.field_interval is not None and s.field_interval > s.end - last_end:
        raise SchemaError(f"{path}.field_interval", f"got {s.field_interval:g}; must be <= the stage's duration "
                          f"{s.end - last_end:g} (s)")
    if s.kind == "quasi_static":
        _refuse(s, path, ("velocities", "voltage"), "a 'quasi_static' stage has no inertia and no discharge")
        if s.integrator not in (None, "implicit"):
            raise SchemaError(f"{path}.integrator", f"got {s.integrator!r}; a 'quasi_static' stage is implicit "
                              "static steps: remove it, or make the stage kind = 'pulse'")
        if getdp:
            raise SchemaError(f"{path}.kind", "got 'quasi_static'; it loads the bodies with the pressure [[loads]] "
                              "(case.kind = 'mechanics' or coupling.load = 'pressure'), not a GetDP discharge")
    integrator = stage_integrator(case, s)
    if integrator == "implicit":
        if s.dt is None and case.mechanics.implicit.dt is None:
            raise SchemaError(f"{path}.dt", "missing; an implicit stage needs its step (s): give dt here or "
                              "mechanics.implicit.dt")
        if case.mechanics.kinetic_damping_until > 0.0:
            raise SchemaError("mechanics.kinetic_damping_until", f"kinetic damping is the explicit integrator's; "
                              f"{path} is implicit: use a 'quasi_static' stage instead")
        check_implicit_reach(case, f"{path} is implicit: ", f"integrator = 'explicit' in {path}")
        im, first = case.mechanics.implicit, s.dt or case.mechanics.implicit.dt
        if im.adaptive and s.kind == "pulse" and not ((im.dt_min or 0.0) <= first <= (case.time.dt_max or first)):
            raise SchemaError(f"{path}.dt", f"got {first!r} s; the first adaptive step must lie within "
                              "mechanics.implicit.dt_min and time.dt_max")
    elif s.dt is not None:
        raise SchemaError(f"{path}.dt", "the explicit integrator takes its stable step: remove dt, or set "
                          "integrator = 'implicit'")
    if s.voltage is not None:
        bank = getdp and (case.em.circuit is not None or any(src.type == "bank" for src in case.em.sources))
        if not bank:
            raise SchemaError(f"{path}.voltage", "a stage's voltage charges a capacitor bank: this case has none "
                              "(em.circuit, or a [[em.sources]] of type 'bank', with coupling.load = 'getdp')")
        if pulses == 0:
            raise SchemaError(f"{path}.voltage", "the first pulse is the bank's own discharge: set its voltage "
                              "in the bank, and stage voltages from the second pulse on")
    if discharges(case) and s.kind == "pulse" and pulses >= 1:
        _check_new_discharge(case, path)


def discharges(case) -> bool:
    """Whether a later ``'pulse'`` stage of ``case`` is a new discharge of a capacitor bank: a GetDP-coupled case
    with one (em.circuit, or a ``'bank'`` source). Without a bank the sources are functions of the run's time and a
    later pulse goes on with them (the EM state carried, as the pressure [[loads]] go on with their times)."""
    if case.case.kind != "coupled" or case.coupling.load != "getdp":
        return False
    return case.em.circuit is not None or any(src.type == "bank" for src in case.em.sources)


def _check_new_discharge(case, path: str) -> None:
    """A second pulse of a case with a bank is a fresh discharge: what ``[em.shots]`` needs, the built-in deck."""
    geo = case.geometry
    if geo.type == "user_deck" or getattr(geo, "library", None) == "getdp_template":
        raise SchemaError(f"{path}.kind", "a second 'pulse' stage of a case with a capacitor bank is a new discharge "
                          "of the bank: it needs the built-in deck (not a user deck or a GetDP template)")
