"""Read a case file (TOML), apply ``--set key.path=value`` overrides, validate, and write it back."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from typing import Any

import tomli_w

from .deck_files import resolve_deck_paths
from .em_applied import resolve_applied_field_file
from .em_sources import resolve_source_files
from .geometry3d import check_raw_geometry_3d, resolve_geometry_file
from .errors import MAX_MESSAGE, CaseError, one_line  # noqa: F401  (the case-file API)
from .model import Case
from .schema import SchemaError, from_dict, shorten, to_dict
from .solid3d import FORMULATION_3D, TWO_D_ONLY_KEYS, check_explicit_2d_keys

CASE_FILE_NAME = "case.toml"
MAX_CASE_FILE = 2 * 2**20  # bytes: a case is a few kB; 2 MiB hold a polygon of ~80,000 vertices
MAX_STRING = 10_000  # characters of any string in a case
PATH_KEYS = (("geometry", "mesh"), ("geometry", "pro"), ("geometry", "file"))  # strings that name files
MAX_KEY_PARTS = 32  # of a dotted key; tomllib's time and memory grow with the square of it
_SEGMENT = re.compile(r"^([A-Za-z_][A-Za-z0-9_\-]*)((?:\[\d+\])*)$")
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")
_STRING = re.compile(r""""(?:[^"\\\n]|\\.)*"|'[^'\n]*'""")  # one-line TOML strings
_LONG_KEY = re.compile(r"""(?:(?:[A-Za-z0-9_-]+|"[^"\n]*"|'[^'\n]*')[ \t]*\.[ \t]*){%d}""" % MAX_KEY_PARTS)


def resolve_case_file(path: str | Path) -> Path:
    """Accept a case folder (holding ``case.toml``) or a ``.toml`` file; return the file path."""
    p = Path(path)
    try:
        if p.is_dir():
            p = p / CASE_FILE_NAME
        found = p.is_file()
    except (OSError, ValueError) as exc:  # too long, NUL byte, no permission, ...
        raise CaseError(str(path), "", f"cannot open: {getattr(exc, 'strerror', None) or exc}") from None
    if not found:
        raise CaseError(str(path), "", f"no case file found (expected a folder with {CASE_FILE_NAME} "
                        "or a .toml file)")
    return p


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; syntax errors become :class:`CaseError` with line and column."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_CASE_FILE + 1)
        if len(raw) > MAX_CASE_FILE:
            raise CaseError(str(path), "", f"larger than {MAX_CASE_FILE // 2**20} MiB; not a case file")
        return _parse_toml(raw.decode("utf-8"), str(path), "")
    except (OSError, UnicodeDecodeError) as exc:
        raise CaseError(str(path), "", f"cannot read: {exc}") from None


def _parse_toml(text: str, source: str, key: str) -> dict[str, Any]:
    """``tomllib.loads`` whose every failure (syntax, nesting, huge integers) is a :class:`CaseError`."""
    _refuse_long_keys(text, source, key)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(source, key, f"TOML syntax error: {exc}") from None
    except (RecursionError, ValueError) as exc:
        raise CaseError(source, key, _unreadable(exc)) from None


def _refuse_long_keys(text: str, source: str, key: str) -> None:
    """Refuse a dotted key of more than :data:`MAX_KEY_PARTS` parts before tomllib spends minutes and
    gigabytes on it (100,000 parts exhaust the memory)."""
    long_lines = (ln for ln in text.splitlines() if ln.count(".") >= MAX_KEY_PARTS)  # a key is on one line
    if any(_LONG_KEY.search(_STRING.sub('""', ln)) for ln in long_lines):
        raise CaseError(source, key, f"TOML key with more than {MAX_KEY_PARTS} dotted parts; not a case key")


def _unreadable(exc: RecursionError | ValueError) -> str:
    """Message for a TOML text that parses but cannot be read (tomllib's recursion, int digit limit)."""
    if isinstance(exc, RecursionError):
        return "TOML nested too deeply"
    return f"TOML value not readable: {str(exc).split(';')[0]}"  # more than sys.get_int_max_str_digits()


