"""The GetDP eddy-current load provider of the staggered loop.

Each EM step [t0, t1]:

1. the EM mesh follows the mechanics: the nodes of every conductor body (workpiece, die, outer
   tube) take the mechanical displacement (the meshes share them), coil, shell and outer boundary
   stay, axis (or symmetry-plane) nodes slide along it, the rest of the air is smoothed
   harmonically (:class:`pulseform.orchestrator.mesh.motion.MeshMover`); an inverted or degenerate element raises
   before the mesh reaches GetDP;
2. getdp runs the EM step on the moved mesh (geometry frozen): one BDF2 step from a shifted Init
   state (``time_scheme = "bdf2"``), or ``em_substeps`` implicit-Euler sub-steps restarting from
   the previous ``.res`` (``"euler"``);
3. the per-element force density f = j × B (N/m³) of the conductors becomes consistent nodal forces
   ∫ N_i f 2πr dA (planar: ∫ N_i f dA × the mechanics' thickness) on the shared nodes, or on a six-node body
   (``element = "tri6"``: the EM mesh moves with its vertex rows) f V shared by its cell's six nodes as their
   HRZ masses (:func:`~pulseform.orchestrator.coupling.transfer.body_forces`); the ledger compares their sum
   with Σ f_e V_e.

The returned force is the impulse-consistent mean over the EM step (BDF2: trapezoid of the start
and end values; implicit Euler: the mean of the sub-steps), held over the n mechanical substeps.
Implicit Euler is first order and damps the bank's LC ringing by about (ω dt)²/2 per step, so
there the EM time step, not the hold, dominates the error at large n; BDF2 is second order
(docs/coupling.md).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import threading
import time
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp import EMMesh, EMModel, EMState, GetDPSolver
from pulseform.solvers.getdp.mesh import AXIS as AXIS_TAG
from pulseform.solvers.getdp.mesh import OUTER as OUTER_TAG
from pulseform.solvers.getdp.mesh import SHELL as SHELL_TAG
from pulseform.solvers.getdp.conductivity import coil_mass_cp, coil_temperature
from pulseform.solvers.getdp.files import discard_folder
from pulseform.solvers.getdp.magnetic_force import model_magnetisation_forces
from pulseform.solvers.getdp.persistent_process import FactorReuse

from ..coupling.interfaces import LoadCapabilities, LoadStep
from ..coupling.transfer import body_forces, cell_force_integral
from ..mesh.em_geometry import EMGeometry
from ..mesh.motion import MeshMover, MeshQualityError
from ..mesh.remesh import remesh_around
from ..mesh.triangles import region_surface
from ..mesh.shared import ConductorBody, ConductorMesh  # noqa: F401  (ConductorBody: the participant's API)
from .joule_heat import JouleHeat, element_temperatures
from .shot_model import begin_model_shot, load_model_shot_state, model_shot_state
from .snapshots import EMSnapshots
from .solver import make_em_solver

log = logging.getLogger(__name__)


#: the history columns of a GetDP load
LOAD_COLUMNS_COUPLED = ("force_x_N", "force_y_N", "conservation_error_rel", "coil_current_A",
                        "coil_current_abs_max_A", "coil_voltage_V",
                        "capacitor_voltage_V", "coil_joule_heat_J", "coil_temperature_rise_K",
                        "magnetic_energy_J", "workpiece_joule_power_W", "getdp_force_z_N",
                        "em_mesh_min_quality", "em_remeshes", "em_factorisations", "em_corrections")
#: with several coils: the columns shared by all coils (coil_current_abs_max_A: the largest |current| of
#: any coil over the EM step), then :data:`COIL_COLUMNS` per coil, prefixed by its name
LOAD_COLUMNS_SHARED = ("force_x_N", "force_y_N", "conservation_error_rel", "coil_current_abs_max_A",
                       "capacitor_voltage_V", "magnetic_energy_J", "workpiece_joule_power_W", "getdp_force_z_N",
                       "em_mesh_min_quality", "em_remeshes", "em_factorisations", "em_corrections")
COIL_COLUMNS = ("current_A", "voltage_V", "joule_heat_J", "temperature_rise_K")


def coupled_columns(coil_names: list[str]) -> tuple[str, ...]:
    """History columns of a GetDP load: :data:`LOAD_COLUMNS_COUPLED` for one coil (today's names), else
    :data:`LOAD_COLUMNS_SHARED` and ``<coil>_current_A``, ``<coil>_voltage_V``, ... per coil."""
    if len(coil_names) <= 1:
        return LOAD_COLUMNS_COUPLED
    return LOAD_COLUMNS_SHARED + tuple(f"{n}_{c}" for n in coil_names for c in COIL_COLUMNS)


class GetDPLoad(EMSnapshots, LoadCapabilities):
    """Load provider: GetDP eddy-current forces on the conductor bodies (see the module docstring).

    Parameters
    ----------
    geometry : EMGeometry
        The EM mesh and its regions.
    model : EMModel
        The GetDP model.
    work_dir : Path
        Folder of the getdp runs (one sub-folder per EM step).
    bodies : list of ConductorBody
        The mechanical bodies that are EM conductors (the workpiece first).
    keep_runs : bool
        Keep every run folder (default: only the last two).
    remesh_quality : float
        Remesh the air when the worst element quality (:func:`~.mesh_motion.triangle_quality`) falls
        below this fraction of the worst quality of the freshly made mesh.
    sizes : (float, float)
        Element sizes (m) near the coil and far in the air, for remeshing.
    em_substeps : int
        Implicit sub-steps inside each EM step (one getdp run, frozen geometry); the force
        handed to the mechanics is their mean, so the EM step's impulse is kept.
    time_scheme : {"euler", "bdf2"}
        See :class:`~pulseform.solvers.getdp.GetDPSolver`.
    depth : float
        Planar geometries: the mechanics' thickness (m) that multiplies GetDP's per-metre forces.
    getdp_process : {"per_step", "persistent", "auto"}
        One getdp process per EM step (:class:`~pulseform.solvers.getdp.GetDPSolver`), or one for the
        whole run (:class:`~pulseform.solvers.getdp.persistent.PersistentGetDPSolver`, BDF2 only;
        "auto" takes it with BDF2).
    factor_reuse : FactorReuse
        Kept LU factors across the persistent getdp's EM steps; history columns ``em_factorisations``,
        ``em_corrections`` (the counts so far).
    """

    def __init__(self, geometry: EMGeometry, model: EMModel, work_dir: Path, bodies: list[ConductorBody],
                 keep_runs: bool = False, remesh_quality: float = 0.3, sizes: tuple[float, float] = (1e-3, 0.02),
                 em_substeps: int = 1, depth: float = 1.0, time_scheme: str = "euler",
                 getdp_process: str = "per_step", factor_reuse: FactorReuse = FactorReuse()) -> None:
        self.geometry, self.bodies = geometry, list(bodies)
        self.keep_runs, self.remesh_quality, self.sizes = keep_runs, remesh_quality, sizes
        self.em_substeps = em_substeps
        self.axisymmetric = not geometry.planar
        self.scale = 1.0 if self.axisymmetric else float(depth)
        self.solver = make_em_solver(model, work_dir, time_scheme, getdp_process, factor_reuse=factor_reuse)
        #: coil names of the history columns (several coils: one column set per coil)
        self.coil_names = [c.name or f"coil{k}" for k, c in enumerate(model.coils, start=1)]
        self.columns = coupled_columns(self.coil_names) + (("em_newton_iterations",) if model.is_nonlinear else ())
        self.state = self.solver.initial_state(0.0)
        # the bodies' material coordinates
        self.X0 = {b.name: geometry.mesh.points[b.body_to_em].copy() for b in self.bodies}
        self.material = geometry.mesh.points.copy()  # material coordinates of every EM node
        self.remeshes = 0
        self.joule = JouleHeat()   # the Joule heat per mechanical cell of the bodies with a temperature
        #: a conductor's σ follows its cells' temperatures (:mod:`pulseform.solvers.getdp.conductivity`)
        self.conductivity_follows_temperature = any(c.conductivity_law is not None for c in model.conductors)
        self.gmsh_time_limit: float | None = None  # wall-time limit of a remesh (s)
        self._set_mesh(geometry.mesh)
        self.min_quality = float(self.mover.q_ref.min())
        self._moved: tuple[float, np.ndarray] | None = None  # (t0, moved EM nodes) of the coming step
        self._runs: list[Path] = []
        self._pinned: Path | None = None  # run folder the last checkpoint restarts from
        self._deleting: list[threading.Thread] = []  # background deletions of old run folders
        self.last = None  # (moved EM points, EMStepResult, EM mesh) of the latest step
        self.field_times: np.ndarray | None = None  # EM steps ending at these times (s) print whole-domain fields
        self.peak_abs_current = 0.0  # largest |coil current| at the end of an EM step so far (A)
        self._peak: dict | None = None  # that step's snapshot material (see take_peak_snapshot)
        self._fetched_peak: dict | None = None  # the latest earlier peak candidate with its fields
        self._rise: list[tuple[float, float]] = []  # (t, |coil current|) of the last three EM steps
        self._post_fields_ok = True  # False once the deck turned out to have no PostOperation EM_Field
        self.timers = {"getdp_process_s": 0.0, "getdp_io_s": 0.0, "mesh_motion_s": 0.0, "transfer_s": 0.0}

    @property
    def tags(self) -> np.ndarray:
        """EM physical ids of the conductor bodies."""
        return np.array([b.tag for b in self.bodies])

    def _set_mesh(self, mesh) -> None:
        """Use ``mesh`` (current configuration) as the reference of the mesh motion."""
        self.geometry = dataclasses.replace(self.geometry, mesh=mesh)
        self.x_ref = mesh.points.copy()
        coil_tags = [tag for tag, _ in self.geometry.coil_turns()]
        fixed = np.unique(np.concatenate([
            mesh.triangles[np.isin(mesh.tri_tags, coil_tags)].ravel(),
            mesh.triangles[mesh.tri_tags == SHELL_TAG].ravel(),
            mesh.lines[mesh.line_tags == OUTER_TAG].ravel()] + [b.body_to_em for b in self.bodies]))
        axis = np.unique(mesh.lines[mesh.line_tags == AXIS_TAG].ravel())  # slide along the axis/symmetry line
        self.mover = MeshMover(self.x_ref, mesh.triangles, (np.union1d(fixed, axis), fixed))
        self.mover.min_quality = self.remesh_quality * float(self.mover.q_ref.min())

    def _remesh(self, positions: dict[str, np.ndarray]) -> None:
        """Mesh air, coil and shell again around the bodies' current shapes (see :mod:`.remesh`)."""
        parts = []
        for b in self.bodies:
            cur = np.zeros_like(self.x_ref)
            cur[b.body_to_em] = b.vertices(positions[b.name])
            parts.append((cur[b.sub.em_nodes], b.sub.cells, b.tag))
        g = self.solver.model
        mesh, indices = remesh_around(parts, self.geometry.coil_turns(), g.shell[0], g.shell[1], *self.sizes,
                                      time_limit=self.gmsh_time_limit)
        mesh.names = dict(self.geometry.mesh.names)
        self.material = mesh.points.copy()
        for b, (pts, _, _), index in zip(self.bodies, parts, indices):
            local = np.full(len(self.x_ref), -1, dtype=np.int64)  # old EM node -> row of the submesh
            local[b.sub.em_nodes] = np.arange(len(b.sub.em_nodes))
            b.body_to_em = index[local[b.body_to_em]]
            b.sub = ConductorMesh(np.flatnonzero(mesh.tri_tags == b.tag), index, pts, b.sub.cells)
            b.match_cells()   # a six-node body: its cells' EM triangles (renumbered, node for node the same)
            self.material[b.body_to_em] = self.X0[b.name]
        self._set_mesh(mesh)
        self.remeshes += 1

    def follow(self, t0: float, mechanics) -> None:
        """Mesh motion for the EM step starting at ``t0`` (step 2 of the loop's EM step,
        :mod:`pulseform.orchestrator.coupling.loop`): the EM mesh follows the bodies.

        When the moved mesh's worst element falls below ``remesh_quality`` (or inverts), the air
        is remeshed around the bodies and the EM state is carried in material coordinates.
        """
        c0 = time.perf_counter()
        positions = mechanics.positions()
        u = np.zeros_like(self.x_ref)
        for b in self.bodies:
            u[b.body_to_em] = b.vertices(positions[b.name]) - self.x_ref[b.body_to_em]
        try:
            x_em = self.mover.moved(u)  # checks quality: a degenerate or inverted element never reaches GetDP
        except MeshQualityError as exc:
            log.info("t = %.6g s: %s: remeshing the air around the conductors", t0, exc)
            self._remesh(positions)
            x_em = self.mover.moved(np.zeros_like(self.x_ref))
        self.min_quality = min(self.min_quality, float(self.mover.last_min_quality))
        self._moved = (t0, x_em)
        self.timers["mesh_motion_s"] += time.perf_counter() - c0

    def load(self, t0: float, t1: float, t_mid: float, mechanics) -> LoadStep:
        """Run one getdp step to ``t1`` on the mesh :meth:`follow` moved, return nodal forces (N).

        A caller that drives the load alone (no loop) gets :meth:`follow` here."""
        if self._moved is None or self._moved[0] != t0:
            self.follow(t0, mechanics)
        x_em, self._moved = self._moved[1], None
        mesh_k = self.geometry.mesh.with_points(x_em)
        if abs(self.state.t - t0) > 1e-9 * max(t1, 1e-300):
            raise RuntimeError(f"EM state at t = {self.state.t:.9g} s, but the step starts at {t0:.9g} s")
        start0 = getattr(self.solver, "startup_s", 0.0)   # a persistent getdp's process starts (s)
        fetch0 = self.timers["getdp_process_s"]            # _track_peak's post-processing adds to it
        c1 = time.perf_counter()
        # after a remesh, keep carrying the state through the Init path: a -restart from the .res of an
        # Init-path run gave garbage fields near the axis (GetDP 3.2.0; seen in tests, see the issue notes)
        fields = {"field_output": True} if self._wants_fields(t1) else {}
        if self.conductivity_follows_temperature:   # σ(T) per element from the cells' temperatures at t0
            self.solver.set_element_temperatures(*element_temperatures(mechanics, self.bodies, mesh_k.triangles,
                                                                       mesh_k.tri_tags))
        result, self.state = self.solver.step(mesh_k, self.state, t1, n_sub=self.em_substeps,
                                              material_points=self.material,
                                              force_init_path=self.remeshes > 0 and self.init_after_remesh, **fields)
        self.last = (x_em, result, self.geometry.mesh)
        self._track_peak(t1, x_em, result)
        self._prune(Path(result.path))
        c2 = time.perf_counter()
        keep = np.isin(result.element_tags, self.tags)
        f = result.force_density_mean[keep]  # impulse-consistent mean over the sub-steps
        tris = mesh_k.triangles[result.elements[keep]]
        forces = body_forces(self.bodies, x_em, mesh_k.triangles, result.elements[keep], f,
                             axisymmetric=self.axisymmetric, scale=self.scale)
        integral = self.scale * cell_force_integral(x_em, tris, f, axisymmetric=self.axisymmetric)
        mag = model_magnetisation_forces(self.solver.model, x_em, mesh_k.triangles, result, mesh_k.lines)
        if mag is not None:   # magnetised bodies: their surface force joins the Lorentz force (on the vertex rows)
            integral = integral + self.scale * mag.sum(axis=0)
            for b in self.bodies:
                forces[b.name][:len(b.body_to_em)] += (self.scale * mag)[b.body_to_em]
        getdp_total = result.conductor_force[-1, 0]
        heat = self.joule.heat(mechanics, self.bodies, result, mesh_k.triangles, t1 - t0)
        c3 = time.perf_counter()
        # getdp's own time: the step's answer, a process start (pre-processing) and any fields fetched for the
        # peak snapshot (timed by _fields); the rest of c1..c2 is the files and the bookkeeping around them
        fetched = self.timers["getdp_process_s"] - fetch0
        process = (result.run.wall_time if result.run is not None else 0.0) \
            + getattr(self.solver, "startup_s", 0.0) - start0
        self.timers["getdp_process_s"] += process
        self.timers["getdp_io_s"] += (c2 - c1) - process - fetched
        self.timers["transfer_s"] += c3 - c2
        return LoadStep(forces, integral, self._values(result, getdp_total), heat)

    def _values(self, result, getdp_total: np.ndarray) -> dict[str, float]:
        """History values of an EM step (circuit, energies, the workpiece's GetDP force; per coil with several)."""
        if len(self.coil_names) > 1:
            return self._coil_values(result, getdp_total)
        return {
            "coil_current_A": float(result.coil_current[-1, 0]),
            "coil_current_abs_max_A": float(np.abs(result.coil_current[:, 0]).max()),
            "coil_voltage_V": float(result.coil_voltage[-1, 0]),
            "capacitor_voltage_V": float(result.capacitor_voltage[-1]) if result.capacitor_voltage is not None else 0.0,
            "coil_joule_heat_J": float(result.coil_heat[0]),
            "coil_temperature_rise_K": float(result.coil_temperature_rise[0]),
            "magnetic_energy_J": float(result.magnetic_energy[-1]),
            "workpiece_joule_power_W": float(result.conductor_power[-1, 0]),
            "getdp_force_z_N": float(self.scale * getdp_total[1]),
            "em_mesh_min_quality": float(self.mover.last_min_quality),
            "em_remeshes": float(self.remeshes), **self._solve_counts(result),
        }

    def _solve_counts(self, result) -> dict[str, float]:
        """The run's factorisations and kept-factor corrections so far (history columns): the persistent
        getdp's counts (:class:`~pulseform.solvers.getdp.persistent_process.FactorReuse`); a getdp
        process per EM step factorises every one of its ``em_substeps`` sub-steps. With a B–H curve
        ``em_newton_iterations``: the most linear solves (first + Newton's) of a sub-step of ``result``."""
        s = self.state
        nl = {"em_newton_iterations": float(max(result.newton_iterations)) if result is not None else 0.0} \
            if self.solver.model.is_nonlinear else {}
        if hasattr(self.solver, "factor_reuse"):
            return {"em_factorisations": float(s.factorisations), "em_corrections": float(s.corrections), **nl}
        return {"em_factorisations": float(s.step_index * self.em_substeps), "em_corrections": 0.0, **nl}

    def _coil_values(self, result, getdp_total: np.ndarray) -> dict[str, float]:
        """:meth:`_values` with several coils: the shared columns, then each coil's."""
        out = {
            "coil_current_abs_max_A": float(np.abs(result.coil_current).max()),
            "capacitor_voltage_V": float(result.capacitor_voltage[-1]) if result.capacitor_voltage is not None else 0.0,
            "magnetic_energy_J": float(result.magnetic_energy[-1]),
            "workpiece_joule_power_W": float(result.conductor_power[-1, 0]),
            "getdp_force_z_N": float(self.scale * getdp_total[1]),
            "em_mesh_min_quality": float(self.mover.last_min_quality),
            "em_remeshes": float(self.remeshes), **self._solve_counts(result),
        }
        for k, name in enumerate(self.coil_names):
            out.update({f"{name}_current_A": float(result.coil_current[-1, k]),
                        f"{name}_voltage_V": float(result.coil_voltage[-1, k]),
                        f"{name}_joule_heat_J": float(result.coil_heat[k]),
                        f"{name}_temperature_rise_K": float(result.coil_temperature_rise[k])})
        return out

    def initial(self, mechanics) -> LoadStep:
        """The EM state at t = 0 for the history's first row: the circuit as it starts (current 0,
        a bank charged to V0), no field yet (no force, magnetic energy or Joule power), the fresh
        mesh's quality. The coil voltage is the one before the switch closes (0 V): it jumps to
        about V0·L_coil/(L_coil + L_ext) as the discharge starts, which the first EM step shows."""
        s = self.state
        if len(self.coil_names) > 1:
            signs = [c.sign for c in self.solver.model.coils]
            values = {"coil_current_abs_max_A": abs(float(s.current)), "capacitor_voltage_V": float(s.capacitor_voltage),
                      "magnetic_energy_J": 0.0, "workpiece_joule_power_W": 0.0, "getdp_force_z_N": 0.0,
                      "em_mesh_min_quality": float(self.mover.q_ref.min()), "em_remeshes": float(self.remeshes),
                      **self._solve_counts(None)}
            for k, name in enumerate(self.coil_names):
                values.update({f"{name}_current_A": signs[k] * float(s.current), f"{name}_voltage_V": 0.0,
                               f"{name}_joule_heat_J": float(s.coil_heat[k]) if s.coil_heat else 0.0,
                               f"{name}_temperature_rise_K": 0.0})
            return LoadStep({}, None, values)
        return LoadStep({}, None, {
            "coil_current_A": float(s.current),
            "coil_current_abs_max_A": abs(float(s.current)),
            "coil_voltage_V": 0.0,
            "capacitor_voltage_V": float(s.capacitor_voltage),
            "coil_joule_heat_J": float(s.coil_heat[0]) if s.coil_heat else 0.0,
            "coil_temperature_rise_K": 0.0,
            "magnetic_energy_J": 0.0,
            "workpiece_joule_power_W": 0.0,
            "getdp_force_z_N": 0.0,
            "em_mesh_min_quality": float(self.mover.q_ref.min()),
            "em_remeshes": float(self.remeshes), **self._solve_counts(None),
        })

    #: after a remesh, every step carries the state through the Init path (False: the remesh carried a
    #: ``.res`` to the new mesh and restarts go on, :class:`~.user_remesh.UserDeckLoad` on a template deck)
    init_after_remesh = True

    # ------------------------------------------------------------------ field snapshots
    columns = LOAD_COLUMNS_COUPLED  # the one-coil columns; an instance with several coils has its own
    em_fields = True

    def run_metrics(self, history, counters) -> dict[str, float]:
        """EM figures of a coupled run from its history (current, peak force, heat, conservation) and the EM timers;
        with several coils the heat and temperature rise per coil (``<coil>_joule_heat_J``, ...) and the
        peak current of each (``<coil>_current_peak_kA``, at the ends of the EM steps)."""
        current = history.column("coil_current_abs_max_A")
        out = {"coil_current_peak_kA": float(np.abs(current).max()) / 1e3,
               # the workpiece's axial (r-z: z; planar: y) Lorentz force, GetDP's integral at the end of each EM step
               "force_peak_N": float(np.abs(history.column("getdp_force_z_N")).max())}
        if len(self.coil_names) > 1:
            for name in self.coil_names:
                out[f"{name}_current_peak_kA"] = float(np.abs(history.column(f"{name}_current_A")).max()) / 1e3
                for col in ("joule_heat_J", "temperature_rise_K"):
                    out[f"{name}_{col}"] = float(history.column(f"{name}_{col}")[-1])
        else:
            out["coil_joule_heat_J"] = float(history.column("coil_joule_heat_J")[-1])
            out["coil_temperature_rise_K"] = float(history.column("coil_temperature_rise_K")[-1])
        return {**out, "conservation_error_rel": float(counters.ledger_max), "em_time_s": float(counters.em_time_s),
                **{f"em_{k}": v for k, v in self.timers.items()}}

    def _prune(self, newest: Path) -> None:
        """Delete run folders older than the last two, except the one the last checkpoint needs."""
        if newest in self._runs:  # a repeated (iterated) step reuses its folder
            return
        self._runs.append(newest)
        if self.keep_runs:
            return
        for old in self._runs[:-2]:
            if old != self._pinned:
                self._discard(old)
        self._runs = [p for p in self._runs[:-2] if p == self._pinned] + self._runs[-2:]

    def _discard(self, path: Path) -> None:
        """Delete a run folder in a background thread (the next getdp run overlaps the deletion);
        :meth:`close` waits for the deletions."""
        self._deleting = [t for t in self._deleting if t.is_alive()]
        thread = discard_folder(path)
        if thread is not None:
            self._deleting.append(thread)

    # ------------------------------------------------------------------ repeated shots (run/shots.py)
    def coil_temperatures(self) -> np.ndarray:
        """The coils' lumped temperatures now (K): their initial temperature + Joule heat / (m c_p)."""
        return coil_temperature(self.solver.model, self.geometry.mesh, self.state)

    def coil_heat_paths(self) -> tuple[np.ndarray, np.ndarray]:
        """(outer surface m², m c_p J/K) of every coil, for their cooling between shots (per metre in planar)."""
        mesh = self.geometry.mesh
        area = np.array([region_surface(mesh.points, mesh.triangles[mesh.tri_tags == tag], self.axisymmetric)
                         for tag, _ in self.geometry.coil_turns()])
        return area, coil_mass_cp(self.solver.model, mesh)

    def begin_shot(self, t0: float, voltage: float, coil_temperature: np.ndarray) -> None:
        """Start a new discharge at ``t0`` (s): the EM state at rest, the bank charged to ``voltage`` (V), the coils
        at ``coil_temperature`` (K; their Joule heat counts from here)."""
        begin_model_shot(self.solver.model, voltage, coil_temperature)
        self.state = self.solver.initial_state(t0)
        self._moved = None
        self._rise = []

    def shot_state(self) -> dict:
        """What a checkpoint keeps of the current shot: the bank's voltage and the coils' start temperatures."""
        return model_shot_state(self.solver.model)

    def load_shot_state(self, d: dict) -> None:
        """Restore :meth:`shot_state`."""
        load_model_shot_state(self.solver.model, d)

    def close(self) -> None:
        """End a persistent getdp and wait until the old run folders are deleted (call once the run is
        over)."""
        self.solver.close()
        for thread in self._deleting:
            thread.join()
        self._deleting = []

    def state_dict(self) -> dict[str, np.ndarray]:
        """EM state (time, circuit, previous .res path, nodal unknown) as a JSON byte array, mesh and
        body maps (the loop's saved state of an iterated step; a checkpoint uses
        :meth:`checkpoint_state_dict`). The run folder holding the state's ``.res`` is kept until the
        next save, so a resume can restart from it.
        """
        if self.state.res_path:
            self._pinned = Path(self.state.res_path).parent
        return self._state_arrays(self.solver.complete_state(self.state))

    def checkpoint_state_dict(self) -> dict[str, np.ndarray]:
        """:meth:`state_dict` at a checkpoint: the state the solver stores there is also the one the
        next step continues from (:meth:`GetDPSolver.checkpoint_state`), and the persistent getdp's
        replay log (``replay_*``, :meth:`PersistentGetDPSolver.replay_arrays`), so that a ``--resume``
        from this checkpoint repeats the uninterrupted run exactly."""
        if self.state.res_path:
            self._pinned = Path(self.state.res_path).parent
        self.state = self.solver.checkpoint_state(self.state)
        d = self._state_arrays(self.state)
        replay = getattr(self.solver, "replay_arrays", None)  # the persistent getdp's segment log
        d.update({f"replay_{k}": v for k, v in (replay() if replay is not None else {}).items()})
        return d

    def _state_arrays(self, state: EMState) -> dict[str, np.ndarray]:
        blob = json.dumps({"state": state.to_dict(), "runs": [str(p) for p in self._runs],
                           "min_quality": self.min_quality, "remeshes": self.remeshes,
                           "peak_abs_current": self.peak_abs_current}).encode()
        m = self.geometry.mesh
        d = {"em_state_json": np.frombuffer(blob, dtype=np.uint8), "mesh_points": m.points.copy(),
             "mesh_triangles": m.triangles.copy(), "mesh_tri_tags": m.tri_tags.copy(), "mesh_lines": m.lines.copy(),
             "mesh_line_tags": m.line_tags.copy(), "material": self.material.copy()}
        for i, b in enumerate(self.bodies):
            d.update({f"body_to_em_{i}": b.body_to_em.copy(), f"sub_rows_{i}": b.sub.rows.copy(),
                      f"sub_em_nodes_{i}": b.sub.em_nodes.copy(), f"sub_points_{i}": b.sub.points.copy()})
        return d

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        data = json.loads(bytes(d["em_state_json"]).decode())
        self.state = EMState.from_dict(data["state"])
        self._runs = [Path(p) for p in data["runs"]]
        self.min_quality = float(data["min_quality"])
        self.remeshes = int(data.get("remeshes", 0))
        # the peak snapshot so far was written with the checkpoint; a repeated (iterated) step
        # restores the value before it and replaces its own earlier try (_track_peak)
        self.peak_abs_current = float(data.get("peak_abs_current", 0.0))
        if "mesh_points" in d and (self.remeshes or not np.array_equal(d["mesh_triangles"], self.geometry.mesh.triangles)):
            mesh = EMMesh(d["mesh_points"], d["mesh_triangles"], d["mesh_tri_tags"], d["mesh_lines"],
                          d["mesh_line_tags"])
            for i, b in enumerate(self.bodies):
                b.body_to_em = np.array(d[f"body_to_em_{i}"])
                b.sub = ConductorMesh(np.array(d[f"sub_rows_{i}"]), np.array(d[f"sub_em_nodes_{i}"]),
                                      np.array(d[f"sub_points_{i}"]), b.sub.cells)
                b.match_cells()
            self._set_mesh(mesh)
        if "material" in d:
            self.material = np.array(d["material"])
        replay = {k[7:]: v for k, v in d.items() if k.startswith("replay_")}  # a checkpoint's getdp log
        if replay and hasattr(self.solver, "load_replay"):
            self.solver.load_replay(replay)
        self._pinned = Path(self.state.res_path).parent if self.state.res_path else None
