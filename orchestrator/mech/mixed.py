"""Rigid bodies of a case file, and the mechanics of a case that has them: deformable and rigid bodies
stepped together.

A rigid body (``[[bodies]] rigid = true``) is a conductor region of the EM geometry that translates
without deforming (:class:`pulseform.solvers.dolfinx.rigid.RigidBody`): its nodes are the region's
EM nodes, its mass the material's density times the region's volume (the full 2πr ring in
axisymmetry, times ``mechanics.thickness`` in plane models) unless the case gives one.

:class:`MixedMechanics` implements the loop's ``Mechanics`` protocol over the explicit DOLFINx
solver's deformable bodies (optional) and the rigid bodies: one time step for all (the deformable
bodies' stable step; the rigid bodies' configured step when every body is rigid), the forces split
by body, one energy ledger.

Units: m, s, kg, N, J.
"""

from __future__ import annotations

import math

import numpy as np

from pulseform.solvers.getdp.mesh3d import tet_volumes
from pulseform.solvers.dolfinx.rigid import EndStop, RigidBody
from pulseform.solvers.dolfinx.rigid_held import HeldRigidBody

from ..case.model import Case
from ..coupling.interfaces import plain_total
from ..mesh.shared import ConductorMesh
from .participants import DolfinxMechanics
from .rigid import RigidMechanics

__all__ = ["region_mass", "region_centroid", "rigid_bodies", "rigid_metrics", "MixedMechanics", "RIGID_ENERGY_KEYS"]

#: the rigid bodies' entries of the energy ledger (J)
RIGID_ENERGY_KEYS = ("kinetic_J", "external_work_J", "stop_dissipated_J")


def region_mass(sub: ConductorMesh, density: float, axisymmetric: bool, thickness: float = 1.0) -> float:
    """Mass (kg) of a region of P1 triangles: ``density`` (kg/m³) × its volume, Σ A_e 2π r_c in
    axisymmetry (r_c the triangle's centroid radius: exact for triangles), Σ A_e × ``thickness`` (m)
    in plane models; of tetrahedra (3D): Σ V_e."""
    if sub.cells.shape[1] == 4:
        return float(density * tet_volumes(sub.points, sub.cells).sum())
    p = sub.points[:, :2][sub.cells]
    area = 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                        - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))
    if axisymmetric:
        return float(density * np.sum(area * 2.0 * math.pi * p[:, :, 0].mean(axis=1)))
    return float(density * thickness * area.sum())


def region_centroid(sub: ConductorMesh) -> np.ndarray:
    """The centroid (m) of a region: of its section's area for triangles (r-z in axisymmetry, x-y in plane
    models), of its volume for tetrahedra (3D): a rigid body's reference point."""
    cells = sub.points[sub.cells]
    if sub.cells.shape[1] == 4:
        w = tet_volumes(sub.points, sub.cells)
    else:
        p = cells[:, :, :2]
        w = 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                         - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))
    return (w[:, None] * cells.mean(axis=1)).sum(axis=0) / w.sum()


def rigid_bodies(case: Case, subs: dict[str, ConductorMesh]) -> list[RigidBody]:
    """The case's rigid bodies on their regions' meshes ``subs`` (role -> the region cut from the EM mesh): stepped
    by central differences (:class:`RigidBody`), or exactly under the force held over each step in implicit runs
    (:class:`~pulseform.solvers.dolfinx.rigid_held.HeldRigidBody`)."""
    out = []
    kind = HeldRigidBody if case.mechanics.integrator == "implicit" else RigidBody
    axisymmetric = case.mechanics.formulation == "axisymmetric"
    for b in case.bodies:
        if not b.rigid:
            continue
        sub = subs[b.region]
        mass = b.mass if b.mass is not None else region_mass(sub, case.materials[b.material].density, axisymmetric,
                                                             case.mechanics.thickness)
        moves = case.rigid_moves(b)
        stops = tuple(EndStop(s.component, s.position, 1 if s.side == "min" else -1, s.restitution) for s in b.stops)
        dim = 3 if case.mechanics.formulation == "3d" else 2
        gravity = b.gravity if b.gravity is not None else (case.mechanics.gravity if dim == 2 else None)

        def vec(v):
            return None if v is None or (not any(v) and len(v) != dim) else tuple(v)

        out.append(kind(b.name, sub.points, mass, free=tuple(i in moves for i in range(dim)),
                             gravity=vec(gravity), offset=vec(b.offset), velocity=vec(b.initial_velocity), stops=stops,
                             reference=tuple(region_centroid(sub)[:dim])))
    return out


