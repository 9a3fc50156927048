"""A JSON Schema (draft 2020-12) of the case file, walked from the case dataclasses and their field metadata.

``pulseform schema`` prints it; ``docs/reference/case.schema.json`` is a committed copy that editors with a
TOML language server (taplo / Even Better TOML, through the repository's ``.taplo.toml``) use to complete and
check keys. Nothing here is written by hand: the walk is the one :func:`.schema.from_dict` and :func:`.schema.convert`
validate with, so the schema accepts what they accept, key by key:

* a dataclass is an ``object`` with its ``properties`` (description: the field's doc text and unit),
  ``additionalProperties: false`` and ``required`` (the fields without a default); JSON-representable defaults are
  given as ``default`` (a default of ``inf`` is named in the description: JSON has no infinity);
* a tagged union of dataclasses (a geometry's, a shape's, a source's ``type``) is an object whose ``type`` is one of
  the tags (``enum``, required) and ``oneOf`` one complete object schema per class, told apart by ``type``'s
  ``const``;
* ``Literal`` is an ``enum``; a fixed tuple an array with ``prefixItems`` and ``minItems = maxItems``; ``tuple[X, ...]``
  an array of ``items``; ``dict[str, X]`` an object of ``additionalProperties``; other unions ``anyOf``;
  ``X | None`` is ``X`` (TOML has no null: an unset key is absent);
* a number's bounds are what ``_check_bounds`` accepts: the field's ``gt``/``ge``/``lt``/``le`` intersected with the
  plausible range of its unit (zero, or ``lo <= |value| <= hi``; :data:`.schema.PLAUSIBLE`). One interval becomes
  ``minimum``/``exclusiveMinimum``/``maximum``/``exclusiveMaximum``; several (e.g. ``>= 0``: 0 or from ``lo``) the
  envelope as those keywords and the pieces in ``anyOf``. A key whose default is an infinity also accepts that
  infinity (``exclusiveMinimum`` of the largest double: +inf only; likewise -inf). NaN, which passes every
  comparison, is refused by ``not`` of ``$defs/nan``. An ``int`` is ``integer``, a ``float`` a ``number`` (an
  integer passes, as in Python); ``bool`` is ``boolean``, never a number;
* a string has at most :data:`.io.MAX_STRING` characters (the loader's limit on every string); so has a table key.

What the schema cannot express, left to ``pulseform check`` (which runs the Python validator):

* the cross-field checks of the ``validate()`` methods and of :meth:`.model.Case.validate`: unique names,
  references between tables (a body's material, a contact pair's bodies, a coil's source), ``xmin <= xmax``,
  ``t_end > t_start``, exactly one of ``shape``/``region``, counter-clockwise polygons, what a coupled case or a
  3D case needs (``[geometry]``, ``[em]``, vector lengths per dimension), rigid-body rules, name patterns of
  names that become file names, file suffixes, ``threads`` against this machine's cores, and the ``[limits]``
  estimates of cells and steps;
* the loader's checks of the raw file: files named by the case (decks, geometry files, CSV tables) exist, lie in
  the case folder and read; no NUL character in a string; path lengths; 2D-only keys in a 3D case
  (``mechanics.thickness``, ``mechanics.gravity``) and ``em.remesh_quality`` in a 3D geometry-file case;
* JSON has one number type: ``1.0`` for an integer key passes the schema, ``pulseform check`` refuses it;

Editors: taplo follows ``$ref`` and the branches of ``oneOf``/``anyOf`` but does not narrow a ``oneOf`` by the
``type`` value: it offers every branch's keys and flags the wrong ones when it validates. The schema therefore
inlines every table (no ``$ref`` but the one to ``$defs/nan``), so that each key's own description shows.
"""

from __future__ import annotations

import dataclasses
import inspect
import json
import logging
import math
import operator
import sys
from typing import Any, Literal, get_args, get_origin, get_type_hints

from .io import MAX_STRING
from .model import Case
from .schema import MISSING, _is_union, _tag, bounds_text, plausible_range

log = logging.getLogger(__name__)

