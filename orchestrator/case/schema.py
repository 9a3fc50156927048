"""Declarative validation of plain data (parsed TOML) into typed, frozen dataclasses.

A dataclass field declares its constraints in ``metadata`` through :func:`spec`::

    end: float = spec(unit="s", gt=0.0, doc="simulated end time")

Supported field types: ``str``, ``int``, ``float`` (an int is accepted), ``bool``, ``Literal[...]``,
fixed-length ``tuple[float, float]``, variable ``tuple[X, ...]``, ``dict[str, X]``, ``X | None``,
nested dataclasses, and tagged unions of dataclasses (``A | B``) told apart by their ``type`` literal.

Every number must be finite (an infinity only where the field's default is that infinity) and lie in
the plausible range of its unit (:data:`PLAUSIBLE`; ``spec(magnitude=...)`` overrides it for one field).

Every problem raises :class:`SchemaError` carrying the dotted key path and what is allowed, so the CLI
can print a single line. No string from the input is ever evaluated.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import operator
import types
from typing import Any, Literal, Union, get_args, get_origin, get_type_hints

MISSING = dataclasses.MISSING

#: Plausible magnitudes of a number by its unit: (smallest non-zero |value|, largest |value|). Generous for
#: pulsed forming and its EM circuits, they refuse absurd inputs (1e308 Pa, 1e30 s) before any meshing.
#: Zero passes wherever the field's own bounds allow it. docs/reference/case-file.md lists this table (generated).
PLAUSIBLE: dict[str, tuple[float, float]] = {
    "m": (1e-12, 10.0),
    "m^2": (1e-20, 100.0),
    "s": (1e-15, 1e3),
    "-": (1e-12, 1e9),
    "kg/m^3": (1e-3, 1e5),
    "Pa": (1e-6, 1e13),
    "Pa·m": (1e-6, 1e13),
    "Pa·s²/m²": (1e-12, 1e12),
    "m/s": (1e-12, 1e5),
    "m/s^2": (1e-9, 1e12),
    "kg": (1e-12, 1e6),
    "1/s": (1e-12, 1e12),
    "rad/s": (1e-6, 1e12),
    "Hz": (1e-6, 1e12),
    "rad": (1e-12, 1e3),
    "deg": (1e-9, 360.0),
    "S/m": (1e-12, 1e9),
    "V": (1e-6, 1e7),
    "A": (1e-6, 1e8),
    "F": (1e-15, 10.0),
    "H": (1e-15, 1.0),
    "Ω": (1e-12, 1e6),
    "J/(kg·K)": (1e-3, 1e6),
    "K": (1.0, 1e4),
    "1/K": (1e-9, 1.0),
    "W/(m²·K)": (1e-6, 1e6),
    "T": (1e-9, 1e3),
    "A/m": (1e-6, 1e10),
}
#: Range of a number without a unit in :data:`PLAUSIBLE` (e.g. user-deck parameters): finite and not huge.
PLAUSIBLE_OTHER: tuple[float, float] = (0.0, 1e15)


class SchemaError(ValueError):
    """A value in the input does not fit the schema.

    Parameters
    ----------
    path : str
        Dotted key path, e.g. ``bodies[0].mesh_size``.
    message : str
        What is wrong and what is allowed.
    """

    def __init__(self, path: str, message: str) -> None:
        self.path = path
        self.message = message
        super().__init__(f"{path}: {message}" if path else message)


def spec(
    default: Any = MISSING,
    *,
    unit: str = "",
    doc: str = "",
    gt: float | None = None,
    ge: float | None = None,
    lt: float | None = None,
    le: float | None = None,
    default_factory: Any = MISSING,
    magnitude: tuple[float, float] | None = None,
) -> Any:
    """Declare a dataclass field with its unit, documentation and numeric bounds.

    Parameters
    ----------
    default : Any
        Default value; omit for a required key.
    unit : str
        SI unit shown in messages and in the generated reference ("-" for dimensionless).
    doc : str
        One-line description for the reference.
    gt, ge, lt, le : float, optional
        Exclusive / inclusive bounds for numbers (applied to every element of a numeric tuple).
    default_factory : callable, optional
        Factory for mutable defaults.
    magnitude : (float, float), optional
        Plausible (smallest non-zero, largest) ``|value|`` of this field instead of the unit's entry in
        :data:`PLAUSIBLE` (e.g. a wall-clock time limit, which may well exceed the simulated times).

    Notes
    -----
    A default of ``inf`` or ``-inf`` makes that infinity an allowed input value of the field.
    """
    inf = default if isinstance(default, float) and math.isinf(default) else None
    meta = {"unit": unit, "doc": doc, "gt": gt, "ge": ge, "lt": lt, "le": le, "magnitude": magnitude, "inf": inf}
    if default_factory is not MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _type_name(tp: Any) -> str:
    origin = get_origin(tp)
    if tp is float:
        return "a number"
    if tp is int:
        return "an integer"
    if tp is bool:
        return "true or false"
    if tp is str:
        return "a string"
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in get_args(tp))
    if origin is tuple:
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_type_name(args[0])}"
        return f"a list of {len(args)} numbers"
    if origin is dict:
        return "a table"
    if dataclasses.is_dataclass(tp):
        return "a table"
    if _is_union(tp):
        parts = [a for a in get_args(tp) if a is not type(None)]
        if len(parts) == 1:
            return _type_name(parts[0])
        if all(dataclasses.is_dataclass(a) for a in parts):
            return "a table with type = " + " | ".join(repr(_tag(a)) for a in parts)
        return " or ".join(_type_name(a) for a in parts)
    return getattr(tp, "__name__", str(tp))


@functools.cache
def _type_hints(cls: type) -> dict[str, Any]:
    """``get_type_hints(cls)``, once per class (a case file is validated on every `check`; the hints of a schema
    class never change). Read it, never change it."""
    return get_type_hints(cls)


def _is_union(tp: Any) -> bool:
    return get_origin(tp) in (Union, types.UnionType)


def _tag(cls: type) -> str:
    hints = _type_hints(cls)
    args = get_args(hints.get("type", None))
    if not args:
        raise TypeError(f"{cls.__name__} in a tagged union needs a `type: Literal[...]` field")
    return args[0]


def shorten(text: str, limit: int = 60) -> str:
    """``text`` cut to ``limit`` characters (``…`` marks the cut)."""
    return text if len(text) <= limit else text[:limit] + "…"


def show_number(value: int | float) -> str:
    """A number for a message: ``repr``, or the digit count of a huge integer (no 4300-digit limit)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        return f"an integer of about {int(value.bit_length() * math.log10(2)) + 1} digits"
    return repr(value)


