"""Fuzzing `pulseform check` (issue 13): no input ever ends in a traceback, a hang or a silent acceptance.

For every case file in cases/ (``case.toml`` and the other ``*.toml`` there) :func:`mutations` makes
:data:`N_PER_FILE` deterministic (seeded) mutations: deleted keys, wrong types, non-finite and extreme
numbers (1e308, -1e308, nan, inf, 0, negative, 5000-digit integers), path tricks for names and file keys,
unicode and NUL, deep nesting, bad ``--set`` strings and broken files. Each runs
``cli.main(["check", FILE, "--set=..."])`` in-process and must

- end with exit code 0 or 2 (no exception escapes, no "internal error" exit 1), within :data:`CALL_LIMIT_S`;
- if 2: print exactly one line ``pulseform: error: ...`` of at most :data:`MAX_LINE` characters;
- if the mutation must be refused (:func:`must_refuse`): exit 2.

The user-deck cases' deck contract check (gmsh + getdp, seconds per call) and the 3D geometry files' meshing
check (gmsh, a second or more per call) are replaced by stubs here: what is fuzzed is the loading and validation
of the case file, the CLI's messages and the resolved-case output; tests/workflow/test_user_deck.py runs the real
contract check, tests/coupling/test_geometry3d.py (and the racetrack's and sector's bad inputs) the real meshing
check. ``pytest -s`` prints the counts.
"""

from __future__ import annotations

import contextlib
import copy
import fnmatch
import io
import logging
import math
import random
import shutil
import signal
import time
import tomllib
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import tomli_w

from pulseform.orchestrator.em import user_deck
from pulseform.orchestrator import cli
from pulseform.orchestrator.cli import main

REPO = Path(__file__).resolve().parents[2]
CASE_FILES = sorted((REPO / "cases").glob("*/*.toml"))
N_PER_FILE = 500
CALL_LIMIT_S = 5.0
MAX_LINE = 300

#: Mutation kinds `check` must refuse (exit 2) wherever they land.
REFUSED_KINDS = {"huge", "nonfinite", "nul_value", "nul_key", "unknown_key", "type", "deep", "name_path", "file_path",
                 "bad_set", "broken_file"}
#: (key glob, kind) that the resource guards (orchestrator/case/guards.py) will refuse but `check` may still
#: accept today, e.g. a 1 nm mesh size (billions of cells) or an end time of 500 s (billions of steps).
#: Not asserted. Once a guard refuses one, move it to GUARDED.
#: A user deck's own mesh parameters (`Lc_*`) are guarded by gmsh's time limit when the deck is meshed,
#: which this test replaces by a stub (tests/workflow/test_user_deck_safety.py runs it for real); its
#: step count is guarded once its mesh exists (driver: before the first step; test_signals.py).
AWAITING_GUARDS = [("*.Lc_*", "tiny_length"), ("time.end", "long_time_deck"), ("geometry.*", "tiny_length_file")]
#: (key glob, kind) that the guards refuse: asserted like REFUSED_KINDS.
GUARDED: list[tuple[str, str]] = [("*mesh_size*", "tiny_length"), ("time.end", "long_time")]
#: keys whose default is an infinity: that infinity is a valid input there
INF_OK = {"xmin": -math.inf, "ymin": -math.inf, "xmax": math.inf, "ymax": math.inf, "mass_damping_until": math.inf}

NAME_TRICKS = ["/tmp/x", "../../x", "/some/path/VICTIM", "..", ".", "a/b", "x" * 5000, "C:\\x", "~user", "a\\b",
               "name with space", "ünïcødé", "tab\there", "new\nline", "a" * 101, ""]
PATH_TRICKS = ["/tmp/x.geo", "../../x.pro", "/etc/passwd", "../" * 40 + "x.geo", "x" * 5000 + ".geo",
               "a/" * 3000 + "b.pro", "sub/../../../x.pro", "~/x.geo", "ünï.pro", ""]