def rigid_metrics(case: Case, history, masses: dict[str, float]) -> dict[str, float]:
    """Per rigid body its mass (kg, ``masses``) and, per free component c (x or y), from ``history``
    (the run's history.csv columns of :meth:`RigidBody.history`): the largest, smallest and final position
    of its reference point (``position``, the centroid of its region: :func:`region_centroid`) and of its
    translation from the start (``travel``) (mm) and when the largest was reached (s), the largest speed
    |v| (m/s) and the largest |force| of its Lorentz forces (N)."""
    out: dict[str, float] = {}
    t = history.column("time_s")
    for b in case.bodies:
        if not b.rigid:
            continue
        out[f"{b.name}_mass_kg"] = float(masses[b.name])
        speed2 = np.zeros(len(t))
        for c in ("xyz"[i] for i in case.rigid_moves(b)):
            v = history.column(f"{b.name}_velocity_{c}_m_s")
            speed2 += v * v
            for q in ("position", "travel"):  # the reference point's, the translation from the start
                u = history.column(f"{b.name}_{q}_{c}_m")
                k = int(np.argmax(u))
                out[f"{b.name}_max_{q}_{c}_mm"] = float(u[k]) * 1e3
                out[f"{b.name}_max_{q}_{c}_time_s"] = float(t[k])
                out[f"{b.name}_min_{q}_{c}_mm"] = float(u.min()) * 1e3
                out[f"{b.name}_final_{q}_{c}_mm"] = float(u[-1]) * 1e3
            out[f"{b.name}_max_force_{c}_N"] = float(np.abs(history.column(f"{b.name}_force_{c}_N")).max())
        out[f"{b.name}_max_speed_m_s"] = float(np.sqrt(speed2.max()))
    return out


