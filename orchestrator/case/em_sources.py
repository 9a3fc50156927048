"""Case-file model of the EM sources and coils (``[[em.sources]]``, ``[[em.coils]]``; SI units, validated).

A source is a current waveform (``sine``, ``dc``, ``table``) or a capacitor bank (``bank``); a coil is a
coil of the ``[geometry]`` (the built-in geometries other than ``coaxial_coils`` and a user deck have
one) connected to a source with an orientation ``sign``. Coils on a bank are in series on it (the
deck's one circuit: a case has at most one bank, and then every coil is on it); coils on a prescribed
source each carry that source's current times their sign.

A ``table`` source reads a CSV file of the case folder (:func:`resolve_source_files`, called by the case
loader before the schema: the path, the file and its numbers are checked, and the path made absolute).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from .errors import CaseError
from .names import check_file_name
from .schema import PLAUSIBLE, SchemaError, shorten, spec

__all__ = ["SineSource", "DCSource", "TableSource", "BankSource", "Source", "CoilConnection",
           "read_current_table", "resolve_source_files", "check_sources", "check_coils", "MAX_TABLE_ROWS"]

#: most rows of a ``table`` source's CSV file
MAX_TABLE_ROWS = 100_000


@dataclass(frozen=True, kw_only=True)
class _Named:
    name: str = spec(doc="unique source name (what [[em.coils]] source refers to)")

    def validate(self, path: str) -> None:
        check_file_name(self.name, f"{path}.name", "the source in [[em.coils]] source")


@dataclass(frozen=True, kw_only=True)
class SineTime:
    """The time function e^(−decay (t − t_on)) sin(2π frequency (t − t_on) + phase) for t >= t_on, 0 before: of a
    ``sine`` source's current and of a ``sine`` applied field (:mod:`.em_applied`)."""

    frequency: float = spec(unit="Hz", gt=0.0, doc="f (ω = 2π f)")
    phase: float = spec(0.0, unit="rad", doc="phase φ at t_on")
    decay: float = spec(0.0, unit="1/s", ge=0.0, doc="decay rate β")
    t_on: float = spec(0.0, unit="s", ge=0.0, doc="switch-on time: nothing before")


@dataclass(frozen=True, kw_only=True)
class TableTime:
    """A time function linearly interpolated in a CSV file's rows (time s, value), held at its last value after
    them: a ``table`` source's current (A) and a ``table`` applied field's factor of its magnitude (-)."""

    file: str = spec(doc="CSV file, relative to the case folder: rows time (s), value (a source's current of one turn "
                         "in A, an "
                         "applied field's factor of its magnitude); '#' comments and one header line allowed; times "
                         "strictly increasing from <= 0; at most 100000 rows")
    allow_outside: bool = spec(False, doc="allow a file outside the case folder")

    def validate(self, path: str) -> None:
        if not self.file.endswith(".csv"):
            raise SchemaError(f"{path}.file", f"got {shorten(repr(self.file))}; must be a .csv file")


@dataclass(frozen=True, kw_only=True)
class SineSource(_Named, SineTime):
    """I(t) = amplitude e^(−decay (t − t_on)) sin(2π frequency (t − t_on) + phase) for t >= t_on, 0 before."""

    type: Literal["sine"] = spec(doc="source kind")
    amplitude: float = spec(unit="A", gt=0.0, doc="I0: the peak current of one turn, not rms (an rms current I_rms "
                                                   "is I0 = √2 I_rms); a coil of N turns carries N·I0 ampere-turns")


@dataclass(frozen=True, kw_only=True)
class DCSource(_Named):
    """A direct current I(t) = current for t >= t_on, 0 before."""

    type: Literal["dc"] = spec(doc="source kind")
    current: float = spec(unit="A", gt=0.0, doc="the current I of one turn (a coil of N turns: N·I ampere-turns)")
    t_on: float = spec(0.0, unit="s", ge=0.0, doc="switch-on time: no current before")


@dataclass(frozen=True, kw_only=True)
class TableSource(_Named, TableTime):
    """I(t) linearly interpolated in a CSV file's rows (time s, current A), held at its last value after them."""

    type: Literal["table"] = spec(doc="source kind")

    def validate(self, path: str) -> None:
        _Named.validate(self, path)
        TableTime.validate(self, path)


@dataclass(frozen=True, kw_only=True)
class BankSource(_Named):
    """A capacitor bank C charged to V0 discharging through R_ext, L_ext and its coils in series."""

    type: Literal["bank"] = spec(doc="source kind")
    capacitance: float = spec(unit="F", gt=0.0, doc="bank capacitance C")
    voltage: float = spec(unit="V", gt=0.0, doc="charging voltage V0")
    resistance: float = spec(0.0, unit="Ω", ge=0.0, doc="external resistance R_ext")
    inductance: float = spec(0.0, unit="H", ge=0.0, doc="external inductance L_ext")


