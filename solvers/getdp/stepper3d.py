"""One 3D EM step per getdp run, from a carried state, on a mesh whose nodes may have moved.

The per-step path of the coupled 3D loop (:func:`~.solver3d.solve_transient3d` runs one process for
a whole transient on a fixed mesh). The state after step n is the solution vector x_n (edge
circulations of a, a* in the conductors, the coil and circuit globals) as GetDP wrote it
(``em.res``), the previous vector x_{n-1}, the capacitor voltage and circuit current at both times,
the length of the last step and the per-element force density at t_n (the start value of the next
step's trapezoid). The mesh of step n+1 must have the same connectivity (element ids, edges): the
dof numbering is topological, so the vectors keep their meaning when only the nodes move.

* implicit Euler: ``getdp -restart -res x_n.res`` and one implicit Euler step t_n -> t_{n+1};
* BDF2 (:mod:`.bdf2`): one implicit Euler step of gamma dt from the synthetic state
  x~ = c1 x_n - c2 x_{n-1}, written as a one-solution ``.res`` at time t_{n+1} - gamma dt; the
  circuit's Init values (capacitor voltage, inductor current) get the same combination. GetDP's
  Dt[a] is then the BDF2 derivative (the algebra of ``Lib_PulsedForming3D_BDF2.pro``, which does
  the same on its own vectors in one process). The first step is implicit Euler from zero fields.

The force handed to the mechanics is the impulse-consistent mean over the step: the end value
(implicit Euler) or the trapezoid of the start and end values (BDF2).
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .bdf2 import bdf2_coefficients
from .conductivity import checked_temperatures, coil_heat_step, step_inputs
from .mesh3d import Mesh3D
from .solver3d import EM3DModel, EM3DResult, applied_state_values, solve_transient3d

logger = logging.getLogger(__name__)

__all__ = ["EM3DState", "EM3DStepper", "FactorRecord", "read_res_vector", "write_res_vector", "carry_coil_heat"]


def carry_coil_heat(model: EM3DModel, state: "EM3DState", new: "EM3DState", numbers: dict[str, float],
                    power_end: np.ndarray, dt: float, bdf2: bool) -> None:
    """Fill ``new``'s coil heat, power and (with a σ(T) law) σ from the step of ``dt`` s from ``state`` whose numbers
    were ``numbers`` (a coil's ``Coil_sigma_k`` where a law set it) and end power ``power_end`` (W per coil)."""
    sigma = [float(numbers.get(f"Coil_sigma_{k}", c.sigma)) for k, c in enumerate(model.coils, start=1)]
    new.coil_heat = coil_heat_step(state, sigma, power_end, dt, bdf2).tolist()
    new.coil_power = np.asarray(power_end, float).tolist()
    new.coil_sigma = sigma if model.has_conductivity_laws else None


def read_res_vector(path: str | Path, block: int = -1) -> tuple[str, float, np.ndarray]:
    """A ``$Solution`` block (default: the last) of a GetDP ASCII ``.res``: (its DofData header number
    as text, its time (s), the real solution vector)."""
    text = Path(path).read_text()
    if "$Solution" not in text or not text.rstrip().endswith("$EndSolution"):
        raise ValueError(f"{path}: no complete $Solution block")
    lines = text.split("$Solution")[1:][block].split("\n", 2)
    head = lines[1].split()
    values = np.array(lines[2].split("$EndSolution")[0].split(), dtype=float)
    return head[0], float(head[1]), values


def write_res_vector(path: str | Path, dofdata: str, t: float, values: np.ndarray) -> Path:
    """Write one real solution of DofData ``dofdata`` at time ``t`` (s) as GetDP's ASCII ``.res``
    (what ``getdp -restart -res`` reads); values in 17 digits (exact round trip)."""
    body = "\n".join(f"{v:.17g}" for v in np.asarray(values, float))
    Path(path).write_text("$ResFormat /* GetDP 3.2.0, ascii */\n1.1 0\n$EndResFormat\n"
                          f"$Solution  /* DofData #{dofdata} */\n{dofdata} {t:.17g} 0 0\n{body}\n$EndSolution\n")
    return Path(path)


@dataclass(frozen=True)
class FactorRecord:
    """Which LU factors the next step of a persistent getdp with kept factors uses, so that a process
    started from the state rebuilds them (:meth:`~.persistent3d.PersistentEM3DStepper.complete_state`):
    ``points`` (n, 3) m, getdp's node coordinates at the step that factorised, ``dtime`` (s) its
    implicit-Euler time step gamma dt (the matrix depends on both only, and on σ), ``current`` (n, 3) m, getdp's
    node coordinates at the state (a new process starts at ``points``, factorises there and moves to
    ``current``: recorded only where that move is exact in floating point); ``sigma`` (S/m), with σ(T) laws, the σ
    per element of the factorising step's message (:func:`.conductivity.message_sigma`'s order; None without a
    law), which the new process's prime message carries."""

    points: np.ndarray
    dtime: float
    current: np.ndarray
    sigma: np.ndarray | None = None


@dataclass
class EM3DState:
    """The carried EM state at time ``t`` (s), see the module docstring.

    ``res_path``: getdp's ``.res`` of the last step (x_n; None before the first step);
    ``x_prev``: x_{n-1} (None: zeros, the fields at rest); ``circuit``: (capacitor voltage V, circuit
    current A) at t_n and ``circuit_prev`` at t_{n-1}; ``dt_prev`` the last step (s, 0 before the
    first); ``force_density`` (n_el, 3) N/m^3 at t_n on the conductor elements ``elements`` (rows of
    the mesh's tets), zeros at rest; ``steps`` taken; ``factors``: the kept LU factors a persistent
    getdp's next step uses (:class:`FactorRecord`; None: that step factorises its own matrix);
    ``x_older``: x_{n-2}, x_{n-3} as far as a persistent getdp's kept-factor solves use them (their history
    directions, decks/Lib_PersistentStep.pro; empty: none), so that a process seeded from this state repeats them.
    ``coil_heat``: each coil's Joule heat so far (J, the modelled sector's; implicit Euler: Σ P_end dt, BDF2: the
    trapezoid), ``coil_power`` its power at t_n (W), ``coil_sigma`` (with a σ(T) law) its σ of the last step (S/m):
    the lumped coil temperature of :mod:`.conductivity` (None: 0 J, from rest).
    """

    t: float = 0.0
    res_path: Path | None = None
    x_prev: np.ndarray | None = None
    circuit: tuple[float, float] | None = None
    circuit_prev: tuple[float, float] | None = None
    dt_prev: float = 0.0
    force_density: np.ndarray | None = None
    steps: int = 0
    factors: FactorRecord | None = None
    x_older: tuple[np.ndarray, ...] = ()
    coil_heat: list | None = None
    coil_power: list | None = None
    coil_sigma: list | None = None
    timers: dict[str, float] = field(default_factory=lambda: {"getdp_process_s": 0.0, "getdp_pre_s": 0.0,
                                                              "getdp_loop_s": 0.0, "res_io_s": 0.0,
                                                              "getdp_factorisations": 0.0,
                                                              "getdp_corrections": 0.0})


class EM3DStepper:
    """Advance a 3D EM model one step per getdp process (module docstring).

    Parameters
    ----------
    model : EM3DModel
        The model (coils, conductors, circuit, shell, sector).
    work_dir : Path
        Folder of the runs: ``step_00001``, ... (the caller prunes old ones).
    time_scheme : {"euler", "bdf2"}
        Implicit Euler or variable-step BDF2.
    """

    def __init__(self, model: EM3DModel, work_dir: str | Path, time_scheme: str = "bdf2", **run_kwargs) -> None:
        if time_scheme not in ("euler", "bdf2"):
            raise ValueError(f"time_scheme is 'euler' or 'bdf2', got {time_scheme!r}")
        self.model, self.time_scheme = model, time_scheme
        self.work_dir = Path(work_dir).resolve()
        self.run_kwargs = run_kwargs
        self._elem_temperature: tuple[np.ndarray, np.ndarray] | None = None   # (EM tet rows, K) for σ(T)

    def set_element_temperatures(self, elements: np.ndarray, temperature: np.ndarray) -> None:
        """Temperatures (K) of EM tetrahedra (rows of the mesh's ``tets``) for the conductors' σ(T) laws at the
        next steps (:func:`.conductivity.step_inputs`; an element not listed is at its ``initial_temperature``)."""
        self._elem_temperature = checked_temperatures(elements, temperature)

    def initial_state(self) -> EM3DState:
        """The state at t = 0: fields at rest, the bank charged (``Circuit.V0``), no current."""
        c = self.model.circuit
        return EM3DState(circuit=None if c is None else (float(c.V0), 0.0))

    def step(self, mesh: Mesh3D, state: EM3DState, t1: float, *, field_output: bool = False) -> tuple[EM3DResult, EM3DState]:
        """One EM step from ``state`` to ``t1`` (s) on ``mesh`` (the state's connectivity, nodes at
        their positions for this step); returns getdp's result (per-element tables of the end of
        the step) and the new state. ``result.force_density_mean`` (n_el, 3) N/m^3 is the force to
        hold over the step (implicit Euler: the end value; BDF2: the trapezoid)."""
        dt = t1 - state.t
        if not dt > 0:
            raise ValueError(f"step to t1 = {t1:.9g} s from t = {state.t:.9g} s")
        k = state.steps + 1
        run_dir = self.work_dir / f"step_{k:05d}"
        run_dir.mkdir(parents=True, exist_ok=True)
        c0 = time.perf_counter()
        t0, restart, circuit = state.t, state.res_path, state.circuit
        f1, f2 = applied_state_values(self.model, state.t, state.steps, state.dt_prev)
        applied_start = f1   # the applied field's unit time function of the start state (unused without one)
        if state.res_path is not None and self.time_scheme == "bdf2":
            gamma, c1, c2 = bdf2_coefficients(dt, state.dt_prev)
            applied_start = c1 * f1 - c2 * f2
            dofdata, _, x1 = read_res_vector(state.res_path)
            x0 = state.x_prev
            t0 = t1 - gamma * dt
            restart = write_res_vector(run_dir / "x_tilde.res", dofdata, t0, c1 * x1 - c2 * x0)
            if circuit is not None:
                prev = state.circuit_prev if state.circuit_prev is not None else circuit
                circuit = (c1 * circuit[0] - c2 * prev[0], c1 * circuit[1] - c2 * prev[1])
        c1_ = time.perf_counter()
        first_bdf2 = self.time_scheme == "bdf2" and state.res_path is None
        numbers, lines = step_inputs(self.model, mesh, state, dt, self._elem_temperature) \
            if self.model.has_conductivity_laws else ({}, [])
        if first_bdf2:
            numbers["Flag_SaveInit"] = 1
        res = solve_transient3d(self.model, mesh, t1, 1, run_dir, t0=t0, element_output="last",
                                field_output=field_output, restart_res=restart, circuit_state=circuit,
                                extra_numbers=numbers or None, extra_lines=lines,
                                applied_start=applied_start if self.model.applied_field is not None else None,
                                **self.run_kwargs)
        c2_ = time.perf_counter()
        x_prev = None
        if self.time_scheme == "bdf2":   # x_{n-1}: the carried x_n, or x_0 saved by the first run
            x_prev = x1 if not first_bdf2 else read_res_vector(res.res_path, 0)[2]
        f_end = res.force_density[-1] if res.force_density is not None else None
        f_start = state.force_density if state.force_density is not None else (
            None if f_end is None else np.zeros_like(f_end))
        if f_end is not None:
            res.force_density_mean = 0.5 * (f_start + f_end) if self.time_scheme == "bdf2" else f_end.copy()
        new = EM3DState(t=float(t1), res_path=res.res_path, x_prev=x_prev,
                        circuit=None if res.capacitor_voltage is None else (float(res.capacitor_voltage[-1]),
                                                                             float(res.circuit_current[-1])),
                        circuit_prev=state.circuit, dt_prev=float(dt), force_density=f_end, steps=k,
                        timers=dict(state.timers))
        carry_coil_heat(self.model, state, new, numbers, res.coil_power[-1], float(dt), self.time_scheme == "bdf2")
        tm = new.timers
        tm["getdp_process_s"] += res.run.wall_time if res.run is not None else c2_ - c1_
        tm["getdp_pre_s"] += res.wall_pre if np.isfinite(res.wall_pre) else 0.0
        tm["getdp_loop_s"] += res.wall_loop if np.isfinite(res.wall_loop) else 0.0
        tm["res_io_s"] += (c1_ - c0) + (time.perf_counter() - c2_)
        tm["getdp_factorisations"] = tm.get("getdp_factorisations", 0.0) + 1.0   # system A, once per run
        return res, new

    def complete_state(self, state: EM3DState) -> EM3DState:
        """``state`` as it is: a per-step state carries its vectors (the API of
        :class:`~.persistent3d.PersistentEM3DStepper`, whose states need this for a checkpoint)."""
        return state

    def close(self) -> None:
        """Nothing runs between steps (the API of :class:`~.persistent3d.PersistentEM3DStepper`)."""

    def with_model(self, **changes) -> "EM3DStepper":
        """A stepper of the same kind on a changed model (e.g. the shell centre)."""
        return EM3DStepper(replace(self.model, **changes), self.work_dir, self.time_scheme, **self.run_kwargs)
