"""The participants of a coupled 2D case (axisymmetric or planar): the EM mesh (a built-in geometry or a user's
deck), the deformable bodies' solver on the conductor regions cut from it, the rigid bodies and the GetDP load (or
the ``[[loads]]`` pressure pulses with ``coupling.load = "pressure"``); and a mechanics case's pressure pulses."""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from ..case.model import Case
from ..em.participant import GetDPLoad
from ..em.solver import em_model, factor_reuse
from ..em.time_scale import rigid_mechanical_step
from ..em.user_deck import build_user_geometry, user_deck_load
from ..mech.mixed import rigid_bodies
from ..mech.model import build_solver
from ..mech.participants import PressurePulses
from ..mech.rigid import RigidMechanics
from ..mesh.em_geometry import PendingEMGeometry, build_em_geometry
from ..mesh.shared import body_conductor, conductor_submesh, to_dolfinx
from .results import ResultsFolder

__all__ = ["pressure_pulses", "coupled_participants"]


def pressure_pulses(case: Case) -> PressurePulses:
    """The case's pressure pulses with its damping options."""
    mo = case.mechanics
    return PressurePulses(case.loads, mo.mass_damping, mo.mass_damping_until, mo.mass_damping_from,
                          mo.kinetic_damping_until)


def coupled_participants(case: Case, results: ResultsFolder, comm: MPI.Comm,
                          em_geometry: PendingEMGeometry | None = None):
    """Mesh the EM setup (or take the mesh ``em_geometry`` started earlier, :func:`start_em_geometry`),
    cut the conductor bodies' mechanical meshes from it, build solver and GetDP load."""

    if comm.size > 1:
        raise NotImplementedError("coupled runs are serial for now (the GetDP participant and the force transfer run on one process)")
    user_deck = case.geometry.type == "user_deck"  # a user's own .geo/.msh + .pro (orchestrator/em/user_deck.py)
    if user_deck:

        geometry = build_user_geometry(case, results.root / "em_mesh", results.root / "em")
    elif em_geometry is not None:
        geometry = em_geometry.result()
    else:
        geometry = build_em_geometry(case.geometry, time_limit=case.limits.gmsh_time_limit_s)
    roles = geometry.conductor_roles()
    subs = {role: conductor_submesh(geometry.mesh, geometry.regions[role]) for role in roles}
    rigid_roles = {b.region for b in case.bodies if b.rigid}
    solver = None
    if len(rigid_roles) < len(roles):
        solver = build_solver(case, comm, {role: to_dolfinx(sub, comm) for role, sub in subs.items()
                                           if role not in rigid_roles})
    if case.coupling.load == "pressure":  # same meshes and loop, pressure pulses instead of GetDP
        return solver, pressure_pulses(case), None
    rigid = None
    if rigid_roles:
        rigid = RigidMechanics(rigid_bodies(case, subs), _rigid_step(case, solver))
    scale = float(np.abs(geometry.mesh.points).max())
    bodies = []
    for role in roles:
        name = next(b.name for b in case.bodies if b.region == role)
        body = None if role in rigid_roles else solver.bodies[name]   # six-node: vertex rows on the EM nodes
        bodies.append(body_conductor(name, geometry.regions[role], subs[role], body, geometry.mesh.points,
                                     1e-12 * scale))
    g = case.geometry
    if user_deck:

        load = user_deck_load(case, geometry, results.root / "em", bodies, case.coupling.em_substeps)
    else:
        load = GetDPLoad(geometry, em_model(case, (g.air_radius, g.shell_radius)), results.root / "em", bodies,
                         keep_runs=case.em.keep_runs, remesh_quality=case.em.remesh_quality,
                         sizes=(g.mesh_size_coil, g.mesh_size_air), em_substeps=case.coupling.em_substeps,
                         depth=case.mechanics.thickness, time_scheme=case.em.time_scheme,
                         getdp_process=case.em.getdp_process, factor_reuse=factor_reuse(case))
    load.solver.timeout = case.limits.getdp_time_limit_s
    load.gmsh_time_limit = case.limits.gmsh_time_limit_s
    return solver, load, rigid


def _rigid_step(case: Case, solver) -> float:
    """The rigid bodies' mechanical step (s): the deformable bodies' stable step when there are any;
    without them a period of the source over ``coupling.steps_per_period`` EM steps of ``coupling.n``
    mechanical steps each (:mod:`..em.time_scale`), capped by ``time.dt_max`` (which alone sets it
    when no source has a period)."""
    if solver is not None:
        return solver.stable_time_step()
    return rigid_mechanical_step(case)
