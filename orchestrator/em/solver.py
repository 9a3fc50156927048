"""The GetDP model of a coupled case and the getdp solver that runs it (persistent or one process per step)."""

from __future__ import annotations

import logging
import math
from pathlib import Path

from pulseform.solvers.getdp import (AppliedField, Circuit, Coil, Conductor, CurrentTable, DampedSine, EMModel,
                                     GetDPSolver)
from pulseform.solvers.getdp.model import MagneticCore
from pulseform.solvers.getdp.persistent_process import FactorReuse

from ..case.conductivity import conductivity_law
from ..case.em_applied import AppliedDC, AppliedSine, AppliedTable
from ..case.em_sources import BankSource, DCSource, SineSource, TableSource, read_current_table
from ..case.magnetic import magnetic_keywords
from ..case.model import Case

log = logging.getLogger(__name__)


def source_waveform(source: SineSource | DCSource | TableSource) -> DampedSine | CurrentTable:
    """The GetDP waveform of a prescribed ``[[em.sources]]`` entry (A over s): a sine is
    I0 e^(−β (t − t_on)) sin(2π f (t − t_on) + φ), a direct current I is ω = 0, φ = π/2 (sin = 1 exactly),
    a table is read from its CSV file (already checked by the case loader)."""
    if isinstance(source, SineSource):
        return DampedSine(I0=source.amplitude, beta=source.decay, omega=2.0 * math.pi * source.frequency,
                          phase=source.phase, t_on=source.t_on)
    if isinstance(source, DCSource):
        return DampedSine(I0=source.current, beta=0.0, omega=0.0, phase=0.5 * math.pi, t_on=source.t_on)
    if isinstance(source, TableSource):
        return CurrentTable(*read_current_table(source.file))
    raise TypeError(f"not a prescribed source: {source!r}")


def applied_field(spec: AppliedDC | AppliedSine | AppliedTable | None) -> AppliedField | None:
    """The GetDP applied field of ``[em.applied_field]`` (None without one): magnitude (T) and direction,
    its time function as a source's waveform of amplitude 1 (:func:`source_waveform`'s formulas)."""
    if spec is None:
        return None
    if isinstance(spec, AppliedSine):
        wave = DampedSine(I0=1.0, beta=spec.decay, omega=2.0 * math.pi * spec.frequency, phase=spec.phase,
                          t_on=spec.t_on)
    elif isinstance(spec, AppliedDC):
        wave = DampedSine(I0=1.0, beta=0.0, omega=0.0, phase=0.5 * math.pi, t_on=spec.t_on)
    else:
        wave = CurrentTable(*read_current_table(spec.file, quantity=("factor", "-")))
    return AppliedField(B0=spec.magnitude, direction=spec.direction, waveform=wave)


def coil_drives(case: Case, names: list[str | None]) -> tuple[list[tuple[DampedSine | CurrentTable | None, int]],
                                                              Circuit | None]:
    """(waveform or None on the bank, sign) of each coil ``names`` (the geometry's coil order; ``[None]`` for
    the one coil of a geometry on em.circuit / em.current), and the circuit (None without a bank): every coil
    on em.circuit or em.current, or each on its ``[[em.coils]]`` source with that entry's sign."""
    em = case.em
    if not em.sources:
        wave = None
        if em.current is not None:
            wave = DampedSine(I0=em.current.amplitude, beta=em.current.beta, omega=em.current.omega)
        circuit = None
        if em.circuit is not None:
            c = em.circuit
            circuit = Circuit(C=c.capacitance, V0=c.voltage, R_ext=c.resistance, L_ext=c.inductance)
        return [(wave, 1) for _ in names], circuit
    sources = {s.name: s for s in em.sources}
    connection = {c.name: c for c in em.coils}
    drives, circuit = [], None
    for name in names:
        con = connection[name if name is not None else em.coils[0].name]
        src = sources[con.source]
        if isinstance(src, BankSource):
            circuit = Circuit(C=src.capacitance, V0=src.voltage, R_ext=src.resistance, L_ext=src.inductance)
            drives.append((None, con.sign))
        else:
            drives.append((source_waveform(src), con.sign))
    return drives, circuit


def coil_keywords(case: Case) -> dict:
    """The coils' material of ``[em]`` as keywords of a 2D or 3D coil: σ (S/m), density (kg/m³), heat capacity
    (J/(kg·K)), σ(T) law and initial temperature (K)."""
    em = case.em
    return {"sigma": em.coil_conductivity, "density": em.coil_density, "heat_capacity": em.coil_heat_capacity,
            "conductivity_law": conductivity_law(em.coil_conductivity_curve, em.coil_conductivity),
            "initial_temperature": em.coil_initial_temperature}