__all__ = ["case_json_schema", "case_json_schema_text", "type_schema", "SCHEMA_FILE", "REGENERATE"]

#: the committed copy, relative to the repository root
SCHEMA_FILE = "docs/reference/case.schema.json"
#: the command that writes it again
REGENERATE = f".venv/bin/pulseform schema --out {SCHEMA_FILE}"
DRAFT = "https://json-schema.org/draft/2020-12/schema"
#: the largest double: only +inf is above it (only -inf below its negative)
_BIG = sys.float_info.max
_NOT_NAN = {"not": {"$ref": "#/$defs/nan"}}
_BOUNDS = (("gt", operator.gt), ("ge", operator.ge), ("lt", operator.lt), ("le", operator.le))

#: an interval of allowed numbers: (lower, lower included, upper, upper included)
Interval = tuple[float, bool, float, bool]


def case_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a whole case file.

    Returns
    -------
    dict
        The schema, JSON-serialisable (no infinities, no NaN).
    """
    root = _object_schema(Case)
    schema = {
        "$schema": DRAFT,
        "title": "pulseform case file",
        "description": "A pulseform case (case.toml): every key with its unit and allowed range. Cross-field "
                       "checks (names that refer to other tables, what a coupled or 3D case needs) are "
                       "pulseform check's.",
        "$comment": f"Generated from the case dataclasses (orchestrator/case/json_schema.py); do not edit. "
                    f"Regenerate: {REGENERATE}",
        **{k: v for k, v in root.items() if k != "description"},
        "$defs": {"nan": {
            "description": "NaN: no number is >= 1 and <= 0, but every comparison with NaN is false, so only NaN "
                           "passes; a number refuses it with `not` (a TOML nan is not a finite number)",
            "minimum": 1, "maximum": 0}},
    }
    log.debug("case JSON Schema: %d properties at the top", len(root["properties"]))
    return schema


def case_json_schema_text() -> str:
    """:func:`case_json_schema` as the text of the committed file: indented JSON, UTF-8 characters kept, a final
    newline."""
    return json.dumps(case_json_schema(), indent=2, ensure_ascii=False, allow_nan=False) + "\n"


def type_schema(tp: Any, meta: dict[str, Any] | None = None) -> dict[str, Any]:
    """The JSON Schema of one field type ``tp`` with the field's metadata ``meta`` (see :func:`.schema.spec`).

    Mirrors :func:`.schema.convert` branch by branch (the metadata reaches the same places: tuple elements
    and union members, not the values of a table).

    Parameters
    ----------
    tp : type
        A field type of the case dataclasses (``float``, ``tuple[float, float]``, ``Shape | None``, ...).
    meta : dict, optional
        The field's metadata: ``unit``, ``gt``/``ge``/``lt``/``le``, ``magnitude``, ``inf``.

    Returns
    -------
    dict
        The schema of the values :func:`.schema.convert` accepts for ``tp`` (a TOML value's JSON form).

    Raises
    ------
    TypeError
        For a type :func:`.schema.convert` does not support either.
    """
    meta = meta or {}
    origin = get_origin(tp)
    if tp is Any:
        return {}
    if _is_union(tp):
        parts = [a for a in get_args(tp) if a is not type(None)]
        if len(parts) == 1:
            return type_schema(parts[0], meta)
        if all(dataclasses.is_dataclass(a) for a in parts):
            return _tagged_schema(parts)
        return {"anyOf": [type_schema(a, meta) for a in parts]}
    if origin is Literal:
        values = list(get_args(tp))
        out: dict[str, Any] = {"enum": values}
        if all(isinstance(v, str) for v in values):
            out = {"type": "string", **out}
        return out
    if tp is bool:
        return {"type": "boolean"}
    if tp is int:
        return {"type": "integer", **_number_bounds(meta, integer=True)}
    if tp is float:
        return {"type": "number", **_number_bounds(meta, integer=False), **_NOT_NAN}
    if tp is str:
        return {"type": "string", "maxLength": MAX_STRING}
    if origin is tuple:
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return {"type": "array", "items": type_schema(args[0], meta)}
        return {"type": "array", "prefixItems": [type_schema(a, meta) for a in args],
                "minItems": len(args), "maxItems": len(args)}
    if origin is dict:
        _, val_t = get_args(tp)
        return {"type": "object", "propertyNames": {"maxLength": MAX_STRING},
                "additionalProperties": type_schema(val_t, meta)}  # the field's bounds hold for each value
    if dataclasses.is_dataclass(tp):
        return _object_schema(tp)
    raise TypeError(f"unsupported schema type {tp!r}")


def _object_schema(cls: type) -> dict[str, Any]:
    """A dataclass as a closed object: its init fields, the required ones, each with description and default."""
    hints = get_type_hints(cls)
    props: dict[str, Any] = {}
    required: list[str] = []
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        meta = dict(f.metadata)
        sub = type_schema(hints[f.name], meta)
        has_default = f.default is not MISSING or f.default_factory is not MISSING
        default = f.default if f.default is not MISSING else (f.default_factory() if has_default else None)
        text = _field_text(meta, default if has_default else None)
        if dataclasses.is_dataclass(_plain(hints[f.name])) and _class_doc(_plain(hints[f.name])):
            text = f"{text}: {_class_doc(_plain(hints[f.name]))}" if text else _class_doc(_plain(hints[f.name]))
        props[f.name] = {"description": text, **{k: v for k, v in sub.items() if k != "description"}} if text else sub
        if has_default:
            value = _json_default(default)
            if value is not None:
                props[f.name]["default"] = value
        else:
            required.append(f.name)
    out: dict[str, Any] = {"type": "object"}
    if _class_doc(cls):
        out["description"] = _class_doc(cls)
    out.update({"properties": props, "additionalProperties": False})
    if required:
        out["required"] = required
    return out


def _tagged_schema(classes: list[type]) -> dict[str, Any]:
    """A tagged union: ``type`` one of the tags (required), and one complete object per class keyed on its tag."""
    tags = [_tag(c) for c in classes]
    return {"type": "object", "required": ["type"],
            "properties": {"type": {"description": "kind: " + ", ".join(repr(t) for t in tags) + " (the other keys "
                                                   "depend on it)", "type": "string", "enum": tags}},
            "oneOf": [_branch(c, t) for c, t in zip(classes, tags)]}


def _branch(cls: type, tag: str) -> dict[str, Any]:
    """The object schema of one class of a tagged union, its ``type`` a ``const``."""
    schema = {"title": f"type = {tag!r}", **_object_schema(cls)}
    kind = schema["properties"]["type"]
    schema["properties"]["type"] = {k: v for k, v in kind.items() if k not in ("enum", "type")} | {"const": tag}
    return schema


def _plain(tp: Any) -> Any:
    """``X`` of ``X | None``; else ``tp``."""
    if _is_union(tp):
        parts = [a for a in get_args(tp) if a is not type(None)]
        if len(parts) == 1:
            return parts[0]
    return tp


def _class_doc(cls: type) -> str:
    """First paragraph of a class docstring as one line ('' when the class has none of its own)."""
    doc = inspect.getdoc(cls) or ""
    if not doc or doc.startswith(f"{cls.__name__}("):  # the docstring dataclasses generate
        return ""
    return " ".join(doc.split("\n\n")[0].split()).replace("``", "`")  # reST literals as Markdown (hovers)


def _field_text(meta: dict[str, Any], default: Any) -> str:
    """A field's description: its doc text, unit in brackets, bounds, and an infinite default in words."""
    text = meta.get("doc", "") or ""
    unit = meta.get("unit") or ""
    if unit and unit != "-":
        text += f" [{unit}]"
    if bounds_text(meta):
        text += f"; {bounds_text(meta)}"
    if isinstance(default, float) and math.isinf(default):
        text += f"; default {default} (unbounded)"
    return text.strip()


def _json_default(value: Any) -> Any:
    """A default as JSON, or None when it has no JSON form worth giving (None, infinity, a table)."""
    if value is None or dataclasses.is_dataclass(value):
        return None
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, (tuple, list)):
        items = [_json_default(v) for v in value]
        return None if any(v is None for v in items) else items
    if isinstance(value, dict):
        return {k: _json_default(v) for k, v in value.items()}
    return value


