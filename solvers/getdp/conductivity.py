"""Electrical conductivity that follows temperature, σ(T), of a coil or a massive conductor (issue 33).

Two laws:

* :class:`ConductivityTable`: σ(T) piecewise linear through (temperature, conductivity) points, the end
  values held outside the table;
* :class:`LinearResistivity`: the resistivity grows linearly, ρ(T) = ρ_ref (1 + α (T − T_ref)), i.e.
  σ(T) = σ_ref / (1 + α (T − T_ref)) (copper: α = 3.9e-3 /K at 293 K).

How GetDP receives them: a coil is one lumped body (its temperature uniform, adiabatic during a shot: the
Joule heat so far over m c_p), so its σ is one number per EM step (``Coil_sigma_k``); a massive conductor's
σ is one value per element, ``Cond_SigmaList_k() = {element tag, σ, ...}`` read by the built-in deck with
``InterpolationLinear[ElementNum[]]`` (exact at the listed tags: no grouping of elements into bins).
Both are evaluated at the step's start temperatures (explicit in temperature, like the mechanics' heating).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

__all__ = ["ConductivityTable", "LinearResistivity", "ConductivityLaw", "law_from_dict", "element_list_line"]


@dataclass(frozen=True)
class ConductivityTable:
    """σ(T) piecewise linear through the points (``temperatures`` K, strictly increasing; ``values`` S/m,
    > 0), the end values held outside the table."""

    temperatures: tuple[float, ...]
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        t = np.asarray(self.temperatures, float)
        v = np.asarray(self.values, float)
        if t.ndim != 1 or t.shape != v.shape or len(t) < 1:
            raise ValueError("a conductivity table needs as many conductivities as temperatures (at least one)")
        if np.any(np.diff(t) <= 0) or np.any(t <= 0):
            raise ValueError("a conductivity table's temperatures must be > 0 K and strictly increasing")
        if np.any(v <= 0) or not np.all(np.isfinite(v)):
            raise ValueError("a conductivity table's values must be finite and > 0 (S/m)")
        object.__setattr__(self, "temperatures", tuple(float(x) for x in t))
        object.__setattr__(self, "values", tuple(float(x) for x in v))

    def __call__(self, temperature: float | np.ndarray) -> np.ndarray:
        """σ (S/m) at ``temperature`` (K)."""
        return np.interp(np.asarray(temperature, float), self.temperatures, self.values)


@dataclass(frozen=True)
class LinearResistivity:
    """σ(T) = σ_ref / (1 + α (T − T_ref)): ``sigma_ref`` S/m at ``reference_temperature`` K, ``alpha`` 1/K.
    Refused where the resistivity would not stay positive (a temperature below T_ref − 1/α is an error)."""

    sigma_ref: float
    alpha: float
    reference_temperature: float = 293.15

    def __post_init__(self) -> None:
        if not (self.sigma_ref > 0 and np.isfinite(self.sigma_ref)):
            raise ValueError("LinearResistivity: sigma_ref must be finite and > 0 (S/m)")
        if not self.reference_temperature > 0:
            raise ValueError("LinearResistivity: reference_temperature must be > 0 (K)")

    def __call__(self, temperature: float | np.ndarray) -> np.ndarray:
        """σ (S/m) at ``temperature`` (K)."""
        f = 1.0 + self.alpha * (np.asarray(temperature, float) - self.reference_temperature)
        if np.any(f <= 0):
            raise ValueError(f"LinearResistivity: 1 + alpha (T - T_ref) <= 0 at T = "
                             f"{float(np.min(temperature)):.6g} K (alpha = {self.alpha:g} /K)")
        return self.sigma_ref / f


ConductivityLaw = ConductivityTable | LinearResistivity


def law_from_dict(d: dict | ConductivityLaw | None) -> ConductivityLaw | None:
    """A law from its ``dataclasses.asdict`` form (an :class:`~.model.EMModel` read back from JSON)."""
    if d is None or isinstance(d, (ConductivityTable, LinearResistivity)):
        return d
    if "temperatures" in d:
        return ConductivityTable(tuple(d["temperatures"]), tuple(d["values"]))
    return LinearResistivity(**d)


def element_list_line(name: str, tags: Sequence[int] | np.ndarray, sigma: Sequence[float] | np.ndarray) -> str:
    """``<name>() = {tag, σ, ...};`` sorted by tag, for ``InterpolationLinear[ElementNum[]]`` (one element is
    listed twice, at tag and tag + 1: the interpolation needs two points)."""
    tags = np.asarray(tags, np.int64)
    sigma = np.asarray(sigma, float)
    if tags.shape != sigma.shape or tags.ndim != 1 or len(tags) == 0:
        raise ValueError("element_list_line needs as many conductivities as element tags (at least one)")
    order = np.argsort(tags, kind="stable")
    tags, sigma = tags[order], sigma[order]
    if np.any(np.diff(tags) == 0):
        raise ValueError("element_list_line: an element tag is listed twice")
    if len(tags) == 1:
        tags, sigma = np.array([tags[0], tags[0] + 1]), np.array([sigma[0], sigma[0]])
    pairs = [f"{t}, {s:.17g}" for t, s in zip(tags.tolist(), sigma.tolist())]
    body = ",\n  ".join(", ".join(pairs[j:j + 8]) for j in range(0, len(pairs), 8))
    return f"{name}() = {{\n  {body}}};"