class MixedMechanics:
    """The loop's ``Mechanics`` over deformable bodies (``deformable``: the explicit solver's
    participant, or None) and rigid bodies (``rigid``), stepped together with one step.

    Checkpoint keys: the deformable solver's as they are, the rigid bodies' under ``rigid/``.
    """

    def __init__(self, deformable: DolfinxMechanics | None, rigid: RigidMechanics) -> None:
        self.deformable = deformable
        self.rigid = rigid

    @property
    def time(self) -> float:
        """Current time (s)."""
        return self.deformable.time if self.deformable is not None else self.rigid.time

    @property
    def step_count(self) -> int:
        """Mechanical steps taken."""
        return self.deformable.step_count if self.deformable is not None else self.rigid.step_count

    def stable_time_step(self) -> float:
        """The deformable bodies' stable step (s); the rigid bodies' configured step without them."""
        return self.deformable.stable_time_step() if self.deformable is not None else self.rigid.stable_time_step()

    @property
    def retries_steps(self) -> bool:
        """Whether :meth:`advance` may reject its step (the deformable bodies' adaptive implicit step)."""
        return bool(getattr(self.deformable, "retries_steps", False))

    def impulse_window(self, t0: float, dt: float, k: int) -> float:
        """Where the loop evaluates the load of ``k`` steps of ``dt`` from ``t0`` (s): the deformable bodies' window
        (:meth:`DolfinxMechanics.impulse_window`), else the rigid bodies' (:meth:`RigidMechanics.impulse_window`)."""
        if self.deformable is not None:
            return self.deformable.impulse_window(t0, dt, k)
        return self.rigid.impulse_window(t0, dt, k)

    def _split(self, forces: dict[str, np.ndarray] | None) -> tuple[dict | None, dict | None]:
        if forces is None:
            return None, None
        rigid = {n: f for n, f in forces.items() if n in self.rigid.bodies}
        return {n: f for n, f in forces.items() if n not in self.rigid.bodies}, rigid

    def advance(self, dt: float, n_steps: int, forces: dict[str, np.ndarray] | None) -> None:
        """``n_steps`` steps of ``dt`` (s) of every body with held nodal forces (N); the deformable bodies first (an
        adaptive implicit step that rejects its step raises before any body moved)."""
        deformable, rigid = self._split(forces)
        if self.deformable is not None:
            self.deformable.advance(dt, n_steps, deformable)
        self.rigid.advance(dt, n_steps, rigid)

    def heated_cells(self) -> dict[str, np.ndarray]:
        """The deformable bodies' cells that carry a temperature (:meth:`DolfinxMechanics.heated_cells`)."""
        return self.deformable.heated_cells() if self.deformable is not None else {}

    def cell_temperatures(self) -> dict[str, np.ndarray]:
        """The deformable bodies' temperatures per cell (:meth:`DolfinxMechanics.cell_temperatures`)."""
        return self.deformable.cell_temperatures() if self.deformable is not None else {}

    def add_heat(self, heat: dict[str, np.ndarray]) -> None:
        """Joule heat (J/m^3 per cell) of deformable bodies (rigid bodies carry no temperature)."""
        if self.deformable is not None:
            self.deformable.add_heat({n: e for n, e in heat.items() if n not in self.rigid.bodies})

    def positions(self) -> dict[str, np.ndarray]:
        """Current node coordinates per body (m)."""
        out = self.deformable.positions() if self.deformable is not None else {}
        out.update(self.rigid.positions())
        return out

    def total_force(self, forces: dict[str, np.ndarray]) -> np.ndarray:
        """Resultant (N) of nodal forces on every body."""
        deformable, rigid = self._split(forces)
        total = plain_total(rigid, self.rigid.dim)
        if self.deformable is not None and deformable:
            total = total + self.deformable.total_force(deformable)
        return total

    def state_dict(self) -> dict[str, np.ndarray]:
        """The deformable solver's state and the rigid bodies' (under ``rigid/``)."""
        out = self.deformable.state_dict() if self.deformable is not None else {}
        out.update({f"rigid/{k}": v for k, v in self.rigid.state_dict().items()})
        return out

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        self.rigid.load_state_dict({k[6:]: v for k, v in state.items() if k.startswith("rigid/")})
        if self.deformable is not None:
            self.deformable.load_state_dict({k: v for k, v in state.items() if not k.startswith("rigid/")})

    def energies(self, deformable: dict[str, float] | None) -> dict[str, float]:
        """One energy ledger (J): the deformable solver's ``deformable`` (None without deformable bodies)
        with the rigid bodies' kinetic energy, work of their forces and gravity and the energy their
        stops took added, and its balance error including theirs."""
        e = dict(deformable) if deformable is not None else {"kinetic_J": 0.0, "external_work_J": 0.0,
                                                                 "balance_error_J": 0.0}
        r = self.rigid.energies()
        e["kinetic_J"] += r["kinetic_J"]
        e["external_work_J"] += r["external_work_J"]
        e["stop_dissipated_J"] = r["stop_dissipated_J"]
        e["balance_error_J"] += r["kinetic_J"] + r["stop_dissipated_J"] - r["external_work_J"] - self._rigid_e0
        return e

    @property
    def _rigid_e0(self) -> float:
        """The rigid bodies' kinetic energy at t = 0 (J), from their initial velocities."""
        return sum(0.5 * b.mass * float(np.sum((np.array(b.velocity) * np.array(b.free)) ** 2))
                   for b in self.rigid.bodies.values())
