"""The 3D GetDP eddy-current load provider of the staggered loop (one persistent getdp, or one per EM step).

Each EM step [t0, t1] (:mod:`pulseform.orchestrator.coupling.loop`):

1. ``follow``: the 3D EM mesh follows the mechanics: the conductor bodies' nodes take the mechanical
   positions (the meshes share them; a ten-node body's vertex rows, its edge nodes follow the mechanics
   only), coil, shell and outer boundary stay, nodes on the symmetry planes slide in them, the rest of
   the air is moved harmonically (:class:`~pulseform.orchestrator.mesh.motion3d.MeshMover3D`); a
   tetrahedron that inverts or whose quality falls below the threshold raises a clear message (its
   subclasses mesh the air again or freeze: :mod:`.remesh3d`, :mod:`.frozen3d`);
2. ``load``: getdp advances one step from the carried state on the moved nodes (same connectivity):
   by default one persistent getdp process for the run whose mesh is moved by ``DeformMesh``
   (:class:`~pulseform.solvers.getdp.persistent3d.PersistentEM3DStepper`, BDF2), or
   (``getdp_process="per_step"``, and always with implicit Euler) one getdp process per step on the
   moved mesh written anew (``Mesh3D.moved``; :class:`~pulseform.solvers.getdp.stepper3d.EM3DStepper`:
   implicit Euler by ``-restart``, BDF2 from x~) -- the same results to round-off;
3. the per-tetrahedron force density held over the step (BDF2: the trapezoid of the start and end
   values) becomes consistent nodal forces f V / 4 on the shared nodes, or on a ten-node body
   (``element = "tet10"``) f V shared by its cell's ten nodes as their HRZ masses
   (:mod:`~pulseform.orchestrator.coupling.transfer3d`); the ledger compares their sum with Σ f V.

Several bodies (e.g. a sheet and a conducting die): each is one EM conductor region; each gets the
nodal forces of its own tetrahedra, and with more than one body the history has per-body columns
(``<name>_force_{x,y,z}_N``, ``<name>_ledger_rel``: |Σ nodal F − Σ f V| of that body alone,
``<name>_getdp_force_z_N``: GetDP's own integral of f over the region, ``<name>_joule_power_W``);
the loop's ``conservation_error_rel`` is the total's.

Forces, impulse and powers are those of the modelled sector; ``symmetry_factor`` (360 / angle)
scales them to the whole device in the history's ``device_*`` columns (of the first body; and in ``coil_joule_heat_J``,
the whole coil's heat: Σ P_end dt over the EM steps).

Checkpoints (:meth:`GetDPLoad3D.state_dict`): the carried state of the stepper (x_n as numbers with
its DofData id, x_{n-1}, the circuit at both times, the last step, the force density at t_n), the
running sums and the peak-current bookkeeping; a resume writes x_n back as a one-solution ``.res``
(17 digits: the same doubles) and continues as the uninterrupted run does.
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp.conductivity import coil_mass_cp, coil_temperature
from pulseform.solvers.getdp.files import discard_folder
from pulseform.solvers.getdp.magnetic_force import model_magnetisation_forces, no_surface
from pulseform.solvers.getdp.mesh import CONDUCTOR_BASE, coil_tag
from pulseform.solvers.getdp.mesh3d import Mesh3D
from pulseform.solvers.getdp.persistent3d import PersistentEM3DStepper
from pulseform.solvers.getdp.persistent_process import FactorReuse
from pulseform.solvers.getdp.solver3d import EM3DModel
from pulseform.solvers.getdp.stepper3d import EM3DState, EM3DStepper, FactorRecord, read_res_vector, write_res_vector

from ..coupling.interfaces import LoadCapabilities, LoadStep
from ..coupling.transfer3d import body_forces, tet_force_integral
from ..mesh.geometry3d import boundary_faces, outer_area
from ..mesh.motion3d import MeshMover3D
from .conductor3d import ConductorBody3D
from .joule_heat import JouleHeat, element_temperatures
from .shot_model import begin_model_shot, load_model_shot_state, model_shot_state

log = logging.getLogger(__name__)

#: history columns of the 3D GetDP load (sector values unless ``device_``)
LOAD_COLUMNS_3D = ("force_x_N", "force_y_N", "force_z_N", "conservation_error_rel", "coil_current_A",
                   "coil_current_abs_max_A", "capacitor_voltage_V", "coil_joule_heat_J", "coil_temperature_rise_K",
                   "magnetic_energy_J",
                   "workpiece_joule_power_W", "getdp_force_z_N", "device_force_z_N", "device_impulse_z_Ns",
                   "em_mesh_min_quality", "em_factorisations", "em_corrections")
#: per-body history columns (prefixed ``<name>_``) of a load with several bodies
BODY_COLUMNS_3D = ("force_x_N", "force_y_N", "force_z_N", "ledger_rel", "getdp_force_z_N", "joule_power_W")


def _check_bodies(bodies: list[ConductorBody3D]) -> None:
    """Each body its own name and region, no EM node in two bodies (ValueError otherwise)."""
    if len({b.tag for b in bodies}) != len(bodies) or len({b.name for b in bodies}) != len(bodies):
        raise ValueError("GetDPLoad3D: each body needs its own name and conductor region")
    seen = np.concatenate([np.unique(b.body_to_em) for b in bodies])
    if np.unique(seen).size != seen.size:
        raise ValueError("GetDPLoad3D: two bodies share EM nodes (their regions touch)")


class GetDPLoad3D(LoadCapabilities):
    """Load provider: 3D GetDP eddy-current forces on the conductor bodies (module docstring).

    Parameters
    ----------
    mesh : Mesh3D
        The EM mesh in its reference configuration.
    model : EM3DModel
        The 3D model (coil, circuit, conductors, shell, sector).
    work_dir : Path
        Folder of the getdp runs (``persistent3d_001``, or one per EM step of which the last two are kept).
    bodies : list of ConductorBody3D
        The conductor bodies (the workpiece first), each on its own EM conductor region (their
        nodes disjoint: bodies that touch in the EM mesh would share nodes).
    mover : MeshMover3D
        The air motion on ``mesh`` (conductor nodes prescribed, planes sliding).
    time_scheme : {"euler", "bdf2"}
        The EM time scheme.
    getdp_process : {"auto", "persistent", "per_step"}
        One persistent getdp for the run (BDF2 only) or a getdp process per EM step; ``"auto"``:
        persistent with BDF2, per step with implicit Euler.
    getdp_timeout : float or None
        Wall-time limit of each getdp answer (persistent) or run (per step), s; None: the runner's default.
    factor_reuse : FactorReuse
        Kept LU factors across the persistent getdp's EM steps (a process per step factorises every
        step). History columns ``em_factorisations`` and ``em_corrections``: the run's counts so far.
    """

    columns = LOAD_COLUMNS_3D

    def __init__(self, mesh: Mesh3D, model: EM3DModel, work_dir: Path, bodies: list[ConductorBody3D],
                 mover: MeshMover3D, time_scheme: str = "bdf2", getdp_process: str = "auto",
                 getdp_timeout: float | None = None, factor_reuse: FactorReuse = FactorReuse()) -> None:
        _check_bodies(bodies)
        self.mesh, self.model, self.bodies, self.mover = mesh, model, list(bodies), mover
        self.work_dir = Path(work_dir).resolve()
        if getdp_process not in ("auto", "persistent", "per_step"):
            raise ValueError(f"getdp_process is 'auto', 'persistent' or 'per_step', got {getdp_process!r}")
        if getdp_process == "persistent" and time_scheme != "bdf2":
            raise ValueError("the persistent getdp implements time_scheme='bdf2' only")
        self.persistent = getdp_process == "persistent" or (getdp_process == "auto" and time_scheme == "bdf2")
        stepper = PersistentEM3DStepper if self.persistent else EM3DStepper
        self.stepper = stepper(model, self.work_dir, time_scheme=time_scheme, timeout=getdp_timeout,
                               **({"factor_reuse": factor_reuse} if self.persistent else {}))
        self.state = self.stepper.initial_state()
        self.tags = np.array([b.tag for b in self.bodies])
        if len(self.bodies) > 1:
            self.columns = LOAD_COLUMNS_3D + tuple(f"{b.name}_{k}" for b in self.bodies for k in BODY_COLUMNS_3D)
        #: with several coils each has its current and Joule power column (``<name>_current_A``, ...)
        self.coil_names = [c.name or f"coil_{k}" for k, c in enumerate(model.coils, start=1)] \
            if len(model.coils) > 1 else []
        self.columns = tuple(self.columns) + tuple(f"{n}_{q}" for n in self.coil_names
                                                   for q in ("current_A", "joule_power_W", "temperature_rise_K")) \
            + (("em_newton_iterations",) if model.is_nonlinear else ())
        self.min_quality = float(mover.q_ref.min())
        self._moved: tuple[float, np.ndarray] | None = None
        self._runs: list[Path] = []
        self.timers = {"mesh_motion_s": 0.0, "getdp_s": 0.0, "transfer_s": 0.0}
        self.impulse_device = 0.0   # Σ s ∫f_z dV dt over the steps (N·s), the device's
        self.body_impulse = np.zeros((len(self.bodies), 3))   # per body Σ s F dt of its nodal forces (N·s)
        #: 1 for the force components the whole device has (every symmetry plane contains that axis), 0 for
        #: those its mirror images cancel (a plane normal to z: no device axial force); set by the caller
        self.device_axes = np.ones(3)
        self.coil_heat = 0.0        # Σ s P_coil(t1) dt (J), the whole coil's
        self.peak_current = 0.0     # largest |I| at the end of a step (A) and the snapshot there
        self._peak: tuple | None = None
        self._peak_conductors: tuple | None = None   # every conductor at the peak (:meth:`take_peak_conductors`)
        self._last_step: tuple | None = None        # (t1, current, x_em, result) of the last step
        self._last_snapshot: tuple | None = None    # its sheet snapshot, made when first asked for
        self.joule = JouleHeat()   # the Joule heat per mechanical cell of the bodies with a temperature
        #: a conductor's σ follows its cells' temperatures (:mod:`pulseform.solvers.getdp.conductivity`)
        self.conductivity_follows_temperature = any(c.conductivity_law is not None for c in model.conductors)
        self._elem_t: tuple[np.ndarray, np.ndarray] | None = None   # (EM tet rows, K) of the last step's σ(T)
        sub = self.bodies[0].sub
        self._sheet_pos = np.full(len(mesh.tets), -1, dtype=np.int64)
        self._sheet_pos[sub.rows] = np.arange(len(sub.rows))

    def follow(self, t0: float, mechanics) -> None:
        """The EM mesh follows the bodies for the EM step starting at ``t0`` (s)."""
        c0 = time.perf_counter()
        positions = mechanics.positions()
        u = np.zeros_like(self.mesh.points)
        for b in self.bodies:
            u[b.body_to_em] = b.vertices(positions[b.name]) - self.mesh.points[b.body_to_em]
        x_em = self.mover.moved(u)   # raises MeshQualityError (a remeshing load meshes the air again)
        self.min_quality = min(self.min_quality, float(self.mover.last_min_quality))
        self._moved = (t0, x_em)
        self.timers["mesh_motion_s"] += time.perf_counter() - c0

    def load(self, t0: float, t1: float, t_mid: float, mechanics) -> LoadStep:
        """One getdp step to ``t1`` (s) on the moved mesh; nodal forces (N) on the bodies."""
        if self._moved is None or self._moved[0] != t0:
            self.follow(t0, mechanics)
        x_em, self._moved = self._moved[1], None
        if abs(self.state.t - t0) > 1e-9 * max(t1, 1e-300):
            raise RuntimeError(f"EM state at t = {self.state.t:.9g} s, but the step starts at {t0:.9g} s")
        c0 = time.perf_counter()
        if self.conductivity_follows_temperature:   # σ(T) per EM tetrahedron from its mechanical cell's T at t0
            self._elem_t = element_temperatures(mechanics, self.bodies, self.mesh.tets, self.mesh.tet_tags)
            self.stepper.set_element_temperatures(*self._elem_t)
        if self.persistent:  # getdp moves its own mesh: no file
            result, self.state = self.stepper.step(replace(self.mesh, points=x_em), self.state, t1)
        else:
            run_dir = self.work_dir / f"step_{self.state.steps + 1:05d}"
            run_dir.mkdir(parents=True, exist_ok=True)
            mesh_k = self.mesh.moved(x_em, run_dir / "mesh.msh")
            result, self.state = self.stepper.step(mesh_k, self.state, t1)
            self._prune(run_dir)
        c1 = time.perf_counter()
        keep = np.isin(result.element_tags, self.tags)
        f = result.force_density_mean[keep]
        tets = self.mesh.tets[result.elements[keep]]
        forces = body_forces(self.bodies, x_em, self.mesh.tets, result.elements[keep], f)
        integral = tet_force_integral(x_em, tets, f)
        mag = model_magnetisation_forces(self.model, x_em, self.mesh.tets, result, no_surface(self.mesh)) \
            if self.model.is_magnetic else None
        if mag is not None:   # magnetised bodies: their surface force joins the Lorentz force (on the vertex rows)
            integral = integral + mag.sum(axis=0)
            for b in self.bodies:
                forces[b.name][:len(b.body_to_em)] += mag[b.body_to_em]
        per_body = {}
        if len(self.bodies) > 1:
            tags = result.element_tags[keep]
            for b in self.bodies:
                mine = tags == b.tag
                ref = tet_force_integral(x_em, tets[mine], f[mine])
                if mag is not None:
                    ref = ref + mag[b.body_to_em].sum(axis=0)
                total = forces[b.name].sum(axis=0)
                per_body.update({f"{b.name}_force_x_N": float(total[0]), f"{b.name}_force_y_N": float(total[1]),
                                 f"{b.name}_force_z_N": float(total[2]),
                                 f"{b.name}_ledger_rel": float(np.linalg.norm(total - ref) / max(np.linalg.norm(ref), 1e-300)),
                                 f"{b.name}_getdp_force_z_N": float(result.conductor_force[-1, self._index(b), 2]),
                                 f"{b.name}_joule_power_W": float(result.conductor_power[-1, self._index(b)])})
        self.timers["getdp_s"] += c1 - c0
        self.timers["transfer_s"] += time.perf_counter() - c1
        s = float(self.model.symmetry_factor)
        i0 = self._index(self.bodies[0])
        fz = float(result.conductor_force[-1, i0, 2])
        current = float(result.coil_current[-1, 0])
        self.impulse_device += s * self.device_axes[2] * float(integral[2]) * (t1 - t0)
        for i, b in enumerate(self.bodies):
            self.body_impulse[i] += s * self.device_axes * forces[b.name].sum(axis=0) * (t1 - t0)
        self.coil_heat += s * float(result.coil_power[-1].sum()) * (t1 - t0)   # every coil's
        values = {"coil_current_A": current, "coil_current_abs_max_A": abs(current),
                  "capacitor_voltage_V": float(result.capacitor_voltage[-1]) if result.capacitor_voltage is not None else 0.0,
                  "coil_joule_heat_J": self.coil_heat,
                  "magnetic_energy_J": float(result.magnetic_energy[-1]),
                  "workpiece_joule_power_W": float(result.conductor_power[-1, i0]),
                  "getdp_force_z_N": fz, "device_force_z_N": s * self.device_axes[2] * fz, "device_impulse_z_Ns": self.impulse_device,
                  "em_mesh_min_quality": float(self.mover.last_min_quality),
                  **self._solve_counts(), **per_body}
        if result.newton_iterations:   # a B–H curve: the linear solves of the step (first + Newton's)
            values["em_newton_iterations"] = float(max(result.newton_iterations))
        rise = self.coil_temperatures() - np.array([c.initial_temperature for c in self.model.coils])
        values["coil_temperature_rise_K"] = float(rise[0]) if len(rise) else 0.0
        for k, name in enumerate(self.coil_names):   # several coils: each one's current, power (whole device), rise
            values[f"{name}_current_A"] = float(result.coil_current[-1, k])
            values[f"{name}_joule_power_W"] = s * float(result.coil_power[-1, k])
            values[f"{name}_temperature_rise_K"] = float(rise[k])
        heat = self.joule.heat(mechanics, self.bodies, result, self.mesh.tets, t1 - t0)
        self.last = (x_em, result)   # the moved nodes and GetDP's result of the last step
        self._last_step, self._last_snapshot = (t1, current, x_em, result), None
        if abs(current) > self.peak_current:
            self.peak_current, self._peak = abs(current), self.last_snapshot
            self._peak_conductors = self._conductor_snapshot(t1, current, x_em, result)
        return LoadStep(forces, integral, values, heat)

    @property
    def last_snapshot(self) -> tuple | None:
        """The sheet's snapshot at the end of the last step (:meth:`_sheet_snapshot`), None before the first;
        made when first asked for (a persistent getdp computes the Joule power per element only then), which
        must be before the next step."""
        if self._last_snapshot is None and self._last_step is not None:
            self._last_snapshot = self._sheet_snapshot(*self._last_step)
        return self._last_snapshot

    def _solve_counts(self) -> dict[str, float]:
        """The run's factorisations and kept-factor GCR iterations so far (history columns; the steppers count
        them: :class:`~pulseform.solvers.getdp.persistent_process.FactorReuse`, a getdp process per EM step
        factorises once)."""
        tm = self.state.timers
        return {"em_factorisations": tm.get("getdp_factorisations", 0.0),
                "em_corrections": tm.get("getdp_corrections", 0.0)}

    @staticmethod
    def _index(body: ConductorBody3D) -> int:
        """The body's row in GetDP's per-conductor results (conductor k has the physical id 200 + k)."""
        return body.tag - CONDUCTOR_BASE - 1

    def _sheet_snapshot(self, t: float, current: float, x_em: np.ndarray, result) -> tuple:
        """(t s, coil current A, sheet node positions (n, 3) m, sheet tetrahedra (m, 4), cell data): the
        force density (N/m^3) and Joule power density (W/m^3) at the end of the step on the sheet's
        tetrahedra (rows of its submesh)."""
        sub = self.bodies[0].sub
        pos = self._sheet_pos[result.elements]
        on = pos >= 0
        f = np.zeros((len(sub.rows), 3))
        f[pos[on]] = result.force_density[-1][on]
        cells = {"force_density_N_m3": f, "force_density_magnitude_N_m3": np.linalg.norm(f, axis=1)}
        if result.joule_density is not None:
            q = np.zeros(len(sub.rows))
            q[pos[on]] = result.joule_density[-1][on]
            cells["joule_power_density_W_m3"] = q
        return float(t), current, x_em[sub.em_nodes].copy(), sub.cells, cells

    def _conductor_snapshot(self, t: float, current: float, x_em: np.ndarray, result) -> tuple:
        """(t s, coil current A, node positions (n, 3) m, tetrahedra (m, 4), cell data) of every conductor -- the
        bodies and the fixed ones -- at the end of the step: force density (N/m^3), Joule power density q (W/m^3),
        the eddy current density's magnitude |j| = sqrt(sigma q) (A/m^2) and the conductor's number k (200 + k)."""
        rows = result.elements
        nodes, inverse = np.unique(self.mesh.tets[rows], return_inverse=True)
        k = result.element_tags - CONDUCTOR_BASE
        sigma = np.array([c.sigma for c in self.model.conductors])[k - 1]
        if self._elem_t is not None:   # σ(T): each element's σ of the step (its temperature at the step's start)
            temp = np.full(len(self.mesh.tets), np.nan)
            temp[self._elem_t[0]] = self._elem_t[1]
            for i, c in enumerate(self.model.conductors, start=1):
                if c.conductivity_law is not None and np.any(k == i):
                    mine = temp[rows[k == i]]
                    sigma[k == i] = c.conductivity_law(np.where(np.isnan(mine), c.initial_temperature, mine))
        f = result.force_density[-1]
        cells = {"force_density_N_m3": f, "force_density_magnitude_N_m3": np.linalg.norm(f, axis=1),
                 "conductor": k.astype(float)}
        if result.joule_density is not None:
            q = np.maximum(result.joule_density[-1], 0.0)
            cells["joule_power_density_W_m3"] = q
            cells["current_density_magnitude_A_m2"] = np.sqrt(sigma * q)
        return float(t), current, x_em[nodes].copy(), inverse.reshape(-1, 4), cells

    def take_peak_conductors(self) -> tuple | None:
        """Every conductor's snapshot at the largest |coil current| so far, once when it is new (else None)."""
        peak, self._peak_conductors = self._peak_conductors, None
        return peak

    def initial(self, mechanics) -> LoadStep:
        """The load at t = 0: no force, the bank charged to V0 (the history's first row)."""
        c = self.model.circuit
        return LoadStep({}, None, {"capacitor_voltage_V": float(c.V0) if c is not None else 0.0,
                                   "coil_temperature_rise_K": 0.0})

    def snapshot(self) -> tuple | None:
        """(sheet node positions m, tetrahedra, cell data) at the end of the last EM step, None before."""
        return None if self.last_snapshot is None else self.last_snapshot[2:]

    def take_peak_snapshot(self) -> tuple | None:
        """The sheet's snapshot at the largest |coil current| so far, once when it is new (else None)."""
        peak, self._peak = self._peak, None
        return peak

    def run_metrics(self, history, counters) -> dict[str, float]:
        """The 2D coupled run's figures for the whole device (sector values × 360 / angle: impulse,
        peak force, coil heat, plastic work, final kinetic energy; ``sector_*`` the modelled sector's),
        and the 3D EM timers."""
        s = float(self.model.symmetry_factor)
        impulse_z = float(counters.impulse[2]) if len(counters.impulse) > 2 else 0.0
        last = {k: float(history.column(f"energy_{k}_J")[-1]) for k in ("plastic", "kinetic")}
        sz = s * self.device_axes[2]   # 0 where a symmetry plane's mirror cancels the device's axial force
        return {"force_impulse_z_Ns": sz * impulse_z, "force_impulse_Ns": sz * abs(impulse_z),
                "sector_force_impulse_z_Ns": impulse_z,
                "plastic_work_J": s * last["plastic"], "kinetic_energy_final_J": s * last["kinetic"],
                "sector_plastic_work_J": last["plastic"],
                "coil_current_peak_kA": float(np.abs(history.column("coil_current_abs_max_A")).max()) / 1e3,
                "force_peak_N": float(np.abs(history.column("device_force_z_N")).max()),
                "coil_joule_heat_J": self.coil_heat, "conservation_error_rel": float(counters.ledger_max),
                "coil_temperature_rise_K": float(history.column("coil_temperature_rise_K")[-1]),
                "em_time_s": float(counters.em_time_s), "em_min_quality": self.min_quality,
                "symmetry_factor": float(self.model.symmetry_factor),
                "em_tets": float(self.mesh.n_tets), "em_nodes": float(self.mesh.n_nodes),
                **{f"{b.name}_impulse_{c}_Ns": float(self.body_impulse[i, j]) for i, b in enumerate(self.bodies)
                   for j, c in enumerate("xyz") if c == "z" or self.device_axes[j]},   # the device's components
                **{f"{b.name}_tets": float(len(b.sub.cells)) for b in self.bodies},
                **{f"{b.name}_ledger_rel": float(np.max(history.column(f"{b.name}_ledger_rel")))
                   for b in self.bodies if f"{b.name}_ledger_rel" in history.columns},
                **{f"em_{k}": v for k, v in self.timers.items()},
                **{f"em_{k}": v for k, v in self.state.timers.items()}}

    def _prune(self, newest: Path) -> None:
        """Keep the last two run folders (the carried ``.res`` lives in the newest)."""
        if newest not in self._runs:
            self._runs.append(newest)
        for old in self._runs[:-2]:
            discard_folder(old)
        self._runs = self._runs[-2:]

    # ------------------------------------------------------------------ repeated shots (run/shots.py)
    def coil_temperatures(self) -> np.ndarray:
        """The coils' lumped temperatures now (K): their initial temperature + the sector's Joule heat / the
        sector's m c_p (:func:`~pulseform.solvers.getdp.conductivity.coil_temperature`)."""
        return coil_temperature(self.model, self.mesh, self.state)

    def coil_heat_paths(self) -> tuple[np.ndarray, np.ndarray]:
        """(outer surface m², m c_p J/K) of every coil, the modelled sector's (the faces on the symmetry planes left
        out), for their cooling between shots."""
        area = np.array([outer_area(self.mesh.points, boundary_faces(self.mesh.tets, self.mesh.tet_tags == coil_tag(k)),
                                    self.symmetry_planes) for k in range(1, len(self.model.coils) + 1)])
        return area, coil_mass_cp(self.model, self.mesh)

    def begin_shot(self, t0: float, voltage: float, coil_temperature: np.ndarray) -> None:
        """Start a new discharge at ``t0`` (s): the EM state at rest (a persistent getdp starts a new process), the
        bank charged to ``voltage`` (V), the coils at ``coil_temperature`` (K; their Joule heat counts from here)."""
        begin_model_shot(self.model, voltage, coil_temperature)
        self.state = replace(self.stepper.initial_state(), t=float(t0))
        self._moved = None
        self.coil_heat = 0.0   # the history's coil_joule_heat_J counts from the shot's start (as in 2D)
        for old in self._runs:   # the last shot's per-step runs (their step numbers start again)
            discard_folder(old)
        self._runs = []

    def shot_state(self) -> dict:
        """What a checkpoint keeps of the current shot: the bank's voltage and the coils' start temperatures."""
        return model_shot_state(self.model)

    def load_shot_state(self, d: dict) -> None:
        """Restore :meth:`shot_state`."""
        load_model_shot_state(self.model, d)

    def close(self) -> None:
        """End the persistent getdp (if any); idempotent."""
        self.stepper.close()

    def state_dict(self) -> dict[str, np.ndarray]:
        """Everything a resume needs to continue exactly (module docstring); times in s. The persistent
        getdp is asked for its solution vectors (a query; it continues)."""
        st = self.stepper.complete_state(self.state)
        out = {"t": np.float64(st.t), "steps": np.int64(st.steps), "dt_prev": np.float64(st.dt_prev),
               "sums": np.array([self.impulse_device, self.coil_heat, self.peak_current, self.min_quality]),
               "body_impulse": self.body_impulse.copy(),
               "timers": np.array([*self.timers.values(), *st.timers.values()])}
        if st.res_path is not None:
            dofdata, t_res, x = read_res_vector(st.res_path)
            out.update({"x": x, "x_dofdata": np.int64(int(dofdata)), "x_time": np.float64(t_res)})
        for key in ("x_prev", "force_density", "circuit", "circuit_prev", "coil_heat", "coil_power", "coil_sigma"):
            value = getattr(st, key)
            if value is not None:
                out[key] = np.asarray(value, dtype=float)
        for i, x in enumerate(st.x_older):   # the kept-factor solves' older states (history directions)
            out[f"x_older_{i}"] = np.asarray(x, dtype=float)
        if st.factors is not None:   # the kept factors a resumed process rebuilds (FactorRecord)
            out.update({"factor_points": st.factors.points, "factor_dtime": np.float64(st.factors.dtime),
                        "factor_current": st.factors.current})
            if st.factors.sigma is not None:   # σ(T): the conductivities the factors were made with
                out["factor_sigma"] = np.asarray(st.factors.sigma, dtype=float)
        return out

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`: x_n goes back to disk as the ``.res`` the next step starts from."""
        if not state:
            return
        steps = int(state["steps"])
        for old in self.work_dir.glob("step_*"):   # an interrupted run's steps after the checkpoint
            if old.name[5:].isdigit() and int(old.name[5:]) > steps:
                discard_folder(old)
        res_path = None
        if "x" in state:
            folder = self.work_dir / f"resume_{steps:05d}"
            folder.mkdir(parents=True, exist_ok=True)
            res_path = write_res_vector(folder / "em.res", str(int(state["x_dofdata"])), float(state["x_time"]),
                                        state["x"])
            self._runs.append(folder)

        def opt(key: str):
            return np.array(state[key], dtype=float) if key in state else None

        circ, circ_prev = opt("circuit"), opt("circuit_prev")
        timers = [float(v) for v in state["timers"]]
        self.timers = dict(zip(self.timers, timers[:len(self.timers)]))
        self.state = EM3DState(t=float(state["t"]), res_path=res_path, x_prev=opt("x_prev"),
                               circuit=None if circ is None else (float(circ[0]), float(circ[1])),
                               circuit_prev=None if circ_prev is None else (float(circ_prev[0]), float(circ_prev[1])),
                               dt_prev=float(state["dt_prev"]), force_density=opt("force_density"), steps=steps,
                               factors=FactorRecord(opt("factor_points"), float(state["factor_dtime"]),
                                                    opt("factor_current"), opt("factor_sigma"))
                               if "factor_points" in state else None,
                               x_older=tuple(opt(f"x_older_{i}") for i in range(2) if f"x_older_{i}" in state),
                               **{k: opt(k).tolist() for k in ("coil_heat", "coil_power", "coil_sigma") if k in state},
                               timers=dict(zip(self.state.timers, timers[len(self.timers):])))
        self.impulse_device, self.coil_heat, self.peak_current, self.min_quality = (float(v) for v in state["sums"])
        if "body_impulse" in state:   # checkpoints before 2026-11-28 have none
            self.body_impulse = np.array(state["body_impulse"], dtype=float).reshape(len(self.bodies), 3)
        self._peak = self._peak_conductors = None  # the checkpoint wrote the snapshots at the peak so far