def _describe_value(value: Any) -> str:
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return show_number(value)
    return shorten(repr(value))


def plausible_range(meta: dict[str, Any]) -> tuple[float, float]:
    """(smallest non-zero, largest) ``|value|`` of a field: its ``magnitude``, else its unit's entry."""
    return meta.get("magnitude") or PLAUSIBLE.get(meta.get("unit") or "", PLAUSIBLE_OTHER)


def _check_bounds(value: int | float, meta: dict[str, Any], path: str) -> None:
    """Finite, within the field's bounds, and within its plausible range (see :data:`PLAUSIBLE`)."""
    unit = meta.get("unit") or ""
    suffix = f" ({unit})" if unit and unit != "-" else ""
    shown = show_number(value)
    is_float = isinstance(value, float)
    if is_float and (math.isnan(value) or (math.isinf(value) and value != meta.get("inf"))):
        allowed = f" or {meta['inf']!r}" if meta.get("inf") is not None else ""
        raise SchemaError(path, f"got {shown}; must be a finite number{allowed}{suffix}")
    for key, ok in (("gt", operator.gt), ("ge", operator.ge), ("lt", operator.lt), ("le", operator.le)):
        bound = meta.get(key)
        if bound is not None and not ok(value, bound):
            raise SchemaError(path, f"got {shown}; must be {bounds_text(meta)}{suffix}")
    if is_float and math.isinf(value):
        return  # the field's default infinity
    lo, hi = plausible_range(meta)
    if not (value == 0 or lo <= abs(value) <= hi):
        zero = " (or 0)" if _zero_allowed(meta) else ""
        raise SchemaError(path, f"got {shown}; outside the plausible range {lo:g} <= |value| <= {hi:g}"
                                f"{' ' + unit if unit and unit != '-' else ''}{zero}")


