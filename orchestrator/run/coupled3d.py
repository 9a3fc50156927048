"""A coupled 3D run of a thin sector of an axisymmetric flat-coil case (issue 20, case (a)).

From a validated axisymmetric ``flat_coil_sheet`` case (``cases/emf_sheet_bulge``): the same coil
turns (rings), bank, sheet, materials and clamp, as a sector of ``sector_deg`` about the z-axis
meshed with tetrahedra (:func:`~pulseform.solvers.getdp.mesh3d.ring_sector_mesh`: the sheet as
its sector face extruded in layers). The sheet's tetrahedra of the EM mesh are the mechanical
mesh (shared nodes); both meridian faces are symmetry planes: n x a = 0 for the field, sliding
planes for the sheet and the air motion (the face at the sector angle is oblique). The loop is the
2D one (:class:`~pulseform.orchestrator.coupling.loop.StaggeredLoop`) with the 3D participants. When the
moved air breaks (``on_mesh_break``), the air is meshed again with the EM state carried
(:class:`~..em.remesh3d.RemeshingGetDPLoad3D`: both meridian faces re-triangulated in their own
coordinates, the axis' nodes kept), the EM mesh freezes or the run stops, as in the racetrack case.
"""

from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from pulseform.solvers import dolfinx as mech
from pulseform.solvers.dolfinx.solver3d import ExplicitSolver3D
from pulseform.solvers.getdp import Circuit, Conductor, DampedSine, Rect
from pulseform.solvers.getdp.mesh import COIL_BASE, SHELL, conductor_tag
from pulseform.solvers.getdp.mesh3d import Mesh3D, ring_sector_mesh
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel

from ..case.model import Case
from ..coupling.loop import LoopOptions, StaggeredLoop
from ..em.frozen3d import FreezingGetDPLoad3D
from ..em.participant3d import ConductorBody3D
from ..em.remesh3d import RemeshingGetDPLoad3D
from ..mech.model import solver_material
from ..mech.participants import DolfinxMechanics
from ..mesh.em_geometry import flat_coil_turns
from ..mesh.motion3d import MeshMover3D, nodes_on_plane
from ..mesh.shared3d import conductor_submesh3d, match_nodes3d, to_dolfinx3d

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SectorOptions:
    """Discretisation of the sector model (lengths in m, times in s).

    ``sector_deg`` the angle; ``h_sheet`` the in-plane element size over the coil (a box from the
    axis to the coil's outer radius + 5 mm, between the coil and the sheet's top) and
    ``sheet_layers`` tetrahedron layers through the sheet; ``h_sheet_out`` the sheet's size elsewhere;
    ``h_coil``, ``h_air`` sizes in the turns and at the sphere; ``em_step`` the target EM step
    (n = em_step / stable mechanical step, the loop's even landing); ``remesh_quality`` the air's worst
    quality as a fraction of the fresh mesh's below which the air mesh counts as broken, ``on_mesh_break``
    what then happens ("remesh", "freeze" or "stop": as ``geometry.on_mesh_break`` of a 3D geometry file);
    ``clamp_rmin`` the sheet is held for r >= clamp_rmin (m; None: the smallest ``xmin`` of the
    axisymmetric case's fixed boxes, none: free).
    """

    sector_deg: float = 2.5
    h_sheet: float = 0.5e-3
    h_sheet_out: float = 1.5e-3
    sheet_layers: int = 4
    h_coil: float = 1.5e-3
    h_air: float = 0.02
    em_step: float = 0.45e-6
    time_scheme: str = "bdf2"
    remesh_quality: float = 0.2
    clamp_rmin: float | None = None
    on_mesh_break: str = "remesh"


#: the sector of the comparison with the axisymmetric demo (docs/coupling.md, "Coupling in 3D"):
#: 1.25 deg, 0.35 mm over the coil, 8 layers through the sheet (33.8k EM tets, 12.2k sheet tets)
DEMO_SECTOR = SectorOptions(sector_deg=1.25, h_sheet=0.35e-3, sheet_layers=8, h_coil=1.5e-3, h_air=0.015)