def conductor_of(case: Case, material: str, name: str, role: str, deck_own: bool = False) -> Conductor:
    """The GetDP conductor of a body (or fixed conductor) ``name`` of ``materials.<material>`` in ``role``: its σ
    (a table law alone: its σ at the initial temperature), σ(T) law, initial temperature and magnetic keywords;
    σ must be > 0 unless the deck has its own (``deck_own``)."""
    mat = case.materials[material]
    sigma = mat.electrical_conductivity
    law = conductivity_law(mat.conductivity_curve, sigma)
    if sigma <= 0.0 and law is not None:   # a table law alone: its σ at the initial temperature
        sigma = float(law(mat.initial_temperature))
    if sigma <= 0.0 and not deck_own:
        raise ValueError(f"materials.{material}.electrical_conductivity must be > 0 for the {role}")
    return Conductor(sigma=sigma, name=name, conductivity_law=law, initial_temperature=mat.initial_temperature,
                     **magnetic_keywords(mat))


def _coils(case: Case) -> tuple[list[Coil], Circuit | None]:
    """The coils of a coupled case in the mesh's coil order (coil k is physical 100 + k: the order of
    ``[[geometry.coils]]`` where the geometry names its coils), and the circuit (None without a bank)."""
    em, g = case.em, case.geometry
    kw = coil_keywords(case)
    if not em.sources:  # em.circuit or em.current: the geometry's one coil
        drives, circuit = coil_drives(case, [None])
        return [Coil(turns=g.turns, waveform=drives[0][0], **kw)], circuit
    if getattr(g, "coils", ()):  # named coils: coaxial_coils, a user deck's [[geometry.coils]]
        shapes = [(c.name, c.turns) for c in g.coils]
    else:
        shapes = [(em.coils[0].name, g.turns)]
    drives, circuit = coil_drives(case, [name for name, _ in shapes])
    coils = [Coil(turns=turns, waveform=wave, sign=sign, name=name, **kw)
             for (name, turns), (wave, sign) in zip(shapes, drives)]
    return coils, circuit


def em_model(case: Case, shell: tuple[float, float] | None) -> EMModel:
    """The GetDP model of a coupled case: its stranded coils (the geometry's one coil on em.circuit or
    em.current, or every coil on its [[em.sources]] entry with its sign), the conductor bodies as massive
    conductors 1, 2, ... in the geometry's conductor order (workpiece first), and [em.applied_field].

    ``shell``: inner and outer radius (m) of the shell transformation to infinity, or None.
    """
    g = case.geometry
    coils, circuit = _coils(case)
    conductors = []
    deck_own = getattr(g, "library", "pulseform") == "getdp_template"  # 0: the deck's own (user_deck.user_em_model)
    for role in g.conductor_roles():
        body = next(b for b in case.bodies if b.region == role)
        conductors.append(conductor_of(case, body.material, body.name, role, deck_own))
    cores = [MagneticCore(name=c.name, **magnetic_keywords(case.materials[c.material]))   # one per box (the mesh's)
             for c in getattr(g, "cores", ()) or () for _ in c.boxes]
    return EMModel(axisymmetric=not g.planar, coils=coils, conductors=conductors, circuit=circuit, shell=shell,
                   cores=cores,
                   applied_field=applied_field(case.em.applied_field), newton_tolerance=case.em.newton_tolerance,
                   newton_max_iterations=case.em.newton_max_iterations)


def factor_reuse(case: Case) -> FactorReuse:
    """The kept LU factors of the case's persistent getdp (``em.factor_reuse_tol``,
    ``em.factor_reuse_max_corrections``)."""
    return FactorReuse(tol=case.em.factor_reuse_tol, max_corrections=case.em.factor_reuse_max_corrections)


def make_em_solver(model: EMModel, work_dir: Path, time_scheme: str, getdp_process: str,
                   factor_reuse: FactorReuse = FactorReuse(), **kw) -> GetDPSolver:
    """The EM participant: a persistent getdp for BDF2 (``getdp_process`` "persistent" or "auto";
    with ``factor_reuse``), else one getdp process per EM step. ``kw`` go to the solver (deck,
    numbers, preamble)."""
    if getdp_process not in ("auto", "persistent", "per_step"):
        raise ValueError(f"getdp_process must be 'auto', 'persistent' or 'per_step', got {getdp_process!r}")
    if getdp_process == "persistent" and time_scheme != "bdf2":
        raise ValueError("the persistent getdp implements time_scheme='bdf2' only")
    if getdp_process != "per_step" and time_scheme == "bdf2":
        from pulseform.solvers.getdp.persistent import PersistentGetDPSolver

        return PersistentGetDPSolver(model, work_dir, factor_reuse=factor_reuse, **kw)
    return GetDPSolver(model, work_dir, time_scheme=time_scheme, **kw)
