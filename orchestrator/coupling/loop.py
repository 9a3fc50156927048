"""The staggered EM–mechanics loop with subcycling: one load (EM) step per n mechanical steps.

One EM step k covers [t_k, t_k + n·dt_mech]:

1. ``dt_mech`` is the mechanics' stable step (capped by ``dt_max``) and H = n·dt_mech the nominal EM
   step. EM steps land exactly on every milestone (output time) without a short step there
   (``landing = "even"``, the default): the m = ceil(remaining / H) EM steps left to the next
   milestone are made equal, remaining / m ≤ H, each of ceil(step / dt_mech) equal substeps, and
   an EM step is never more than ``max_growth`` (2) times the previous one. Shrinking only the
   last EM step before a milestone (``landing = "last"``, the mechanics-only cases: the explicit
   scheme has no step-ratio limit) made the next EM step up to n times longer; variable-step BDF2
   is zero-stable only for ratios below 1 + √2, and the coil voltage rang at every output time.
2. Mesh motion: a load with a mesh of its own (GetDP's EM mesh) moves it with the mechanics' current
   positions (``follow``: conductor nodes with the bodies, the air smoothed, remeshed when its worst
   element degrades).
3. The load provider computes nodal forces on the *current* geometry for that interval (GetDP: the
   mean of its implicit sub-steps; pressure and analytic loads: at t0 + (n − 1)·dt/2, the centre of
   the window over which central differences deliver the held force's impulse: a force passed to
   ``advance`` acts from the current time on, i.e. in the velocity updates at t0, ..., t1 − dt; an
   implicit mechanics holds it over [t0, t1], centre t0 + n·dt/2, static steps at t1: the mechanics'
   ``impulse_window``).
4. The forces are **held** constant over the n mechanical substeps (zero-order hold; no
   interpolation), the conservation ledger |Σ nodal F − ∫ f dV| / |∫ f dV| and the impulse
   Σ F·Δt are updated.
5. The mechanics advances n substeps.

The loop does not know which participants it drives (see :mod:`.interfaces`).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from .interfaces import LoadProvider, Mechanics, RetryStep
from .transfer import ledger_error

log = logging.getLogger(__name__)



def clock_round_off(t: float, dt: float) -> float:
    """A bound (s) of the round-off of a clock that reached ``t`` (s) by adding steps of ``dt`` (s).

    Each addition rounds by at most half an ulp of the time, ε·t, and the errors of a run of equal steps
    add up with one sign (measured: 1.3e-13 s after 3400 steps of 0.5 ms, 5.0e-11 s after 1.7e6 steps of
    1 µs); the bound is ε·t·(t/dt), at most 1e-3·dt (a run of more than ~2e6 steps to the same milestone).
    """
    eps = float(np.finfo(float).eps)
    return min(eps * abs(t) * max(1.0, abs(t) / dt), 1e-3 * dt)


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
    landing : {"even", "last"}
        How EM steps land on a milestone. "even": the EM steps left to it are equal (the step
        changes smoothly, an output time does not perturb the EM time scheme); "last": full steps,
        then one shorter step (only for the mechanics alone, whose explicit scheme has no
        step-ratio limit; keeps the mechanics cases' figures).
    max_growth : float
        "even" only: an EM step is at most this many times the previous one (variable-step BDF2 is
        zero-stable for ratios below 1 + √2 ≈ 2.41), also when n doubles (adaptive) or the stable
        mechanical step grows.
    block : int
        Mechanics alone (n = 1, "last", not adaptive, not iterated): let a load provider with
        ``advance_block`` run up to this many EM steps in one compiled block, ending where the EM
        step count is a multiple of ``block`` (the caller's history cadence: ``on_em_step`` still
        gets every step's row, but reads the state only there). 1: every EM step from Python.
    """

    n: int = 10
    adaptive: bool = False
    n_min: int = 1
    n_max: int = 1000
    adapt_tol: float = 0.05
    iterate: bool = False
    iterate_tol: float = 1e-3
    iterate_max: int = 10
    landing: str = "even"
    max_growth: float = 2.0
    block: int = 1

    @classmethod
    def from_coupling(cls, coupling: Any, **overrides: Any) -> LoopOptions:
        """The options of a coupled case: every field the case's ``[coupling]`` table shares with
        these options (n, adaptive, n_min, n_max, adapt_tol, iterate, iterate_tol, iterate_max) taken
        from it by name, the rest defaults or ``overrides``."""
        shared = {f.name: getattr(coupling, f.name) for f in fields(cls) if hasattr(coupling, f.name)}
        return cls(**{**shared, **overrides})

    def __post_init__(self) -> None:
        if not 1 <= self.n_min <= self.n <= self.n_max:
            raise ValueError(f"need 1 <= n_min <= n <= n_max, got {self.n_min}, {self.n}, {self.n_max}")
        if self.adapt_tol <= 0 or self.iterate_tol <= 0 or self.iterate_max < 1:
            raise ValueError("adapt_tol and iterate_tol must be > 0, iterate_max >= 1")
        if self.block < 1:
            raise ValueError(f"block must be >= 1, got {self.block}")
        if self.landing not in ("even", "last") or not self.max_growth > 1.0:
            raise ValueError(f"landing must be 'even' or 'last' and max_growth > 1, got {self.landing!r}, "
                             f"{self.max_growth}")


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
    last_em_step: float = 0.0  # length of the last EM step (s); 0 before the first
    retries: int = 0  # EM steps repeated shorter because the mechanics rejected its step (RetryStep)

    def state_dict(self) -> dict[str, np.ndarray]:
        """As arrays, for checkpoints."""
        return {"counters": np.array([self.em_steps, self.ledger_max, self.em_time_s, self.mech_time_s, self.n,
                                      self.iterations, self.iterations_max, self.unconverged, self.f_scale,
                                      self.retries]),
                "impulse": self.impulse.copy(), "last_resultant": self.last_resultant.copy(),
                "last_em_step": np.array([self.last_em_step])}

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        k, lm, et, mt, n, it, itm, unc, fs = d["counters"][:9]
        self.retries = int(d["counters"][9]) if len(d["counters"]) > 9 else 0  # older checkpoints: none
        self.em_steps, self.ledger_max, self.em_time_s, self.mech_time_s = int(k), float(lm), float(et), float(mt)
        self.n, self.iterations, self.iterations_max, self.unconverged = int(n), int(it), int(itm), int(unc)
        self.f_scale = float(fs)
        self.impulse = d["impulse"].copy()
        self.last_resultant = d["last_resultant"].copy()
        self.last_em_step = float(d["last_em_step"][0]) if "last_em_step" in d else 0.0  # older checkpoints


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

    def substeps(self, t_stop: float, cap: float | None = None) -> tuple[float, int]:
        """(dt_mech, number of substeps) of the next EM step, landing exactly on ``t_stop``; ``cap`` (s): the
        step a mechanics that rejected its step asks for (:class:`~.interfaces.RetryStep`), an upper bound.

        A function of the current time, stable step, n and the previous EM step's length only
        (all in the checkpoint), so a resumed run takes the same steps.
        """
        dt = self.mech.stable_time_step()
        if self.dt_max is not None:
            dt = min(dt, self.dt_max)
        if cap is not None:
            dt = min(dt, cap)
        remaining = t_stop - self.mech.time
        if self.options.landing == "last":
            if self.n * dt >= remaining * (1.0 - 1e-12):
                k = max(1, math.ceil(remaining / dt - 1e-9))
                return remaining / k, k
            return dt, self.n
        h = self.n * dt
        if self.counters.last_em_step > 0.0:
            h = min(h, self.options.max_growth * self.counters.last_em_step)
        # the clock is a sum of steps and `remaining` carries its round-off. A remaining time that little above
        # a whole number of steps is that number of steps: counted as one more, it split EM steps into two
        # substeps (issue 32: 4056 mechanical steps for 3400 EM steps at n = 1) or shortened the EM steps to an
        # output time (halved the last ones)
        slack = clock_round_off(t_stop, dt)
        m = max(1, math.ceil(remaining / h * (1.0 - 1e-12) - slack / h))  # EM steps left to the milestone, all equal
        step = remaining / m
        k = max(1, math.ceil(step / dt * (1.0 - 1e-13) - slack / dt))  # step / k <= dt + slack
        return step / k, k

    def em_step(self, t_stop: float) -> dict[str, float]:
        """One EM step followed by its mechanical substeps; returns the step's scalars. A mechanics that rejects
        the step it was given (:class:`~.interfaces.RetryStep`: the adaptive implicit step) gets the EM step
        again from its start, at most as long as it asks, with the load evaluated again (its state restored)."""
        c = self.counters
        cap = None
        while True:
            dt, k = self.substeps(t_stop, cap)
            t0 = self.mech.time
            t1 = t0 + dt * k
            t_mid = self._load_time(t0, dt, k)
            try:
                step, resultant, iterations = self._attempt(dt, k, t0, t1, t_mid)
                break
            except RetryStep as exc:
                c.retries += 1
                cap = exc.dt
                log.debug("t = %.6g s: %s", t0, exc)
        if step.heat:   # the step's Joule heat, once the mechanics has gone through the step
            self.mech.add_heat(step.heat)
        err = ledger_error(resultant[None, :], step.reference_integral) if step.reference_integral is not None else 0.0
        c.em_steps += 1
        c.last_em_step = dt * k
        if c.impulse.shape != resultant.shape and not c.impulse.any():   # 3D: three components
            c.impulse = np.zeros(resultant.shape)
        c.impulse += resultant * (t1 - t0)
        c.ledger_max = max(c.ledger_max, err)
        c.iterations += iterations
        c.iterations_max = max(c.iterations_max, iterations)
        row = {"force_x_N": float(resultant[0]), "force_y_N": float(resultant[1]),
               **({"force_z_N": float(resultant[2])} if resultant.shape[0] > 2 else {}),
               "conservation_error_rel": err, "substeps": float(k), "dt_s": dt, "iterations": float(iterations),
               **step.values}
        if self.options.adaptive:
            self._adapt(resultant)
        c.last_values = dict(step.values)
        c.last_resultant = resultant
        return row

    def _attempt(self, dt: float, k: int, t0: float, t1: float, t_mid: float):
        """The load and the mechanics' substeps of one EM step (iterated when asked); on
        :class:`~.interfaces.RetryStep` the load's state is restored (the mechanics' is unchanged) and it goes on."""
        c = self.counters
        saved = (self.mech.state_dict(), self.load.state_dict()) if self.options.iterate else None
        load_state = saved[1] if saved is not None else (
            self.load.state_dict() if getattr(self.mech, "retries_steps", False) else None)
        c0 = time.perf_counter()
        self._follow(t0)
        step = self.load.load(t0, t1, t_mid, self.mech)
        c1 = time.perf_counter()
        c.em_time_s += c1 - c0
        resultant = self.mech.total_force(step.forces)
        try:
            try:
                self.mech.advance(dt, k, step.forces)
            finally:
                c.mech_time_s += time.perf_counter() - c1
            iterations = 1
            if saved is not None:
                step, resultant, iterations = self._iterate(saved, step, resultant, dt, k, t0, t1, t_mid)
        except RetryStep:
            self.load.load_state_dict(load_state)
            raise
        return step, resultant, iterations

    def _load_time(self, t0: float, dt: float, k: int) -> float:
        """Where the load of an EM step of ``k`` mechanical steps of ``dt`` from ``t0`` is evaluated (s): the
        centre of the window over which the mechanics delivers a held force's impulse (its
        ``impulse_window``; without one the explicit scheme's t0 + (k − 1)·dt/2)."""
        window = getattr(self.mech, "impulse_window", None)
        return window(t0, dt, k) if window is not None else t0 + 0.5 * (k - 1) * dt

    def _follow(self, t0: float) -> None:
        """Step 2: the load's mesh follows the mechanics (a no-op for a load without a mesh of its own)."""
        self.load.follow(t0, self.mech)

    def _iterate(self, saved, step, resultant, dt, k, t0, t1, t_mid):
        """Repeat the EM step on the end-of-step geometry until force and motion settle."""
        c, o = self.counters, self.options
        mech_state, load_state = saved
        start = _flat_positions(mech_state, self.mech)
        end = _flat(self.mech.positions())
        for it in range(2, o.iterate_max + 1):
            c0 = time.perf_counter()
            self.load.load_state_dict(load_state)
            self._follow(t0)  # mechanics sits at the end geometry
            new_step = self.load.load(t0, t1, t_mid, self.mech)
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

    def run_until(self, t_stop: float, on_em_step=None, after_steps=None) -> None:
        """EM steps until the mechanics reaches ``t_stop`` exactly; ``on_em_step(row)`` after each, and
        ``after_steps()`` once the rows of an EM step (or of a compiled block of them) are delivered (a check
        of the state that may stop the run: it raises)."""
        while self.mech.time < t_stop * (1.0 - 1e-12):
            rows = self._block(t_stop)
            if not rows and (rows is None or rows.error is None):
                rows = [self.em_step(t_stop)]
            for row in rows:
                if on_em_step is not None:
                    on_em_step(row)
            if getattr(rows, "error", None) is not None:
                raise rows.error
            if after_steps is not None:
                after_steps()

    def _block(self, t_stop: float) -> "_Rows | None":
        """EM steps run by the load provider's compiled block (see ``LoopOptions.block``), with the
        counters and rows :meth:`em_step` would give them; None (or empty) where it cannot run."""
        o, c = self.options, self.counters
        if o.block < 2 or o.n != 1 or o.adaptive or o.iterate or o.landing != "last":
            return None
        c0 = time.perf_counter()
        blk = self.load.advance_block(self.mech, t_stop, o.block - c.em_steps % o.block, self.dt_max)
        if blk is None:
            return None
        c.mech_time_s += time.perf_counter() - c0
        rows = _Rows(error=blk.error)
        for j, (t0, dt, res) in enumerate(zip(blk.t0, blk.dt, blk.resultant)):
            dt, k = float(dt), 1
            t1 = float(t0) + dt * k
            resultant = res.copy()
            values = {name: float(v[j]) for name, v in blk.values.items()}
            c.em_steps += 1
            c.last_em_step = dt * k
            c.impulse += resultant * (t1 - float(t0))
            c.ledger_max = max(c.ledger_max, 0.0)
            c.iterations += 1
            c.iterations_max = max(c.iterations_max, 1)
            rows.append({"force_x_N": float(resultant[0]), "force_y_N": float(resultant[1]),
                         "conservation_error_rel": 0.0, "substeps": float(k), "dt_s": dt,
                         "iterations": 1.0, **values})
            c.last_values = values
            c.last_resultant = resultant
        return rows


class _Rows(list):
    """History rows of a compiled block, and the event that stopped it (raised after the rows)."""

    def __init__(self, error: Exception | None = None) -> None:
        super().__init__()
        self.error = error


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