UNICODE = ["ünïcødé ✓", "日本語", "\u202eevil", "e\u0301", "😀" * 10, "\ufeffbom", "ℌ", "\u2028sep"]
#: the NAME_TRICKS and UNICODE values that are valid case names (issue 32: letters of any script, digits, spaces,
#: ". _ -"; orchestrator/case/names.py): `check` accepts them as case.name; body and probe names stay ASCII
CASE_NAMES_OK = {"name with space", "ünïcødé", "日本語", "e\u0301", "ℌ"}
BAD_SETS = [
    "time[0]=1", "time.end=1e-3\n[extra]", "time.end=1e-3\r\ncase.name='x'", "time.end=1\x00", "tim\x00e.end=1",
    "time.end", "=1", "time.end=", "time..end=1", ".time.end=1", "time.end.x=1", "time.end=nan", "time.end=inf",
    "time.end=-inf", "time.end=1e308", "time.end=-1e308", "time.end=" + "9" * 5000, "time.end=" + "[" * 3000,
    "time.end=" + "[" * 3000 + "]" * 3000, "time.end={a={b={c=1}}}", "case.name='/tmp/x'", "case.name='../../x'",
    "case.name=..", "case.name='" + "y" * 5000 + "'", "case.name=\udcff", "zeit.end=1", "bodies[999].name=x",
    "bodies.nobody.name=x", "time.end=1e-3 # ok\n[x]", "case.name=\"a\\u0000b\"", "time.end=\"1e-3\"",
    "time.end=true", "time[0][1]=1", "case[0]=1", "time.end=1e-3\x1b[2J", "case.kind=thermal",
    "a" + ".a" * 50000 + "=1", "case.description={" + "a." * 50000 + "b = 1}",
]


@dataclass(frozen=True)
class Mutation:
    """One fuzzed input: a file text (None: the original file) and --set strings."""

    kind: str
    key: str
    text: str | bytes | None
    sets: tuple[str, ...] = ()


def must_refuse(m: Mutation) -> bool:
    """Whether `check` must exit 2 on ``m``."""
    if m.kind in REFUSED_KINDS:
        return True
    return any(m.kind == kind and fnmatch.fnmatchcase(m.key, glob) for glob, kind in GUARDED)


# ----------------------------------------------------------------------------- generation
def _names_a_file(path: tuple) -> bool:
    """case.name (results/<name>), body names (fields/<case>_<body>.xdmf) and probe names
    (plots/<probe>_<quantity>.png) become file names."""
    return path == ("case", "name") or (len(path) == 3 and path[0] in ("bodies", "probes") and path[2] == "name")


def _key(path: tuple) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


