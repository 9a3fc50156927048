"""Set-ups of the verification problems (paper section 4 bar impact), shared by ``pulseform validate``
(its bar-impact entries), the solver's tests, the MPI check and the viscosity study
(``studies/bar_impact/``). Each returns plain histories; metrics come from :mod:`.analysis`."""
from __future__ import annotations

import logging
from typing import Dict, Optional, Sequence

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from .analysis import contact_stress_metrics
from .body import BodySpec
from .contact import ContactPairSpec, RigidWallSpec
from .material import Material
from .solver import ExplicitSolver

__all__ = ["PAPER_BAR_MATERIAL", "bar_impact", "bar_impact_3d"]

log = logging.getLogger(__name__)

#: Paper section 4: rho 2800 kg/m3, G 26.5 GPa, K 65.1 GPa, sigma_s = 0.24 + 0.56 eps GPa.
PAPER_BAR_MATERIAL = Material(2800.0, 26.5e9, 65.1e9, 0.24e9, 0.56e9)


def bar_impact(nx: int = 40, ny: int = 20, formulation: str = "plane_stress",
               rigid_wall: bool = False, t_end: Optional[float] = None, stiffness: float = 1e8,
               h0: float = 0.01, viscosity: float = 0.0, cfl: float = 0.5,
               bulk_viscosity: bool = True, comm=MPI.COMM_WORLD,
               material: Material = PAPER_BAR_MATERIAL, wall_sliding: bool = False,
               element: str = "tet4") -> Dict[str, object]:
    """Paper section 4: bars 4 m (x) by 2 m (y); the left one at 10 m/s hits the resting right one
    across a soft layer of width h0 (initial gap h0), or, with ``rigid_wall``, one bar at 5 m/s
    hits a rigid wall at x0 = 4 + h0/2 (contact then starts at t = h0 / (2 x 5 m/s) = 1 ms).
    ``t_end`` defaults to 2 ms after the first contact; ``element``: the bars' ("tet4": linear triangles,
    "tri6": six-node ones, one process).

    Returns
    -------
    dict
        ``t`` (s), ``stress`` (Pa, contact stress at the middle of the contact surface: soft
        contact stress at the left bar's node (4, 1), or the wall reaction per area there),
        ``energies`` (list of energy dicts), ``ke0`` (J), ``metrics`` (see
        :func:`.analysis.contact_stress_metrics`, plus ``energy_error_rel``), ``solver``.
    """
    if t_end is None:
        t_end = 2.0e-3 + (0.5 * h0 / 5.0 if rigid_wall else 0.0)
    left = dmesh.create_rectangle(comm, [np.array([0.0, 0.0]), np.array([4.0, 2.0])], [nx, ny])
    bodies = [BodySpec("left", left, material, initial_velocity=(5.0 if rigid_wall else 10.0, 0.0), element=element)]
    pairs, walls = (), ()
    if rigid_wall:
        walls = (RigidWallSpec(point=(4.0 + 0.5 * h0, 0.0), normal=(-1.0, 0.0), sliding=wall_sliding),)
    else:
        right = dmesh.create_rectangle(comm, [np.array([4.0 + h0, 0.0]),
                                              np.array([8.0 + h0, 2.0])], [nx, ny])
        bodies.append(BodySpec("right", right, material, element=element))
        pairs = (ContactPairSpec("left", "right", stiffness=stiffness, h0=h0,
                                 viscosity=viscosity),)
    solver = ExplicitSolver(bodies, formulation=formulation, contact_pairs=pairs,
                            rigid_walls=walls, cfl=cfl, bulk_viscosity=bulk_viscosity, comm=comm)
    ke0 = solver.energies()["kinetic_J"]
    probe = np.array([4.0, 1.0])
    b = solver.bodies["left"]
    d = np.linalg.norm(b.X0[: b.n_owned] - probe, axis=1)
    cand = comm.allgather((float(d.min()) if d.size else np.inf, comm.rank))
    owner = min(cand)[1]
    row = int(np.argmin(d)) if comm.rank == owner else -1
    ts, ss, es = [0.0], [0.0], [solver.energies()]
    dt = solver.stable_time_step()
    while solver.time < t_end - 1e-12:
        solver.advance(min(dt, t_end - solver.time))
        if rigid_wall:
            val = 0.0
            if comm.rank == owner:
                rows, _, p = solver.wall_pressure(0, "left")
                hitrow = np.flatnonzero(rows == row)
                val = float(p[hitrow[0]]) if hitrow.size else 0.0
            val = comm.bcast(val, root=owner)
        else:
            val = solver.contact_pressure_at(0, probe)
        ts.append(solver.time)
        ss.append(val)
        es.append(solver.energies())
        dt = solver.stable_time_step()
    t = np.array(ts)
    s = np.array(ss)
    try:
        metrics = contact_stress_metrics(t, s)
    except ValueError as err:       # e.g. t_end before the end of the contact
        log.warning("bar impact: no contact metrics (%s)", err)
        metrics = {}
    metrics["energy_error_rel"] = max(abs(e["balance_error_J"]) for e in es) / ke0
    return {"t": t, "stress": s, "energies": es, "ke0": ke0, "metrics": metrics, "solver": solver}


