"""The staggered EM–mechanics loop with subcycling: one load (EM) step per n mechanical steps.

One EM step k covers [t_k, t_k + n·dt_mech]:

1. ``dt_mech`` is the mechanics' stable step (capped by ``dt_max``); near a milestone the last EM
   step takes ``ceil(remaining / dt_mech)`` equal substeps so that it lands exactly on it.
2. The load provider computes nodal forces on the *current* geometry for that interval (GetDP: the
   mean of its implicit sub-steps; pressure and analytic loads: at t0 + (n − 1)·dt/2, the centre of
   the window over which central differences deliver the held force's impulse: a force passed to
   ``advance`` acts from the current time on, i.e. in the velocity updates at t0, ..., t1 − dt).
3. The forces are **held** constant over the n mechanical substeps (zero-order hold; no
   interpolation), the conservation ledger |Σ nodal F − ∫ f dV| / |∫ f dV| and the impulse
   Σ F·Δt are updated.
4. The mechanics advances n substeps.

The loop does not know which participants it drives (see :mod:`.participants`).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from .participants import LoadProvider, Mechanics
from .transfer import ledger_error

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LoopOptions:
    """How the loop picks n and whether it iterates.

    Attributes
    ----------
    n : int
        Mechanical steps per EM step (the start value when adaptive).
    adaptive : bool
        Adapt n from the relative change of the force resultant between EM steps: above
        ``adapt_tol`` n halves (down to ``n_min``), below ``adapt_tol / 4`` it doubles (up to ``n_max``).
    iterate : bool
        Repeat each EM step on the geometry reached at its end until the resultant and the
        displacement change by less than ``iterate_tol`` (relative), at most ``iterate_max`` times.
    """

    n: int = 10
    adaptive: bool = False
    n_min: int = 1
    n_max: int = 1000
    adapt_tol: float = 0.05
    iterate: bool = False
    iterate_tol: float = 1e-3
    iterate_max: int = 10

    def __post_init__(self) -> None:
        if not 1 <= self.n_min <= self.n <= self.n_max:
            raise ValueError(f"need 1 <= n_min <= n <= n_max, got {self.n_min}, {self.n}, {self.n_max}")
        if self.adapt_tol <= 0 or self.iterate_tol <= 0 or self.iterate_max < 1:
            raise ValueError("adapt_tol and iterate_tol must be > 0, iterate_max >= 1")


@dataclass
class LoopCounters:
    """Running totals of a coupled run."""

    em_steps: int = 0
    impulse: np.ndarray = field(default_factory=lambda: np.zeros(2))
    ledger_max: float = 0.0
    em_time_s: float = 0.0
    mech_time_s: float = 0.0
    n: int = 1
    iterations: int = 0
    iterations_max: int = 0
    unconverged: int = 0
    f_scale: float = 0.0
    last_values: dict[str, float] = field(default_factory=dict)
    last_resultant: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def state_dict(self) -> dict[str, np.ndarray]:
        """As arrays, for checkpoints."""
        return {"counters": np.array([self.em_steps, self.ledger_max, self.em_time_s, self.mech_time_s, self.n,
                                      self.iterations, self.iterations_max, self.unconverged, self.f_scale]),
                "impulse": self.impulse.copy(), "last_resultant": self.last_resultant.copy()}

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        k, lm, et, mt, n, it, itm, unc, fs = d["counters"]
        self.em_steps, self.ledger_max, self.em_time_s, self.mech_time_s = int(k), float(lm), float(et), float(mt)
        self.n, self.iterations, self.iterations_max, self.unconverged = int(n), int(it), int(itm), int(unc)
        self.f_scale = float(fs)
        self.impulse = d["impulse"].copy()
        self.last_resultant = d["last_resultant"].copy()


class StaggeredLoop:
    """Drive a load provider and a mechanics to milestones with subcycling.

    Parameters
    ----------
    load : LoadProvider
        Gives nodal forces for each EM step.
    mechanics : Mechanics
        Advances with held forces.
    n : int or LoopOptions
        Mechanical steps per EM step (≥ 1), or the full options.
    dt_max : float, optional
        Upper bound on the mechanical step (s).
    """

    def __init__(self, load: LoadProvider, mechanics: Mechanics, n: "int | LoopOptions",
                 dt_max: float | None = None) -> None:
        self.options = n if isinstance(n, LoopOptions) else LoopOptions(n=n, n_min=1, n_max=max(n, 1))
        self.load, self.mech, self.dt_max = load, mechanics, dt_max
        self.counters = LoopCounters(n=self.options.n)

    @property
    def n(self) -> int:
        """Current number of mechanical steps per EM step."""
        return self.counters.n

    def substeps(self, t_stop: float) -> tuple[float, int]:
        """(dt_mech, number of substeps) of the next EM step, landing exactly on ``t_stop``."""
        dt = self.mech.stable_time_step()
        if self.dt_max is not None:
            dt = min(dt, self.dt_max)
        remaining = t_stop - self.mech.time
        if self.n * dt >= remaining * (1.0 - 1e-12):
            k = max(1, math.ceil(remaining / dt - 1e-9))
            return remaining / k, k
        return dt, self.n

    def em_step(self, t_stop: float) -> dict[str, float]:
        """One EM step followed by its mechanical substeps; returns the step's scalars."""
        dt, k = self.substeps(t_stop)
        t0 = self.mech.time
        t1 = t0 + dt * k
        t_mid = t0 + 0.5 * (k - 1) * dt
        c = self.counters
        saved = (self.mech.state_dict(), self.load.state_dict()) if self.options.iterate else None
        c0 = time.perf_counter()
        step = self.load.load(t0, t1, t_mid, self.mech)
        c1 = time.perf_counter()
        resultant = self.mech.total_force(step.forces)
        self.mech.advance(dt, k, step.forces)
        c2 = time.perf_counter()
        c.em_time_s += c1 - c0
        c.mech_time_s += c2 - c1
        iterations = 1
        if saved is not None:
            step, resultant, iterations = self._iterate(saved, step, resultant, dt, k, t0, t1, t_mid)
        err = ledger_error(resultant[None, :], step.reference_integral) if step.reference_integral is not None else 0.0
        c.em_steps += 1
        c.impulse += resultant * (t1 - t0)
        c.ledger_max = max(c.ledger_max, err)
        c.iterations += iterations
        c.iterations_max = max(c.iterations_max, iterations)
        row = {"force_x_N": float(resultant[0]), "force_y_N": float(resultant[1]),
               "conservation_error_rel": err, "substeps": float(k), "dt_s": dt, "iterations": float(iterations),
               **step.values}
        if self.options.adaptive:
            self._adapt(resultant)
        c.last_values = dict(step.values)
        c.last_resultant = resultant
        return row

    def _iterate(self, saved, step, resultant, dt, k, t0, t1, t_mid):
        """Repeat the EM step on the end-of-step geometry until force and motion settle."""
        c, o = self.counters, self.options
        mech_state, load_state = saved
        start = _flat_positions(mech_state, self.mech)
        end = _flat(self.mech.positions())
        for it in range(2, o.iterate_max + 1):
            c0 = time.perf_counter()
            self.load.load_state_dict(load_state)
            new_step = self.load.load(t0, t1, t_mid, self.mech)  # mechanics sits at the end geometry
            c1 = time.perf_counter()
            new_res = self.mech.total_force(new_step.forces)
            self.mech.load_state_dict(mech_state)
            self.mech.advance(dt, k, new_step.forces)
            c2 = time.perf_counter()
            c.em_time_s += c1 - c0
            c.mech_time_s += c2 - c1
            new_end = _flat(self.mech.positions())
            df = np.linalg.norm(new_res - resultant) / max(np.linalg.norm(new_res), c.f_scale, 1e-300)
            moved = np.linalg.norm(end - start)
            du = np.linalg.norm(new_end - end) / moved if moved > 0 else 0.0
            step, resultant, end = new_step, new_res, new_end
            if df < o.iterate_tol and du < o.iterate_tol:
                return step, resultant, it
        c.unconverged += 1
        log.warning("t = %.6g s: iterated coupling not converged in %d iterations", t1, o.iterate_max)
        return step, resultant, o.iterate_max

    def _adapt(self, resultant: np.ndarray) -> None:
        c, o = self.counters, self.options
        f = float(np.linalg.norm(resultant))
        prev = float(np.linalg.norm(c.last_resultant))
        c.f_scale = max(c.f_scale, f)
        if c.em_steps < 2 or c.f_scale == 0.0:
            return
        change = float(np.linalg.norm(resultant - c.last_resultant)) / max(f, prev, 0.05 * c.f_scale)
        if change > o.adapt_tol and c.n > o.n_min:
            c.n = max(o.n_min, c.n // 2)
        elif change < 0.25 * o.adapt_tol and c.n < o.n_max:
            c.n = min(o.n_max, 2 * c.n)

    def run_until(self, t_stop: float, on_em_step=None) -> None:
        """EM steps until the mechanics reaches ``t_stop`` exactly; ``on_em_step(row)`` after each."""
        while self.mech.time < t_stop * (1.0 - 1e-12):
            row = self.em_step(t_stop)
            if on_em_step is not None:
                on_em_step(row)


def _flat(positions: dict[str, np.ndarray]) -> np.ndarray:
    return np.concatenate([np.asarray(p, dtype=float).ravel() for _, p in sorted(positions.items())]) \
        if positions else np.zeros(0)


def _flat_positions(state: dict[str, np.ndarray], mech: Mechanics) -> np.ndarray:
    """Positions held in a saved state: restore it into the mechanics, read, and step back."""
    current = mech.state_dict()
    mech.load_state_dict(state)
    pos = _flat(mech.positions())
    mech.load_state_dict(current)
    return pos
