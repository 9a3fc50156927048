"""The participants of a coupled 3D case built from a geometry file (``[geometry] type = "geometry_3d"``): one
path for every 3D geometry (issue 29).

The EM mesh (:func:`~..mesh.geometry3d.build_geometry3d`) holds every conductor body's tetrahedra; each body's
mechanical mesh is cut from it (shared nodes, :mod:`~..mesh.shared3d`; a ten-node body, ``element = "tet10"``,
shares its vertices and adds a node on every edge) and held by the case's supports:
``[[symmetry]]`` planes as rollers (axis-aligned: the normal component held; with an oblique plane every plane of
the body slides), ``[[bodies.fixed]]`` boxes (3D bounds, every node inside) or physical surface groups; soft
contact from ``[[contact]]``. The air follows the bodies harmonically (:class:`~..mesh.motion3d.MeshMover3D`:
coils, shell, fixed conductors and the outer boundary stay, the planes slide); when it breaks
(``geometry.on_mesh_break``) it is meshed again with the EM state carried, the EM mesh freezes, or the run stops.
The loop's options come from ``[coupling]``; ``geometry.em_step`` sets n from the stable mechanical step.

With ``coupling.load = "pressure"`` the same meshes, supports and loop are driven by the ``[[loads]]`` pulses
(:class:`~..mech.pulses3d.PressurePulses3D`: boxes with 3D bounds, the device's figures × the symmetry factor)
instead of getdp: the pressure run of ``pulseform compare`` (the rigid bodies, if any, stay where they are).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from mpi4py import MPI

from pulseform.solvers import dolfinx as mech
from pulseform.solvers.dolfinx.implicit import ImplicitSolver3D
from pulseform.solvers.dolfinx.solver3d import ExplicitSolver3D
from pulseform.solvers.getdp.mesh import COIL_BASE, CONDUCTOR_BASE, SHELL, conductor_tag
from pulseform.solvers.getdp.mesh3d import Mesh3D
from pulseform.solvers.getdp.solver3d import model_numbers

from ..case.model import Case
from ..coupling.loop import LoopOptions
from ..em.frozen3d import FreezingGetDPLoad3D
from ..em.model3d import em_model3d
from ..em.conductor3d import ConductorBody3D
from ..em.solver import factor_reuse
from ..em.remesh3d import RemeshingGetDPLoad3D
from ..mech.mixed import rigid_bodies
from ..mech.model import implicit_options, solver_material
from ..mech.participants import DolfinxMechanics
from ..mech.pulses3d import PressurePulses3D
from ..mech.rigid import RigidMechanics
from ..mech.model3d import plane_marker
from ..mesh.geometry3d import Geometry3D, GeometryError, PlaneSpec, boundary_faces, build_geometry3d
from ..mesh.markers import box_marker, points_marker
from ..mesh.motion3d import MeshMover3D, nodes_on_plane
from ..mesh.shared3d import conductor_submesh3d, match_nodes3d, to_dolfinx3d

log = logging.getLogger(__name__)


def _supports(case: Case, name: str, fixed, geo: Geometry3D, tol: float, quadratic: bool = False) -> tuple[tuple, tuple]:
    """(fixed, sliding) of a body's :class:`~pulseform.solvers.dolfinx.BodySpec`: its symmetry planes (module
    docstring) then its ``[[bodies.fixed]]`` supports (a surface group: its nodes, and for a ``quadratic`` body the
    middles of its triangles' edges, where the ten-node body's edge nodes are)."""
    own = [s for s in case.symmetry if not s.bodies or name in s.bodies]
    aligned = all(s.axis_aligned() for s in own)
    held = tuple((plane_marker(s, tol), (s.component(),)) for s in own) if aligned else ()
    sliding = () if aligned else tuple((plane_marker(s, tol), tuple(s.normal)) for s in own)
    for f in fixed:
        marker = box_marker(f.where, tol) if f.where is not None else \
            points_marker(_group_points(geo, f.group, quadratic), tol)
        held += ((marker, tuple(f.components)),)
    return held, sliding


def _group_points(geo: Geometry3D, group: str, quadratic: bool) -> np.ndarray:
    """The points (n, 3) m of a physical surface group's nodes, with its triangles' edge middles if ``quadratic``."""
    x = geo.mesh.points
    pts = x[geo.surface_nodes[group]]
    if not quadratic:
        return pts
    tri = geo.surface_tris[group]
    edges = np.unique(np.sort(tri[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1), axis=0)
    return np.concatenate([pts, 0.5 * (x[edges[:, 0]] + x[edges[:, 1]])])


def air_mover3d(mesh: Mesh3D, planes: list[PlaneSpec], tol: float) -> MeshMover3D:
    """The air's motion on ``mesh`` (also on a remeshed one): conductors prescribed (the bodies move, the fixed
    ones stay), coils, shell and the outer boundary fixed, the symmetry planes sliding."""
    tags = mesh.tet_tags
    held = (tags > COIL_BASE) & (tags < COIL_BASE + 100) | (tags == SHELL) | \
        (tags > CONDUCTOR_BASE) & (tags < CONDUCTOR_BASE + 100)
    faces = boundary_faces(mesh.tets)
    scale = float(np.abs(mesh.points).max())
    on_plane = np.zeros(len(faces), dtype=bool)
    for p in planes:
        on_plane |= np.all(np.abs((mesh.points[faces] - p.point) @ p.normal) <= 1e-7 * scale, axis=1)
    fixed = np.unique(np.concatenate([mesh.tets[held].ravel(), faces[~on_plane].ravel()]))
    return MeshMover3D(mesh.points, mesh.tets, fixed,
                       [(nodes_on_plane(mesh.points, p.point, p.normal, tol), p.normal) for p in planes])


def participants_3d(case: Case, work: Path):
    """(3D solver or None, rigid bodies' mechanics or None, 3D GetDP load, loop options, :class:`Geometry3D`) of a
    coupled 3D geometry-file case; the mesh and the getdp runs in ``work`` (the results folder's ``em/``)."""
    g = case.geometry
    work = Path(work).resolve()
    geo = build_geometry3d(case, work)
    mesh = geo.mesh
    model = em_model3d(case, geo)
    try:   # what the deck would refuse (a cut, an applied field against a symmetry plane): bad input, found now
        model_numbers(model, mesh)
    except ValueError as exc:
        raise GeometryError(f"{Path(g.file).name}: geometry: {exc}") from None
    tol = 1e-9 * float(np.abs(mesh.points).max())
    specs, subs = [], {}
    for k, b in enumerate(case.bodies, start=1):
        sub = subs[b.region] = conductor_submesh3d(mesh, conductor_tag(k))
        if b.rigid:
            continue
        held, sliding = _supports(case, b.name, b.fixed, geo, tol, quadratic=b.element == "tet10")
        v0 = tuple(b.initial_velocity) if len(b.initial_velocity) == 3 else (0.0, 0.0, 0.0)
        specs.append(mech.BodySpec(name=b.name, mesh=to_dolfinx3d(sub, MPI.COMM_SELF),
                                   material=solver_material(case.materials[b.material]), initial_velocity=v0,
                                   fixed=held, sliding=sliding, element=b.element))
    pairs = tuple(mech.ContactPairSpec(slave=c.slave, master=c.master, stiffness=c.stiffness, h0=c.h0,
                                       friction=c.friction, viscosity=c.viscosity, two_pass=c.two_pass)
                  for c in case.contact)
    mo = case.mechanics
    if mo.integrator == "implicit" and specs:
        solver = ImplicitSolver3D(specs, implicit_options(case), comm=MPI.COMM_SELF, contact_pairs=pairs)
    else:
        solver = ExplicitSolver3D(specs, contact_pairs=pairs, cfl=case.time.cfl, bulk_viscosity=mo.bulk_viscosity,
                                  bulk_linear=mo.bulk_viscosity_linear, bulk_quadratic=mo.bulk_viscosity_quadratic,
                                  comm=MPI.COMM_SELF, threads=mo.threads) if specs else None
    dt_mech = solver.stable_time_step() if solver is not None else rigid_step_3d(case)
    if case.coupling.load == "pressure":   # the same meshes and loop, the [[loads]] pulses instead of getdp
        load = pressure_pulses_3d(case, solver, float(model.symmetry_factor), Path(g.file).name)
        load.device_axes = device_axes(geo.planes)
        return solver, None, load, loop_options_3d(case, dt_mech), geo
    rigid = None
    if any(b.rigid for b in case.bodies):
        rigid = RigidMechanics(rigid_bodies(case, subs), dt_mech)
    bodies = []
    for k, b in enumerate(case.bodies, start=1):
        sub = subs[b.region]
        if b.rigid:
            bodies.append(ConductorBody3D(b.name, conductor_tag(k), sub, sub.em_nodes))
            continue
        body = solver.bodies[b.name]   # a ten-node body: its vertex rows first, then the edge nodes (no EM node)
        quadratic = body.element == "tet10"
        nodes = match_nodes3d(body.X0[:body.n_vertices] if quadratic else body.X0, mesh.points, tol)
        bodies.append(ConductorBody3D(b.name, conductor_tag(k), sub, nodes, cells10=body.cells if quadratic else None))
    planes = geo.planes
    mover = air_mover3d(mesh, planes, tol)
    mover.min_quality = g.break_quality * float(mover.q_ref.min())
    args = (mesh, model, work / "getdp", bodies, mover)
    kw = {"time_scheme": case.em.time_scheme, "getdp_process": case.em.getdp_process,
          "getdp_timeout": case.limits.getdp_time_limit_s, "factor_reuse": factor_reuse(case)}
    if g.on_mesh_break == "remesh":   # a failed remesh freezes (orchestrator/em/remesh3d.py)
        load = RemeshingGetDPLoad3D(*args, make_mover=lambda m: air_mover3d(m, planes, tol),
                                    planes=[(p.point, p.normal) for p in planes], **kw)
    else:
        load = FreezingGetDPLoad3D(*args, freeze=g.on_mesh_break == "freeze", **kw)
    load.device_axes = device_axes(planes)
    load.symmetry_planes = tuple(planes)   # no outer surface: the cooling between shots
    options = loop_options_3d(case, dt_mech if solver is not None else None)
    log.info("3D geometry: %d EM tets, bodies %s, mechanical step %.3g s, n = %d", mesh.n_tets,
             {b.name: len(subs[b.region].cells) for b in case.bodies}, dt_mech, options.n)
    return solver, rigid, load, options, geo


def pressure_pulses_3d(case: Case, solver: ExplicitSolver3D, symmetry_factor: float, label: str) -> PressurePulses3D:
    """The ``[[loads]]`` pulses of a pressure-driven 3D geometry-file case (``coupling.load = "pressure"``) on
    ``solver``'s bodies, the device's figures × ``symmetry_factor``; raises :class:`GeometryError` (``label``:
    the geometry file) naming the load whose box holds no boundary triangle of its body."""
    mo = case.mechanics
    load = PressurePulses3D(case.loads, symmetry_factor, mo.mass_damping, mo.mass_damping_until,
                            mo.mass_damping_from, mo.kinetic_damping_until)
    areas = load.loaded_areas(DolfinxMechanics(solver), solver.bodies)
    for i, (ld, a) in enumerate(zip(case.loads, areas)):
        if a <= 0.0:
            raise GeometryError(f"{label}: loads[{i}].surface: the box holds no boundary triangle of body {ld.body!r} "
                                "(all three nodes inside; bounds x, y, z, and rmin/rmax about the z-axis, m)")
    log.info("3D geometry driven by %d pressure pulse(s) on %s m^2 (the model's)", len(case.loads),
             ", ".join(f"{a:.6g}" for a in areas))
    return load


def device_axes(planes: list[PlaneSpec]) -> np.ndarray:
    """1.0 for each axis x, y, z that lies in every symmetry plane (the whole device's resultant along it is the
    model's times the symmetry factor), 0.0 for an axis a plane's mirror image reverses (the device's resultant
    along it vanishes: a z = 0 mid-plane, the x and y of a wedge about z)."""
    return np.array([float(all(abs(p.normal[i]) <= 1e-12 for p in planes)) for i in range(3)])


def rigid_step_3d(case: Case) -> float:
    """The mechanical step (s) of a 3D case whose bodies are all rigid: geometry.em_step / coupling.n, capped
    by time.dt_max (which alone sets it without an EM step); an implicit run: its mechanics.implicit.dt, capped."""
    im = case.mechanics.implicit
    if case.mechanics.integrator == "implicit" and im.dt is not None:
        return im.dt if case.time.dt_max is None else min(im.dt, case.time.dt_max)
    em_step = case.geometry.em_step
    dt = em_step / case.coupling.n if em_step is not None else case.time.dt_max
    return dt if case.time.dt_max is None else min(dt, case.time.dt_max)


def loop_options_3d(case: Case, dt_mech: float | None) -> LoopOptions:
    """The loop's options: ``[coupling]``'s, with n = round(geometry.em_step / ``dt_mech``) when the EM step
    is given (then n_min 1 and n_max n unless adaptive); ``dt_mech`` None (rigid bodies only: their step is
    already em_step / n) and adaptive implicit steps (one mechanical step per EM step, ``coupling.n`` = 1) keep
    coupling.n."""
    cp, em_step = case.coupling, case.geometry.em_step
    if em_step is None or dt_mech is None:
        return LoopOptions.from_coupling(cp)
    implicit = case.mechanics.implicit if case.mechanics.integrator == "implicit" else None
    if implicit is not None and implicit.adaptive:   # the adaptive step sets the EM step: one mechanical step each
        log.info("geometry.em_step = %g s not used: adaptive implicit steps set the EM step (one mechanical step "
                 "per EM step)", em_step)
        return LoopOptions.from_coupling(cp)
    n = max(1, round(em_step / dt_mech))
    if cp.adaptive:
        return LoopOptions.from_coupling(cp, n=n, n_min=min(cp.n_min, n), n_max=max(cp.n_max, n))
    return LoopOptions.from_coupling(cp, n=n, n_min=1, n_max=n)
