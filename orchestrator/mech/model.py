"""Translate a validated :class:`Case` into the DOLFINx solvers' objects (explicit, or implicit with mechanics.integrator)."""

from __future__ import annotations

import logging
import math
from dataclasses import replace

from mpi4py import MPI

from pulseform.solvers import dolfinx as mech
from pulseform.solvers.dolfinx.implicit import ImplicitOptions, ImplicitSolver, ImplicitSolver3D

from ..case.schema import SchemaError
from ..case.flow import FlowCurveTable, LudwikTable, SwiftTable, TableFlowTable, VoceTable
from ..case.model import Case, CowperSymondsTable, MaterialTable
from ..mesh.shapes import mesh_shape
from .model3d import build_solver_3d
from ..mesh.markers import box_marker

log = logging.getLogger(__name__)


def solver_flow_curve(fc: FlowCurveTable | None):
    """Case flow-curve table -> solver flow curve (:mod:`pulseform.solvers.dolfinx.flow_curves`), None: the
    linear law."""
    if fc is None:
        return None
    if isinstance(fc, TableFlowTable):
        return mech.TabulatedFlow(plastic_strain=fc.plastic_strain, yield_stress=fc.curves(),
                                  strain_rates=fc.strain_rates, temperatures=fc.temperatures,
                                  extrapolation=fc.extrapolation)
    if isinstance(fc, SwiftTable):
        return mech.Swift(K=fc.K, eps0=fc.eps0, n=fc.n)
    if isinstance(fc, VoceTable):
        return mech.Voce(sigma0=fc.sigma0, Q=fc.Q, b=fc.b)
    if isinstance(fc, LudwikTable):
        return mech.Ludwik(sigma0=fc.sigma0, K=fc.K, n=fc.n)
    return mech.JohnsonCookFlow(A=fc.A, B=fc.B, n=fc.n, C=fc.C, reference_strain_rate=fc.reference_strain_rate,
                                room_temperature=fc.room_temperature, melting_temperature=fc.melting_temperature,
                                m=fc.m)


def solver_material(m: MaterialTable) -> "mech.Material":
    """Case material table -> solver material (SI units are the same on both sides)."""
    rate = None
    if isinstance(m.rate_law, CowperSymondsTable):
        rate = mech.CowperSymonds(D=m.rate_law.D, p=m.rate_law.q)
    elif m.rate_law is not None:
        rate = mech.JohnsonCook(C=m.rate_law.C, eps_rate0=m.rate_law.reference_strain_rate)
    return mech.Material(density=m.density, shear_modulus=m.shear_modulus,
                         bulk_modulus=m.bulk_modulus, yield_stress=m.initial_yield_stress,
                         hardening_modulus=m.hardening_modulus, rate_law=rate,
                         flow_curve=solver_flow_curve(m.flow_curve), specific_heat=m.specific_heat,
                         taylor_quinney=m.taylor_quinney, initial_temperature=m.initial_temperature)


def implicit_options(case: Case) -> ImplicitOptions:
    """The case's ``[mechanics.implicit]`` table -> the implicit solver's options (alpha only for 'hht'). A coupled
    case without ``coupling.iterate`` gets a warning: its staggered loop gains energy when the implicit step is not
    small against the parts' periods (docs/mechanics.md, *Coupled runs*). A stage's own step and scheme enter
    through the case of the stage (:func:`stage_case`)."""
    mo = case.mechanics
    if case.case.kind == "coupled" and not case.coupling.iterate:
        log.warning("implicit mechanics in a coupled run without coupling.iterate: the staggered loop gains energy "
                    "when mechanics.implicit.dt is not small against the parts' periods (set coupling.iterate = "
                    "true, or take a short step; docs/mechanics.md)")
    im = mo.implicit
    adaptive = im.adaptive and im.scheme != "static"   # (a quasi-static stage's steps: fixed)
    return ImplicitOptions(dt=im.dt, scheme=im.scheme, alpha=im.alpha if im.scheme == "hht" else 0.0,
                           newton_tol=im.newton_tol, newton_max=im.newton_max, max_cuts=im.max_cuts,
                           adaptive=adaptive, error_tol=im.error_tol, error_atol=im.error_atol, dt_min=im.dt_min,
                           dt_max=case.time.dt_max if case.time.dt_max is not None and adaptive else math.inf)


def stage_case(case: Case, stage) -> Case:
    """``case`` with the mechanics of a timed ``[[stages]]`` entry: its integrator, its implicit step (``dt``) and,
    for a ``quasi_static`` stage, the static scheme."""
    from ..case.stages import stage_integrator

    mo = case.mechanics
    integrator = stage_integrator(case, stage)
    implicit = mo.implicit
    if integrator == "implicit":
        implicit = replace(implicit, dt=stage.dt or implicit.dt,
                           scheme="static" if stage.kind == "quasi_static" else implicit.scheme)
    return replace(case, mechanics=replace(mo, integrator=integrator, implicit=implicit))


