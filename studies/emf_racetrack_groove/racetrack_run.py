"""The coupled 3D racetrack case (issue 20, case (b)): a racetrack coil forms a rectangular aluminium
sheet into the groove of a deformable steel die.

The study's own runner of the quarter model of :mod:`design` (planes x = 0 and y = 0) meshed by
:func:`~pulseform.solvers.getdp.racetrack_mesh.racetrack_groove_mesh`. The sheet's and the die's
tetrahedra of the EM mesh are the two mechanical bodies (shared nodes,
:mod:`~pulseform.orchestrator.mesh.shared3d`); both conduct and both get their Lorentz forces
(:class:`~pulseform.orchestrator.em.participant3d.GetDPLoad3D` with two bodies). Supports:

* symmetry: nodes of either body on x = 0 keep u_x = 0, on y = 0 u_y = 0 (rollers; the field has
  n x a = 0 there, the air slides in the planes);
* the sheet's far edges (x = ``sheet_half_x`` and y = ``sheet_half_y``) are clamped (all components
  zero: the blank holder's grip); between them the sheet is held only by the die's flats, through
  contact;
* the die's top face (z = top) is fixed (all components): the press holds the die there; the rest of
  the die deforms elastically under the sheet's impact and its own Lorentz force;
* soft contact sheet (slave) - die (master), eq. (5) node to face with Coulomb friction
  (:mod:`~pulseform.solvers.dolfinx.contact3d`).

The loop is the 2D :class:`~pulseform.orchestrator.coupling.loop.StaggeredLoop` (BDF2 EM steps of
``em_step``, each held over n mechanical steps); the air moves harmonically
(:class:`~pulseform.orchestrator.mesh.motion3d.MeshMover3D`), coil, shell and the outer sphere stay.
Outputs (:func:`run_racetrack`): ``history.csv``, ``metrics.json``, ``fields/mech_{sheet,die}.xdmf``
(+ .h5) at the output times, ``em/force_density_peak.vtu`` (per-tet Lorentz force density at the
peak coil current) and ``em/force_density_peak.npz`` for the pictures (:mod:`racetrack_pictures`).

It was ``pulseform.orchestrator.run.coupled_racetrack`` until the case file moved to the 3D geometry path
(issue 29): the product now runs the case through the driver (``pulseform run cases/emf_racetrack_groove``,
orchestrator/run/participants3d.py), which reproduces this runner's reference to round-off
(tests/coupling/test_case_racetrack.py); this runner stays as the study's reference and its per-body
bookkeeping (momentum vs free impulse, the force density of both bodies at the peak current).
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from mpi4py import MPI

from pulseform.solvers import dolfinx as mech
from pulseform.solvers.dolfinx.output import FieldWriter
from pulseform.solvers.dolfinx.solver3d import ExplicitSolver3D
from pulseform.solvers.getdp import Circuit
from pulseform.solvers.getdp.mesh import COIL_BASE, SHELL, conductor_tag
from pulseform.solvers.getdp.mesh3d import Mesh3D
from pulseform.solvers.getdp.racetrack_mesh import DIE, SHEET, RacetrackGroove, racetrack_groove_mesh
from pulseform.solvers.getdp.solver3d import EM3DModel

from pulseform.orchestrator.coupling.loop import LoopOptions, StaggeredLoop
from pulseform.orchestrator.em.frozen3d import FreezingGetDPLoad3D
from pulseform.orchestrator.em.remesh3d import RemeshingGetDPLoad3D
from pulseform.orchestrator.em.participant3d import ConductorBody3D
from pulseform.orchestrator.mech.participants import DolfinxMechanics
from pulseform.orchestrator.mesh.motion import MeshQualityError
from pulseform.orchestrator.mesh.motion3d import MeshMover3D, nodes_on_plane
from pulseform.orchestrator.mesh.shared3d import conductor_submesh3d, match_nodes3d, to_dolfinx3d
from design import (DIE_MATERIAL, RACETRACK, RACETRACK_BANK, SHEET_MATERIAL, SIGMA_COIL, SIGMA_DIE,
                    SIGMA_SHEET, em_model)

log = logging.getLogger(__name__)

#: Newton's check (momentum = impulse of the held forces on the free nodes) holds until the supports
#: react: the sheet's clamp is 16 mm from the coil's outer edge (a dilatational wave needs ~3 us); the
#: die's fixed top is 6 mm above the groove (~1 us at 5.9 km/s), one or two elements: it reacts at once,
#: and its figure is only reported. The check is made up to these times (s)
MOMENTUM_CHECK_S = {"sheet": 3e-6, "die": 1e-6}
#: the planes of the quarter model: (point, unit normal)
PLANES = ((np.zeros(3), np.array([1.0, 0.0, 0.0])), (np.zeros(3), np.array([0.0, 1.0, 0.0])))


@dataclass(frozen=True)
class RacetrackOptions:
    """The coupled racetrack run (SI units: m, s, Pa m).

    ``geometry`` and ``bank`` (:mod:`design`); ``em_step`` the target EM step (n = em_step
    / the stable mechanical step); ``t_end`` the end of the run and ``outputs`` the number of equal
    intervals at whose ends the fields are written; ``contact_stiffness`` k (Pa m) and ``contact_h0`` (m,
    below the sheet-die gap, so the layer is open at t = 0) of eq. (5): the layer's energy
    k (ln(h0/h) - (h0 - h)/h0) per unit area stops a 1 mm Al sheet at ~150 m/s (30 kJ/m^2) near h = 0.4 h0
    at p ~ 300 MPa, where k / h^2 ~ 3e12 Pa/m stays far below E / dx (~2e14; SOLVER_NOTES' rule of
    thumb); a 100x stiffer layer stopped it within microns at GPa pressures and slung a node at
    1.7 km/s. ``friction`` (Coulomb); ``contact_two_pass``: the die's nodes are also pushed off the sheet's
    faces (each pass with half the force): with the sheet's nodes alone, the groove's edge cut into the
    sheet from 40 us on (2-6 die nodes inside sheet tetrahedra), the air between them inverted at 36.4 us
    and the draw came out 4.745 mm instead of 4.394 mm;
    ``remesh_quality`` the air's worst mean-ratio quality, as a fraction of the fresh mesh's, below
    which the air mesh counts as broken, ``on_mesh_break`` what then happens: "remesh" (default: the air
    is meshed again with the EM state carried, :mod:`~pulseform.orchestrator.em.remesh3d`; a remesh that
    fails freezes), "freeze" (the EM mesh stays at the last valid one,
    :mod:`~pulseform.orchestrator.em.frozen3d`) or "stop" (the run ends there, its outputs kept); ``cfl``
    the mechanics' safety factor. ``sheet_material`` and ``die_material`` the bodies' mechanics, ``sigma``
    the conductivities (S/m) of the sheet, the die and the coil, ``getdp_timeout`` the wall-time limit of a
    getdp answer (s; None: the runner's default).
    ``em_order`` 1 or 2 and ``em_order2_air`` (:class:`EM3DModel`'s ``order``, ``order2_air``): the EM
    deck's edge elements (docs/em_geometries.md, racetrack: the figures of order 2); order 2 cannot remesh
    (``on_mesh_break`` "freeze" or "stop"); the case file sets ``geometry.em_order`` (with the air first order).
    """

    geometry: RacetrackGroove = RACETRACK
    bank: Circuit = field(default_factory=lambda: RACETRACK_BANK)
    em_step: float = 1e-6
    time_scheme: str = "bdf2"
    t_end: float = 60e-6
    outputs: int = 6
    contact_stiffness: float = 1e5
    contact_h0: float = 0.5e-3
    friction: float = 0.1
    remesh_quality: float = 1e-3
    cfl: float = 0.5
    on_mesh_break: str = "remesh"
    sheet_material: mech.Material = field(default_factory=lambda: SHEET_MATERIAL)
    die_material: mech.Material = field(default_factory=lambda: DIE_MATERIAL)
    sigma: tuple[float, float, float] = (SIGMA_SHEET, SIGMA_DIE, SIGMA_COIL)
    getdp_timeout: float | None = None
    contact_two_pass: bool = True
    em_order: int = 1
    em_order2_air: bool = True


@dataclass
class RacetrackModel:
    """What :func:`build_racetrack` builds: the EM mesh and model, the 3D solver, the load provider,
    and per body the reference-coordinate masks of its clamped nodes (``clamped``)."""

    mesh: Mesh3D
    model: EM3DModel
    solver: ExplicitSolver3D
    load: FreezingGetDPLoad3D
    clamped: dict[str, np.ndarray]


def build_racetrack(work: Path, opt: RacetrackOptions = RacetrackOptions()) -> RacetrackModel:
    """Mesh the quarter model and build the participants (module docstring) in ``work``."""
    g = opt.geometry
    work = Path(work).resolve()
    mesh = racetrack_groove_mesh(work / "racetrack.msh", g)
    model = em_model(g, opt.bank, sigma=opt.sigma)
    if opt.em_order != 1:
        model = replace(model, order=opt.em_order, order2_air=opt.em_order2_air)
    tol = 1e-9 * g.air_radius
    subs = {name: conductor_submesh3d(mesh, conductor_tag(k)) for name, k in (("sheet", SHEET), ("die", DIE))}
    x_edge, y_edge, z_top = g.sheet_half_x - tol, g.sheet_half_y - tol, g.die_z[1] - tol
    sym = ((lambda x: np.abs(x[0]) <= tol, (0,)), (lambda x: np.abs(x[1]) <= tol, (1,)))
    sheet_clamp = (lambda x: (x[0] >= x_edge) | (x[1] >= y_edge), (0, 1, 2))
    die_top = (lambda x: x[2] >= z_top, (0, 1, 2))
    specs = [mech.BodySpec(name="sheet", mesh=to_dolfinx3d(subs["sheet"], MPI.COMM_SELF), material=opt.sheet_material,
                           initial_velocity=(0.0, 0.0, 0.0), fixed=sym + (sheet_clamp,)),
             mech.BodySpec(name="die", mesh=to_dolfinx3d(subs["die"], MPI.COMM_SELF), material=opt.die_material,
                           initial_velocity=(0.0, 0.0, 0.0), fixed=sym + (die_top,))]
    pair = mech.ContactPairSpec(slave="sheet", master="die", stiffness=opt.contact_stiffness, h0=opt.contact_h0,
                                friction=opt.friction, two_pass=opt.contact_two_pass)
    solver = ExplicitSolver3D(specs, contact_pairs=(pair,), cfl=opt.cfl, comm=MPI.COMM_SELF)
    bodies, clamped = [], {}
    for name, k in (("sheet", SHEET), ("die", DIE)):
        b = solver.bodies[name]
        bodies.append(ConductorBody3D(name, conductor_tag(k), subs[name], match_nodes3d(b.X0, mesh.points, tol)))
        marker = sheet_clamp[0] if name == "sheet" else die_top[0]
        clamped[name] = np.asarray(marker(b.X0.T), dtype=bool)
    mover = air_mover(mesh, g)
    mover.min_quality = opt.remesh_quality * float(mover.q_ref.min())
    if opt.on_mesh_break not in ("remesh", "freeze", "stop"):
        raise ValueError(f"on_mesh_break is 'remesh', 'freeze' or 'stop', got {opt.on_mesh_break!r}")
    if opt.on_mesh_break == "remesh":   # a failed remesh freezes (orchestrator/em/remesh3d.py)
        load = RemeshingGetDPLoad3D(mesh, model, work / "getdp", bodies, mover, time_scheme=opt.time_scheme,
                                    make_mover=lambda m: air_mover(m, g), planes=PLANES,
                                    getdp_timeout=opt.getdp_timeout)
    else:
        load = FreezingGetDPLoad3D(mesh, model, work / "getdp", bodies, mover, time_scheme=opt.time_scheme,
                                   freeze=opt.on_mesh_break == "freeze", getdp_timeout=opt.getdp_timeout)
    return RacetrackModel(mesh, model, solver, load, clamped)


def air_mover(mesh: Mesh3D, g: RacetrackGroove) -> MeshMover3D:
    """The air follows: both bodies prescribed, coil, shell and the outer sphere fixed, the planes sliding
    (also the motion of a remeshed air)."""
    tol = 1e-9 * g.air_radius
    r = np.linalg.norm(mesh.points, axis=1)
    coil = mesh.tets[(mesh.tet_tags > COIL_BASE) & (mesh.tet_tags < COIL_BASE + 100)].ravel()
    bodies = mesh.tets[np.isin(mesh.tet_tags, [conductor_tag(SHEET), conductor_tag(DIE)])].ravel()
    fixed = np.unique(np.concatenate([coil, mesh.tets[mesh.tet_tags == SHELL].ravel(),
                                      np.flatnonzero(r >= g.air_radius * (1 - 1e-9)), bodies]))
    return MeshMover3D(mesh.points, mesh.tets, fixed, [(nodes_on_plane(mesh.points, p, n, tol), n) for p, n in PLANES])


def momentum(solver: ExplicitSolver3D, name: str) -> np.ndarray:
    """Σ m v (kg m/s) of a body's owned nodes (the half-step velocities)."""
    b = solver.bodies[name]
    return (b.mass[: b.n_owned, None] * b.v[: b.n_owned]).sum(axis=0)


class RacetrackRecorder:
    """History rows, per-body impulses (all nodes, and the clamped nodes' share), the momentum check
    and the force density at the peak coil current."""

    def __init__(self, rm: RacetrackModel, mechanics: DolfinxMechanics):
        self.rm, self.mech = rm, mechanics
        self.rows: list[dict] = []
        self.impulse = {n: np.zeros(3) for n in rm.clamped}
        self.clamp_impulse = {n: np.zeros(3) for n in rm.clamped}
        # the first velocity update of a run is a half step: the first held force lands dt/2 short
        self.half_step = {n: np.zeros(3) for n in rm.clamped}
        self.first_contact_s = np.nan
        self.peak_current = -1.0
        self.peak: dict | None = None

    def __call__(self, row: dict) -> None:
        s, load = self.rm.solver, self.rm.load
        h = row["dt_s"] * row["substeps"]
        forces = load.last_forces
        for n in self.impulse:
            f = forces[n][: s.bodies[n].n_owned]
            free = f[~self.rm.clamped[n][: s.bodies[n].n_owned]].sum(axis=0)
            if not self.rows:
                self.half_step[n] = 0.5 * row["dt_s"] * free
            self.impulse[n] += h * f.sum(axis=0)
            self.clamp_impulse[n] += h * (f.sum(axis=0) - free)
        sheet, die = s.bodies["sheet"], s.bodies["die"]
        _, _, p, _ = s.contact_pressure(0)
        if p.size and not np.isfinite(self.first_contact_s):
            self.first_contact_s = self.mech.time
        out = {"time_s": self.mech.time, **row,
               "sheet_max_uz_m": float((sheet.x[:, 2] - sheet.X0[:, 2]).max()),
               "sheet_min_uz_m": float((sheet.x[:, 2] - sheet.X0[:, 2]).min()),
               "die_max_u_m": float(np.linalg.norm(die.x - die.X0, axis=1).max()),
               "sheet_max_speed_m_s": float(np.linalg.norm(sheet.v, axis=1).max()),
               "contact_nodes": float(p.size), "contact_pressure_max_Pa": float(p.max()) if p.size else 0.0,
               **{f"{n}_momentum_z_kg_m_s": float(momentum(s, n)[2]) for n in self.impulse},
               **{f"{n}_impulse_z_Ns": float(self.impulse[n][2]) for n in self.impulse},
               **{f"{n}_free_impulse_z_Ns": float(self.impulse[n][2] - self.clamp_impulse[n][2] - self.half_step[n][2])
                  for n in self.impulse},
               "plastic_J": s.energies()["plastic_J"]}
        self.rows.append(out)
        current = abs(row["coil_current_A"])
        if current > self.peak_current:
            self.peak_current = current
            x_em, result = load.last
            keep = np.isin(result.element_tags, load.tags)
            self.peak = {"time_s": self.mech.time, "points": x_em.copy(), "reference_points": load.mesh.points,
                         "tets": load.mesh.tets[result.elements[keep]], "tags": result.element_tags[keep],
                         "force_density": result.force_density_mean[keep], "coil_current_A": row["coil_current_A"]}


def run_racetrack(out: Path, opt: RacetrackOptions = RacetrackOptions()) -> dict:
    """Run the coupled racetrack case to ``opt.t_end``; writes the outputs of the module docstring in
    ``out`` and returns the metrics (SI units in the names; ``device_*``: times 4, the whole device)."""
    out = Path(out)
    (out / "fields").mkdir(parents=True, exist_ok=True)
    w0 = time.perf_counter()
    rm = build_racetrack(out, opt)
    w1 = time.perf_counter()
    solver, load = rm.solver, rm.load
    mechanics = DolfinxMechanics(solver)
    n = max(1, round(opt.em_step / solver.stable_time_step()))
    loop = StaggeredLoop(load, mechanics, LoopOptions(n=n, n_min=1, n_max=n))
    rec = RacetrackRecorder(rm, mechanics)
    writer = FieldWriter(solver, out / "fields" / "mech")
    writer.write(0.0)
    e_out, stopped = [], ""
    try:
        for k in range(1, opt.outputs + 1):
            t_k = opt.t_end * k / opt.outputs
            try:
                loop.run_until(t_k, on_em_step=rec)
            except MeshQualityError as err:   # on_mesh_break="stop": the run ends here, its outputs are kept
                stopped = f"t = {mechanics.time:.4g} s: {err}"
                log.error("racetrack run stopped at %s", stopped)
                writer.write(mechanics.time)
                break
            writer.write(t_k)
            e_out.append({"time_s": t_k, **solver.energies()})
    finally:
        writer.close()
        load.close()
    w2 = time.perf_counter()
    rows = rec.rows
    keys = list(rows[0])
    np.savetxt(out / "history.csv", np.array([[r.get(k, np.nan) for k in keys] for r in rows]), delimiter=",",
               header=",".join(keys), comments="")
    if rec.peak is not None:
        write_force_density(out / "em", rec.peak)
    metrics = racetrack_metrics(rm, loop, rec, opt, n, wall=(w0, w1, w2))
    metrics["energies_at_outputs"] = e_out
    metrics["stopped"] = stopped
    metrics["em_mesh_frozen_at_s"] = load.frozen_at if load.frozen_at is not None else float("nan")
    metrics["em_mesh_freeze_reason"] = load.freeze_reason
    if load.frozen_at is not None:
        late = [r for r in rows if r.get("em_mesh_frozen", 0.0) > 0]
        metrics["impulse_after_freeze_device_z_Ns"] = float(rm.model.symmetry_factor) * sum(
            r["force_z_N"] * r["dt_s"] * r["substeps"] for r in late)
    metrics["em_remeshes"] = int(getattr(load, "remeshes", 0))
    metrics["em_remesh_log"] = list(getattr(load, "remesh_log", []))
    metrics["end_time_s"] = mechanics.time
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2, default=float))
    log.info("racetrack run: %s", {k: v for k, v in metrics.items() if not isinstance(v, (dict, list))})
    return metrics


