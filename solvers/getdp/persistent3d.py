"""One getdp process advances many 3D EM steps while the mesh moves (BDF2): no process per step.

:class:`PersistentEM3DStepper` has the step API of :class:`~.stepper3d.EM3DStepper` (``BDF2`` only):
``step(mesh, state, t1, field_output=...)`` returns the same :class:`~.solver3d.EM3DResult` and an
:class:`~.stepper3d.EM3DState`, and gives the same results to round-off
(tests/getdp/test_persistent3d.py). It drives one :class:`~.persistent_process.PersistentProcess`
(FIFOs, binary ``.res`` messages carrying the node displacement increment of a 3-component
displacement system U, failures as :class:`~.runner.GetDPError` with the log tail, time limits) on
the Resolution ``EM_Persistent3D`` of ``decks/Lib_Persistent3D.pro``: per EM step ``DeformMesh``
moves getdp's nodes to the step's positions and BDF2 runs on GetDP's own vectors. Pre-processing
(the gauge tree, the dof numbering) and the electrokinetic pre-solve of the coil directions happen
once per process; the coils must therefore not move (checked).

State: the returned states carry the circuit, the BDF2 scalars and the start value of the next
step's force trapezoid; the solution vectors stay in getdp (``res_path`` and ``x_prev`` are None).
:meth:`PersistentEM3DStepper.complete_state` adds them (a query: x_n written as the per-step path's
ASCII ``.res``, x_{n-1} as an array): a complete state continues on the per-step
:class:`~.stepper3d.EM3DStepper`, or seeds a new process (a checkpoint's resume, a state from
elsewhere: the two vectors sent through the FIFO, ``ReadSolution[A]``), exact to round-off.

Kept factors (``factor_reuse``, :class:`~.persistent_process.FactorReuse`): a step solves its own
system by GCR preconditioned with the LU factors of an earlier step to a relative residual. A state
completed by :meth:`PersistentEM3DStepper.complete_state` (a checkpoint) records which factors the next
step uses (:class:`~.stepper3d.FactorRecord`: getdp's node coordinates and gamma dt of the step that
factorised, and the current coordinates); a new process seeded from it starts at the factorisation's
coordinates, factorises that matrix and moves to the current ones (``prime`` messages) before its first
step, so that a resumed run repeats the uninterrupted one bit for bit while the uninterrupted run keeps its
factors. Where no record can be made (no kept factors, or a move that floating point cannot make exact:
:func:`~.persistent_data.exact_increment`) the step after the checkpoint factorises in both runs. Node
increments are exact: getdp's coordinates are the mechanics' positions bit for bit wherever an increment
can land there (so a new process started from a mesh file at those positions has the same).
Each step's state counts the factorisations and corrections (``timers["getdp_factorisations"]``,
``timers["getdp_corrections"]``).

A conductivity that follows temperature (σ(T), :mod:`.conductivity`): each step message carries σ of every element
of the coils and conductors with a law (``decks/Lib_PersistentSigma.pro``, as in 2D), at the element temperatures
of :meth:`PersistentEM3DStepper.set_element_temperatures` and the coil's lumped temperature; the kept factors' GCR
solves each step's own matrix (assembled with its σ), and a :class:`~.stepper3d.FactorRecord` keeps the σ of the
step that factorised, which the new process's prime message carries. With a B–H curve each step is Newton's method (``decks/Lib_Newton.pro``,
every iteration a factorisation: no kept factors), its linear solves in the result's ``newton_iterations``.

The outputs are the library's own PostOperations (``EM_Step3D`` with the magnetic energy from the
sources, ``Flag_WSources``; ``EM_ElemF3D``, ``EM_Field3D``), read with :func:`~.solver3d.read_results3d`
like the per-step path's, their files deleted after each step. Joule power and b on the conductor
elements (``EM_ElemPB3D``) are asked for only when read (:class:`PersistentEM3DResult`: snapshots,
fields): a step computes what the coupled loop needs.
"""
from __future__ import annotations

