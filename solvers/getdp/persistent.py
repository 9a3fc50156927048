"""One getdp process advances many EM steps while the mesh moves (BDF2): no process per step.

:class:`PersistentGetDPSolver` has the stepping API of :class:`~.solver.GetDPSolver` (BDF2 only)
and gives the same results to round-off (tests/getdp/test_persistent.py); it drives one
:class:`PersistentProcess` per mesh connectivity (a remesh or a resume starts a new one, seeded
with both BDF2 history states).

The process and its message protocol (FIFOs, binary ``.res`` messages, failures) are in
:mod:`.persistent_process`.

Only what the loop needs is computed each step (``PF_GlobalsSet`` = 37): the coil current and
voltage and the circuit (global unknowns), the magnetic energy as ½ (j, a) over coils and
conductors (equal to the whole-domain ½ (ν curl a, curl a) of the discrete solution), the
conductors' Joule power, and the per-element force integrals (with a B–H curve the energy is the
whole-domain ∫ w(b): :data:`NONLINEAR_GLOBALS`); the conductor force is their sum,
the coil's Joule power (N_s I / S_c)² / σ × V_coil (uniform current density), the coil force is
not computed (NaN).  B and Joule power per element are fetched only when read (a field output).

With σ(T) laws (:mod:`.conductivity`) each step message also carries σ of every element of the regions with a law,
and the coil's Joule power is taken at the step's σ.

With a B–H curve (``model.is_nonlinear``) each step is Newton's method of ``decks/Lib_Newton.pro`` (every iteration
factorises: no kept factors); the step's linear solves are its result's ``newton_iterations``
(:func:`.bh_curve.step_newton`).
"""
from __future__ import annotations

import json
import logging
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np

from .bdf2 import match_rows, trapezoid_mean
from .conductivity import message_sigma, persistent_numbers, start_power, step_sigma
from .files import element_volumes, init_list_line, read_element_table
from .mesh import EMMesh, coil_tag, conductor_tag
from .model import EMModel, EMState, EMStepResult
from .persistent_data import nodal_dof_map, read_binary_res
from .bh_curve import newton_factor_reuse, step_newton
from .persistent_process import (FLAG_COND_FIELDS, FLAG_ELEM, FLAG_FIELDS, FLAG_STATE, LEAN_GLOBALS, PERSISTENT_LIB,
                                 FactorReuse, PersistentProcess, StepAnswer)
from .replay import ReplayLog, connectivity_signature, segment_length
from .runner import GetDPError, RunInfo, log_tail
from .solver import CASE_DECK, DEFAULT_PETSC_ARGS, GetDPSolver

log = logging.getLogger(__name__)
#: ``PF_GlobalsSet`` with a B–H curve: the magnetic energy is the whole domain's ∫ w(b) (2), not ½ (j, a) over the
#: sources (32), which equals the stored energy ½ (ν curl a, curl a) only for a linear ν
NONLINEAR_GLOBALS = LEAN_GLOBALS - 32 + 2


class PersistentStepResult(EMStepResult):
    """An :class:`~.model.EMStepResult` whose Joule power and B on the conductors are fetched from
    getdp when first read (possible until the next step)."""

    _solver: "PersistentGetDPSolver | None" = None
    _step: int = -1
    _lazy: dict | None = None

    def _get(self, name: str) -> np.ndarray:
        lazy = self.__dict__.setdefault("_lazy", {})
        if lazy.get(name) is None:
            self._solver._conductor_fields(self)
        return lazy[name]

    def _put(self, name: str, value) -> None:
        self.__dict__.setdefault("_lazy", {})[name] = value

    joule_density = property(lambda self: self._get("joule_density"), lambda self, v: self._put("joule_density", v))
    flux_density = property(lambda self: self._get("flux_density"), lambda self, v: self._put("flux_density", v))