def _walk(node: Any, path: tuple = ()) -> list[tuple[tuple, Any]]:
    """Every (path, value) below ``node``, tables and lists included."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    out = []
    for k, v in items:
        out.append((path + (k,), v))
        out.extend(_walk(v, path + (k,)))
    return out


def _put(data: dict, path: tuple, value: Any) -> None:
    node = data
    for p in path[:-1]:
        node = node[p]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value


_DELETE = object()
_RAW = "@@raw@@"


def _dump(data: dict, raw: str | None = None) -> str:
    """TOML text of ``data``; the string value ``_RAW`` becomes the raw TOML ``raw`` (huge ints, nesting)."""
    text = tomli_w.dumps(data)
    return text.replace(f'"{_RAW}"', raw) if raw is not None else text


def _category(v: Any) -> str:
    if isinstance(v, bool):
        return "bool"
    if isinstance(v, (int, float)):
        return "number"
    return type(v).__name__


def mutations(data: dict, text: str, rng: random.Random, n: int) -> list[Mutation]:
    """``n`` mutations of the case ``data`` (its file ``text``), drawn with ``rng``."""
    nodes = _walk(data)
    numbers = [(p, v) for p, v in nodes if _category(v) == "number"]
    strings = [(p, v) for p, v in nodes if isinstance(v, str)]
    tables = [(p, v) for p, v in nodes if isinstance(v, dict)] + [((), data)]
    names = [(p, v) for p, v in strings if p[-1] == "name"]
    files = [(p, v) for p, v in strings if p in (("geometry", "mesh"), ("geometry", "pro"))]

    def edit(kind: str, path: tuple, value: Any, raw: str | None = None) -> Mutation:
        d = copy.deepcopy(data)
        _put(d, path, value)
        return Mutation(kind, _key(path), _dump(d, raw))

    def number(kind: str) -> Mutation:
        path, v = rng.choice(numbers)
        if kind == "huge":
            if rng.random() < 0.25:
                return edit(kind, path, _RAW, ("-" if rng.random() < 0.5 else "") + "7" * rng.choice([400, 4000, 5000]))
            return edit(kind, path, rng.choice([1e308, -1e308, 1e30 * (abs(v) or 1.0) * 1e20]))
        if kind == "nonfinite":
            value = rng.choice([math.nan, math.inf, -math.inf])
            return edit("valid_inf" if INF_OK.get(path[-1]) == value else kind, path, value)
        if kind == "zero_negative":
            return edit(kind, path, rng.choice([0, 0.0, -v, -abs(v) - 1.0, -1e-300]))
        if kind == "scaled":
            return edit(kind, path, v * rng.choice([1e-6, 1e-3, 0.5, 2.0, 1e3, 1e6]) if isinstance(v, float)
                        else v * rng.choice([0, 2, 1000]))
        return edit(kind, path, 1e-300)  # "tiny"

    def generate(kind: str) -> Mutation:
        if kind in ("huge", "nonfinite", "zero_negative", "scaled", "tiny"):
            return number(kind)
        if kind == "delete":
            path, _ = rng.choice(nodes)
            return edit(kind, path, _DELETE)
        if kind == "type":
            path, v = rng.choice(nodes)
            new = rng.choice(["abc", True, [1, 2], {"a": 1}, 1.5, "", []])
            same = _category(new) == _category(v) or (isinstance(v, list) and not v)
            return edit("type_same" if same else kind, path, new)
        if kind == "unknown_key":
            path, _ = rng.choice(tables)
            d = copy.deepcopy(data)
            node = d
            for p in path:
                node = node[p]
            node[rng.choice(["bogus", "ключ", "a b", "x" * 300, "mesh-size", "Name"])] = 1.0
            # geometry.parameters is free: a new name there is a new -setnumber (names: user_deck.py's checks)
            return Mutation("param_key" if path == ("geometry", "parameters") else kind, _key(path), _dump(d))
        if kind == "nul_value":
            path, v = rng.choice(strings)
            i = rng.randrange(len(v) + 1)
            return edit(kind, path, v[:i] + "\x00" + v[i:])
        if kind == "nul_key":
            path, _ = rng.choice(tables)
            d = copy.deepcopy(data)
            node = d
            for p in path:
                node = node[p]
            node["a\x00b"] = 1
            return Mutation(kind, _key(path), _dump(d))
        if kind == "unicode":
            path, v = rng.choice(strings)
            value = rng.choice(UNICODE)
            ok = path == ("case", "name") and value in CASE_NAMES_OK
            return edit("case_name_ok" if ok else "name_path" if _names_a_file(path) else kind, path, value)
        if kind == "name_path":
            if rng.random() < 0.6 or not names:
                value = rng.choice(NAME_TRICKS)
                return edit("case_name_ok" if value in CASE_NAMES_OK else kind, ("case", "name"), value)
            path, _ = rng.choice(names)  # body and probe names name files
            value = rng.choice(NAME_TRICKS)
            ok = path == ("case", "name") and value in CASE_NAMES_OK
            return edit("case_name_ok" if ok else "name_path" if _names_a_file(path) else "other_name_path", path,
                        value)
        if kind == "file_path":
            if not files:
                return generate("name_path")
            path, _ = rng.choice(files)
            return edit(kind, path, rng.choice(PATH_TRICKS))
        if kind == "deep":
            if rng.random() < 0.2:  # a dotted key of many parts: tomllib's cost grows with its square
                return Mutation(kind, "file", text + "\n" + ".".join(["a"] * rng.choice([40, 5000, 60000])) + " = 1\n")
            path, _ = rng.choice(nodes)
            depth = rng.choice([50, 500, 3000])
            opener, closer = rng.choice([("[", "]"), ("{a=", "}")])
            return edit(kind, path, _RAW, opener * depth + "1" + closer * depth)
        if kind == "bad_set":
            return Mutation(kind, "--set", None, (rng.choice(BAD_SETS),))
        if kind == "set":  # well-formed --set of a random key to a random value: valid or refused, never a crash
            path, v = rng.choice(nodes)
            value = rng.choice(["1", "0", "-1", "1e-3", "'x'", "true", "[1, 2]", "{a = 1}", "1e6", "'../x'"])
            return Mutation(kind, _key(path), None, (f"{_key(path)}={value}",))
        if kind == "broken_file":
            choice = rng.randrange(4)
            if choice == 0:
                return Mutation(kind, "file", b"")  # no [case], [time], ...
            if choice == 1:
                return Mutation(kind, "file", text.encode() + b"\n\xff\xfe\n")
            if choice == 2:
                return Mutation(kind, "file", text + "\n[case]\nname = 'again'\n")  # a table twice
            return Mutation(kind, "file", text + "\nx = = 1\n")
        if kind == "truncated":
            return Mutation(kind, "file", text[: rng.randrange(len(text))])
        if kind == "long_time":  # a user deck's / a 3D geometry file's mesh size is known only once meshed: the
            # guard of `check`'s meshing (stubbed here) and the run's
            deck = data.get("geometry", {}).get("type") in ("user_deck", "geometry_3d")
            return edit("long_time_deck" if deck else kind, ("time", "end"), 500.0)
        if kind == "tiny_length":
            mesh = [(p, v) for p, v in numbers if any(fnmatch.fnmatchcase(_key(p), g)
                                                       for g, k in AWAITING_GUARDS + GUARDED if k == kind)]
            if not mesh:
                return number("tiny")
            path, _ = rng.choice(mesh)
            # a 3D geometry file's sizes are guarded when it is meshed (the estimate of `check`'s meshing, stubbed
            # here, tests/coupling/test_geometry3d.py; a .geo's own size parameters: gmsh's time limit, then
            # limits.max_cells), as a user deck's Lc_* are
            file3d = data.get("geometry", {}).get("type") == "geometry_3d"
            return edit("tiny_length_file" if file3d else kind, path, 1e-9)
        raise ValueError(kind)

    kinds = ["huge", "nonfinite", "zero_negative", "scaled", "tiny", "delete", "type", "unknown_key", "nul_value",
             "nul_key", "unicode", "name_path", "file_path", "deep", "bad_set", "set", "broken_file", "truncated",
             "long_time", "tiny_length"]
    weights = [6, 5, 5, 3, 2, 6, 6, 2, 3, 1, 3, 4, 3, 3, 5, 5, 1, 2, 1, 2]
    return [generate(k) for k in rng.choices(kinds, weights, k=n)]


# ----------------------------------------------------------------------------- running
class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang()


def run_check(file: Path, sets: tuple[str, ...]) -> tuple[int | str, str, str, float]:
    """``main(["check", file, --set=...])`` in-process: (exit code or the escaped exception, stdout, stderr, s)."""
    root = logging.getLogger()
    handlers = list(root.handlers)  # main() adds a console handler per call
    out, err = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, 4 * CALL_LIMIT_S)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc: int | str = main(["check", str(file), *(f"--set={s}" for s in sets)])
    except SystemExit as exc:
        rc = exc.code if exc.code in (0, 2) else f"SystemExit({exc.code!r})"
    except _Hang:
        rc = "hang"
    except BaseException as exc:  # noqa: BLE001 -- any escaping exception is what this test looks for
        rc = f"{type(exc).__name__}: {str(exc)[:200]}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
        root.handlers[:] = handlers
    return rc, out.getvalue(), err.getvalue(), time.perf_counter() - t0


def _problem(m: Mutation, rc: int | str, out: str, err: str, dt: float) -> str | None:
    """What is wrong with the outcome of ``m`` (None: fine)."""
    if not isinstance(rc, int) or rc not in (0, 2):
        return f"exit {rc!r}; stderr {err[-300:]!r}"
    if "Traceback" in err or "Traceback" in out:
        return "traceback printed"
    if dt > CALL_LIMIT_S:
        return f"took {dt:.1f} s"
    if rc == 2 and m.kind == "case_name_ok":
        return f"a valid case name refused: {err[:300]!r}"
    if rc == 2:
        lines = [ln for ln in err.splitlines() if ln.strip()]
        if len(lines) != 1 or not lines[0].startswith("pulseform: error: ") or len(lines[0]) > MAX_LINE:
            return f"not one line of <= {MAX_LINE} characters: {err[:400]!r}"
    elif must_refuse(m):
        return "accepted, must be refused"
    elif not any(ln.startswith("# ") and ln.endswith(": valid") for ln in out.splitlines()[:2]):
        return f"exit 0 without the resolved case: {out[:200]!r}"
    return None


@pytest.fixture(autouse=True)
def _no_deck_contract_run(monkeypatch):
    """The deck contract check runs gmsh + getdp (seconds), a 3D geometry file's check gmsh (a second or more); the
    fuzz is about loading and validation."""
    monkeypatch.setattr(user_deck, "check_user_deck", lambda case: None)
    monkeypatch.setattr(cli, "_check_geometry_3d", lambda case, file: [])


@pytest.mark.parametrize("case_file", CASE_FILES, ids=[f"{p.parent.name}/{p.name}" for p in CASE_FILES])
def test_fuzz_check(tmp_path, case_file):
    folder = tmp_path / case_file.parent.name
    shutil.copytree(case_file.parent, folder, ignore=shutil.ignore_patterns("reference"))
    text = case_file.read_text()
    data = tomllib.loads(text)
    rng = random.Random(f"pulseform-fuzz/{case_file.parent.name}/{case_file.name}")
    tally: Counter = Counter()
    problems = []
    for i, m in enumerate(mutations(data, text, rng, N_PER_FILE)):
        file = folder / case_file.name
        if m.text is not None:
            file = folder / f"fuzz_{i:03d}.toml"
            (file.write_bytes if isinstance(m.text, bytes) else file.write_text)(m.text)
        rc, out, err, dt = run_check(file, m.sets)
        problem = _problem(m, rc, out, err, dt)
        tally["tried"] += 1
        tally["refused cleanly" if rc == 2 and problem is None else "accepted" if rc == 0 else "failed"] += 1
        tally[f"{m.kind}:{'refused' if rc == 2 else 'accepted' if rc == 0 else 'failed'}"] += 1
        if problem:
            problems.append(f"#{i} {m.kind} at {m.key} {m.sets!r}: {problem}")
        if m.text is not None:
            file.unlink()
    print(f"\n{case_file.relative_to(REPO)}: tried {tally['tried']}, refused cleanly {tally['refused cleanly']}, "
          f"accepted {tally['accepted']}, failed {tally['failed']}")
    print("  by kind: " + ", ".join(f"{k} {v}" for k, v in sorted(tally.items()) if ":" in k))
    assert tally["tried"] >= 500
    assert not problems, f"{len(problems)} problems, first ones:\n" + "\n".join(problems[:15])


def test_must_refuse_rules():
    """The refusal rule of the fuzz test itself: refused kinds, awaited guards, default infinities."""
    assert must_refuse(Mutation("huge", "time.end", ""))
    assert must_refuse(Mutation("tiny_length", "bodies[0].mesh_size", ""))
    assert must_refuse(Mutation("long_time", "time.end", ""))
    assert not must_refuse(Mutation("tiny_length", "geometry.parameters.Lc_Sheet", ""))
    assert not must_refuse(Mutation("valid_inf", "mechanics.mass_damping_until", ""))
    assert not must_refuse(Mutation("case_name_ok", "case.name", ""))
    assert not set(kind for _, kind in AWAITING_GUARDS) & REFUSED_KINDS