# --------------------------------------------------------------------------- numbers
def _number_bounds(meta: dict[str, Any], integer: bool) -> dict[str, Any]:
    """The keywords of the numbers ``_check_bounds`` accepts for a field with metadata ``meta``."""
    pieces = _allowed_intervals(meta, integer)
    inf = meta.get("inf")
    tails = [] if inf is None or not all(meta.get(k) is None or ok(inf, meta[k]) for k, ok in _BOUNDS) else [inf]
    if not pieces and not tails:
        return {"not": {}}
    if len(pieces) == 1 and not tails:
        return _interval_keywords(pieces[0])
    out: dict[str, Any] = {}
    if pieces:  # the envelope first: the keywords an editor shows
        lower, upper = pieces[0], pieces[-1]  # sorted and disjoint
        if not (tails and tails[0] < 0):
            out.update(_interval_keywords((lower[0], lower[1], math.inf, True)))
        if not (tails and tails[0] > 0):
            out.update(_interval_keywords((-math.inf, True, upper[2], upper[3])))
    branches = [_interval_keywords(p) for p in pieces]
    branches += [{"exclusiveMinimum": _BIG} if t > 0 else {"exclusiveMaximum": -_BIG} for t in tails]
    out["anyOf"] = branches
    return out


def _allowed_intervals(meta: dict[str, Any], integer: bool) -> list[Interval]:
    """The finite numbers a field accepts as disjoint intervals: its bounds within the plausible range."""
    lo, hi = plausible_range(meta)
    if integer and lo <= 1.0:
        lo = 0.0  # no integer lies strictly between 0 and lo
    pieces: list[Interval] = [(-hi, True, -lo, True), (0.0, True, 0.0, True), (lo, True, hi, True)] if lo > 0 \
        else [(-hi, True, hi, True)]
    for key, value in ((k, meta.get(k)) for k, _ in _BOUNDS):
        if value is not None:
            pieces = [_cut(p, key, float(value)) for p in pieces]
    return _merge([p for p in pieces if _nonempty(p)])