class PersistentGetDPSolver(GetDPSolver):
    """:class:`~.solver.GetDPSolver` with ``time_scheme="bdf2"`` on one persistent getdp process.

    Same constructor and :meth:`step` (``n_sub = 1``); a step's whole-domain fields
    (:meth:`post_fields`) and conductor fields can be fetched only until the next step
    (:attr:`fields_expire`).  The returned :class:`~.model.EMState` carries the circuit and the
    BDF2 scalars; :meth:`complete_state` adds the nodal history for a checkpoint (a query).
    Call :meth:`close` at the end (a finalizer kills a forgotten process).
    """

    #: fields of a step are available only until the next step
    fields_expire = True

    def __init__(self, model: EMModel, work_dir: str | Path, *, executable: str = "getdp",
                 petsc_args: Sequence[str] = DEFAULT_PETSC_ARGS, timeout: float | None = None,
                 deck: str | Path = CASE_DECK, extra_numbers: dict[str, float] | None = None,
                 preamble: Sequence[str] = (), time_scheme: str = "bdf2", verbosity: int = 2,
                 factor_reuse: FactorReuse = FactorReuse(), **_unused) -> None:
        if time_scheme != "bdf2":
            raise ValueError("the persistent getdp implements time_scheme='bdf2' only")
        super().__init__(model, work_dir, executable=executable, petsc_args=petsc_args, timeout=timeout, deck=deck,
                         extra_numbers=extra_numbers, preamble=preamble, time_scheme="bdf2")
        self.verbosity = verbosity
        self.factor_reuse = newton_factor_reuse(self.model, factor_reuse)  # kept LU factors (Lib_PersistentStep.pro)
        self.proc: PersistentProcess | None = None
        self.segment = 0
        self.startup_s = 0.0  # wall time of the process starts (s)
        self._last: tuple | None = None  # (step_index, t) of the last step's start: a repeat is a redo
        self._hist: dict | None = None  # Python-side history at the start of the current step
        self._result: PersistentStepResult | None = None
        self.replay_log: ReplayLog | None = None  # the running segment's seed and messages
        self._pending: ReplayLog | None = None  # a checkpoint's log, replayed at the first step
        self.replayed_steps = 0
        self._replay_sigma: tuple | None = None  # (coil σ, element σ) of a replayed step (its log's, not recomputed)

    # ------------------------------------------------------------------ processes
    def make_process(self, mesh: EMMesh, material: np.ndarray, state: EMState, run_dir: Path,
                     extra_numbers: dict[str, float] | None = None) -> PersistentProcess:
        """The getdp process (prepared in ``run_dir``, not started) that continues ``state`` on ``mesh``:
        fresh, or seeded with the BDF2 history interpolated from the material coordinates ``material``
        (m). ``extra_numbers`` go last (bench/em_step.py sets the self-clocked baseline's ``PF_Self*``)."""
        m = self.model
        numbers = self.run_numbers(mesh)
        numbers.update(Flag_ElemOut=0, PF_GlobalsSet=NONLINEAR_GLOBALS if m.is_nonlinear else LEAN_GLOBALS,
                       PF_T1=state.t, PF_Step0=state.step_index, PF_DtPrev=0.0, PF_Seed=1, **self.factor_reuse.numbers(), **persistent_numbers(m))
        lines = [f'PulseformPersistentLib = "{PERSISTENT_LIB}";'] + self.preamble + self._table_lines()
        if m.circuit is not None:
            numbers["Init_Vc"], numbers["Init_I"] = state.capacitor_voltage, state.current
        if state.a_values is not None:
            ids, v1 = self._interpolate_a(mesh, material, state, state.a_values)
            lines.append(init_list_line("InitA_List", ids, v1))
            numbers["Flag_InitA"] = 1
            if state.a_prev_values is not None and state.dt_prev:
                _, v2 = self._interpolate_a(mesh, material, state, state.a_prev_values)
                lines.append(init_list_line("InitA2_List", ids, v2))
                numbers.update(Flag_InitA=2, PF_Seed=2, PF_DtPrev=state.dt_prev, PF_T2=state.t - state.dt_prev)
                if m.circuit is not None:
                    numbers["Init2_Vc"], numbers["Init2_I"] = state.capacitor_voltage_prev, state.current_prev
        elif state.step_index or state.res_path:
            raise ValueError("the EM state has no nodal values to start a getdp process from")
        if m.applied_field is not None:   # the unit time function of the seed states (0 at rest)
            numbers["Field_F1"] = state.applied_f
            numbers["Field_F2"] = state.applied_f_prev if numbers["PF_Seed"] == 2 else state.applied_f
        numbers.update(extra_numbers or {})
        return PersistentProcess(run_dir, mesh, numbers, lines, self.deck, executable=self.executable,
                                 petsc_args=self.factor_reuse.solver_args(self.petsc_args), time_limit=self.timeout,
                                 verbosity=self.verbosity, element_values=m.has_conductivity_laws)

    def _start(self, mesh: EMMesh, material: np.ndarray, state: EMState) -> None:
        """A new process on ``mesh`` from ``state`` (fresh, or seeded with its BDF2 history)."""
        self.close()
        self.segment += 1
        m = self.model
        seed = EMState.from_dict(json.loads(json.dumps(state.to_dict())))  # a copy, as a checkpoint stores it
        self.proc = self.make_process(mesh, material, state, self.work_dir / f"persistent_{self.segment:03d}")
        self.startup_s += self.proc.start(state.step_index, state.t)
        self.material = np.array(material, float)
        self.replay_log = ReplayLog(seed, self.material.copy(), connectivity_signature(mesh.triangles, mesh.tri_tags))
        self.mass_cp = np.array([c.density * c.heat_capacity * self._volume(mesh, coil_tag(k), True)
                                 for k, c in enumerate(m.coils, start=1)])
        self.coil_joule = np.array([self._volume(mesh, coil_tag(k), True) / c.sigma
                                    * (c.turns / self._volume(mesh, coil_tag(k), False)) ** 2
                                    for k, c in enumerate(m.coils, start=1)])  # P = this * I^2 (W/A^2)
        self.coil_sigma = [c.sigma for c in m.coils]  # σ of this step's coils (S/m; a σ(T) law's per step)
        self.elements = None
        self._a_index = None  # (node -> unknown of system A, number of unknowns), read at the first state query
        self._f_prev = None
        if state.force_density is not None and state.force_points is not None:
            self._f_prev = (np.asarray(state.force_density, float), np.asarray(state.force_points, float))
        log.debug("persistent getdp %s started at t = %.6g s (step %d)", self.proc.run_dir.name, state.t,
                  state.step_index)

    def probe(self, mesh: EMMesh) -> bool:
        """True if the deck runs ``EM_Persistent`` on ``mesh`` (a process started and stopped, no step);
        False with the reason logged when getdp fails (e.g. a deck without the resolution)."""
        try:
            self._start(mesh, mesh.points, self.initial_state())
            return True
        except GetDPError as exc:
            log.info("no persistent getdp for deck %s: %s", self.deck, exc.summary)
            return False
        finally:
            self.close()
            self.segment = 0

    def _volume(self, mesh: EMMesh, tag: int, weighted: bool) -> float:
        """Volume (2πr-weighted in axisymmetry when ``weighted``) or area of region ``tag`` (m³ or m²)."""
        axi = self.model.axisymmetric and weighted
        return float(element_volumes(mesh, np.flatnonzero(mesh.tri_tags == tag), axi).sum())

    def close(self) -> None:
        """End the getdp process (if any)."""
        if self.proc is not None:
            rc = self.proc.close()
            if rc and not getattr(self.proc, "reported", False):
                log.warning("persistent getdp ended with exit code %s (log: %s)", rc, self.proc.log_path)
            self.proc = None

    def _same_mesh(self, mesh: EMMesh) -> bool:
        p = self.proc
        return p is not None and (mesh.triangles is p.mesh.triangles or np.array_equal(mesh.triangles, p.mesh.triangles)) \
            and (mesh.tri_tags is p.mesh.tri_tags or np.array_equal(mesh.tri_tags, p.mesh.tri_tags))

    # ------------------------------------------------------------------ one step
    def step(self, mesh: EMMesh, state: EMState, t_end: float, n_sub: int = 1, *,
             material_points: np.ndarray | None = None, run_name: str | None = None,
             force_init_path: bool = False, element_output: str = "all",
             field_output: bool = False) -> tuple[EMStepResult, EMState]:
        """One BDF2 step from ``state.t`` to ``t_end`` on ``mesh`` (its current node positions); see
        :meth:`GetDPSolver.step`.  A step repeated from the same state (``coupling.iterate``) is redone
        from its start vectors on the new geometry; a new connectivity (remesh) starts a new process
        seeded with both history states interpolated in material coordinates."""
        if n_sub != 1:
            raise ValueError("time_scheme='bdf2' takes one step per EM step: n_sub (em_substeps) must be 1")
        if not t_end > state.t:
            raise ValueError(f"t_end={t_end} must be after state.t={state.t}")
        mat = mesh.points if material_points is None else np.asarray(material_points, float)
        if self._pending is not None:
            self._replay(mesh, state)
        redo = False
        p = self.proc
        if p is not None and not p.alive:  # it ended by itself (close() drops it): a crash, a signal
            self.proc = None
            raise p.died(f"before step {p.k + 1}")
        if p is not None and self._same_mesh(mesh):
            if p.k == state.step_index + 1 and self._last == (state.step_index, state.t):
                redo = True
            elif p.k != state.step_index or abs(p.t - state.t) > 1e-12 * max(abs(state.t), 1e-300):
                self._start(mesh, mat, state)  # a state from elsewhere (restored): start from it
            elif len(self.replay_log) >= segment_length(mesh.n_nodes):  # the segment is full: seed a new one
                self._start(mesh, mat, self.complete_state(state))
        elif p is not None:  # remesh: carry the history of the old process
            full = self.complete_state(state)
            self._start(mesh, mat, full)
        else:
            self._start(mesh, mat, state)
        sigma = self._step_sigma(mesh, state, float(t_end))
        self.replay_log.add(mesh.points, t_end, state.step_index, field_output, sigma)
        if redo:
            self._f_prev, self.elements = self._hist["f_prev"], self._hist["elements"]
        else:
            self._hist = {"f_prev": self._f_prev, "elements": self.elements}
        self._last = (state.step_index, state.t)
        flags = FLAG_ELEM | (FLAG_FIELDS | FLAG_COND_FIELDS if field_output else 0)
        ans = self.proc.step(mesh.points, float(t_end), flags, redo=redo)
        result = self._result_of(ans, mesh, mat, state, float(t_end), field_output)
        result.newton_iterations = step_newton(self.model, self.proc)
        new_state = EMState(t=float(t_end), step_index=state.step_index + 1,
                            capacitor_voltage=float(ans.glob[1]) if self.model.circuit is not None else 0.0,
                            current=float(ans.glob[3]) if self.model.circuit is not None else 0.0,
                            coil_heat=result.coil_heat.tolist(), dt_prev=result.dt,
                            capacitor_voltage_prev=state.capacitor_voltage, current_prev=state.current,
                            coil_power=result.coil_power[-1].tolist(),
                            coil_sigma=list(self.coil_sigma) if self.model.has_conductivity_laws else None,
                            factorisations=state.factorisations + (sum(result.newton_iterations or ())
                                                                   or int(ans.factorised)),   # Newton: each
                            corrections=state.corrections + ans.corrections)
        if self.model.applied_field is not None:
            new_state.applied_f = float(self.model.applied_field.unit_f(float(t_end)))
            new_state.applied_f_prev = float(state.applied_f)
        return result, new_state

    def _step_sigma(self, mesh: EMMesh, state: EMState, t_end: float) -> tuple[list[float], np.ndarray] | None:
        """With σ(T) laws: this step's σ into the message (:func:`.conductivity.step_sigma` at the element
        temperatures given, or a replayed step's logged values) and ``self.coil_sigma``; (coil σ, element σ) for
        the replay log. None without a law."""
        m = self.model
        if not m.has_conductivity_laws:
            return None
        coils, conductors = step_sigma(m, mesh, state, t_end - state.t, self._elem_temperature)
        tags, values = message_sigma(m, mesh, coils, conductors)
        coil_sigma = [coils.get(k, c.sigma) for k, c in enumerate(m.coils, start=1)]
        if self._replay_sigma is not None:
            coil_sigma, values = self._replay_sigma
            self._replay_sigma = None
        self.proc.set_element_values(tags, values)
        self.coil_sigma = list(coil_sigma)
        return self.coil_sigma, np.array(values, float)

    def _result_of(self, ans: StepAnswer, mesh: EMMesh, mat: np.ndarray, state: EMState, t_end: float,
                   field_output: bool) -> PersistentStepResult:
        m = self.model
        out = self.proc.out_dir
        dt = t_end - state.t
        nk = len(m.conductors)
        if nk:
            ids, eF = read_element_table(out / "elem_F.txt", 3, 1)
            elements = ids - 1
            if self.elements is None or not np.array_equal(elements, self.elements):
                self.elements = elements
                self._tags = mesh.tri_tags[elements]
            vol = element_volumes(mesh, elements, m.axisymmetric)
            force = eF[:, :, :2] / vol[None, :, None]
            cond_force = np.stack([eF[0, self._tags == conductor_tag(j), :2].sum(axis=0) for j in range(1, nk + 1)])
        else:
            elements, force = np.zeros(0, np.int64), np.zeros((1, 0, 2))
            self._tags = np.zeros(0, np.int64)
            cond_force = np.zeros((0, 2))
        current = ans.coil[:, 0]
        if m.has_conductivity_laws:   # the coils' σ of this step (σ(T)): P = V (N / S)² I² / σ
            scale = np.array([c.sigma for c in m.coils]) / np.array(self.coil_sigma)
            coil_power = self.coil_joule * scale * current ** 2
            p_start = start_power(state, self.coil_sigma)
        else:
            coil_power = self.coil_joule * current ** 2
            p_start = np.asarray(state.coil_power if state.coil_power is not None else np.zeros(len(m.coils)), float)
        heat = np.asarray(state.coil_heat or [0.0] * len(m.coils), float) + trapezoid_mean(p_start, coil_power[None]) * dt
        if not (np.all(np.isfinite(force)) and np.all(np.isfinite(current)) and np.isfinite(ans.glob[0])):
            raise GetDPError(f"non-finite EM results at t = {t_end:.6g} s", log_path=self.proc.log_path,
                             run_dir=self.proc.run_dir, log_tail=log_tail(self.proc.log_path))
        circuit = m.circuit is not None
        r = PersistentStepResult(
            times=np.array([t_end]), dt=dt, elements=elements, element_tags=self._tags, force_density=force,
            force_density_centroid=np.full_like(force, np.nan), joule_density=None, flux_density=None,
            coil_current=current[None], coil_voltage=-ans.coil[None, :, 1], coil_power=coil_power[None],
            coil_force=np.full((1, len(m.coils), 2), np.nan), conductor_force=cond_force[None],
            conductor_power=ans.cond[None, :, 0], magnetic_energy=ans.glob[None, 0],
            capacitor_voltage=ans.glob[None, 1] if circuit else None,
            circuit_current=ans.glob[None, 2] if circuit else None, coil_heat=heat,
            coil_temperature_rise=heat / self.mass_cp if len(m.coils) else heat,
            probe_b=np.zeros((1, 0, 2)))
        r._solver, r._step = self, self.proc.k
        r.run = RunInfo(argv=self.proc.argv, run_dir=self.proc.run_dir, log_path=self.proc.log_path,
                        wall_time=ans.wall, cpu_parts=ans.cpu)
        r.path = str(self.proc.run_dir)
        self._start_value(r, mat, mesh, state)
        if field_output:
            self._read_conductor_fields(r, mesh)
            self._read_fields(mesh, out, r)
        self._result = r
        return r

    def _start_value(self, r: PersistentStepResult, mat: np.ndarray, mesh: EMMesh, state: EMState) -> None:
        """The force density at the step's start on these elements (BDF2's trapezoid mean)."""
        if len(r.elements) == 0:
            return
        centroids = None
        if self._f_prev is None:
            if state.a_values is None and state.step_index == 0:  # from rest: no current, no force
                r.force_density_start = np.zeros_like(r.force_density[-1])
        elif self._f_prev[1] is None:  # the same elements as the step before
            r.force_density_start = self._f_prev[0]
        else:  # after a restart: match the element centroids in material coordinates
            centroids = mat[mesh.triangles[r.elements]].mean(axis=1)
            scale = max(float(np.abs(centroids).max()), 1e-30)
            idx = match_rows(centroids, self._f_prev[1], 1e-9 * scale)
            if idx is not None:
                r.force_density_start = self._f_prev[0][idx]
        if r.force_density_start is None:
            warnings.warn("BDF2: no force density at the step's start on these elements; "
                          "force_density_mean falls back to the end value", RuntimeWarning, stacklevel=4)
        self._f_prev = (r.force_density[-1], None)

    # ------------------------------------------------------------------ fields and state
    def _current(self, result: EMStepResult) -> None:
        if self.proc is None or not self.proc.alive or getattr(result, "_step", None) != self.proc.k \
                or result is not self._result:
            raise RuntimeError("fields of an older EM step: the persistent getdp has moved on")

    def _read_conductor_fields(self, r: PersistentStepResult, mesh: EMMesh) -> None:
        out = self.proc.out_dir
        ids, eP = read_element_table(out / "elem_P.txt", 1, 1)
        vol = element_volumes(mesh.with_points(self.proc.points), ids - 1, self.model.axisymmetric)
        r.joule_density = eP[:, :, 0] / vol[None, :]
        r.flux_density = read_element_table(out / "elem_b.txt", 3, 1)[1][:, :, :2]

    def _conductor_fields(self, r: PersistentStepResult) -> None:
        """Fetch Joule power and B on the conductors of the current step (a query)."""
        self._current(r)
        self.proc.query(FLAG_COND_FIELDS)
        self._read_conductor_fields(r, self.proc.mesh)

    def post_fields(self, result: EMStepResult, mesh: EMMesh) -> bool:
        """Whole-domain B and nodal potential of the current step (``result.b_cells``, ``a_nodes``), and
        Joule power and B on the conductors: a query (PostOperation ``EM_Field``); only until the next
        step (:attr:`fields_expire`)."""
        if result.b_cells is not None and result.a_nodes is not None:
            return True
        self._current(result)
        self.proc.query(FLAG_FIELDS | FLAG_COND_FIELDS)
        self._read_fields(mesh, self.proc.out_dir, result)
        self._read_conductor_fields(result, mesh)
        return result.b_cells is not None and result.a_nodes is not None

    def checkpoint_state(self, state: EMState) -> EMState:
        """:meth:`complete_state`; the process continues. A checkpoint also stores
        :meth:`replay_arrays`, from which a ``--resume`` brings a new process into this process's state
        bit for bit (a process seeded with the state itself would differ at round-off, 1e-15 on the
        first step: docs/getdp.md); the state is the fallback when the log cannot be replayed."""
        return self.complete_state(state)  # plain floats and lists: what JSON gives back, bit for bit

    def replay_arrays(self) -> dict[str, np.ndarray]:
        """The running segment's :class:`~.replay.ReplayLog` as arrays (for a checkpoint); empty if
        no process runs."""
        if self.proc is None or not self.proc.alive or self.replay_log is None or not len(self.replay_log):
            return {}
        return self.replay_log.to_arrays()

    def load_replay(self, arrays: dict[str, np.ndarray]) -> None:
        """A checkpoint's :meth:`replay_arrays`: the next :meth:`step` from the checkpoint's state first
        replays the segment in a new process."""
        self._pending = ReplayLog.from_arrays(arrays) if arrays else None

    def _replay(self, mesh: EMMesh, state: EMState) -> None:
        """Replay the pending log if ``state`` is where it ends, on ``mesh``'s connectivity: a new
        process from the segment's seed, sent the same messages; its state is checked against
        ``state`` (circuit scalars bit for bit). Otherwise, or on a mismatch, the caller seeds a
        process from ``state`` (exact to round-off)."""
        rec, self._pending = self._pending, None
        end = rec.ends_at()
        if end is None or end[0] != state.step_index or end[1] != state.t \
                or not np.array_equal(rec.signature, connectivity_signature(mesh.triangles, mesh.tri_tags)):
            _log_fallback("the checkpoint's getdp log does not end at the resumed state")
            return
        states = {rec.seed.step_index: rec.seed}
        new = rec.seed
        for i, (points, t_end, base, fields) in enumerate(zip(rec.points, rec.t_end, rec.base, rec.fields)):
            self._replay_sigma = (rec.coil_sigma[i], rec.sigma[i]) if rec.sigma else None
            _, new = self.step(mesh.with_points(points), states[base], t_end, material_points=rec.material,
                               field_output=fields)
            states[new.step_index] = new
        self.replayed_steps += len(rec)
        log.info("persistent getdp: %d EM steps replayed from the checkpoint's log", len(rec))
        same = (new.step_index, new.t, new.capacitor_voltage, new.current) == \
            (state.step_index, state.t, state.capacitor_voltage, state.current)
        if not same:
            _log_fallback(f"replaying {len(rec)} EM steps gave another state (I = {new.current!r} A vs "
                          f"{state.current!r} A)")
            self.close()

    def complete_state(self, state: EMState) -> EMState:
        """``state`` (the one the last step returned) with the nodal BDF2 history and the start values
        of the next step's trapezoid means: what a checkpoint, a remesh or a per-step solver needs."""
        p = self.proc
        if p is None or not p.alive or p.k != state.step_index or state.a_values is not None:
            return state
        res = p.run_dir / "em.res"
        res.unlink(missing_ok=True)
        p.query(FLAG_STATE)  # x_n and x_{n-1} of system A, binary: the exact unknowns
        if self._a_index is None:
            self._a_index = nodal_dof_map(p.run_dir / "em.pre", 0, p.mesh.n_nodes)
        index, n_dofs = self._a_index
        x_n, x_prev = read_binary_res(res, n_dofs)[-2:]
        tri, used = self.conductor_nodes(p.mesh)
        remap = np.full(p.mesh.n_nodes, -1, np.int64)
        remap[used] = np.arange(len(used))

        def nodal(x: np.ndarray) -> list:
            i = index[used]
            return np.where(i >= 0, x[i], 0.0).tolist()  # a Dirichlet node (axis): 0

        full = EMState(**state.to_dict())
        full.a_points = self.material[used].tolist()
        full.a_triangles = remap[tri].tolist()
        full.a_values = nodal(x_n)
        full.a_prev_values = nodal(x_prev)
        if self._f_prev is not None and self.elements is not None and len(self.elements):
            full.force_density = np.asarray(self._f_prev[0]).tolist()
            full.force_points = self.material[p.mesh.triangles[self.elements]].mean(axis=1).tolist()
        return full


def _log_fallback(why: str) -> None:
    log.warning("persistent getdp: %s; continuing from the stored state (equal to round-off, not bit for bit)", why)