def _box(comm, lo, hi, n):
    """``create_box`` of tetrahedra (six per brick) from ``lo`` to ``hi`` (m), ``n`` bricks."""
    return dmesh.create_box(comm, [np.array(lo, float), np.array(hi, float)], n,
                            dmesh.CellType.tetrahedron)


def bar_impact_3d(nx: int = 40, ny: int = 10, quarter: bool = True, t_end: Optional[float] = None,
                  h0: float = 0.01, speed: float = 5.0, soft_plane: bool = False,
                  two_body: bool = False, stiffness: float = 1e8, viscosity: float = 0.0,
                  cfl: float = 0.5, bulk_viscosity: bool = True,
                  comm=MPI.COMM_WORLD, material: Material = PAPER_BAR_MATERIAL,
                  element: str = "tet4", probe: Optional[Sequence[float]] = None,
                  ) -> Dict[str, object]:
    """Paper section 4 in 3D, the rigid-wall form: a bar 4 m long (x) with a 2 m x 2 m cross
    section (the paper's 2 m x 4 m bodies given a 2 m depth) at 5 m/s hits a frictionless rigid
    wall at x0 = 4 + h0/2 (the symmetry plane of the two-body impact at 10 m/s; contact starts at
    h0 / (2 x 5 m/s) = 1 ms). Linear tetrahedra (``dolfinx.mesh.create_box``, six per brick).

    Parameters
    ----------
    nx, ny : int
        Bricks along the length and along each side of the (modelled) cross section.
    quarter : bool
        Model the quarter y, z >= 0 (1 m x 1 m) with roller conditions on the symmetry planes
        y = 0 and z = 0 (default), or the full 2 m x 2 m section.
    t_end : float, optional
        End time, s; default 2 ms after the first contact.
    speed : float
        Impact speed, m/s (5: the paper's; faster for a plastic impact).
    soft_plane : bool
        Instead of the wall, a rigid plane at x = 4 + h0 with the soft layer of eq. (5)
        (``stiffness`` k in Pa m, width ``h0``): the bar enters the layer at t = 0.
    two_body : bool
        The paper's own set-up: the bar at 2 x ``speed`` hits an equal bar at rest across a soft
        layer (node to face, ``stiffness``, ``h0``, ``viscosity``), the second bar starting at
        x = 4 + h0; the stress is the contact stress at the first bar's face centre.
    element : {"tet4", "tet10"}
        The bars' element (:attr:`.body.BodySpec.element`).
    probe : (3,) floats, optional
        Where the stress is read (the node nearest it in the reference configuration), m; default the
        middle of the contact face, (4, 0, 0) for the quarter, (4, 1, 1) for the full section.

    Returns
    -------
    dict
        ``t`` (s), ``stress`` (Pa: the wall reaction per (projected) area at the middle of the
        contact face (4, 0, 0), resp. (4, 1, 1)), ``energies``, ``ke0`` (J), ``metrics``
        (:func:`.analysis.contact_stress_metrics` + ``energy_error_rel``), ``solver``, ``steps``,
        ``loop_s`` (wall time of the step loop, s), ``cells`` (global number of tetrahedra).
    """
    import time as _time

    from .soft_plane import SoftPlaneSpec
    from .solver3d import ExplicitSolver3D

    if t_end is None:
        t_end = 2.2e-3 if (soft_plane or two_body) else 2.0e-3 + 0.5 * h0 / speed
    side = 1.0 if quarter else 2.0
    msh = _box(comm, [0.0, 0.0, 0.0], [4.0, side, side], [nx, ny, ny])
    fixed = ()
    if quarter:
        fixed = ((lambda x: np.isclose(x[1], 0.0), (1,)), (lambda x: np.isclose(x[2], 0.0), (2,)))
    walls, planes, pairs = (), (), ()
    bodies = []
    if two_body:
        right = _box(comm, [4.0 + h0, 0.0, 0.0], [8.0 + h0, side, side], [nx, ny, ny])
        bodies.append(BodySpec("right", right, material, initial_velocity=(0.0, 0.0, 0.0),
                               fixed=fixed, element=element))
        pairs = (ContactPairSpec("bar", "right", stiffness=stiffness, h0=h0, viscosity=viscosity),)
    elif soft_plane:
        planes = (SoftPlaneSpec(point=(4.0 + h0, 0.0, 0.0), normal=(-1.0, 0.0, 0.0),
                                stiffness=stiffness, h0=h0),)
    else:
        walls = (RigidWallSpec(point=(4.0 + 0.5 * h0, 0.0, 0.0), normal=(-1.0, 0.0, 0.0),
                               sliding=True),)
    v0 = 2.0 * speed if two_body else speed
    solver = ExplicitSolver3D([BodySpec("bar", msh, material, initial_velocity=(v0, 0.0, 0.0),
                                        fixed=fixed, element=element)] + bodies, rigid_walls=walls,
                              soft_planes=planes, contact_pairs=pairs, cfl=cfl,
                              bulk_viscosity=bulk_viscosity, comm=comm)
    ke0 = solver.energies()["kinetic_J"]
    if probe is None:
        probe = [4.0, 0.0, 0.0] if quarter else [4.0, 1.0, 1.0]
    probe = np.asarray(probe, dtype=float)
    b = solver.bodies["bar"]
    d = np.linalg.norm(b.X0[: b.n_owned] - probe, axis=1)
    cand = comm.allgather((float(d.min()) if d.size else np.inf, comm.rank))
    owner = min(cand)[1]
    row = int(np.argmin(d)) if comm.rank == owner else -1
    ts, ss, es = [0.0], [0.0], [solver.energies()]
    t0 = _time.perf_counter()
    loop = 0.0
    dt = solver.stable_time_step()
    while solver.time < t_end - 1e-12:
        ta = _time.perf_counter()
        solver.advance(min(dt, t_end - solver.time))
        loop += _time.perf_counter() - ta
        val = 0.0
        if two_body:
            ts.append(solver.time)
            ss.append(solver.contact_pressure_at(0, probe))
            es.append(solver.energies())
            dt = solver.stable_time_step()
            continue
        if comm.rank == owner:
            rows, _, p = (solver.soft_plane_pressure(0, "bar") if soft_plane
                          else solver.wall_pressure(0, "bar"))
            hit = np.flatnonzero(rows == row)
            val = float(p[hit[0]]) if hit.size else 0.0
        ts.append(solver.time)
        ss.append(comm.bcast(val, root=owner))
        es.append(solver.energies())
        dt = solver.stable_time_step()
    log.info("3D bar impact: %d steps in %.2f s (%.2f s in advance)", solver.step_count,
             _time.perf_counter() - t0, loop)
    t = np.array(ts)
    s = np.array(ss)
    try:
        metrics = contact_stress_metrics(t, s)
    except ValueError as err:
        log.warning("3D bar impact: no contact metrics (%s)", err)
        metrics = {}
    metrics["energy_error_rel"] = max(abs(e["balance_error_J"]) for e in es) / ke0
    cells = comm.allreduce(sum(len(bb.cells) for bb in solver.bodies.values()))
    return {"t": t, "stress": s, "energies": es, "ke0": ke0, "metrics": metrics, "solver": solver,
            "steps": solver.step_count, "loop_s": loop, "cells": cells}
