"""The GetDP model of a coupled case and the getdp solver that runs it (persistent or one process per step)."""

from __future__ import annotations

from pathlib import Path

from pulseform.solvers.getdp import Circuit, Coil, Conductor, DampedSine, EMModel, GetDPSolver

from ..case.model import Case


def em_model(case: Case, shell: tuple[float, float] | None) -> EMModel:
    """The GetDP model of a coupled case: one stranded coil, the conductor bodies as massive
    conductors 1, 2, ... in the geometry's conductor order (workpiece first).

    ``shell``: inner and outer radius (m) of the shell transformation to infinity, or None.
    """
    em, g = case.em, case.geometry
    wave = None
    if em.current is not None:
        wave = DampedSine(I0=em.current.amplitude, beta=em.current.beta, omega=em.current.omega)
    coil = Coil(turns=g.turns, sigma=em.coil_conductivity, waveform=wave, density=em.coil_density,
                heat_capacity=em.coil_heat_capacity)
    conductors = []
    for role in g.conductor_roles():
        body = next(b for b in case.bodies if b.region == role)
        sigma = case.materials[body.material].electrical_conductivity
        if sigma <= 0.0:
            raise ValueError(f"materials.{body.material}.electrical_conductivity must be > 0 for the {role}")
        conductors.append(Conductor(sigma=sigma, name=body.name))
    circuit = None
    if em.circuit is not None:
        c = em.circuit
        circuit = Circuit(C=c.capacitance, V0=c.voltage, R_ext=c.resistance, L_ext=c.inductance)
    return EMModel(axisymmetric=not g.planar, coils=[coil], conductors=conductors, circuit=circuit, shell=shell)


def make_em_solver(model: EMModel, work_dir: Path, time_scheme: str, getdp_process: str, **kw) -> GetDPSolver:
    """The EM participant: a persistent getdp for BDF2 (``getdp_process`` "persistent" or "auto"),
    else one getdp process per EM step. ``kw`` go to the solver (deck, numbers, preamble)."""
    if getdp_process not in ("auto", "persistent", "per_step"):
        raise ValueError(f"getdp_process must be 'auto', 'persistent' or 'per_step', got {getdp_process!r}")
    if getdp_process == "persistent" and time_scheme != "bdf2":
        raise ValueError("the persistent getdp implements time_scheme='bdf2' only")
    if getdp_process != "per_step" and time_scheme == "bdf2":
        from pulseform.solvers.getdp.persistent import PersistentGetDPSolver

        return PersistentGetDPSolver(model, work_dir, **kw)
    return GetDPSolver(model, work_dir, time_scheme=time_scheme, **kw)