Source = SineSource | DCSource | TableSource | BankSource


@dataclass(frozen=True, kw_only=True)
class CoilConnection:
    """A coil of the [geometry] connected to a source."""

    name: str = spec(doc="the coil: a name of [[geometry.coils]] (coaxial_coils, user_deck), free for the one coil "
                         "of the other geometries (and of regions.coil); with several coils it names the history "
                         "columns <name>_current_A, ...")
    source: str = spec(doc="name of the [[em.sources]] entry that drives it")
    sign: int = spec(1, unit="-", ge=-1, le=1, doc="orientation: +1, or -1 for a coil wound the other way (its "
                                                   "current is minus the source's, or minus the bank's in series)")

    def validate(self, path: str) -> None:
        check_file_name(self.name, f"{path}.name", "history columns <name>_current_A, ...")
        if self.sign not in (1, -1):
            raise SchemaError(f"{path}.sign", f"got {self.sign}; allowed: 1, -1")


def check_sources(sources: tuple, coils: tuple, path: str) -> None:
    """Cross-checks of ``[[em.sources]]`` and ``[[em.coils]]`` (``path``: the [em] table's path): unique
    names, every coil on a known source, every source used, at most one bank and then every coil on it."""
    if not coils:
        raise SchemaError(f"{path}.coils", "[[em.sources]] need at least one [[em.coils]] entry using them")
    names = {}
    for i, s in enumerate(sources):
        if s.name in names:
            raise SchemaError(f"{path}.sources[{i}].name", f"got {s.name!r}; source names must be unique")
        names[s.name] = s
    seen: list[str] = []
    for i, c in enumerate(coils):
        if c.name in seen:
            raise SchemaError(f"{path}.coils[{i}].name", f"got {c.name!r}; coil names must be unique")
        seen.append(c.name)
        if c.source not in names:
            raise SchemaError(f"{path}.coils[{i}].source", f"got {c.source!r}; allowed: "
                              + (", ".join(repr(n) for n in names) or "(no [[em.sources]] defined)"))
    used = {c.source for c in coils}
    for i, s in enumerate(sources):
        if s.name not in used:
            raise SchemaError(f"{path}.sources[{i}].name", f"got {s.name!r}; no [[em.coils]] entry uses this "
                              "source: connect a coil to it or remove it")
    banks = [i for i, s in enumerate(sources) if isinstance(s, BankSource)]
    if len(banks) > 1:
        raise SchemaError(f"{path}.sources[{banks[1]}].type", "a second 'bank': not supported (the deck has one "
                          "circuit: every coil in series on one bank)")
    if banks:
        bank = sources[banks[0]].name
        for i, c in enumerate(coils):
            if c.source != bank:
                raise SchemaError(f"{path}.coils[{i}].source", f"got {c.source!r} beside coils on the bank "
                                  f"{bank!r}: not supported (with a bank every coil is in series on it)")


def check_coils(case: Any) -> None:
    """The case-level checks of ``[[em.coils]]`` against the geometry (a coupled case with [em] and
    [geometry]): a geometry with named coils (``[[geometry.coils]]`` of coaxial_coils or of a user deck)
    needs sources and exactly one connection per coil of the geometry; the other geometries (and a
    user deck's ``regions.coil``) have one coil; a planar geometry takes no bank (per metre of depth)."""
    em, g = case.em, case.geometry
    named = tuple(getattr(g, "coils", ()))
    if not em.sources:
        if named:
            raise SchemaError("em.sources", f"the coils of geometry.coils ({g.type}) need [[em.sources]] and "
                              "[[em.coils]] (em.circuit and em.current drive a geometry's one coil)")
        return
    if named:
        want = [c.name for c in named]
        for i, c in enumerate(em.coils):
            if c.name not in want:
                raise SchemaError(f"em.coils[{i}].name", f"got {c.name!r}; the coils of geometry.coils are "
                                  + ", ".join(repr(n) for n in want))
        have = {c.name for c in em.coils}
        missing = [n for n in want if n not in have]
        if missing:
            raise SchemaError("em.coils", f"geometry coil {missing[0]!r} has no [[em.coils]] entry (give it a "
                              "source)")
    elif len(em.coils) != 1:
        several = ("[[geometry.coils]] with a group each" if g.type == "user_deck"
                   else "geometry type 'coaxial_coils'")
        raise SchemaError("em.coils[1]", f"got {len(em.coils)} coils; the {g.type} geometry has one coil "
                          f"(several coils: {several})")
    if g.planar and any(isinstance(s, BankSource) for s in em.sources):
        i = next(i for i, s in enumerate(em.sources) if isinstance(s, BankSource))
        raise SchemaError(f"em.sources[{i}].type", "planar geometries are per metre of depth: give a prescribed "
                          "current source (a capacitor bank would need the coil's length)")