def _zero_allowed(meta: dict[str, Any]) -> bool:
    return all(meta.get(k) is None or ok(0.0, meta[k]) for k, ok in
               (("gt", operator.gt), ("ge", operator.ge), ("lt", operator.lt), ("le", operator.le)))


def bounds_text(meta: dict[str, Any]) -> str:
    """Human-readable allowed range from a field's metadata, e.g. ``> 0 and <= 1``."""
    parts = []
    for key, sym in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
        if meta.get(key) is not None:
            parts.append(f"{sym} {meta[key]:g}")
    return " and ".join(parts)


def convert(tp: Any, value: Any, path: str, meta: dict[str, Any] | None = None) -> Any:
    """Convert ``value`` to type ``tp``, validating it; raise :class:`SchemaError` with ``path``."""
    meta = meta or {}
    origin = get_origin(tp)
    if tp is Any:
        return value
    if _is_union(tp):
        args = get_args(tp)
        if value is None and type(None) in args:
            return None
        parts = [a for a in args if a is not type(None)]
        if len(parts) == 1:
            return convert(parts[0], value, path, meta)
        if all(dataclasses.is_dataclass(a) for a in parts):
            return _convert_tagged(parts, value, path)
        if isinstance(value, (list, tuple)):  # fixed-length lists told apart by length: the element's error
            sized = [a for a in parts if get_origin(a) is tuple and Ellipsis not in get_args(a)
                     and len(get_args(a)) == len(value)]
            if len(sized) == 1:
                return convert(sized[0], value, path, meta)
        for a in parts:
            try:
                return convert(a, value, path, meta)
            except SchemaError:
                continue
        raise SchemaError(path, f"got {_describe_value(value)}; expected {_type_name(tp)}")
    if origin is Literal:
        allowed = get_args(tp)
        if value not in allowed or isinstance(value, bool) != isinstance(allowed[0], bool):
            raise SchemaError(path, f"got {_describe_value(value)}; allowed: "
                              + ", ".join(repr(a) for a in allowed))
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise SchemaError(path, f"got {_describe_value(value)}; expected true or false")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise SchemaError(path, f"got {_describe_value(value)}; expected an integer"
                              + (f" {bounds_text(meta)}" if bounds_text(meta) else ""))
        _check_bounds(value, meta, path)
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            unit = meta.get("unit") or ""
            raise SchemaError(path, f"got {_describe_value(value)}; expected a number"
                              + (f" in {unit}" if unit and unit != "-" else "")
                              + (f" {bounds_text(meta)}" if bounds_text(meta) else ""))
        _check_bounds(value, meta, path)
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise SchemaError(path, f"got {_describe_value(value)}; expected a string")
        return value
    if origin is tuple:
        args = get_args(tp)
        if not isinstance(value, (list, tuple)):
            raise SchemaError(path, f"got {_describe_value(value)}; expected {_type_name(tp)}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(convert(args[0], v, f"{path}[{i}]", meta) for i, v in enumerate(value))
        if len(value) != len(args):
            raise SchemaError(path, f"got a list of {len(value)}; expected a list of {len(args)} numbers")
        return tuple(convert(a, v, f"{path}[{i}]", meta) for i, (a, v) in enumerate(zip(args, value)))
    if origin is dict:
        key_t, val_t = get_args(tp)
        if not isinstance(value, dict):
            raise SchemaError(path, f"got {_describe_value(value)}; expected a table")
        return {k: convert(val_t, v, f"{path}.{k}" if path else k, meta) for k, v in value.items()}
    if dataclasses.is_dataclass(tp):
        return from_dict(tp, value, path)
    raise TypeError(f"unsupported schema type {tp!r} at {path}")


def _convert_tagged(classes: list[type], value: Any, path: str) -> Any:
    tags = {_tag(c): c for c in classes}
    if not isinstance(value, dict):
        raise SchemaError(path, f"got {_describe_value(value)}; expected a table with type = "
                          + " | ".join(repr(t) for t in tags))
    if "type" not in value:
        raise SchemaError(f"{path}.type", "missing required key; allowed: "
                          + ", ".join(repr(t) for t in tags))
    tag = value["type"]
    if not isinstance(tag, str) or tag not in tags:  # a list or table here is unhashable
        raise SchemaError(f"{path}.type", f"got {_describe_value(tag)}; allowed: "
                          + ", ".join(repr(t) for t in tags))
    return from_dict(tags[tag], value, path)


def from_dict(cls: type, data: Any, path: str = "") -> Any:
    """Build the frozen dataclass ``cls`` from a plain mapping, validating every key.

    Unknown keys, missing required keys, wrong types and out-of-range values raise
    :class:`SchemaError`. After construction, a ``validate(path)`` method on the class (if any)
    runs cross-field checks.
    """
    if not isinstance(data, dict):
        raise SchemaError(path, f"got {_describe_value(data)}; expected a table")
    hints = _type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = [k for k in data if k not in fields]
    if unknown:
        where = f"{path}.{unknown[0]}" if path else unknown[0]
        raise SchemaError(where, "unknown key; allowed keys here: " + ", ".join(fields))
    kwargs = {}
    for name, f in fields.items():
        sub = f"{path}.{name}" if path else name
        if name in data:
            kwargs[name] = convert(hints[name], data[name], sub, dict(f.metadata))
        elif f.default is MISSING and f.default_factory is MISSING:
            raise SchemaError(sub, f"missing required key ({describe_field(hints[name], f)})")
    obj = cls(**kwargs)
    check = getattr(obj, "validate", None)
    if callable(check):
        check(path)
    return obj


def describe_field(tp: Any, f: dataclasses.Field) -> str:
    """Short text of what a field accepts: type, range and unit."""
    meta = f.metadata
    text = _type_name(tp)
    rng = bounds_text(meta)
    if rng:
        text += f" {rng}"
    unit = meta.get("unit")
    if unit and unit != "-":
        text += f", in {unit}"
    return text


def to_dict(obj: Any) -> Any:
    """Plain-data form of a schema dataclass (for writing the resolved case as TOML)."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                if getattr(obj, f.name) is not None}
    if isinstance(obj, (list, tuple)):
        return [to_dict(v) for v in obj]
    if isinstance(obj, dict):
        return {k: to_dict(v) for k, v in obj.items()}
    return obj


def reference_rows(cls: type, prefix: str = "") -> list[tuple[str, str, str, str, str]]:
    """Rows (key, type/range, unit, default, description) for every key reachable from ``cls``."""
    rows: list[tuple[str, str, str, str, str]] = []
    hints = get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        tp = hints[f.name]
        key = f"{prefix}{f.name}"
        inner, suffix = _container_inner(tp)
        if f.default is not MISSING:
            default = _fmt_default(f.default)
        elif f.default_factory is not MISSING:
            default = _fmt_default(f.default_factory())
        else:
            default = "required"
        meta = f.metadata
        allowed = _type_name(tp)
        if bounds_text(meta):
            allowed += f", {bounds_text(meta)}"
        rows.append((key, allowed, meta.get("unit", "") or "", default, meta.get("doc", "")))
        for sub in inner:
            tag = f"[type = {_tag(sub)!r}] " if len(inner) > 1 else ""
            for r in reference_rows(sub, f"{key}{suffix}."):
                rows.append(r[:4] + (tag + r[4],))
    return rows


def _container_inner(tp: Any) -> tuple[list[type], str]:
    origin = get_origin(tp)
    if dataclasses.is_dataclass(tp):
        return [tp], ""
    if _is_union(tp):
        classes = [a for a in get_args(tp) if dataclasses.is_dataclass(a)]
        return classes, ""
    if origin is tuple:
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            inner, _ = _container_inner(args[0])
            return inner, "[]"
    if origin is dict:
        inner, _ = _container_inner(get_args(tp)[1])
        return inner, ".<name>"
    return [], ""


def _fmt_default(value: Any) -> str:
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, tuple) and not value:
        return "[]"
    if dataclasses.is_dataclass(value):
        return "(table)"
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_fmt_default(v) for v in value) + "]"
    return repr(value) if isinstance(value, str) else str(value)


__all__ = ["SchemaError", "spec", "convert", "from_dict", "to_dict", "reference_rows",
           "describe_field", "bounds_text", "PLAUSIBLE", "PLAUSIBLE_OTHER", "plausible_range", "shorten",
           "show_number"]
