"""The case file's JSON Schema (``pulseform schema``, orchestrator/case/json_schema.py) and the Python validator
agree: the committed copy is the generated one, every shipped case passes both, a set of known-bad files fails
both, and every field's numbers, lists and values are accepted by one exactly when the other accepts them."""

from __future__ import annotations

import copy
import shutil
import dataclasses
import json
import math
import sys
import tomllib
from pathlib import Path
from typing import get_type_hints

import pytest
import tomli_w
from jsonschema import Draft7Validator, Draft202012Validator

from pulseform.orchestrator.case.io import CaseError, load_case
from pulseform.orchestrator.case.json_schema import (REGENERATE, SCHEMA_FILE, case_json_schema,
                                                     case_json_schema_text, type_schema)
from pulseform.orchestrator.case.model import Case
from pulseform.orchestrator.case.schema import SchemaError, _container_inner, convert, plausible_range
from pulseform.orchestrator.cli import main

REPO = Path(__file__).resolve().parents[2]
SCHEMA = case_json_schema()
VALIDATOR = Draft202012Validator(SCHEMA)
#: what taplo's validator (jsonschema-rs without the 2020-12 feature) falls back to: prefixItems unknown there
TAPLO_LIKE = Draft7Validator(SCHEMA)


def _case_files() -> list[Path]:
    """The shipped TOML files under cases/ that are case files (a [case] table), not other data."""
    out = []
    for path in sorted((REPO / "cases").rglob("*.toml")):
        data = tomllib.loads(path.read_text(encoding="utf-8"))
        if isinstance(data.get("case"), dict):
            out.append(path)
    return out


CASE_FILES = _case_files()


def _errors(validator, data) -> list[str]:
    """Every error as "key.path: message", with those of each ``oneOf`` branch (a tagged union's)."""
    todo, out = list(validator.iter_errors(data)), []
    while todo:
        e = todo.pop(0)
        out.append(f"{'.'.join(map(str, e.absolute_path)) or '(top)'}: {e.message[:200]}")
        todo += e.context or []
    return out


def test_committed_schema_is_the_generated_one():
    committed = (REPO / SCHEMA_FILE).read_text(encoding="utf-8")
    same = committed == case_json_schema_text()
    assert same, f"{SCHEMA_FILE} is stale (the case dataclasses changed): regenerate it with `{REGENERATE}`"


