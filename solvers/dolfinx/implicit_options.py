"""Options and errors of the implicit integrator (:mod:`.implicit`): the time scheme, step and Newton settings,
checked on construction."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

__all__ = ["SCHEMES", "ImplicitOptions", "ImplicitConvergenceError", "NotConverged"]

#: the implicit time schemes
SCHEMES = ("trapezoidal", "hht", "static")


class ImplicitConvergenceError(RuntimeError):
    """Newton did not converge even on the smallest allowed step; the state is that of the last
    converged step."""


class NotConverged(Exception):
    """A Newton solve failed (iterations exhausted, a cell inverted, a non-finite residual): ``why``, and the
    relative residuals of its iterations."""

    def __init__(self, why: str, residuals: Sequence[float]):
        self.why = why
        self.residuals = list(residuals)
        super().__init__(why)


@dataclass(frozen=True)
class ImplicitOptions:
    """Options of the implicit step.

    Attributes
    ----------
    dt : float
        The step, s (what :meth:`ImplicitSolver.stable_time_step` reports to the loop).
    scheme : {"trapezoidal", "hht", "static"}
        Newmark average acceleration; HHT-alpha; static equilibrium steps (no inertia).
    alpha : float
        HHT's alpha in [-1/3, 0] (0: the trapezoidal rule; -0.05 ... -0.3 damp the high modes).
    newton_tol : float
        Relative residual that ends the Newton iterations (dimensionless).
    newton_max : int
        Most Newton iterations per step.
    max_cuts : int
        Most halvings of a step that does not converge.
    adaptive : bool
        Choose each step from a local error estimate (:mod:`.implicit_adapt`); ``dt`` is the first step.
        Not with the static scheme (no inertia: no time-integration error to estimate).
    error_tol : float
        Adaptive: the accepted local error estimate relative to the displacement scale (dimensionless).
    error_atol : float
        Adaptive: the accepted local error estimate added to ``error_tol`` times the scale, m (root mean square
        over the free components; it keeps the steps of a start from rest from shrinking to nothing).
    dt_min : float or None
        Adaptive: the smallest step, s (a step this short is accepted whatever its error); None: dt / 1000.
    dt_max : float
        Adaptive: the largest step, s (inf: only the output times and the growth limit bound it).
    """

    dt: float
    scheme: str = "trapezoidal"
    alpha: float = 0.0
    newton_tol: float = 1e-8
    newton_max: int = 25
    max_cuts: int = 6
    adaptive: bool = False
    error_tol: float = 1e-3
    error_atol: float = 1e-9
    dt_min: Optional[float] = None
    dt_max: float = math.inf

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"implicit dt must be a positive number of seconds, got {self.dt!r}")
        if self.scheme not in SCHEMES:
            raise ValueError(f"implicit scheme must be one of {SCHEMES}, got {self.scheme!r}")
        if not -1.0 / 3.0 <= self.alpha <= 0.0:
            raise ValueError(f"HHT alpha must lie in [-1/3, 0], got {self.alpha}")
        if self.scheme != "hht" and self.alpha != 0.0:
            raise ValueError(f"alpha = {self.alpha} needs scheme 'hht' (got {self.scheme!r})")
        if not 0.0 < self.newton_tol < 1.0:
            raise ValueError(f"newton_tol must lie in (0, 1), got {self.newton_tol}")
        if int(self.newton_max) != self.newton_max or self.newton_max < 1:
            raise ValueError(f"newton_max must be a positive integer, got {self.newton_max}")
        if int(self.max_cuts) != self.max_cuts or not 0 <= self.max_cuts <= 30:
            raise ValueError(f"max_cuts must be an integer from 0 to 30, got {self.max_cuts}")
        if self.adaptive:
            if self.scheme == "static":
                raise ValueError("adaptive steps need a dynamic scheme ('trapezoidal' or 'hht'); static steps have "
                                 "no time-integration error to estimate")
            if not 0.0 < self.error_tol < 1.0:
                raise ValueError(f"error_tol must lie in (0, 1), got {self.error_tol}")
            if not (math.isfinite(self.error_atol) and self.error_atol >= 0.0):
                raise ValueError(f"error_atol must be a length >= 0 (m), got {self.error_atol}")
            if not self.step_min <= self.dt <= self.dt_max:
                raise ValueError(f"adaptive steps need dt_min <= dt <= dt_max, got {self.step_min}, {self.dt}, "
                                 f"{self.dt_max} s")

    @property
    def step_min(self) -> float:
        """The smallest adaptive step, s (``dt_min``, or dt / 1000)."""
        return self.dt * 1e-3 if self.dt_min is None else self.dt_min

    @property
    def beta(self) -> float:
        """Newmark beta = (1 - alpha)^2 / 4."""
        return 0.25 * (1.0 - self.alpha) ** 2

    @property
    def gamma(self) -> float:
        """Newmark gamma = 1/2 - alpha."""
        return 0.5 - self.alpha
