"""The staggered EM–mechanics loop with subcycling: one load (EM) step per n mechanical steps.

One EM step k covers [t_k, t_k + n·dt_mech]:

1. ``dt_mech`` is the mechanics' stable step (capped by ``dt_max``); near a milestone the last EM
   step takes ``ceil(remaining / dt_mech)`` equal substeps so that it lands exactly on it.
2. The load provider computes nodal forces on the *current* geometry for that interval (GetDP: the
   implicit-Euler value at the step end; pressure and analytic loads: at t0 + (n + 1)·dt/2, the
   centre of the window over which central differences deliver the held force's impulse: a force
   passed to ``advance`` acts at the ends of the substeps, t0 + dt, ..., t1, and enters the
   velocity updates that follow them).
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


@dataclass
class LoopCounters:
    """Running totals of a coupled run."""

    em_steps: int = 0
    impulse: np.ndarray = field(default_factory=lambda: np.zeros(2))
    ledger_max: float = 0.0
    em_time_s: float = 0.0
    mech_time_s: float = 0.0
    last_values: dict[str, float] = field(default_factory=dict)
    last_resultant: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def state_dict(self) -> dict[str, np.ndarray]:
        """As arrays, for checkpoints."""
        return {"counters": np.array([self.em_steps, self.ledger_max, self.em_time_s, self.mech_time_s]),
                "impulse": self.impulse.copy(), "last_resultant": self.last_resultant.copy()}

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        k, lm, et, mt = d["counters"]
        self.em_steps, self.ledger_max, self.em_time_s, self.mech_time_s = int(k), float(lm), float(et), float(mt)
        self.impulse = d["impulse"].copy()
        self.last_resultant = d["last_resultant"].copy()


class StaggeredLoop:
    """Drive a load provider and a mechanics to milestones with subcycling ``n``.

    Parameters
    ----------
    load : LoadProvider
        Gives nodal forces for each EM step.
    mechanics : Mechanics
        Advances with held forces.
    n : int
        Mechanical steps per EM step (≥ 1).
    dt_max : float, optional
        Upper bound on the mechanical step (s).
    """

    def __init__(self, load: LoadProvider, mechanics: Mechanics, n: int, dt_max: float | None = None) -> None:
        if n < 1:
            raise ValueError(f"n must be >= 1, got {n}")
        self.load, self.mech, self.n, self.dt_max = load, mechanics, n, dt_max
        self.counters = LoopCounters()

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
        c0 = time.perf_counter()
        step = self.load.load(t0, t1, t0 + 0.5 * (k + 1) * dt, self.mech)
        c1 = time.perf_counter()
        resultant = self.mech.total_force(step.forces)
        err = ledger_error(resultant[None, :], step.reference_integral) if step.reference_integral is not None else 0.0
        self.mech.advance(dt, k, step.forces)
        c2 = time.perf_counter()
        c = self.counters
        c.em_steps += 1
        c.impulse += resultant * (t1 - t0)
        c.ledger_max = max(c.ledger_max, err)
        c.em_time_s += c1 - c0
        c.mech_time_s += c2 - c1
        c.last_values = dict(step.values)
        c.last_resultant = resultant
        return {"force_x_N": float(resultant[0]), "force_y_N": float(resultant[1]),
                "conservation_error_rel": err, "substeps": float(k), "dt_s": dt, **step.values}

    def run_until(self, t_stop: float, on_em_step=None) -> None:
        """EM steps until the mechanics reaches ``t_stop`` exactly; ``on_em_step(row)`` after each."""
        while self.mech.time < t_stop * (1.0 - 1e-12):
            row = self.em_step(t_stop)
            if on_em_step is not None:
                on_em_step(row)
