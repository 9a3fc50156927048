"""The two participants of the staggered loop, as small interfaces (fakes: :mod:`.fakes`).

The loop (:mod:`.loop`) only sees these protocols, so a fake load (an analytic force), a
pressure pulse, a GetDP eddy-current load, the explicit DOLFINx mechanics, a rigid body or a
prescribed motion all plug in without touching it.

Conventions: nodal forces are dicts ``body name -> (N, 2) array`` in N (planar: for the case's
thickness; axisymmetric: over the full 2π ring); positions likewise in m.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


@dataclass
class LoadStep:
    """What a load provider hands the loop for one EM step [t0, t1].

    Attributes
    ----------
    forces : dict
        Nodal forces per body (N), held constant over the step.
    reference_integral : ndarray (2,)
        The provider's own ∫ f dV (N) for the conservation ledger (None when not applicable).
    values : dict
        Scalars for history.csv (SI units in the names), e.g. coil current.
    heat : dict
        Heat per unit volume deposited over the step per mechanical cell of a body (J/m^3; the Joule
        heat of the bodies that carry a temperature), added by the mechanics at the end of the step
        (``add_heat``); empty for none.
    """

    forces: dict[str, np.ndarray]
    reference_integral: np.ndarray | None = None
    values: dict[str, float] = field(default_factory=dict)
    heat: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass
class StepBlock:
    """EM steps of one mechanical step each that a load provider ran in one compiled block
    (:meth:`LoadProvider.advance_block`), per step.

    Attributes
    ----------
    t0, dt : ndarray (K,)
        Start time and length of each step (s).
    resultant : ndarray (K, 2)
        Resultant of the held nodal forces (N).
    values : dict
        History scalars, name -> (K,) array (SI units in the names).
    error : Exception or None
        The event that stopped the block after the K steps (raised by the loop after their rows).
    """

    t0: np.ndarray
    dt: np.ndarray
    resultant: np.ndarray
    values: dict[str, np.ndarray]
    error: Exception | None = None


class RetryStep(Exception):
    """Raised by a mechanics' ``advance`` that chooses its own step (the adaptive implicit step) and rejected the
    one it was given, its state unchanged: the loop repeats the EM step from its start with a step of at most
    ``dt`` (s), the load evaluated again for it."""

    def __init__(self, dt: float, why: str = "") -> None:
        self.dt = float(dt)
        super().__init__(f"retry with a step of {dt:.6g} s" + (f" ({why})" if why else ""))


class Mechanics(Protocol):
    """A mechanical participant. One whose ``advance`` may raise :class:`RetryStep` says so with a true
    ``retries_steps`` attribute (the loop then keeps the load's state at every EM step, to evaluate it again)."""

    time: float
    step_count: int

    def stable_time_step(self) -> float:
        """Largest stable step (s), safety factor included."""

    def advance(self, dt: float, n_steps: int, forces: dict[str, np.ndarray] | None) -> None:
        """``n_steps`` steps of ``dt`` (s) with nodal forces held constant.

        The forces act from the current time on: the acceleration of the first velocity update
        already includes them (the convention of the explicit DOLFINx solver).
        """

    def positions(self) -> dict[str, np.ndarray]:
        """Current node coordinates per body (m)."""

    def total_force(self, forces: dict[str, np.ndarray]) -> np.ndarray:
        """Resultant (N), shape (2,), of nodal forces: each node counted once over all ranks."""

    def state_dict(self) -> dict[str, np.ndarray]:
        """Everything needed to continue exactly."""

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""

    def impulse_window(self, t0: float, dt: float, k: int) -> float:
        """The centre (s) of the window over which ``k`` steps of ``dt`` from ``t0`` deliver a held
        force's impulse, where the loop evaluates the load. Optional: without it the explicit
        scheme's t0 + (k − 1)·dt/2 (central differences apply the force in the velocity updates at
        t0, ..., t1 − dt); an implicit step holds it over [t0, t1]: t0 + k·dt/2 (a static one: its end, t1)."""


def plain_total(forces: dict[str, np.ndarray], dim: int | None = None) -> np.ndarray:
    """Resultant (N) of nodal forces held entirely on this process: ``dim`` components (default: those of the
    first array, 2 without any)."""
    arrays = [np.asarray(f) for f in forces.values()]
    d = dim if dim is not None else (arrays[0].shape[1] if arrays else 2)
    total = np.zeros(d)
    for f in arrays:
        total += f[:, :d].sum(axis=0)
    return total


class LoadProvider(Protocol):
    """A load participant."""

    def load(self, t0: float, t1: float, t_mid: float, mechanics: Mechanics) -> LoadStep:
        """Nodal forces for the EM step [t0, t1] (s) on the mechanics' current geometry.

        ``t_mid`` is the centre of the window over which central differences deliver the held
        force's impulse, t0 + (n − 1)·dt/2; providers with an explicit time law evaluate there
        (second order); GetDP returns the mean of its implicit-Euler sub-steps.
        """

    def initial(self, mechanics: Mechanics) -> LoadStep:
        """The load at t = 0, before the first step, for the first row of history.csv.

        The true initial values (e.g. a charged bank's capacitor voltage, a pulse's pressure at
        t = 0) and nodal forces, without changing the provider's state. Optional: the loop's
        owner writes zeros for a provider without it.
        """

    def state_dict(self) -> dict[str, np.ndarray]:
        """Everything needed to continue exactly."""

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""

    def checkpoint_state_dict(self) -> dict[str, np.ndarray]:
        """:meth:`state_dict` at a checkpoint (a point a ``--resume`` continues from). Optional: the
        run's owner calls :meth:`state_dict` for a provider without it. A provider whose in-memory
        continuation would differ from a resumed one (the persistent getdp) continues from the
        stored state here."""

    def follow(self, t0: float, mechanics: Mechanics) -> None:
        """Step 2 of an EM step (:mod:`.loop`): the load's own mesh follows the mechanics' current
        positions before each :meth:`load` (t0 in s). Optional: no-op for a load without a mesh."""

    def advance_block(self, mechanics: Mechanics, t_stop: float, n_max: int,
                      dt_max: float | None) -> StepBlock | None:
        """Up to ``n_max`` EM steps of one mechanical step each, load and mechanics together, in
        compiled code, stopping before the step that lands on ``t_stop`` (s); ``dt_max`` (s) caps the
        mechanical step. Optional: None (nothing done, the loop steps from Python)."""

    # The optional methods (``initial``, ``checkpoint_state_dict``, ``follow``, ``advance_block``)
    # and the run owner's optional capabilities (run/driver.py) have their defaults in
    # :class:`LoadCapabilities`; a provider inherits them from it.


class LoadCapabilities:
    """The optional capabilities of a load provider, declared once with what a provider without them
    does: the run's owner calls them without asking whether they exist."""

    #: history columns of :attr:`LoadStep.values`, in order (besides the resultant's)
    columns: tuple[str, ...] = ("force_x_N", "force_y_N")
    #: the provider has EM fields to write (:meth:`snapshot`, :meth:`request_fields`, :meth:`take_peak_snapshot`)
    em_fields: bool = False
    #: the model's symmetry planes (3D: :class:`~pulseform.orchestrator.mesh.geometry3d.PlaneSpec`), whose faces are
    #: no outer surface (the cooling between repeated shots, :mod:`pulseform.orchestrator.run.shots`); none in 2D
    symmetry_planes: tuple = ()

    def initial(self, mechanics: Mechanics) -> LoadStep | None:
        """The load at t = 0 (see :meth:`LoadProvider.initial`); None: the history's first row gets zeros."""
        return None

    def checkpoint_state_dict(self) -> dict[str, np.ndarray]:
        """See :meth:`LoadProvider.checkpoint_state_dict`: here the plain :meth:`state_dict`."""
        return self.state_dict()

    def run_metrics(self, history, counters) -> dict[str, float]:
        """The provider's own figures for ``metrics.json`` at the end of a run (``history``: the run's
        :class:`~pulseform.orchestrator.run.history.History`, ``counters``: the loop's counters)."""
        return {}

    def request_fields(self, times) -> None:
        """Whole-domain fields wanted at these times (s) only (no-op without EM fields)."""

    def take_peak_snapshot(self) -> tuple | None:
        """The field snapshot at the peak coil current once, when it is new (None: nothing to write)."""
        return None

    def take_peak_conductors(self) -> tuple | None:
        """Every conductor's field snapshot at the peak coil current once, when it is new (None: nothing)."""
        return None

    def snapshot(self) -> tuple | None:
        """The current EM field snapshot (None: nothing to write)."""
        return None

    def follow(self, t0: float, mechanics: Mechanics) -> None:
        """No mesh of its own: nothing follows the mechanics (see :meth:`LoadProvider.follow`)."""

    def advance_block(self, mechanics: Mechanics, t_stop: float, n_max: int,
                      dt_max: float | None) -> StepBlock | None:
        """No compiled blocks: None, the loop steps from Python (see :meth:`LoadProvider.advance_block`)."""
        return None

    def close(self) -> None:
        """End what the provider runs (a persistent getdp) and wait for its clean-up; idempotent."""
