"""Case-file keys of a material's flow curve (``[materials.<name>.flow_curve]``, issue 33) and of its
temperature: the laws of :mod:`pulseform.solvers.dolfinx.flow_curves` with units and plausible ranges,
and the checks of their tables (increasing abscissas, positive stresses, consistent lengths,
temperatures below melting) as one-line :class:`~.schema.SchemaError` messages.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from .schema import SchemaError, show_number, spec

__all__ = ["TableFlowTable", "SwiftTable", "VoceTable", "LudwikTable", "JohnsonCookFlowTable", "FlowCurveTable",
           "check_increasing", "initial_yield_stress"]


def check_increasing(values: tuple[float, ...], path: str, unit: str) -> None:
    """Refuse a list that is not strictly increasing (one line naming ``path``)."""
    for i in range(1, len(values)):
        if not values[i] > values[i - 1]:
            raise SchemaError(f"{path}[{i}]", f"got {show_number(values[i])} after {show_number(values[i - 1])}; "
                                              f"the list must be strictly increasing{f' ({unit})' if unit else ''}")


@dataclass(frozen=True, kw_only=True)
class TableFlowTable:
    """Tabulated flow curve(s) σ_y(ε_p), piecewise linear (LS-DYNA's piecewise-linear plasticity)."""

    type: Literal["table"] = spec(doc="flow curve kind")
    plastic_strain: tuple[float, ...] = spec(unit="-", ge=0.0, doc="equivalent plastic strains of the points, "
                                                                    "from 0, strictly increasing")
    yield_stress: tuple[float, ...] | tuple[tuple[float, ...], ...] = spec(
        unit="Pa", doc="yield stress at each plastic strain (> 0): one list, or one list per curve, "
                       "temperature-major (every strain rate of the first temperature, then the next)")
    strain_rates: tuple[float, ...] = spec((), unit="1/s", gt=0.0, doc="strain rates of the curves, increasing "
                                                                       "(interpolated in ln ε̇, clamped outside)")
    temperatures: tuple[float, ...] = spec((), unit="K", gt=0.0, doc="temperatures of the curves, increasing "
                                                                     "(interpolated linearly, clamped outside)")
    extrapolation: Literal["constant", "linear"] = spec("linear", doc="beyond the last plastic strain: the last "
                                                                      "yield stress, or the last segment continued")

    def curves(self) -> tuple[tuple[float, ...], ...]:
        """The yield stresses as a list of curves."""
        ys = self.yield_stress
        return ys if ys and isinstance(ys[0], tuple) else (ys,)  # type: ignore[return-value]

    def validate(self, path: str) -> None:
        eps = self.plastic_strain
        if len(eps) < 2 or eps[0] != 0.0:
            raise SchemaError(f"{path}.plastic_strain", f"got {list(eps)}; needs at least 2 points, the first 0")
        check_increasing(eps, f"{path}.plastic_strain", "")
        check_increasing(self.strain_rates, f"{path}.strain_rates", "1/s")
        check_increasing(self.temperatures, f"{path}.temperatures", "K")
        curves = self.curves()
        n = max(len(self.strain_rates), 1) * max(len(self.temperatures), 1)
        if len(curves) != n:
            raise SchemaError(f"{path}.yield_stress", f"got {len(curves)} curve(s); needs {n}: one per temperature "
                                                      f"({len(self.temperatures)}) and strain rate "
                                                      f"({len(self.strain_rates)})")
        nested = isinstance(self.yield_stress[0], tuple) if self.yield_stress else False
        for i, row in enumerate(curves):
            where = f"{path}.yield_stress[{i}]" if nested else f"{path}.yield_stress"
            if len(row) != len(eps):
                raise SchemaError(where, f"got {len(row)} values; needs {len(eps)}, one per plastic_strain")
            for j, s in enumerate(row):
                if not s > 0:
                    raise SchemaError(f"{where}[{j}]", f"got {show_number(s)}; must be > 0 (Pa)")


@dataclass(frozen=True, kw_only=True)
class SwiftTable:
    """Swift law σ_y = K (ε_0 + ε_p)^n."""

    type: Literal["swift"] = spec(doc="flow curve kind")
    K: float = spec(unit="Pa", gt=0.0, doc="strength coefficient K")
    eps0: float = spec(unit="-", gt=0.0, doc="pre-strain ε_0")
    n: float = spec(unit="-", ge=0.0, le=1.0, doc="hardening exponent n")


@dataclass(frozen=True, kw_only=True)
class VoceTable:
    """Voce law σ_y = σ_0 + Q (1 − exp(−b ε_p))."""

    type: Literal["voce"] = spec(doc="flow curve kind")
    sigma0: float = spec(unit="Pa", gt=0.0, doc="initial yield stress σ_0")
    Q: float = spec(unit="Pa", ge=0.0, doc="saturation hardening Q")
    b: float = spec(unit="-", ge=0.0, doc="saturation rate b")


@dataclass(frozen=True, kw_only=True)
class LudwikTable:
    """Ludwik law σ_y = σ_0 + K ε_p^n."""

    type: Literal["ludwik"] = spec(doc="flow curve kind")
    sigma0: float = spec(unit="Pa", gt=0.0, doc="initial yield stress σ_0")
    K: float = spec(unit="Pa", ge=0.0, doc="strength coefficient K")
    n: float = spec(unit="-", gt=0.0, le=1.0, doc="hardening exponent n")


@dataclass(frozen=True, kw_only=True)
class JohnsonCookFlowTable:
    """The full Johnson–Cook law σ_y = (A + B ε_p^n)(1 + C ln ε̇*)(1 − T*^m), ε̇* = ε̇/ε̇_0 (the rate term is
    1 below ε̇_0), T* = (T − T_room)/(T_melt − T_room) (0 below room temperature; σ_y = 0 at melting)."""

    type: Literal["johnson_cook"] = spec(doc="flow curve kind")
    A: float = spec(unit="Pa", gt=0.0, doc="yield stress A")
    B: float = spec(unit="Pa", ge=0.0, doc="hardening modulus B")
    n: float = spec(unit="-", gt=0.0, le=1.0, doc="hardening exponent n")
    C: float = spec(0.0, unit="-", ge=0.0, doc="rate sensitivity C")
    reference_strain_rate: float = spec(1.0, unit="1/s", gt=0.0, doc="reference strain rate ε̇_0")
    room_temperature: float = spec(293.15, unit="K", gt=0.0, doc="room temperature T_room")
    melting_temperature: float = spec(unit="K", gt=0.0, doc="melting temperature T_melt")
    m: float = spec(1.0, unit="-", gt=0.0, doc="thermal softening exponent m")

    def validate(self, path: str) -> None:
        if not self.melting_temperature > self.room_temperature:
            raise SchemaError(f"{path}.melting_temperature",
                              f"got {show_number(self.melting_temperature)}; must be above room_temperature = "
                              f"{show_number(self.room_temperature)} (K)")


FlowCurveTable = TableFlowTable | SwiftTable | VoceTable | LudwikTable | JohnsonCookFlowTable


def initial_yield_stress(fc: FlowCurveTable) -> float:
    """The curve's yield stress at zero plastic strain (the reference rate, the first temperature), Pa."""
    if isinstance(fc, TableFlowTable):
        return fc.curves()[0][0]
    if isinstance(fc, SwiftTable):
        return fc.K * fc.eps0 ** fc.n
    if isinstance(fc, JohnsonCookFlowTable):
        return fc.A
    return fc.sigma0