def parse_override(text: str, source: str = "") -> tuple[list[str | int], Any]:
    """Split ``key.path=value`` into path segments and a TOML-typed value.

    ``bodies[0].mesh_size=0.05`` and ``bodies.left.mesh_size=0.05`` (by body name) both work.
    The value is read as a TOML literal (number, bool, string, array, inline table); a bare word
    that is not valid TOML is taken as a string. Nothing is evaluated.
    """
    source = source or f"--set {text}"
    bad = _CONTROL.search(text)
    if bad or not _encodable(text):
        what = repr(bad.group()) if bad else "a character that is not valid UTF-8"
        raise CaseError(source, "", f"got {what}; a --set holds one key.path=value without control characters")
    if "=" not in text:
        raise CaseError(source, "", "expected key.path=value")
    key, raw = text.split("=", 1)
    key, raw = key.strip(), raw.strip()
    if key.count(".") >= MAX_KEY_PARTS:
        raise CaseError(source, key, f"more than {MAX_KEY_PARTS} dotted parts; not a case key")
    _refuse_long_keys(raw, source, key)
    segments: list[str | int] = []
    for part in key.split("."):
        m = _SEGMENT.match(part)
        if not m:
            raise CaseError(source, key, "malformed key path (use e.g. time.end or bodies[0].mesh_size)")
        segments.append(m.group(1))
        segments.extend(int(i) for i in re.findall(r"\[(\d+)\]", m.group(2)))
    if not raw:
        raise CaseError(source, key, "missing value after '='")
    try:
        doc = tomllib.loads(f"v = {raw}")
    except tomllib.TOMLDecodeError:
        return segments, raw
    except (RecursionError, ValueError) as exc:
        raise CaseError(source, key, _unreadable(exc)) from None
    if list(doc) != ["v"]:  # no second key smuggled in (a comment ends the line, a newline is refused)
        raise CaseError(source, key, "the value must be one TOML value")
    return segments, doc["v"]


def _encodable(text: str) -> bool:
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def apply_override(data: dict[str, Any], segments: list[str | int], value: Any, source: str) -> None:
    """Set ``value`` at ``segments`` inside the raw case mapping (in place)."""
    node: Any = data
    shown = ""
    for i, seg in enumerate(segments):
        last = i == len(segments) - 1
        if isinstance(node, list):
            idx = _list_index(node, seg, shown, source)
            shown += f"[{idx}]"
            if last:
                node[idx] = value
            else:
                node = node[idx]
            continue
        if not isinstance(node, dict):
            raise CaseError(source, shown, "is not a table; cannot set a key inside it")
        if isinstance(seg, int):
            raise CaseError(source, f"{shown}[{seg}]", f"{shown or 'the case'} is a table, not a list; "
                            "name a key instead of an index")
        shown = f"{shown}.{seg}" if shown else seg
        if last:
            node[seg] = value
        else:
            nxt = segments[i + 1]
            if seg not in node:
                node[seg] = [] if isinstance(nxt, int) else {}
            node = node[seg]


def _list_index(node: list, seg: str | int, shown: str, source: str) -> int:
    if isinstance(seg, int):
        if seg >= len(node):
            raise CaseError(source, f"{shown}[{seg}]", f"index out of range; the list has {len(node)} entries")
        return seg
    names = [e.get("name") for e in node if isinstance(e, dict)]
    if seg in names:
        return names.index(seg)
    raise CaseError(source, f"{shown}.{seg}", "no entry with that name; allowed: "
                    + ", ".join(repr(n) for n in names if n is not None))