def test_schema_is_a_valid_draft_2020_12_schema():
    Draft202012Validator.check_schema(SCHEMA)
    assert SCHEMA["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert json.loads(case_json_schema_text()) == SCHEMA


def test_case_files_found():
    names = {p.relative_to(REPO).as_posix() for p in CASE_FILES}
    assert len(names) >= 20 and "cases/bar_impact/case.toml" in names and "cases/bar_impact_3d/two_bodies.toml" in names


@pytest.mark.parametrize("path", CASE_FILES, ids=lambda p: p.relative_to(REPO / "cases").as_posix())
def test_every_shipped_case_validates(path):
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    assert not _errors(VALIDATOR, data)
    assert not _errors(TAPLO_LIKE, data)  # an editor flags nothing in a shipped case either


def _rename(data, old: str, new: str) -> None:
    data[new] = data.pop(old)


from test_bad_input import _DELETE, _set  # noqa: E402  (the same mutation of a case mapping)

# (id, base case, mutation (path, value) or a function, the key path the Python validator names)
BAD = [
    ("unknown_key", "bar_impact", (("time", "ends"), 1e-3), "time.ends"),
    ("unknown_table", "bar_impact", (("solver",), {"threads": 2}), "solver"),
    ("misspelled_table", "bar_impact", lambda d: _rename(d, "mechanics", "mechanic"), "mechanic"),
    ("wrong_type_string", "bar_impact", (("time", "end"), "2 ms"), "time.end"),
    ("wrong_type_bool", "bar_impact", (("time", "cfl"), True), "time.cfl"),
    ("table_for_a_number", "bar_impact", (("time", "end"), {"value": 1e-3}), "time.end"),
    ("list_for_a_table", "bar_impact", (("time",), [2.2e-3]), "time"),
    ("float_for_an_integer", "bar_impact", (("coupling",), {"n": 2.5}), "coupling.n"),
    ("above_bound", "bar_impact", (("time", "cfl"), 1.5), "time.cfl"),
    ("zero_where_positive", "bar_impact", (("bodies", 0, "mesh_size"), 0.0), "bodies[0].mesh_size"),
    ("negative_where_positive", "bar_impact", (("bodies", 0, "shape", "width"), -4.0), "bodies[0].shape.width"),
    ("below_plausible", "bar_impact", (("bodies", 0, "mesh_size"), 1e-13), "bodies[0].mesh_size"),
    ("above_plausible", "bar_impact", (("materials", "paper_al", "density"), 1e6), "materials.paper_al.density"),
    ("nan", "bar_impact", (("time", "end"), math.nan), "time.end"),
    ("inf_not_default", "bar_impact", (("time", "end"), math.inf), "time.end"),
    ("wrong_infinity", "bar_impact", (("bodies", 0, "fixed"), [{"where": {"xmax": -math.inf}}]),
     "bodies[0].fixed[0].where.xmax"),
    ("integer_out_of_range", "bar_impact", (("bodies", 0, "fixed"), [{"where": {"xmax": 1.0}, "components": [3]}]),
     "bodies[0].fixed[0].components[0]"),
    ("list_length", "bar_impact", (("bodies", 0, "initial_velocity"), [10.0]), "bodies[0].initial_velocity"),
    ("list_element_type", "bar_impact", (("probes", 0, "point"), [4.0, "top"]), "probes[0].point[1]"),
    ("unknown_geometry_type", "emf_sheet_bulge", (("geometry", "type"), "spiral_coil"), "geometry.type"),
    ("key_of_another_geometry_type", "emf_sheet_bulge", (("geometry", "tube_length"), 0.1), "geometry.tube_length"),
    ("unknown_shape_type", "bar_impact", (("bodies", 0, "shape", "type"), "circle"), "bodies[0].shape.type"),
    ("key_of_another_shape_type", "bar_impact", (("bodies", 0, "shape", "radius"), 1.0), "bodies[0].shape.radius"),
    ("missing_tag", "bar_impact", (("bodies", 0, "shape", "type"), _DELETE), "bodies[0].shape.type"),
    ("missing_required_key", "bar_impact", (("time", "end"), _DELETE), "time.end"),
    ("missing_required_table", "bar_impact", (("time",), _DELETE), "time"),
    ("missing_required_in_union", "emf_sheet_bulge", (("geometry", "turns"), _DELETE), "geometry.turns"),
    ("bad_literal", "bar_impact", (("mechanics", "formulation"), "planar"), "mechanics.formulation"),
    ("bad_literal_in_list", "bar_impact", (("probes", 0, "quantity"), "stress"), "probes[0].quantity"),
    ("table_value_zero", "emf_tube_field_shaper", (("geometry", "mesh_sizes", "tube"), 0.0),
     "geometry.mesh_sizes.tube"),
    ("string_too_long", "bar_impact", (("case", "description"), "x" * 10_001), "case.description"),
]


def _write(tmp_path: Path, base: str, mutation) -> Path:
    data = copy.deepcopy(tomllib.loads((REPO / "cases" / base / "case.toml").read_text(encoding="utf-8")))
    if callable(mutation):
        mutation(data)
    else:
        _set(data, *mutation)
    for f in (REPO / "cases" / base).iterdir():  # the files the case names (a geometry file, a deck)
        if f.is_file() and f.suffix != ".toml":
            shutil.copy(f, tmp_path / f.name)
    path = tmp_path / "case.toml"
    path.write_text(tomli_w.dumps(data), encoding="utf-8")
    return path


@pytest.mark.parametrize("base", ["bar_impact", "emf_sheet_bulge"])
def test_bases_pass_both(tmp_path, base):
    path = _write(tmp_path, base, lambda d: None)
    load_case(path)
    assert not _errors(VALIDATOR, tomllib.loads(path.read_text(encoding="utf-8")))


@pytest.mark.parametrize("name,base,mutation,key", BAD, ids=[b[0] for b in BAD])
def test_known_bad_files_fail_both(tmp_path, name, base, mutation, key):
    path = _write(tmp_path, base, mutation)
    errors = _errors(VALIDATOR, tomllib.loads(path.read_text(encoding="utf-8")))
    assert errors, f"{name}: the JSON Schema accepts it"
    with pytest.raises(CaseError) as exc:
        load_case(path)
    assert exc.value.path == key, str(exc.value)
    last = [k for k in key.replace("]", "").replace("[", ".").split(".") if not k.isdigit()][-1]
    assert any(last in e for e in errors), errors  # the schema refuses the same key (in its path or message)


# values both accept that a naive schema would refuse
GOOD = [
    ("int_for_a_float", (("time", "end"), 2)),
    ("default_infinity", (("bodies", 0, "fixed"), [{"where": {"xmax": math.inf, "xmin": -math.inf}}])),
    ("zero_where_ge_zero", (("materials", "paper_al", "hardening_modulus"), 0)),
    ("three_vector_length_choice", (("walls",), [{"point": [0.0, 0.0], "normal": [1.0, 0.0]}])),
]


@pytest.mark.parametrize("name,mutation", GOOD, ids=[g[0] for g in GOOD])
def test_unusual_but_valid_values_pass_both(tmp_path, name, mutation):
    path = _write(tmp_path, "bar_impact", mutation)
    load_case(path)
    assert not _errors(VALIDATOR, tomllib.loads(path.read_text(encoding="utf-8")))


# --------------------------------------------------------------------------- field by field
def _classes(cls: type, seen: list[type]) -> list[type]:
    if cls not in seen:
        seen.append(cls)
        hints = get_type_hints(cls)
        for f in dataclasses.fields(cls):
            for inner in _container_inner(hints[f.name])[0]:
                _classes(inner, seen)
    return seen


def _probes(meta: dict) -> list:
    """Numbers at and next to every edge a field has (its bounds, its unit's plausible range, zero), the
    infinities and NaN, other types, and lists of them."""
    lo, hi = plausible_range(meta)
    edges = [lo, hi, 1.0, 2.0] + [meta[k] for k in ("gt", "ge", "lt", "le") if meta.get(k) is not None]
    values: list = [0, 0.0, -0.0, 1, -1, 3, True, False, "1", math.inf, -math.inf, math.nan, 10 ** 20,
                    sys.float_info.max, -sys.float_info.max]
    for x in edges:
        for y in (x, -x, x / 2, x * 2):
            values += [y, math.nextafter(y, math.inf), math.nextafter(y, -math.inf)]
            if float(y).is_integer() and abs(y) < 1e18:
                values += [int(y) - 1, int(y), int(y) + 1]
    lists = [[v] for v in values[:12]] + [[], [0.001, 0.002], [0.001, 0.002, 0.003], [1, 2, 3, 4], ["a", "b"],
                                          [[0.0, -0.001], [0.001, 0.0], [0.001, 0.001]], [[0.0, 0.0, 1.0, 1.0]]]
    return values + lists + [{"a": 1.0}, {"a": -1.0}, "x", ""]


FIELDS = [(cls, f) for cls in _classes(Case, []) for f in dataclasses.fields(cls) if f.init]


def test_field_walk_sees_the_model():
    names = {cls.__name__ for cls, _ in FIELDS}
    assert {"Case", "BodyTable", "Box", "FlatCoilSheet", "GeometryFile3D", "SineSource", "AppliedTable"} <= names
    assert len(FIELDS) > 250


def test_every_field_accepts_exactly_what_the_validator_accepts():
    """Each field's schema against ``convert`` on its edge values. The one difference JSON forces: a float with
    an integral value (1.0) is a JSON integer, so the schema takes it for an integer key; ``convert`` does not."""
    mismatches = []
    for cls, f in FIELDS:
        tp, meta = get_type_hints(cls)[f.name], dict(f.metadata)
        validator = Draft202012Validator({**type_schema(tp, meta), "$defs": SCHEMA["$defs"]})
        for value in _probes(meta):
            try:
                convert(tp, value, f.name, meta)
                ok = True
            except SchemaError:
                ok = False
            if validator.is_valid(value) != ok and not _integral_float_for_int(value, ok):
                mismatches.append(f"{cls.__name__}.{f.name} = {value!r}: validator {ok}, schema {not ok}")
    assert not mismatches, "\n".join(mismatches[:30])


def _integral_float_for_int(value, python_ok: bool) -> bool:
    """A float like 1.0 where the validator refused it (an integer key): JSON cannot tell it from 1."""
    def integral(v):
        return isinstance(v, float) and v.is_integer() or isinstance(v, list) and any(integral(x) for x in v)
    return not python_ok and integral(value)


# --------------------------------------------------------------------------- CLI
def test_cli_prints_the_schema(capsys):
    assert main(["schema"]) == 0
    assert json.loads(capsys.readouterr().out) == SCHEMA


def test_cli_writes_the_schema_atomically(tmp_path, capsys):
    out = tmp_path / "sub" / "case.schema.json"
    assert main(["schema", "--out", str(out)]) == 0
    assert out.read_text(encoding="utf-8") == case_json_schema_text()
    assert str(out) in capsys.readouterr().out
    assert [p.name for p in out.parent.iterdir()] == ["case.schema.json"]  # no temporary file left


def test_cli_refuses_an_unwritable_out(tmp_path, capsys):
    assert main(["schema", "--out", str(tmp_path)]) == 2  # a folder
    err = capsys.readouterr().err
    assert err.startswith("pulseform: error: --out") and len(err.splitlines()) == 1