def rebuild_solver(case: Case, source) -> "mech.ExplicitSolver":
    """A new solver of ``case``'s mechanics (integrator, implicit options, explicit settings) on the bodies of
    ``source`` (its meshes, materials and supports), with its contact pairs and walls; in the initial state (carry
    ``source``'s state over with :func:`pulseform.solvers.dolfinx.handover.carry_state`)."""
    specs = [b.spec for b in source.bodies.values()]
    return make_solver(case, specs, source.contact_pairs, source.rigid_walls, source.comm)


def make_solver(case: Case, bodies, pairs, walls, comm: MPI.Comm, compiled_steps: bool = True):
    """The solver of ``case``'s mechanics (2D or 3D, explicit or implicit) over the solver's ``bodies``
    (:class:`~pulseform.solvers.dolfinx.BodySpec`), contact ``pairs`` and rigid ``walls``."""
    mo = case.mechanics
    three = mo.formulation == "3d"
    if mo.integrator == "implicit":
        if three:
            return ImplicitSolver3D(bodies, implicit_options(case), comm=comm, contact_pairs=pairs, rigid_walls=walls)
        return ImplicitSolver(bodies, implicit_options(case), formulation=mo.formulation, thickness=mo.thickness,
                              comm=comm, contact_pairs=pairs, rigid_walls=walls)
    if three:
        return mech.ExplicitSolver3D(bodies, rigid_walls=walls, contact_pairs=pairs, cfl=case.time.cfl,
                                     bulk_viscosity=mo.bulk_viscosity, bulk_linear=mo.bulk_viscosity_linear,
                                     bulk_quadratic=mo.bulk_viscosity_quadratic, comm=comm, threads=mo.threads,
                                     mass_scaling_dt=mo.mass_scaling_dt)
    return mech.ExplicitSolver(bodies, formulation=mo.formulation, contact_pairs=pairs, rigid_walls=walls,
                               cfl=case.time.cfl, bulk_viscosity=mo.bulk_viscosity,
                               bulk_linear=mo.bulk_viscosity_linear, bulk_quadratic=mo.bulk_viscosity_quadratic,
                               thickness=mo.thickness, comm=comm, compiled_steps=compiled_steps,
                               threads=mo.threads)


def build_solver(case: Case, comm: MPI.Comm = MPI.COMM_WORLD,
                 region_meshes: dict | None = None, compiled_steps: bool = True) -> "mech.ExplicitSolver":
    """Mesh every deformable body (or take its region's mesh, cut from the EM mesh) and build the
    solver (``compiled_steps``: the solver's compiled block path, else its Python step loop; the implicit
    solver when ``mechanics.integrator = "implicit"``); rigid bodies are not the solver's (:mod:`.mixed`)."""
    if case.mechanics.formulation == "3d":  # tetrahedra (mechanics-only cases for now)
        return build_solver_3d(case, comm, solver_material, make_solver)
    bodies = []
    for i, b in enumerate(case.bodies):
        if b.rigid:
            continue
        if b.element == "tri6" and comm.size > 1:
            raise SchemaError(f"bodies[{i}].element", f"got 'tri6' under MPI ({comm.size} processes); six-node "
                              "triangles run on one process for now: run without mpirun or set element = 'tet4'")
        if b.region is not None:
            mesh = (region_meshes or {})[b.region]
        else:
            mesh = mesh_shape(b.shape, b.mesh_size, comm, name=b.name, time_limit=case.limits.gmsh_time_limit_s)
        fixed = tuple((box_marker(f.where), tuple(f.components)) for f in b.fixed)
        bodies.append(mech.BodySpec(name=b.name, mesh=mesh, material=solver_material(case.materials[b.material]),
                                    initial_velocity=tuple(b.initial_velocity), fixed=fixed, element=b.element))
    pairs = tuple(mech.ContactPairSpec(slave=c.slave, master=c.master, stiffness=c.stiffness, h0=c.h0,
                                       friction=c.friction, viscosity=c.viscosity, two_pass=c.two_pass)
                  for c in case.contact)
    walls = tuple(mech.RigidWallSpec(point=tuple(w.point), normal=tuple(w.normal),
                                     bodies=tuple(w.bodies) or None, sliding=w.sliding) for w in case.walls)
    return make_solver(case, bodies, pairs, walls, comm, compiled_steps)