def write_force_density(folder: Path, peak: dict) -> Path:
    """The per-tet Lorentz force density (N/m^3) of the conductors at the peak coil current as a VTU
    (ParaView) and an npz (the pictures); returns the VTU's path."""
    import meshio

    folder.mkdir(parents=True, exist_ok=True)
    used, inv = np.unique(peak["tets"], return_inverse=True)
    cells = inv.reshape(-1, 4)
    f = np.asarray(peak["force_density"], float)
    body = np.where(peak["tags"] == conductor_tag(SHEET), 0, 1)
    m = meshio.Mesh(peak["points"][used], [("tetra", cells)],
                    cell_data={"force_density_N_m3": [f], "force_density_magnitude_N_m3": [np.linalg.norm(f, axis=1)],
                               "body_0sheet_1die": [body.astype(float)]})
    path = folder / "force_density_peak.vtu"
    m.write(path)
    np.savez(folder / "force_density_peak.npz", points=peak["points"][used], cells=cells, force_density=f, body=body,
             reference_points=peak["reference_points"][used],
             time_s=peak["time_s"], coil_current_A=peak["coil_current_A"])
    return path


def racetrack_metrics(rm: RacetrackModel, loop: StaggeredLoop, rec: RacetrackRecorder, opt: RacetrackOptions, n: int,
                      wall: tuple[float, float, float]) -> dict:
    """The run's figures (SI units in the names)."""
    s, c, rows, solver = float(rm.model.symmetry_factor), loop.counters, rec.rows, rm.solver
    e = solver.energies()
    w0, w1, w2 = wall
    fz = np.array([r["force_z_N"] for r in rows])
    mom = {}
    for nme, until in (("sheet", MOMENTUM_CHECK_S["sheet"]), ("die", MOMENTUM_CHECK_S["die"])):
        early = [r for r in rows if r["time_s"] <= until * (1 + 1e-9)] or rows[:1]
        mom[f"{nme}_momentum_vs_impulse_rel"] = max(
            abs(r[f"{nme}_momentum_z_kg_m_s"] - r[f"{nme}_free_impulse_z_Ns"]) / max(abs(r[f"{nme}_free_impulse_z_Ns"]), 1e-300)
            for r in early)
        mom[f"{nme}_momentum_check_until_s"] = float(early[-1]["time_s"])
    return {"max_deflection_into_groove_mm": 1e3 * max(r["sheet_max_uz_m"] for r in rows),
            "sheet_min_uz_mm": 1e3 * min(r["sheet_min_uz_m"] for r in rows),
            "die_max_displacement_mm": 1e3 * max(r["die_max_u_m"] for r in rows),
            "impulse_quarter_Ns": c.impulse.tolist(), "impulse_device_z_Ns": s * float(c.impulse[2]),
            "sheet_impulse_device_z_Ns": s * float(rec.impulse["sheet"][2]),
            "die_impulse_device_z_Ns": s * float(rec.impulse["die"][2]),
            "force_peak_device_z_N": s * float(np.abs(fz).max()),
            "sheet_force_peak_device_z_N": s * float(np.abs([r["sheet_force_z_N"] for r in rows]).max()),
            "die_force_peak_device_z_N": s * float(np.abs([r["die_force_z_N"] for r in rows]).max()),
            "coil_current_peak_kA": rec.peak_current / 1e3,
            "t_peak_current_s": rec.peak["time_s"] if rec.peak else np.nan,
            "contact_pressure_peak_Pa": max(r["contact_pressure_max_Pa"] for r in rows),
            "first_contact_s": rec.first_contact_s, "max_sheet_speed_m_s": max(r["sheet_max_speed_m_s"] for r in rows),
            "conservation_error_rel": float(c.ledger_max),
            "sheet_ledger_rel": max(r["sheet_ledger_rel"] for r in rows),
            "die_ledger_rel": max(r["die_ledger_rel"] for r in rows), **mom,
            "plastic_work_device_J": s * e["plastic_J"], "kinetic_device_J": s * e["kinetic_J"],
            "external_work_device_J": s * e["external_work_J"],
            "energy_balance_error_rel": e["balance_error_J"] / max(abs(e["external_work_J"]), 1e-300),
            "em_steps": c.em_steps, "mech_steps": solver.step_count, "n": n,
            "em_tets": rm.mesh.n_tets, "em_nodes": rm.mesh.n_nodes,
            "sheet_tets": len(solver.bodies["sheet"].cells), "die_tets": len(solver.bodies["die"].cells),
            "sheet_nodes": solver.bodies["sheet"].n_owned, "die_nodes": solver.bodies["die"].n_owned,
            "em_time_s": c.em_time_s, "mech_time_s": c.mech_time_s, "setup_s": w1 - w0, "wall_s": w2 - w0,
            "em_s_per_step": c.em_time_s / max(c.em_steps, 1),
            "mech_ms_per_step": 1e3 * c.mech_time_s / max(solver.step_count, 1),
            **{f"em_{k}": v for k, v in rm.load.timers.items()},
            **{f"getdp_{k}": v for k, v in rm.load.state.timers.items()},
            "min_em_quality": rm.load.min_quality, "em_quality_floor": float(rm.load.mover.min_quality),
            "options": asdict(opt)}
