"""Case-file keys of a conductivity that follows temperature, σ(T) (issue 33): a material's
``[materials.<name>.conductivity_curve]`` and the coil's ``[em.coil_conductivity_curve]``, with units and
plausible ranges, their one-line checks (temperatures strictly increasing and below melting, conductivities
> 0), and the GetDP law they make (:mod:`pulseform.solvers.getdp.conductivity`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pulseform.solvers.getdp.conductivity import ConductivityLaw, ConductivityTable, LinearResistivity

from .flow import check_increasing
from .schema import SchemaError, show_number, spec

__all__ = ["ConductivityTableSpec", "LinearResistivitySpec", "ConductivityCurve", "conductivity_law"]


@dataclass(frozen=True, kw_only=True)
class ConductivityTableSpec:
    """σ(T) piecewise linear through the points, the end values held outside the table."""

    type: Literal["table"] = spec(doc="conductivity law kind")
    temperatures: tuple[float, ...] = spec(unit="K", gt=0.0, doc="temperatures of the points, strictly increasing")
    conductivities: tuple[float, ...] = spec(unit="S/m", gt=0.0, doc="electrical conductivity at each temperature "
                                                                     "(> 0)")
    melting_temperature: float | None = spec(None, unit="K", gt=0.0,
                                             doc="melting temperature: every table temperature must be below it "
                                                 "(default: the flow curve's, if it has one)")

    def validate(self, path: str) -> None:
        t, s = self.temperatures, self.conductivities
        if len(t) < 2:
            raise SchemaError(f"{path}.temperatures", f"got {list(t)}; needs at least 2 points")
        check_increasing(t, f"{path}.temperatures", "K")
        if len(s) != len(t):
            raise SchemaError(f"{path}.conductivities", f"got {len(s)} values; needs {len(t)}, one per temperature")
        check_below_melting(self, path, self.melting_temperature)


@dataclass(frozen=True, kw_only=True)
class LinearResistivitySpec:
    """ρ(T) = ρ_ref (1 + α (T − T_ref)): σ(T) = σ_ref / (1 + α (T − T_ref)), σ_ref the material's
    electrical_conductivity (em.coil_conductivity for the coil)."""

    type: Literal["linear_resistivity"] = spec(doc="conductivity law kind")
    temperature_coefficient: float = spec(unit="1/K", ge=0.0, le=0.1, doc="α of the resistivity (copper 3.9e-3, "
                                                                          "aluminium 4.0e-3 /K)")
    reference_temperature: float = spec(293.15, unit="K", gt=0.0, doc="T_ref, where σ is σ_ref")
    melting_temperature: float | None = spec(None, unit="K", gt=0.0,
                                             doc="melting temperature: T_ref must be below it (default: the flow "
                                                 "curve's, if it has one)")

    def validate(self, path: str) -> None:
        check_below_melting(self, path, self.melting_temperature)


ConductivityCurve = ConductivityTableSpec | LinearResistivitySpec


def check_below_melting(curve: ConductivityCurve, path: str, melting: float | None) -> None:
    """Refuse a table temperature (or a linear law's reference temperature) at or above ``melting`` (K;
    None: no check) in one line naming the key."""
    if melting is None:
        return
    if isinstance(curve, ConductivityTableSpec):
        for i, t in enumerate(curve.temperatures):
            if not t < melting:
                raise SchemaError(f"{path}.temperatures[{i}]", f"got {show_number(t)}; must be below the melting "
                                                               f"temperature {show_number(melting)} (K)")
    elif not curve.reference_temperature < melting:
        raise SchemaError(f"{path}.reference_temperature", f"got {show_number(curve.reference_temperature)}; must be "
                                                           f"below the melting temperature {show_number(melting)} (K)")


def conductivity_law(curve: ConductivityCurve | None, sigma_ref: float) -> ConductivityLaw | None:
    """The GetDP law of ``curve`` (None without one); ``sigma_ref`` (S/m): σ at the linear law's T_ref."""
    if curve is None:
        return None
    if isinstance(curve, ConductivityTableSpec):
        return ConductivityTable(curve.temperatures, curve.conductivities)
    return LinearResistivity(sigma_ref=sigma_ref, alpha=curve.temperature_coefficient,
                             reference_temperature=curve.reference_temperature)
