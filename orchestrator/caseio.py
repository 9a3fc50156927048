"""Read a case file (TOML), apply ``--set key.path=value`` overrides, validate, and write it back."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from typing import Any

import tomli_w

from .case import Case
from .schema import SchemaError, from_dict, to_dict

CASE_FILE_NAME = "case.toml"
_SEGMENT = re.compile(r"^([A-Za-z_][A-Za-z0-9_\-]*)((?:\[\d+\])*)$")


class CaseError(ValueError):
    """A case file or an override is invalid. ``str()`` is one line naming file and key path."""

    def __init__(self, source: str, path: str, message: str) -> None:
        self.source = source
        self.path = path
        self.message = message
        where = f"{source}: {path}: " if path else f"{source}: "
        super().__init__(where + message)


def resolve_case_file(path: str | Path) -> Path:
    """Accept a case folder (holding ``case.toml``) or a ``.toml`` file; return the file path."""
    p = Path(path)
    if p.is_dir():
        p = p / CASE_FILE_NAME
    if not p.is_file():
        raise CaseError(str(path), "", f"no case file found (expected a folder with {CASE_FILE_NAME} "
                        "or a .toml file)")
    return p


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; syntax errors become :class:`CaseError` with line and column."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(str(path), "", f"TOML syntax error: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CaseError(str(path), "", f"cannot read: {exc}") from None


def parse_override(text: str, source: str = "") -> tuple[list[str | int], Any]:
    """Split ``key.path=value`` into path segments and a TOML-typed value.

    ``bodies[0].mesh_size=0.05`` and ``bodies.left.mesh_size=0.05`` (by body name) both work.
    The value is read as a TOML literal (number, bool, string, array, inline table); a bare word
    that is not valid TOML is taken as a string. Nothing is evaluated.
    """
    if "=" not in text:
        raise CaseError(source or f"--set {text}", "", "expected key.path=value")
    key, raw = text.split("=", 1)
    key, raw = key.strip(), raw.strip()
    segments: list[str | int] = []
    for part in key.split("."):
        m = _SEGMENT.match(part)
        if not m:
            raise CaseError(source or f"--set {text}", key, "malformed key path (use e.g. time.end or bodies[0].mesh_size)")
        segments.append(m.group(1))
        segments.extend(int(i) for i in re.findall(r"\[(\d+)\]", m.group(2)))
    if not raw:
        raise CaseError(source or f"--set {text}", key, "missing value after '='")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return segments, value


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
        assert isinstance(seg, str)
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
    from .user_deck import resolve_deck_paths  # a user's own .geo/.msh + .pro: paths from the case folder

    resolve_deck_paths(data, file, source)
    try:
        case = from_dict(Case, data)
    except SchemaError as exc:
        raise CaseError(source, exc.path, exc.message) from None
    return case, file


def case_to_toml(case: Case) -> str:
    """The resolved case (defaults filled in, overrides applied) as TOML text."""
    data = to_dict(case)
    return tomli_w.dumps(_finite(data))


def _finite(obj: Any) -> Any:
    """TOML has inf/nan literals; tomli_w writes them as inf / nan, which tomllib reads back."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_finite(v) for v in obj]
    return obj