def load_case(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> tuple[Case, Path]:
    """Read, override and validate a case.

    Parameters
    ----------
    path : str or Path
        Case folder (with ``case.toml``) or a TOML file.
    overrides : list of str
        ``key.path=value`` strings applied before validation.

    Returns
    -------
    (Case, Path)
        The validated case and the case file's path.
    """
    file = resolve_case_file(path)
    data = read_toml(file)
    for text in overrides:
        source = f"{file} (--set {text})"
        segments, value = parse_override(text, source)
        apply_override(data, segments, value, source)
    source = f"{file}" + (" (with --set overrides)" if overrides else "")
    check_strings(data, source)
    try:
        resolve_deck_paths(data, file, source)
        resolve_geometry_file(data, file, source)
    except (OSError, ValueError) as exc:  # CaseError is a ValueError: passed on as it is
        if isinstance(exc, CaseError):
            raise
        raise CaseError(source, "geometry", f"cannot resolve mesh/pro: {getattr(exc, 'strerror', None) or exc}") \
            from None
    resolve_source_files(data, file, source)
    resolve_applied_field_file(data, file, source)
    try:
        check_explicit_2d_keys(data)
        check_raw_geometry_3d(data)
        case = from_dict(Case, data)
    except SchemaError as exc:
        raise CaseError(source, exc.path, exc.message) from None
    except RecursionError:
        raise CaseError(source, "", "nested too deeply") from None
    return case, file


def load_resolved_case(file: str | Path) -> Case:
    """The resolved ``case.toml`` of a results folder, validated by the schema.

    Unlike :func:`load_case`, a user deck's files are not looked up or scanned: the stored case
    already names them by absolute path, and reading results never runs a deck.
    """
    file = Path(file)
    data = read_toml(file)
    check_strings(data, str(file))
    try:
        return from_dict(Case, data)
    except SchemaError as exc:
        raise CaseError(str(file), exc.path, exc.message) from None
    except RecursionError:
        raise CaseError(str(file), "", "nested too deeply") from None


def check_strings(data: dict[str, Any], source: str) -> None:
    """Refuse, in the raw case mapping, strings and keys that no later step should see.

    A NUL character or a lone surrogate anywhere, a string longer than :data:`MAX_STRING` characters, and
    in file names (:data:`PATH_KEYS`) more than 4096 bytes or a part of more than 255 bytes (the
    operating system's limits) raise :class:`CaseError` naming the key.
    """
    todo: list[tuple[str, Any]] = [("", data)]
    while todo:  # iterative: any nesting depth
        path, node = todo.pop()
        items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        for k, v in items:
            sub = f"{path}[{k}]" if isinstance(k, int) else (f"{path}.{k}" if path else k)
            for text, what in ((k, "key"), (v, "value")):
                if isinstance(text, str):
                    _check_string(text, what, sub, source)
            if isinstance(v, (dict, list)):
                todo.append((sub, v))
    for table, key in PATH_KEYS:
        node = data.get(table)
        value = node.get(key) if isinstance(node, dict) else None
        if isinstance(value, str):
            parts = value.encode("utf-8").split(b"/")
            if len(value.encode("utf-8")) > 4096 or max(len(p) for p in parts) > 255:
                raise CaseError(source, f"{table}.{key}", f"got a path of {len(value)} characters; a file name "
                                "may have at most 4096 bytes, each part at most 255")


def _check_string(text: str, what: str, path: str, source: str) -> None:
    if "\x00" in text:
        raise CaseError(source, path, f"the {what} {shorten(repr(text))} holds a NUL character; not allowed")
    if not _encodable(text):
        raise CaseError(source, path, f"the {what} holds a character that is not valid UTF-8")
    if len(text) > MAX_STRING:
        raise CaseError(source, path, f"the {what} has {len(text)} characters; at most {MAX_STRING} allowed")


def case_to_toml(case: Case) -> str:
    """The resolved case (defaults filled in, overrides applied) as TOML text.

    A 3D case is written without the 2D-only keys (their defaults are unused; :func:`load_case` refuses them
    in a 3D file), so the resolved case of a 3D run loads as a case file again.
    """
    data = to_dict(case)
    if case.mechanics.formulation == FORMULATION_3D:
        for key in TWO_D_ONLY_KEYS:
            data["mechanics"].pop(key, None)
    return tomli_w.dumps(_finite(data))


def _finite(obj: Any) -> Any:
    """TOML has inf/nan literals; tomli_w writes them as inf / nan, which tomllib reads back."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_finite(v) for v in obj]
    return obj