import logging
import time
from dataclasses import fields, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from .bh_curve import newton_factor_reuse, step_newton
from .conductivity import checked_temperatures, message_sigma, message_tags, persistent_numbers, step_sigma
from .files import read_element_table
from .mesh import coil_tag
from .mesh3d import Mesh3D
from .persistent_data import exact_increment, read_binary_res
from .persistent_process import (FLAG_COND_FIELDS, FLAG_ELEM, FLAG_FACTORISE, FLAG_FIELDS, FLAG_STATE, FactorReuse,
                                 PersistentProcess)
from .runner import GetDPError, RunInfo, log_tail
from .solver import DECK_DIR
from .solver3d import (DECK3D, DEFAULT_PETSC_ARGS_3D, EM3DModel, EM3DResult, applied_state_values, model_numbers,
                       read_conductor_fields3d, read_results3d)
from .stepper3d import EM3DState, FactorRecord, carry_coil_heat, read_res_vector, write_res_vector

log = logging.getLogger(__name__)


class PersistentEM3DResult(EM3DResult):
    """An :class:`~.solver3d.EM3DResult` whose Joule power and b on the conductor elements
    (``joule_density``, ``flux_density``) are fetched from getdp when first read (a query, PostOperation
    ``EM_ElemPB3D``): possible until the process takes its next step. A step computes only what the
    coupled loop needs each step (the per-element force); snapshots and fields ask for the rest."""

    _fetch = None  # () -> (joule_density, flux_density), set by the stepper

    def _get(self, name: str) -> np.ndarray | None:
        lazy = self.__dict__.setdefault("_lazy", {})
        if lazy.get(name) is None and self._fetch is not None:
            lazy["joule_density"], lazy["flux_density"] = self._fetch()
            self._fetch = None
        return lazy.get(name)

    def _put(self, name: str, value) -> None:
        self.__dict__.setdefault("_lazy", {})[name] = value

    joule_density = property(lambda self: self._get("joule_density"), lambda self, v: self._put("joule_density", v))
    flux_density = property(lambda self: self._get("flux_density"), lambda self, v: self._put("flux_density", v))


__all__ = ["PersistentEM3DStepper", "PersistentEM3DResult", "RESOLUTION_PERSISTENT3D", "PERSISTENT_LIB3D", "pre_dof_count"]

RESOLUTION_PERSISTENT3D = "EM_Persistent3D"
#: the library holding it, included by Lib_PulsedForming3D.pro when ``PulseformPersistentLib`` names it
PERSISTENT_LIB3D = (DECK_DIR / "Lib_Persistent3D.pro").resolve()


def pre_dof_count(path: Path, system: int) -> int:
    """Number of unknowns (NbrDof) of DofData #``system`` in a getdp ``.pre`` file."""
    text = Path(path).read_text()
    head = f"$DofData /* #{system} */"
    i = text.find(head)
    if i < 0:
        raise RuntimeError(f"{path}: no {head}")
    return int(text[i:text.find("$EndDofData", i)].splitlines()[5].split()[1])