def sector_options(case: Case) -> SectorOptions:
    """The sector of a coupled 3D case file (``[sector]`` and the ``[geometry]`` sizes, the sheet's
    size resolved: :func:`~..em.skin_depth.with_default_sizes`)."""
    g, s = case.geometry, case.sector
    if s is None:
        from ..case.sector3d import Sector

        s = Sector()
    h = g.mesh_size_sheet
    if h is None:
        raise ValueError("geometry.mesh_size_sheet unresolved: fill the skin-depth defaults first")
    return SectorOptions(sector_deg=s.angle_deg, h_sheet=h, h_sheet_out=s.outer_size(h),
                         sheet_layers=s.layers(g.sheet_thickness, h), h_coil=g.mesh_size_coil, h_air=g.mesh_size_air,
                         em_step=s.em_step, time_scheme=case.em.time_scheme, remesh_quality=s.break_quality,
                         clamp_rmin=s.clamp_rmin, on_mesh_break=s.on_mesh_break)


def sector_participants(case: Case, work: Path, opt: SectorOptions | None = None):
    """(3D solver, 3D GetDP load (remeshing or freezing: ``on_mesh_break``), loop options, EM mesh) of a
    coupled 3D case (the driver's participants); getdp runs in ``work``, within ``limits.getdp_time_limit_s``
    each."""
    opt = sector_options(case) if opt is None else opt
    mesh, _, solver, load = build_sector(case, work, opt)
    n = max(1, round(opt.em_step / solver.stable_time_step()))
    log.info("3D sector %.4g deg: %d EM tets, sheet %d tets, mechanical step %.3g s, n = %d", opt.sector_deg,
             mesh.n_tets, len(solver.bodies[load.bodies[0].name].cells), solver.stable_time_step(), n)
    return solver, load, LoopOptions(n=n, n_min=1, n_max=n), mesh


