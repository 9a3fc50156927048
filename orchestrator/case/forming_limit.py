"""The ``forming_limit`` table of a material: its forming limit curve (FLC), validated.

A forming limit curve gives, for each minor in-plane true (logarithmic) strain ε2 of a sheet, the major
true strain ε1 at which it necks. The table's points are joined by straight lines; beyond its first
and last minor strain the curve stays flat (the end points' major strains). How the run measures the
strains and the margin below the curve: :mod:`pulseform.orchestrator.mech.forming_limit` and
docs/mechanics.md, "Forming limit check".
"""

from __future__ import annotations

from dataclasses import dataclass

from .schema import SchemaError, spec

__all__ = ["FormingLimitTable", "MAX_FLC_POINTS"]

#: the most points a table may give
MAX_FLC_POINTS = 1000


@dataclass(frozen=True, kw_only=True)
class FormingLimitTable:
    """A forming limit curve: major true strain at necking against minor true strain, piecewise linear."""

    minor_strain: tuple[float, ...] = spec(
        unit="-", ge=-1.0, le=1.0,
        doc="minor in-plane true strains ε2 of the curve's points, strictly increasing (2 to 1000 points); "
            "the curve is flat beyond the first and the last")
    major_strain: tuple[float, ...] = spec(
        unit="-", gt=0.0, le=2.0,
        doc="major true strains ε1 at necking at those minor strains, one per point, each >= its minor strain")
    safety_margin: float = spec(
        0.1, unit="-", ge=0.0, le=1.0,
        doc="width of the 'marginal' zone below the curve, in major true strain: an element with "
            "0 <= FLC(ε2) − ε1 < safety_margin is marginal, below 0 failed, else safe")

    def validate(self, path: str) -> None:
        minor, major = self.minor_strain, self.major_strain
        if not 2 <= len(minor) <= MAX_FLC_POINTS:
            raise SchemaError(f"{path}.minor_strain", f"got {len(minor)} points; give 2 to {MAX_FLC_POINTS} "
                              "minor strains (-), strictly increasing")
        if len(major) != len(minor):
            raise SchemaError(f"{path}.major_strain", f"got {len(major)} values for {len(minor)} minor strains; "
                              "give one major strain (-) per minor strain")
        for i in range(1, len(minor)):
            if minor[i] <= minor[i - 1]:
                raise SchemaError(f"{path}.minor_strain[{i}]", f"got {minor[i]!r} after {minor[i - 1]!r}; the "
                                  "minor strains must be strictly increasing")
        for i, (e2, e1) in enumerate(zip(minor, major)):
            if e1 < e2:
                raise SchemaError(f"{path}.major_strain[{i}]", f"got {e1!r} below its minor strain {e2!r}; the "
                                  "major strain is the larger in-plane principal strain (>= minor)")