class PersistentEM3DStepper:
    """Advance a 3D EM model one BDF2 step per message to one persistent getdp process.

    Parameters
    ----------
    model : EM3DModel
        The model (coils, conductors, circuit, shell, sector).
    work_dir : Path
        Folder of the processes (``persistent3d_001``, ...) and of the states written by
        :meth:`complete_state`.
    time_scheme : {"bdf2"}
        Only BDF2 (implicit Euler runs a process per step: :class:`~.stepper3d.EM3DStepper`).
    executable, petsc_args, timeout, verbosity
        getdp, its PETSc options, the wall-time limit (s) of the start-up and of each step (None:
        600 s), getdp's ``-v``.
    factor_reuse : FactorReuse
        Kept LU factors across steps (default: every step factorises).

    Call :meth:`close` at the end (a finalizer kills a forgotten process).
    """

    def __init__(self, model: EM3DModel, work_dir: str | Path, time_scheme: str = "bdf2", *,
                 executable: str = "getdp", petsc_args: Sequence[str] = DEFAULT_PETSC_ARGS_3D,
                 timeout: float | None = None, verbosity: int = 2, factor_reuse: FactorReuse = FactorReuse()) -> None:
        if time_scheme != "bdf2":
            raise ValueError("the persistent 3D getdp implements time_scheme='bdf2' only")
        self.factor_reuse = newton_factor_reuse(model, factor_reuse)   # a B-H curve: Newton, no kept factors
        self._factorise_next = False   # the step after a checkpoint factorises (module docstring)
        #: getdp's nodes, gamma dt and (σ(T)) the element σ of the message of the last factorisation
        self._factors: tuple[np.ndarray, float, np.ndarray | None] | None = None
        self._elem_temperature: tuple[np.ndarray, np.ndarray] | None = None   # (EM tet rows, K) for σ(T)
        self._refactor_next = True     # the process's next step factorises anyway
        self.model, self.time_scheme = model, time_scheme
        self.work_dir = Path(work_dir).resolve()
        self.executable, self.petsc_args = executable, tuple(petsc_args)
        self.timeout, self.verbosity = timeout, verbosity
        n_ek = sum(c.direction == "electrokinetic" for c in model.coils)
        self.a_system = 1 if n_ek else 0  # the DofData numbers: EK, A, U (Lib_Persistent3D.pro)
        self.u_system = self.a_system + 1
        self.proc: PersistentProcess | None = None
        self.segment = 0
        self.startup_s = 0.0  # wall time of the process starts (s)

    def set_element_temperatures(self, elements: np.ndarray, temperature: np.ndarray) -> None:
        """Temperatures (K) of EM tetrahedra (rows of the mesh's ``tets``) for the conductors' σ(T) laws at the
        next steps (:func:`.conductivity.step_sigma`; an element not listed is at its ``initial_temperature``)."""
        self._elem_temperature = checked_temperatures(elements, temperature)

    def initial_state(self) -> EM3DState:
        """The state at t = 0: fields at rest, the bank charged (``Circuit.V0``), no current."""
        c = self.model.circuit
        return EM3DState(circuit=None if c is None else (float(c.V0), 0.0))

    # ------------------------------------------------------------------ processes
    def _start(self, mesh: Mesh3D, state: EM3DState) -> float:
        """A new process on ``mesh`` from ``state`` (fresh, or seeded with its two vectors); its start-up
        wall time (s)."""
        self.close()
        self.segment += 1
        self._factors, self._refactor_next = None, True   # a new process has no factors (or primes them below)
        numbers, lines = model_numbers(self.model, mesh)
        numbers.update(PF_T1=float(state.t), PF_Step0=int(state.steps), PF_DtPrev=0.0, PF_Seed=1,
                       Flag_WSources=0 if self.model.is_nonlinear else 1)   # a B-H curve: ∫ w(b), not ½ (j, a)
        numbers.update(self.factor_reuse.numbers())
        numbers.update(persistent_numbers(self.model))   # σ(T): the messages carry σ per element
        if self.model.applied_field is not None:   # the unit time function of the seed states (0 at rest)
            numbers["Field_F1"], numbers["Field_F2"] = applied_state_values(self.model, state.t, state.steps, state.dt_prev)
        seed = None
        if state.steps or state.res_path is not None:
            if state.res_path is None or state.x_prev is None:
                raise ValueError(f"the EM state of step {state.steps} has no solution vectors to start a getdp "
                                 "process from (a state of another process: take it through complete_state)")
            _, _, x_n = read_res_vector(state.res_path)
            seed = (np.asarray(state.x_prev, float), x_n, *(np.asarray(x, float) for x in state.x_older[:2]))
            numbers.update(PF_Seed=2, PF_DtPrev=float(state.dt_prev), PF_SeedHist=len(seed) - 2)
        elif self.model.circuit is not None and state.circuit is not None:
            numbers["Init_Vc"], numbers["Init_I"] = state.circuit
        lines = [f'PulseformPersistentLib = "{PERSISTENT_LIB3D}";'] + lines
        prime = state.factors if seed is not None and state.factors is not None and \
            state.factors.current.shape == mesh.points.shape else None
        if prime is not None:   # the new process starts where the interrupted one factorised (FactorRecord)
            mesh = replace(mesh, points=np.array(prime.points, float))
        proc = PersistentProcess(self.work_dir / f"persistent3d_{self.segment:03d}", mesh, numbers, lines, DECK3D,
                                 executable=self.executable, petsc_args=self.factor_reuse.solver_args(self.petsc_args),
                                 time_limit=self.timeout,
                                 verbosity=self.verbosity, resolution=RESOLUTION_PERSISTENT3D, u_system=self.u_system,
                                 element_values=self.model.has_conductivity_laws)
        self.proc = proc
        startup = proc.start(state.steps, state.t)
        self.n_dofs = pre_dof_count(proc.run_dir / "em.pre", self.a_system)
        if seed is not None:
            if any(len(x) != self.n_dofs for x in seed):
                raise ValueError(f"the EM state's vectors have {len(seed[1])} values, system A of this mesh "
                                 f"{self.n_dofs}: another connectivity")
            c0 = time.perf_counter()
            proc.seed([(self.a_system, state.t - state.dt_prev, 0.0, 1, seed[0]),
                       (self.a_system, state.t, 0.0, 2, seed[1]),
                       *((self.a_system, state.t, 0.0, 3, x) for x in seed[2:])])   # x_n-2, x_n-3 (history)
            if prime is not None:   # the interrupted process's kept factors, rebuilt bit for bit
                if prime.sigma is not None:   # σ(T): the conductivities the factorised matrix was assembled with
                    proc.set_element_values(message_tags(self.model, mesh), prime.sigma)
                proc.prime(prime.points, prime.dtime)
                proc.prime(prime.current, 0.0)
                self._factors, self._refactor_next = (np.array(prime.points, float), prime.dtime, prime.sigma), False
            startup += time.perf_counter() - c0
        coils = np.isin(mesh.tet_tags, [coil_tag(k) for k in range(1, len(self.model.coils) + 1)])
        self._coil_nodes = np.unique(mesh.tets[coils])
        self.startup_s += startup
        log.debug("persistent 3D getdp %s started at t = %.6g s (step %d, %s)", proc.run_dir.name, state.t,
                  state.steps, "seeded" if seed is not None else "fresh")
        return startup

    def _same_mesh(self, mesh: Mesh3D) -> bool:
        m = self.proc.mesh
        return all(a is b or np.array_equal(a, b) for a, b in ((mesh.tets, m.tets), (mesh.tet_ids, m.tet_ids),
                                                                  (mesh.tet_tags, m.tet_tags)))

    def close(self) -> None:
        """End the getdp process (if any); idempotent."""
        if self.proc is not None:
            rc = self.proc.close()
            if rc and not getattr(self.proc, "reported", False):
                log.warning("persistent 3D getdp ended with exit code %s (log: %s)", rc, self.proc.log_path)
            self.proc = None

    # ------------------------------------------------------------------ one step
    def step(self, mesh: Mesh3D, state: EM3DState, t1: float, *,
             field_output: bool = False) -> tuple[EM3DResult, EM3DState]:
        """One BDF2 step from ``state`` to ``t1`` (s) on ``mesh`` (the connectivity of the process, nodes at
        their positions for this step; only ``points``, ``tets``, ``tet_ids``, ``tet_tags`` are used, the
        file ``mesh.path`` is not read -- except its symmetry faces when a process starts with an applied
        field); see :meth:`.EM3DStepper.step`. A state that is not the process's
        (another connectivity, a restored state) starts a new process from it."""
        dt = t1 - state.t
        if not dt > 0:
            raise ValueError(f"step to t1 = {t1:.9g} s from t = {state.t:.9g} s")
        p = self.proc
        if p is not None and not p.alive:  # it ended by itself (close() drops it): a crash, a signal
            self.proc = None
            raise p.died(f"before step {p.k + 1}")
        startup = 0.0
        if p is None or not self._same_mesh(mesh) or p.k != state.steps or p.t != state.t:
            startup = self._start(mesh, state)
        p = self.proc
        if not np.array_equal(mesh.points[self._coil_nodes], p.points[self._coil_nodes]):
            raise ValueError("a coil node moved: the persistent 3D getdp computes the coils' sections and "
                             "directions once (coils are fixed)")
        for old in p.out_dir.glob("*.txt"):  # getdp appends (File >)
            old.unlink()
        coil_sigma, sigma = self._step_sigma(mesh, state, float(dt))
        nk = len(self.model.conductors)
        flags = (FLAG_ELEM if nk else 0) | (FLAG_FIELDS | (FLAG_COND_FIELDS if nk else 0) if field_output else 0) | \
            (FLAG_FACTORISE if self._factorise_next else 0)
        ans = p.step(mesh.points, float(t1), flags)
        self._factorise_next = False
        if ans.factorised:
            self._factors = (p.points.copy(), ans.dtime, sigma)
        self._refactor_next = ans.refactor_next
        c1 = time.perf_counter()
        res = read_results3d(self.model, mesh, p.out_dir, 1, 2 if nk else 0, element_fields=field_output)
        res = PersistentEM3DResult(**{f.name: getattr(res, f.name) for f in fields(res)})
        res.newton_iterations = step_newton(self.model, p)   # a B-H curve: this step's linear solves
        if nk and not field_output:
            res._fetch = self._conductor_fields_of(p.k, mesh, res)
        if field_output:
            ids, b = read_element_table(p.out_dir / "field_b.txt", 3, 1)
            res.b_cells = np.full((mesh.n_tets, 3), np.nan)
            res.b_cells[mesh.rows_of_ids(ids)] = b[0]
        if not (np.all(np.isfinite(res.conductor_force)) and np.all(np.isfinite(res.coil_current))):
            raise GetDPError(f"non-finite EM results at t = {t1:.6g} s", log_path=p.log_path, run_dir=p.run_dir,
                             log_tail=log_tail(p.log_path))
        res.run = RunInfo(argv=p.argv, run_dir=p.run_dir, log_path=p.log_path, wall_time=ans.wall, cpu_parts=ans.cpu)
        res.n_dofs, res.wall_pre, res.wall_loop, res.wall_per_step = self.n_dofs, startup, ans.wall, ans.wall
        f_end = res.force_density[-1] if res.force_density is not None else None
        if f_end is not None:
            f_start = state.force_density if state.force_density is not None else np.zeros_like(f_end)
            res.force_density_mean = 0.5 * (f_start + f_end)
        new = EM3DState(t=float(t1), circuit=None if res.capacitor_voltage is None else
                        (float(res.capacitor_voltage[-1]), float(res.circuit_current[-1])),
                        circuit_prev=state.circuit, dt_prev=float(dt), force_density=f_end, steps=state.steps + 1,
                        timers=dict(state.timers))
        carry_coil_heat(self.model, state, new, coil_sigma, res.coil_power[-1], float(dt), True)
        tm = new.timers
        tm["getdp_process_s"] += ans.wall + startup
        tm["getdp_pre_s"] += startup
        tm["getdp_loop_s"] += ans.wall
        tm["res_io_s"] += time.perf_counter() - c1
        tm["getdp_factorisations"] = tm.get("getdp_factorisations", 0.0) + float(sum(res.newton_iterations or ())
                                                                                 or ans.factorised)   # (a state of
        tm["getdp_corrections"] = tm.get("getdp_corrections", 0.0) + float(ans.corrections)   # an older checkpoint)
        return res, new

    def _step_sigma(self, mesh: Mesh3D, state: EM3DState, dt: float) -> tuple[dict[str, float], np.ndarray | None]:
        """With σ(T) laws: this step's σ (:func:`.conductivity.step_sigma` at the element temperatures given) into
        the message; ({``Coil_sigma_k``: σ} of the coils with a law, σ per element of the message). Without a law
        ({}, None)."""
        m = self.model
        if not m.has_conductivity_laws:
            return {}, None
        coils, conductors = step_sigma(m, mesh, state, dt, self._elem_temperature)
        tags, values = message_sigma(m, mesh, coils, conductors)
        self.proc.set_element_values(tags, values)
        return {f"Coil_sigma_{k}": v for k, v in coils.items()}, values

    def _conductor_fields_of(self, k: int, mesh: Mesh3D, res: EM3DResult):
        """The fetch of step ``k``'s Joule power and b on the conductor elements (a query of the running
        process, which must still be at step ``k``)."""
        def fetch() -> tuple[np.ndarray, np.ndarray]:
            p = self.proc
            if p is None or not p.alive or p.k != k:
                raise RuntimeError(f"conductor fields of EM step {k}: the persistent 3D getdp has moved on")
            for name in ("elem_P.txt", "elem_b.txt"):
                (p.out_dir / name).unlink(missing_ok=True)
            p.query(FLAG_COND_FIELDS)
            ids = mesh.tet_ids[res.elements]
            return read_conductor_fields3d(mesh, p.out_dir, ids, 1)
        return fetch

    # ------------------------------------------------------------------ state
    def complete_state(self, state: EM3DState) -> EM3DState:
        """``state`` (the one the last step returned) with its solution vectors: x_n as an ASCII ``.res``
        in ``work_dir`` (``res_path``) and x_{n-1} (``x_prev``), asked from getdp (a query; the process
        continues). What a checkpoint stores, what :class:`~.stepper3d.EM3DStepper` continues from, and
        what seeds a new process. A state that already has them (or the initial state) is returned as is."""
        if state.res_path is not None or (state.steps == 0 and state.x_prev is None):
            return state
        p = self.proc
        if p is None or not p.alive or p.k != state.steps or p.t != state.t:
            raise ValueError(f"the EM state of step {state.steps} at t = {state.t:.9g} s is not the running "
                             "process's: its vectors are gone")
        res = p.run_dir / "em.res"
        res.unlink(missing_ok=True)
        p.query(FLAG_STATE)  # x_n and x_{n-1} of system A, binary: the exact unknowns
        *older, x_n, x_prev = read_binary_res(res, self.n_dofs)   # [x_n-2, [x_n-3,]] x_n, x_n-1 (Lib_Persistent3D.pro)
        factors = self._factor_record(p.points)
        # without a record the next step factorises, as a process started from this state does
        self._factorise_next = factors is None
        path = write_res_vector(self.work_dir / f"state_{state.steps:05d}.res", str(self.a_system), state.t, x_n)
        return replace(state, res_path=path, x_prev=x_prev, factors=factors, x_older=tuple(older),
                       timers=dict(state.timers))

    def _factor_record(self, current: np.ndarray) -> FactorRecord | None:
        """The kept factors of the next step as a :class:`~.stepper3d.FactorRecord`, or None where a new process
        could not rebuild them bit for bit: no kept factors (``factor_reuse.tol`` 0, none yet, the next step
        factorises anyway), or nodes that no increment takes from the factorisation's coordinates to the
        current ones exactly in floating point (getdp adds increments as numpy does here; a coordinate that
        shrank by orders of magnitude, say, cannot land on the finer grid of the smaller value)."""
        if self.factor_reuse.tol <= 0.0 or self._factors is None or self._refactor_next:
            return None
        points, dtime, sigma = self._factors
        moved = points + exact_increment(points, current)   # what the new process's second prime message does
        if not np.array_equal(moved, current):
            log.info("kept factors not recorded at the checkpoint (a node cannot move back exactly from the "
                     "factorisation's coordinates): the next EM step factorises")
            return None
        return FactorRecord(points=points.copy(), dtime=float(dtime), current=current.copy(),
                            sigma=None if sigma is None else np.array(sigma, float))

    def with_model(self, **changes) -> "PersistentEM3DStepper":
        """A stepper of the same kind on a changed model (its own process)."""
        return PersistentEM3DStepper(replace(self.model, **changes), self.work_dir, self.time_scheme,
                                     executable=self.executable, petsc_args=self.petsc_args, timeout=self.timeout,
                                     verbosity=self.verbosity, factor_reuse=self.factor_reuse)