# --------------------------------------------------------------------------- table files
def read_current_table(path: str | Path, quantity: tuple[str, str] = ("current", "A")
                       ) -> tuple[list[float], list[float]]:
    """Times (s) and currents (A) of a ``table`` source's CSV file (``quantity``: the second column's name
    and unit in the messages and the plausible range; an applied field's table holds factors, "-").

    Lines starting with ``#`` and blank lines are skipped; the first other line may be a header (its
    fields are not numbers); every other line holds two numbers, time and current. The times must be
    strictly increasing and start at or before 0 (the run's start), the numbers finite and within the
    plausible ranges of s and A (:data:`~.schema.PLAUSIBLE`); 2 to :data:`MAX_TABLE_ROWS` rows.

    Raises
    ------
    ValueError
        One line saying what is wrong and where (line number).
    OSError
        The file cannot be read.
    """
    times: list[float] = []
    values: list[float] = []
    header_allowed = True
    name, unit = quantity
    t_max, i_max = PLAUSIBLE["s"][1], PLAUSIBLE[unit][1]
    with open(path, newline="", encoding="utf-8", errors="replace") as fh:
        for lineno, row in enumerate(csv.reader(fh), start=1):
            if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
                continue
            try:
                numbers = [float(x) for x in row]
            except ValueError:
                if header_allowed:
                    header_allowed = False
                    continue
                raise ValueError(f"line {lineno}: {shorten(','.join(row), 40)!r} is not two numbers "
                                 f"(time s, {name} {unit})") from None
            header_allowed = False
            if len(numbers) != 2:
                raise ValueError(f"line {lineno}: {len(numbers)} columns; need 2 (time s, {name} {unit})")
            t, i = numbers
            if not (math.isfinite(t) and math.isfinite(i)) or abs(t) > t_max or abs(i) > i_max:
                raise ValueError(f"line {lineno}: time {t!r}, {name} {i!r}: need finite numbers with |time| <= "
                                 f"{t_max:g} s and |{name}| <= {i_max:g} {unit}")
            if times and t <= times[-1]:
                raise ValueError(f"line {lineno}: time {t!r} s after {times[-1]!r} s; times must be strictly "
                                 "increasing")
            times.append(t)
            values.append(i)
            if len(times) > MAX_TABLE_ROWS:
                raise ValueError(f"more than {MAX_TABLE_ROWS} rows")
    if len(times) < 2:
        raise ValueError(f"{len(times)} data rows; need at least 2 (time s, {name} {unit})")
    if times[0] > 0.0:
        raise ValueError(f"the first time is {times[0]!r} s; the table must start at or before t = 0")
    return times, values


def resolve_source_files(data: dict[str, Any], file: Path, source: str) -> None:
    """Make every ``table`` source's ``file`` absolute (relative to the case file's folder) and check it:
    inside the case folder unless ``allow_outside`` is true, a file, and a readable table
    (:func:`read_current_table`). Raises :class:`CaseError` naming ``em.sources[i].file`` (one line)."""
    em = data.get("em")
    sources = em.get("sources") if isinstance(em, dict) else None
    if not isinstance(sources, list):
        return  # absent, or a type error the schema reports
    folder = file.resolve().parent
    for i, s in enumerate(sources):
        if not isinstance(s, dict) or s.get("type") != "table":
            continue
        value = s.get("file")
        if not isinstance(value, str) or not value or "\x00" in value:
            continue  # the schema reports the missing / mistyped key
        key = f"em.sources[{i}].file"
        try:
            p = Path(value)
            p = (p if p.is_absolute() else folder / p).resolve()
        except (OSError, ValueError, RuntimeError) as exc:
            raise CaseError(source, key, f"got {shorten(repr(value))}: cannot resolve it ({exc})") from None
        if s.get("allow_outside") is not True and not p.is_relative_to(folder):
            raise CaseError(source, key, f"got {shorten(repr(value))}, which resolves outside the case folder "
                            f"{folder}; move it into the folder or set allow_outside = true")
        if not p.is_file():
            raise CaseError(source, key, f"got {shorten(repr(value))}: file not found ({p})")
        try:
            read_current_table(p)
        except (OSError, ValueError) as exc:
            raise CaseError(source, key, f"{p.name}: {getattr(exc, 'strerror', None) or exc}") from None
        s["file"] = str(p)