def sector_planes(alpha: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """(point, unit normal) of the two meridian faces of the sector 0 <= phi <= alpha (rad)."""
    return [(np.zeros(3), np.array([0.0, 1.0, 0.0])), (np.zeros(3), np.array([-math.sin(alpha), math.cos(alpha), 0.0]))]


def sector_mechanics(case: Case, work: Path, opt: SectorOptions):
    """(EM mesh, the sheet's submesh, 3D solver) of the sector of ``case``: the EM mesh meshed in ``work``,
    the sheet cut from it with its clamp and sliding meridian faces (the mechanics of both the coupled and
    the pressure-driven sector: the same nodes)."""
    g = case.geometry
    work = Path(work).resolve()
    turns = flat_coil_turns(g)
    r_coil = max(t.x1 for t in turns)
    sheet = Rect(0.0, g.coil_gap, g.sheet_radius, g.coil_gap + g.sheet_thickness)
    alpha = math.radians(opt.sector_deg)
    box = ((0.0, r_coil + 5e-3, -1e-3, r_coil * math.sin(alpha) + 1e-3, 0.0, sheet.y1), opt.h_sheet)
    mesh = ring_sector_mesh(work / "sector.msh", turns, [sheet], sector_deg=opt.sector_deg, r_air=g.air_radius,
                            r_shell=g.shell_radius, h_coil=opt.h_coil, h_conductor=opt.h_sheet_out, h_air=opt.h_air,
                            conductor_layers=opt.sheet_layers, fine_box=box)
    body = next(b for b in case.bodies if b.region == "workpiece")
    mat = case.materials[body.material]
    sub = conductor_submesh3d(mesh, conductor_tag(1))
    dmsh = to_dolfinx3d(sub, MPI.COMM_SELF)
    tol = 1e-9 * g.shell_radius
    planes = sector_planes(alpha)
    clamp_r = opt.clamp_rmin if opt.clamp_rmin is not None else \
        min((f.where.xmin for f in body.fixed if f.where.xmin is not None), default=None)
    fixed = () if clamp_r is None else ((lambda x: np.hypot(x[0], x[1]) >= clamp_r - tol, (0, 1, 2)),)
    sliding = tuple(((lambda x, n=n: np.abs(n @ x) <= tol), n) for _, n in planes)
    spec = mech.BodySpec(name=body.name, mesh=dmsh, material=solver_material(mat), initial_velocity=(0.0, 0.0, 0.0),
                         fixed=fixed, sliding=sliding)
    mo = case.mechanics
    solver = ExplicitSolver3D([spec], cfl=case.time.cfl, bulk_viscosity=mo.bulk_viscosity,
                              bulk_linear=mo.bulk_viscosity_linear, bulk_quadratic=mo.bulk_viscosity_quadratic,
                              comm=MPI.COMM_SELF)
    return mesh, sub, solver


def sector_air_mover(mesh: Mesh3D, air_radius: float, alpha: float, sheet_tag: int = conductor_tag(1)) -> MeshMover3D:
    """The sector's air motion (also that of a remeshed air): the sheet's nodes follow the body, coil, shell
    and the outer sphere (r >= ``air_radius``, m) stay, both meridian planes (angle ``alpha``, rad) slide."""
    tol = 1e-9 * float(np.linalg.norm(mesh.points, axis=1).max())
    r = np.linalg.norm(mesh.points, axis=1)
    fixed = np.unique(np.concatenate([mesh.tets[(mesh.tet_tags > COIL_BASE) & (mesh.tet_tags < COIL_BASE + 100)].ravel(),
                                      mesh.tets[mesh.tet_tags == SHELL].ravel(),
                                      np.flatnonzero(r >= air_radius * (1 - 1e-9)),
                                      mesh.tets[mesh.tet_tags == sheet_tag].ravel()]))
    return MeshMover3D(mesh.points, mesh.tets, fixed,
                       [(nodes_on_plane(mesh.points, p, n, tol), n) for p, n in sector_planes(alpha)])


def build_sector(case: Case, work: Path, opt: SectorOptions):
    """(EM mesh, EM model, 3D solver, load provider) of the sector of ``case`` (module docstring)."""
    g, em = case.geometry, case.em
    if g is None or g.type != "flat_coil_sheet" or (em.circuit is None and em.current is None):
        raise ValueError("the 3D sector is built from a flat_coil_sheet case on a capacitor bank or a current")
    work = Path(work).resolve()
    mesh, sub, solver = sector_mechanics(case, work, opt)
    c, cur = em.circuit, em.current
    body = next(b for b in case.bodies if b.region == "workpiece")
    mat = case.materials[body.material]
    wave = None if cur is None else DampedSine(cur.amplitude, cur.beta, cur.omega)
    model = EM3DModel(coils=[Coil3D(turns=g.turns, sigma=em.coil_conductivity, waveform=wave)],
                      conductors=[Conductor(mat.electrical_conductivity, name=body.name)],
                      circuit=None if c is None else Circuit(C=c.capacitance, V0=c.voltage, R_ext=c.resistance,
                                                             L_ext=c.inductance),
                      shell=(g.air_radius, g.shell_radius), sector_deg=opt.sector_deg)
    alpha = math.radians(opt.sector_deg)
    b3 = solver.bodies[body.name]
    body_to_em = match_nodes3d(b3.X0, mesh.points, 1e-9 * g.shell_radius)
    mover = sector_air_mover(mesh, g.air_radius, alpha)
    mover.min_quality = opt.remesh_quality * float(mover.q_ref.min())
    args = (mesh, model, work / "getdp", [ConductorBody3D(body.name, conductor_tag(1), sub, body_to_em)], mover)
    kw = {"time_scheme": opt.time_scheme, "getdp_timeout": case.limits.getdp_time_limit_s}
    if opt.on_mesh_break not in ("remesh", "freeze", "stop"):
        raise ValueError(f"on_mesh_break is 'remesh', 'freeze' or 'stop', got {opt.on_mesh_break!r}")
    if opt.on_mesh_break == "remesh":   # a failed remesh freezes (orchestrator/em/remesh3d.py)
        load = RemeshingGetDPLoad3D(*args, make_mover=lambda m: sector_air_mover(m, g.air_radius, alpha),
                                    planes=sector_planes(alpha), **kw)
    else:
        load = FreezingGetDPLoad3D(*args, freeze=opt.on_mesh_break == "freeze", **kw)
    return mesh, model, solver, load


def run_sector(case: Case, out: Path, opt: SectorOptions = SectorOptions(), t_end: float | None = None) -> dict:
    """Run the coupled sector to ``t_end`` (s; default the case's end time); writes ``history.csv`` and
    ``metrics.json`` in ``out`` and returns the metrics (SI units in the names; ``device_*`` scaled by
    360 / sector angle)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    w0 = time.perf_counter()
    mesh, model, solver, load = build_sector(case, out, opt)
    w1 = time.perf_counter()
    mechanics = DolfinxMechanics(solver)
    n = max(1, round(opt.em_step / solver.stable_time_step()))
    loop = StaggeredLoop(load, mechanics, LoopOptions(n=n, n_min=1, n_max=n))
    t_end = case.time.end if t_end is None else t_end
    body = load.bodies[0].name
    b = solver.bodies[body]
    rows = []

    def record(row: dict) -> None:
        uz = b.x[:, 2] - b.X0[:, 2]
        speed = np.linalg.norm(b.v, axis=1)
        rows.append({"time_s": mechanics.time, **row, "max_uz_m": float(np.abs(uz).max()), "max_speed_m_s": float(speed.max())})

    loop.run_until(t_end, on_em_step=record)
    w2 = time.perf_counter()
    load.close()
    keys = list(rows[0])
    np.savetxt(out / "history.csv", np.array([[r[k] for k in keys] for r in rows]), delimiter=",",
               header=",".join(keys), comments="")
    s = float(model.symmetry_factor)
    c = loop.counters
    e = solver.energies()
    metrics = {"max_deflection_mm": 1e3 * max(r["max_uz_m"] for r in rows),
               "impulse_sector_Ns": float(c.impulse[2]), "impulse_device_Ns": s * float(c.impulse[2]),
               "force_peak_device_N": float(np.abs([r["device_force_z_N"] for r in rows]).max()),
               "coil_current_peak_kA": float(np.abs([r["coil_current_A"] for r in rows]).max()) / 1e3,
               "max_speed_m_s": max(r["max_speed_m_s"] for r in rows),
               "conservation_error_rel": float(c.ledger_max), "plastic_work_device_J": s * e["plastic_J"],
               "energy_balance_error_rel": e["balance_error_J"] / max(e["external_work_J"], 1e-300),
               "em_steps": c.em_steps, "mech_steps": solver.step_count, "n": n,
               "em_tets": mesh.n_tets, "em_nodes": mesh.n_nodes, "sheet_tets": len(b.cells), "sheet_nodes": b.n_owned,
               "em_time_s": c.em_time_s, "mech_time_s": c.mech_time_s, "setup_s": w1 - w0, "wall_s": w2 - w0,
               "em_ms_per_step": 1e3 * c.em_time_s / max(c.em_steps, 1),
               "mech_ms_per_step": 1e3 * c.mech_time_s / max(solver.step_count, 1),
               **{f"em_{k}": v for k, v in load.timers.items()}, **{f"getdp_{k}": v for k, v in load.state.timers.items()},
               "min_em_quality": load.min_quality, "em_remeshes": int(getattr(load, "remeshes", 0)),
               "options": asdict(opt)}
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2))
    log.info("3D sector run: %s", metrics)
    return metrics