def _cut(p: Interval, key: str, v: float) -> Interval:
    """Interval ``p`` restricted by the bound ``key`` (gt, ge, lt, le) at ``v``."""
    a, ai, b, bi = p
    if key == "gt" and v >= a:
        a, ai = v, False
    elif key == "ge" and v > a:
        a, ai = v, True
    elif key == "lt" and v <= b:
        b, bi = v, False
    elif key == "le" and v < b:
        b, bi = v, True
    return a, ai, b, bi


def _nonempty(p: Interval) -> bool:
    """True if interval ``p`` holds a number."""
    return p[0] < p[2] or (p[0] == p[2] and p[1] and p[3])


def _merge(pieces: list[Interval]) -> list[Interval]:
    """Sorted intervals with the touching ones joined."""
    out: list[Interval] = []
    for p in sorted(pieces):
        if out and (out[-1][2] > p[0] or (out[-1][2] == p[0] and (out[-1][3] or p[1]))):
            a, ai, b, bi = out[-1]
            out[-1] = (a, ai, p[2], p[3]) if (p[2], p[3]) > (b, bi) else (a, ai, b, bi)
        else:
            out.append(p)
    return out


def _interval_keywords(p: Interval) -> dict[str, Any]:
    """``minimum``/``exclusiveMinimum``/``maximum``/``exclusiveMaximum`` of an interval (``const`` of a point)."""
    a, ai, b, bi = p
    if a == b:
        return {"const": _num(a)}
    out: dict[str, Any] = {}
    if math.isfinite(a):
        out["minimum" if ai else "exclusiveMinimum"] = _num(a)
    if math.isfinite(b):
        out["maximum" if bi else "exclusiveMaximum"] = _num(b)
    return out


def _num(x: float) -> int | float:
    """An integral bound as an int (1e9 reads 1000000000), others as they are."""
    return int(x) if float(x).is_integer() and abs(x) <= 2.0 ** 53 else x
