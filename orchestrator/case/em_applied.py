"""Case-file model of a uniform applied magnetic field (``[em.applied_field]``; SI units, validated).

B_app(t) = magnitude · d · f(t), d = direction / |direction|, with the time function f given like an
``[[em.sources]]`` current waveform, in units of the magnitude: ``dc`` (f = 1 from t_on on), ``sine``
(f = e^(−decay (t − t_on)) sin(2π frequency (t − t_on) + phase)) or ``table`` (a CSV file of the case
folder: rows time s, factor; held at its last value). The field is switched on from rest: a ``dc``
field at t_on = 0 is a suddenly applied field. It acts beside the coils (GetDP's reduced-field split:
pulseform.solvers.getdp.applied_field). The direction is (0, ±1): in axisymmetry (r, z) a uniform field
is axial; the planar geometries are half models whose symmetry plane x = 0 has a = 0 (the fields of
the coils are tangential to it), so a uniform field there must be tangential too, along y.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from .em_sources import SineTime, TableTime
from .errors import CaseError
from .schema import SchemaError, shorten, spec

__all__ = ["AppliedDC", "AppliedSine", "AppliedTable", "AppliedField", "check_applied_field",
           "resolve_applied_field_file"]


@dataclass(frozen=True, kw_only=True)
class _Applied:
    magnitude: float = spec(unit="T", gt=0.0, doc="B0: the field's magnitude (its sign is the direction's)")
    direction: tuple[float, float] | tuple[float, float, float] = spec(
        unit="-", doc="direction, normalised: 2D (r, z) or (x, y): (0, 1) or (0, -1) (axial; along the symmetry "
                      "plane x = 0 of a planar half model); 3D geometry files [x, y, z]: any direction that lies in "
                      "every b_tangential [[symmetry]] plane and crosses every b_normal one")

    def validate(self, path: str) -> None:
        if not any(self.direction):
            raise SchemaError(f"{path}.direction", f"got {list(self.direction)}; must not be zero")


@dataclass(frozen=True, kw_only=True)
class AppliedDC(_Applied):
    """A constant field B0 · d from t_on on (switched on from rest: a suddenly applied field)."""

    type: Literal["dc"] = spec(doc="time function kind")
    t_on: float = spec(0.0, unit="s", ge=0.0, doc="switch-on time: no field before")


@dataclass(frozen=True, kw_only=True)
class AppliedSine(_Applied, SineTime):
    """B0 · d · e^(−decay (t − t_on)) sin(2π frequency (t − t_on) + phase) for t >= t_on, 0 before."""

    type: Literal["sine"] = spec(doc="time function kind")


@dataclass(frozen=True, kw_only=True)
class AppliedTable(_Applied, TableTime):
    """B0 · d · f(t), f linearly interpolated in a CSV file's rows (time s, factor), held after them."""

    type: Literal["table"] = spec(doc="time function kind")

    def validate(self, path: str) -> None:
        _Applied.validate(self, path)
        TableTime.validate(self, path)


AppliedField = AppliedDC | AppliedSine | AppliedTable


def check_applied_field(case: Any) -> None:
    """Case-level checks of ``[em.applied_field]`` (a coupled case): a field along the axis (axisymmetric)
    or along the symmetry plane x = 0 (planar half models), and a deck on pulseform's library (GetDP's
    template does not know the field)."""
    f = case.em.applied_field
    if f is None:
        return
    g = case.geometry
    if getattr(g, "type", None) == "geometry_3d":
        if len(f.direction) != 3:
            raise SchemaError("em.applied_field.direction", f"got {len(f.direction)} components; a 3D geometry file "
                              "needs [x, y, z]")
        return
    if len(f.direction) != 2:
        raise SchemaError("em.applied_field.direction", f"got {len(f.direction)} components; a 2D case needs [r, z] "
                          "or [x, y]")
    if getattr(g, "library", None) == "getdp_template":
        raise SchemaError("em.applied_field", "a deck on GetDP's template (geometry.library = 'getdp_template') "
                          "has no applied field: use library = 'pulseform' or remove [em.applied_field]")
    if f.direction[0] != 0.0:
        why = ("a plane half model whose symmetry plane x = 0 has a = 0: the field must be tangential to it"
               if g.planar else "axisymmetric: a uniform applied field is axial")
        raise SchemaError("em.applied_field.direction", f"got {list(f.direction)}; the {g.type} geometry is {why}, "
                          "(0, 1) or (0, -1)")


def resolve_applied_field_file(data: dict[str, Any], file: Path, source: str) -> None:
    """Make a ``table`` applied field's ``file`` absolute (relative to the case file's folder) and check it
    (inside the case folder unless ``allow_outside``, a readable table of time s, factor). Raises
    :class:`CaseError` naming ``em.applied_field.file`` (one line)."""
    from .em_sources import read_current_table

    em = data.get("em")
    f = em.get("applied_field") if isinstance(em, dict) else None
    if not isinstance(f, dict) or f.get("type") != "table":
        return
    value = f.get("file")
    if not isinstance(value, str) or not value or "\x00" in value:
        return  # the schema reports the missing / mistyped key
    key = "em.applied_field.file"
    folder = file.resolve().parent
    try:
        p = Path(value)
        p = (p if p.is_absolute() else folder / p).resolve()
    except (OSError, ValueError, RuntimeError) as exc:
        raise CaseError(source, key, f"got {shorten(repr(value))}: cannot resolve it ({exc})") from None
    if f.get("allow_outside") is not True and not p.is_relative_to(folder):
        raise CaseError(source, key, f"got {shorten(repr(value))}, which resolves outside the case folder {folder}; "
                        "move it into the folder or set allow_outside = true")
    if not p.is_file():
        raise CaseError(source, key, f"got {shorten(repr(value))}: file not found ({p})")
    try:
        read_current_table(p, quantity=("factor", "-"))
    except (OSError, ValueError) as exc:
        raise CaseError(source, key, f"{p.name}: {getattr(exc, 'strerror', None) or exc}") from None
    f["file"] = str(p)
