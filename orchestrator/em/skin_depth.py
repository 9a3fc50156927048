"""The skin depth of a coupled case's conductors: their default element sizes, and advice when a set
size is too coarse for it.

The rule (a conductor's elements no coarser than δ / 3, at least two through its thickness) and the
study behind it live in :mod:`~pulseform.orchestrator.case.skin`; here ω, the drive's angular frequency,
is known: a prescribed current's ω, a sine's 2π f, a bank's ringing 2π / its period from C and the coils'
inductance (:func:`~.time_scale.source_period`), all before the run.

- :func:`with_default_sizes` fills in the conductor sizes a case leaves out (``pulseform check`` shows
  them; a run logs them and writes them into its ``case.toml``; ``pulseform converge`` starts from them);
- :func:`mesh_advice` names each set size coarser than the rule (a warning, not an error: a coarse mesh
  is a choice, and ``pulseform converge`` measures what it costs).

Units: m, rad/s, S/m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from ..case.io import CaseError
from ..case.model import Case
from ..case.schema import SchemaError, from_dict, to_dict
from ..case.skin import SKIN_FRACTION, conductor_sizes, default_size, region_sigma, skin_depth
from .time_scale import source_period

__all__ = ["SKIN_FRACTION", "skin_depth", "drive_omega", "DefaultSize", "default_sizes", "with_default_sizes",
           "resolve_defaults", "mesh_advice"]


def drive_omega(case: Case) -> float | None:
    """The highest angular frequency (rad/s) of the case's coil currents: 2π over the shortest period of
    its sources; None when none has a period (direct currents, tables, a user deck's coil on a bank)."""
    try:
        return 2.0 * math.pi / source_period(case)
    except ValueError:
        return None


@dataclass(frozen=True)
class DefaultSize:
    """A conductor size the case left unset, as filled in: key path, size (m), skin depth (m; inf for a
    non-conductor), drive angular frequency (rad/s; None without one)."""

    key: str
    size: float
    delta: float
    omega: float | None

    def text(self) -> str:
        """One line for the log and ``pulseform check``."""
        if not math.isfinite(self.delta):
            return f"{self.key} = {self.size * 1e3:.3g} mm (default: half the thickness; a non-conductor)"
        rule = "δ/3" if self.size >= SKIN_FRACTION * self.delta * (1 - 1e-9) else "half the thickness, finer than δ/3"
        return (f"{self.key} = {self.size * 1e3:.3g} mm (default: {rule}; skin depth {self.delta * 1e3:.3g} mm at "
                f"ω = {self.omega:.3g} rad/s)")


def default_sizes(case: Case) -> list[DefaultSize]:
    """The conductor sizes of a coupled case's built-in geometry that the case leaves unset, with the values
    the rule of :mod:`~pulseform.orchestrator.case.skin` gives them.

    Raises
    ------
    SchemaError
        An unset size of a conductor whose drive has no frequency (direct currents, tables): the key must
        then be given.
    """
    if case.geometry is None or case.em is None:
        return []
    unset = [c for c in conductor_sizes(case.geometry) if c[1] is None]
    if not unset:
        return []
    omega = drive_omega(case)
    out = []
    for key, _, thickness, region in unset:
        sigma = region_sigma(case, region)
        if sigma > 0.0 and omega is None:
            raise SchemaError(key, "missing: no source has a frequency to take the skin depth from (a direct "
                              "current or a table), so there is no default; give the element size (a number > 0, in m)")
        delta = skin_depth(omega, sigma) if sigma > 0.0 else math.inf
        out.append(DefaultSize(key, default_size(delta, thickness), delta, omega))
    return out


def with_default_sizes(case: Case) -> Case:
    """``case`` with its unset conductor sizes filled in (:func:`default_sizes`), validated
    again with them (the resource guards then see the real sizes); ``case`` itself when none is unset.

    Raises
    ------
    SchemaError
        As :func:`default_sizes`, or the case with the defaults exceeds its ``[limits]``.
    """
    filled = default_sizes(case)
    if not filled:
        return case
    data = to_dict(case)
    for d in filled:
        *tables, name = d.key.split(".")
        node = data
        for t in tables:
            node = node[t]
        node[name] = d.size
    return from_dict(Case, data)


def resolve_defaults(case: Case, file: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> Case:
    """:func:`with_default_sizes` of a case loaded from ``file`` (with ``overrides``), its errors as a
    :class:`~pulseform.orchestrator.case.errors.CaseError` (one line naming the file and the key)."""
    try:
        return with_default_sizes(case)
    except SchemaError as exc:
        raise CaseError(f"{file}" + (" (with --set overrides)" if overrides else ""), exc.path, exc.message) from None


def mesh_advice(case: Case) -> list[str]:
    """One line per conductor of a coupled case whose element size (capped by its thickness) is coarser
    than :data:`SKIN_FRACTION` of its skin depth at the drive's frequency, naming the key, the size and δ.
    Empty for other cases, user decks and drives without a frequency."""
    if case.case.kind != "coupled" or case.geometry is None or case.em is None or case.coupling.load != "getdp":
        return []
    sizes = [c for c in conductor_sizes(case.geometry) if c[1] is not None]
    omega = drive_omega(case) if sizes else None
    if omega is None:
        return []
    out = []
    for key, size, thickness, region in sizes:
        sigma = region_sigma(case, region)
        if sigma <= 0.0:
            continue
        delta = skin_depth(omega, sigma)
        h = min(size, thickness)
        if h > SKIN_FRACTION * delta * (1.0 + 1e-9):
            what = f"{key} = {size * 1e3:.3g} mm"
            out.append(f"{what} is coarser than δ/3 = {delta / 3 * 1e3:.3g} mm (skin depth "
                       f"{delta * 1e3:.3g} mm at ω = {omega:.3g} rad/s, σ = {sigma:.3g} S/m): forces and motion may be "
                       "a few % off (pulseform converge measures it)")
    return out
