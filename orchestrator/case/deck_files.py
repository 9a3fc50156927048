"""A user's own EM deck (``[geometry] type = "user_deck"``) as the case loader sees it, before any gmsh
or getdp run: ``mesh`` / ``pro`` resolved against the case folder (and refused outside it unless
``allow_outside = true``), ``parameters`` checked (identifiers, finite numbers, none of the names the
runner sets), decks that run programs refused unless ``allow_system_calls = true``, a deck's misuse of the
magnetic names refused (:mod:`.deck_magnetic`).
Meshing and running the deck: :mod:`pulseform.orchestrator.em.user_deck`."""

from __future__ import annotations

import functools
import math
import re
from pathlib import Path
from typing import Any

from pulseform.solvers.getdp.contract import COIL_NUMBERS, ROLE_NUMBERS, runner_number_names
from pulseform.solvers.getdp.template import WRAPPER_NAMES

from .errors import MAX_MESSAGE, CaseError

def resolve_deck_paths(data: dict[str, Any], file: Path, source: str) -> None:
    """Make ``geometry.mesh`` / ``geometry.pro`` absolute (relative to the case file's folder) and
    check them: they must exist and lie inside the case folder unless ``allow_outside`` is true.
    Then check ``geometry.parameters`` (:func:`check_parameters`) and, unless
    ``allow_system_calls`` is true, refuse decks that run programs (:func:`find_program_call`).
    Raises :class:`CaseError` (one line, file and key named) before any gmsh or getdp run."""
    g = data.get("geometry")
    if not isinstance(g, dict) or g.get("type") != "user_deck":
        return
    folder = file.resolve().parent
    outside_ok = g.get("allow_outside") is True
    for key in ("mesh", "pro"):
        value = g.get(key)
        if not isinstance(value, str) or not value:
            continue  # the schema reports the missing / mistyped key
        p = Path(value)
        p = (p if p.is_absolute() else folder / p).resolve()
        if not outside_ok and not p.is_relative_to(folder):
            raise CaseError(source, f"geometry.{key}", f"got {value!r}, which resolves outside the case folder "
                            f"{folder}; move it into the folder or set geometry.allow_outside = true")
        if not p.is_file():
            raise CaseError(source, f"geometry.{key}", f"got {value!r}: file not found ({p})")
        g[key] = str(p)
    check_parameters(g.get("parameters"), source)
    check_template_deck(g, source, WRAPPER_NAMES)
    if g.get("library", "pulseform") != "getdp_template" and isinstance(g.get("pro"), str):
        from .deck_magnetic import deck_magnetic_problem   # (it reads decks with this module's scanner)

        problem = deck_magnetic_problem(Path(g["pro"]))
        if problem is not None:
            raise CaseError(source, "geometry.pro", problem)
    if g.get("allow_system_calls") is True:
        return
    for key, language in (("mesh", "geo"), ("pro", "pro")):
        value = g.get(key)
        if not isinstance(value, str) or not value or (key == "mesh" and not value.endswith(".geo")):
            continue  # a .msh is data; a wrong suffix is reported by the schema
        found = find_program_call(Path(value), language)
        if found is not None:
            where, what = found
            deck = Path(where.rsplit(":", 1)[0])
            if deck.is_relative_to(folder):  # name it from the case folder: the line stays short
                where = str(deck.relative_to(folder)) + ":" + where.rsplit(":", 1)[1]
            raise CaseError(source, f"geometry.{key}", f"{where}: {what}; refused unless "
                            "geometry.allow_system_calls = true (a deck is code)")


#: longest parameter name accepted (GetDP/Gmsh have no limit; longer names are a mistake)
MAX_PARAMETER_NAME = 64
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def reserved_parameter_names() -> tuple[str, ...]:
    """Names a deck receives from the runner, which ``geometry.parameters`` may not reuse: the role
    ids ``Phys_*`` (:data:`ROLE_NUMBERS`, and ``Phys_Coil_<k>`` of the coils: :data:`COIL_NUMBERS`), the
    string ``PulseformLib`` and every name of a getdp run
    (:func:`pulseform.solvers.getdp.contract.runner_number_names`; ``X_<k>`` stands for X_1, X_2, ...)."""
    return tuple(ROLE_NUMBERS.values()) + (COIL_NUMBERS, "PulseformLib") + runner_number_names()


def is_reserved_parameter(name: str) -> bool:
    """True if ``name`` is one of :func:`reserved_parameter_names` (``X_<k>``: any X_1, X_2, ...)."""
    for r in reserved_parameter_names():
        if r == name or (r.endswith("_<k>") and re.fullmatch(re.escape(r[:-4]) + r"_\d+", name)):
            return True
    return False


#: characters of a one-line case error (:data:`.errors.MAX_MESSAGE`, which shortens longer ones in the middle)
_MESSAGE_ROOM = MAX_MESSAGE


def reserved_listing(room: int = 10_000) -> str:
    """The reserved names in short form (the role ids as ``Phys_*``, families with braces:
    ``Flag_{Axi,Circuit,...}``, ``Coil_{I0,Ns,...}_<k>``), cut to ``room`` characters (``, ...``)."""
    groups: dict[str, list[str]] = {}
    for n in reserved_parameter_names():
        if n in ROLE_NUMBERS.values() or n.startswith("Phys_"):  # role ids, the built-in deck's ids
            groups["Phys_*"] = []
            continue
        groups.setdefault(re.match(r"[A-Z]+(?![a-z])_?|[A-Z][a-z]*[0-9]*_?|[A-Za-z]+", n).group(), []).append(n)
    parts = []
    for prefix, members in groups.items():
        if len(members) < 2:
            parts += members or [prefix]
            continue
        rest = [m[len(prefix):] for m in members]
        tail = "_<k>" if all(r.endswith("_<k>") for r in rest) else ""
        if any("_" in r[:len(r) - len(tail)] for r in rest):  # InitA_List, InitA2_List: no braces
            parts += members
            continue
        parts.append(prefix + "{" + ",".join(r[:len(r) - len(tail)] for r in rest) + "}" + tail)
    text = ", ".join(parts)
    if len(text) <= room:
        return text
    return text[:max(room - 5, 0)].rsplit(", ", 1)[0] + ", ..."


def short(text: str, n: int = 40) -> str:
    """``text`` cut to ``n`` characters (``...`` appended when cut)."""
    return text if len(text) <= n else text[:n] + "..."


def check_parameters(params: Any, source: str) -> None:
    """``geometry.parameters``: names are identifiers (``[A-Za-z_][A-Za-z0-9_]*``, at most
    :data:`MAX_PARAMETER_NAME` characters) that reuse none of :func:`reserved_parameter_names`,
    values finite numbers. Raises :class:`CaseError` naming ``geometry.parameters.<name>``."""
    if not isinstance(params, dict):
        return  # absent, or the schema reports the type
    for name, value in params.items():
        name = str(name)
        if not _IDENTIFIER.fullmatch(name) or len(name) > MAX_PARAMETER_NAME:
            raise CaseError(source, f"geometry.parameters.{short(name)!r}", "a parameter name must be an "
                            f"identifier ([A-Za-z_][A-Za-z0-9_]*, at most {MAX_PARAMETER_NAME} characters): gmsh "
                            "and getdp receive it with -setnumber")
        if is_reserved_parameter(name):
            key = f"geometry.parameters.{name}"
            text = f"the runner sets {name}; rename it. Reserved: {{}} (docs/workflow.md)"
            room = _MESSAGE_ROOM - len(f"{short(source, 120)}: {key}: ") - len(text) + 2
            raise CaseError(source, key, text.format(reserved_listing(room)))
        number = None
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            try:
                number = float(value)
            except OverflowError:
                number = None
        if number is None or not math.isfinite(number):
            raise CaseError(source, f"geometry.parameters.{name}", f"got {short(repr(value), 30)}; must be a "
                            "finite number")


# ----------------------------------------------------------------------------- deck content
#: commands that run programs: in gmsh .geo scripts (``Shell`` is no command of gmsh 4.8 but is
#: refused too) and in GetDP .pro files (``Python[]{...}`` evaluates Python code)
PROGRAM_COMMANDS = {"geo": ("SystemCall", "System", "NonBlockingSystemCall", "Shell", "OnelabRun"),
                    "pro": ("SystemCommand", "Python", "OnelabRun")}
#: commands that open a file by its name. gmsh runs some kinds (``Merge "x.py"`` runs Python, an
#: ``.exe`` or a ``.pro`` is started as an ONELAB client), so only these data formats pass
OPEN_COMMANDS = {"geo": ("Merge", "MergeWithBoundingBox"), "pro": ("GmshRead", "GmshMerge", "GmshOpen")}
DATA_SUFFIXES = (".msh", ".pos", ".step", ".stp", ".brep", ".brp", ".iges", ".igs", ".stl", ".med", ".unv",
                 ".vtk", ".mesh", ".bdf", ".nas", ".inp", ".off", ".x3d", ".xao")
#: files that gmsh's Merge reads as a .geo script (followed like an Include)
SCRIPT_SUFFIXES = (".geo", ".opt")
_TOKEN = re.compile(r'''(?P<lc>//[^\n]*) | (?P<bc>/\*.*?(?:\*/|\Z)) | (?P<str>"(?:[^"\\]|\\.)*(?:"|\Z))
                        | (?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?) | (?P<id>[A-Za-z_]\w*)
                        | (?P<ws>\s+) | (?P<other>.)''', re.S | re.X)


def deck_tokens(text: str) -> list[tuple[str, str, int]]:
    """(kind, text, line) of the identifiers (``id``), string literals (``str``, unquoted) and other
    characters (``other``) of a .geo/.pro text; comments (``//``, ``/* */``), numbers and blanks
    are dropped."""
    out, line = [], 1
    for m in _TOKEN.finditer(text):
        kind, tok = m.lastgroup, m.group()
        if kind == "str":
            body = tok[1:-1] if len(tok) > 1 and tok.endswith('"') else tok[1:]
            out.append(("str", re.sub(r"\\(.)", r"\1", body, flags=re.S), line))
        elif kind in ("id", "other"):
            out.append((kind, tok, line))
        line += tok.count("\n")
    return out


@functools.lru_cache(maxsize=32)
def _deck_tokens_of_text(text: str) -> list[tuple[str, str, int]]:
    """:func:`deck_tokens` of ``text``, once per text (a deck and the files it includes are scanned several
    times per `check`); keyed on the text itself, read each time. Read the list, never change it."""
    return deck_tokens(text)


def _file_argument(tokens: list, i: int) -> str | None:
    """The string literal right after ``tokens[i]`` (past one ``[`` or ``(``), or None."""
    j = i + 1
    if j < len(tokens) and tokens[j][0] == "other" and tokens[j][1] in "[(":
        j += 1
    return tokens[j][1] if j < len(tokens) and tokens[j][0] == "str" else None


#: names of the runner's own deck libraries (absolute paths the runner defines) a .pro may Include
RUNNER_LIBRARIES = ("PulseformLib", "PulseformPersistentLib", "PulseformHarmonicLib", "PulseformNewtonLib",
                    "PulseformMagneticLib")
#: most files one deck scan reads (a deck with more cannot be checked)
MAX_DECK_FILES = 1000


def _read_deck(path: Path, seen: set) -> tuple[Path, list] | None:
    """(resolved path, tokens) of a deck file not seen yet; None if seen, missing or unreadable
    (gmsh/getdp then report it themselves)."""
    try:
        path = Path(path).resolve()
        if path in seen or not path.is_file():
            return None
        seen.add(path)
        return path, _deck_tokens_of_text(path.read_text(errors="replace"))
    except (OSError, ValueError, RuntimeError):  # a NUL or an over-long name, a symlink loop, no permission
        return None


def _assigned(tokens: list, i: int) -> bool:
    """``tokens[i]`` is the target of a plain assignment (``NAME = ...`` or ``NAME += ...``), not a
    ``DefineConstant[ NAME = default ]`` entry (a default never replaces the runner's value)."""
    nxt = tokens[i + 1][1] if i + 1 < len(tokens) else ""
    after = tokens[i + 2][1] if i + 2 < len(tokens) else ""
    if not (nxt == "=" and after != "=") and not (nxt in "+-*/" and nxt and after == "="):
        return False
    prev = tokens[i - 1][1] if i > 0 else ";"
    return prev not in ("[", ",")


def find_program_call(path: Path, language: str) -> tuple[str, str] | None:
    """The first place where the deck ``path`` (``language`` "geo" or "pro") or a file it includes
    runs a program, as ``("<file>:<line>", what)``; None if there is none.

    ``Include "..."`` is followed (relative to the including file; a cycle or a missing file ends
    that branch: gmsh/getdp report missing files), as is a gmsh ``Merge`` of a .geo/.opt. An
    ``Include`` of a computed name (not a string literal; the .pro's ``Include PulseformLib`` and the
    library's ``Include PulseformPersistentLib`` are the runner's own, :data:`RUNNER_LIBRARIES`) cannot be checked and counts as a call, as does a ``Merge``/``GmshRead``
    of anything but a data file (:data:`DATA_SUFFIXES`)."""
    seen: set = set()
    first = _read_deck(path, seen)
    stack = [] if first is None else [(first[0], first[1], 0)]
    while stack:  # depth first, without recursion (include chains may be long)
        path, tokens, i = stack.pop()
        while i < len(tokens):
            kind, tok, line = tokens[i]
            i += 1
            if kind != "id":
                continue
            where, follow = f"{path}:{line}", None
            if tok in PROGRAM_COMMANDS[language]:
                return where, f"{tok} runs a program"
            if language == "pro" and tok in RUNNER_LIBRARIES and _assigned(tokens, i - 1):
                return where, f"{tok} is set (the runner's library path: its Include would read an unchecked file)"
            if tok == "Include":
                follow = _file_argument(tokens, i - 1)
                if follow is None:
                    if language == "pro" and i < len(tokens) and tokens[i][1] in RUNNER_LIBRARIES:
                        continue
                    return where, "Include of a computed file name (cannot be checked)"
            elif tok in OPEN_COMMANDS[language]:
                name = _file_argument(tokens, i - 1)
                suffix = Path(name).suffix.lower() if name else None
                if language == "geo" and suffix in SCRIPT_SUFFIXES:
                    follow = name
                elif suffix not in DATA_SUFFIXES:
                    shown = "a computed file name" if name is None else repr(short(name))
                    return where, f"{tok} of {shown} (may run it as a program)"
            if follow is not None:
                if len(seen) >= MAX_DECK_FILES:
                    return where, f"more than {MAX_DECK_FILES} included files (cannot be checked)"
                nxt = _read_deck(path.parent / follow, seen)
                if nxt is not None:
                    stack.append((path, tokens, i))
                    stack.append((nxt[0], nxt[1], 0))
                    break
    return None




# ----------------------------------------------------------------------------- decks on GetDP's template
#: the file name of GetDP's template a 'getdp_template' deck includes
TEMPLATE_FILE = "Lib_Magnetodynamics2D_av_Cir.pro"


def deck_files_tokens(path: Path) -> list[tuple[Path, list]]:
    """(file, tokens) of the deck ``path`` and of every file it ``Include``s by a string literal
    (relative to the including file; missing files and cycles are skipped), in reading order."""
    seen: set = set()
    out: list[tuple[Path, list]] = []
    first = _read_deck(path, seen)
    stack = [] if first is None else [first]
    while stack and len(out) < MAX_DECK_FILES:
        path, tokens = stack.pop()
        out.append((path, tokens))
        for i, (kind, tok, _) in enumerate(tokens):
            name = _file_argument(tokens, i) if kind == "id" and tok == "Include" else None
            nxt = None if name is None else _read_deck(path.parent / name, seen)
            if nxt is not None:
                stack.append(nxt)
    return out


def assignment_sites(path: Path, names: tuple[str, ...] | list[str]) -> list[tuple[str, Path, int, str]]:
    """Where the deck ``path`` (or a file it ``Include``s, :func:`deck_files_tokens`) assigns one of
    ``names`` with a plain assignment (``TimeFinal = 10e-6;``, not a ``DefineConstant`` default: such an
    assignment beats getdp's ``-setnumber``).

    Returns
    -------
    list of tuple
        ``(name, file, line, right-hand side)`` in reading order; the right-hand side is the text up to
        the ``;`` on that line ("" when it does not end there).
    """
    wanted = set(names)
    out = []
    for file, tokens in deck_files_tokens(Path(path)):
        lines = None
        for i, (kind, tok, line) in enumerate(tokens):
            if kind != "id" or tok not in wanted or not _assigned(tokens, i):
                continue
            if lines is None:
                lines = file.read_text(errors="replace").splitlines()
            m = re.search(rf"\b{re.escape(tok)}\s*=\s*([^;]*);", lines[line - 1] if line <= len(lines) else "")
            out.append((tok, file, line, m.group(1).strip() if m else ""))
    return out


#: functions whose value is a string: a ``DefineConstant`` entry starting with one is a string constant
_STRING_FUNCTIONS = ("Str", "StrCat", "Sprintf", "StrSub", "StrPrefix", "StrRelative", "StrChoice", "GetString",
                     "Date", "NameToString", "CurrentDirectory", "CurrentDir", "AbsolutePath", "DirName")


def define_constant_names(path: Path, skip_files: tuple[str, ...] = (TEMPLATE_FILE,)) -> list[str]:
    """The numbers a deck declares with ``DefineConstant[ NAME = value, NAME = {value, ...}, ... ]`` in
    ``path`` and the files it ``Include``s (except files named in ``skip_files``: GetDP's template),
    in reading order, each once; entries whose value is a string (a literal or a string function)
    are left out."""
    out: dict[str, None] = {}
    for file, tokens in deck_files_tokens(Path(path)):
        if file.name in skip_files:
            continue
        i = 0
        while i < len(tokens):
            if tokens[i][1] != "DefineConstant" or i + 1 >= len(tokens) or tokens[i + 1][1] != "[":
                i += 1
                continue
            depth, j = 0, i + 1
            while j < len(tokens):
                tok = tokens[j][1]
                if tok in "[{(" and tokens[j][0] == "other":
                    depth += 1
                elif tok in "]})" and tokens[j][0] == "other":
                    depth -= 1
                    if depth == 0:
                        break
                elif (depth == 1 and tokens[j][0] == "id" and tokens[j - 1][1] in ("[", ",")
                      and j + 1 < len(tokens) and tokens[j + 1][1] == "="):
                    k = j + 2
                    if k < len(tokens) and tokens[k][1] == "{":
                        k += 1
                    value = tokens[k] if k < len(tokens) else ("other", "", 0)
                    if value[0] != "str" and value[1] not in _STRING_FUNCTIONS:
                        out.setdefault(tokens[j][1])
                j += 1
            i = j + 1
    return list(out)


def _named(tokens: list, i: int, next_word: str) -> str | None:
    """``X`` if ``tokens[i:]`` reads ``Name X ; <next_word>``, else None."""
    if tokens[i][1] != "Name" or i + 3 >= len(tokens):
        return None
    if tokens[i + 1][0] == "id" and tokens[i + 2][1] == ";" and tokens[i + 3][1] == next_word:
        return tokens[i + 1][1]
    return None


def _in_system_block(tokens: list, i: int) -> bool:
    """``tokens[i]`` (a ``Name``) lies in a Resolution's ``System { ... }`` list, not in a PostProcessing
    (both name a formulation with ``NameOfFormulation``): the nearest of the two keywords before it."""
    for kind, tok, _ in reversed(tokens[:i]):
        if kind == "id" and tok in ("System", "PostProcessing"):
            return tok == "System"
    return False


def check_template_deck(g: dict[str, Any], source: str, wrapper_names: tuple[str, ...]) -> None:
    """A ``library = "getdp_template"`` deck: its formulation (``Name F; Type FemEquation``) and a
    system on it (``Name S; NameOfFormulation F``) exist in the .pro or its Includes, it does not
    include pulseform's library, and it defines none of the wrapper's names (``wrapper_names``);
    a ``library = "pulseform"`` deck that includes GetDP's template and not ``PulseformLib`` is
    told to set the library. Raises :class:`CaseError` (one line)."""
    pro = g.get("pro")
    if not isinstance(pro, str) or not Path(pro).is_file():
        return
    files = deck_files_tokens(Path(pro))
    toks = [t for _, tokens in files for t in tokens]
    uses_lib = any(a[1] == "Include" and b[1] in RUNNER_LIBRARIES for a, b in zip(toks, toks[1:]))
    on_template = any(Path(t[1]).name == TEMPLATE_FILE for t in toks if t[0] == "str")
    if g.get("library", "pulseform") != "getdp_template":
        if on_template and not uses_lib:
            raise CaseError(source, "geometry.library", f"the deck includes GetDP's {TEMPLATE_FILE} and not "
                            "PulseformLib: set geometry.library = 'getdp_template'")
        return
    if uses_lib:
        raise CaseError(source, "geometry.library", "got 'getdp_template' but the deck includes PulseformLib "
                        "(pulseform's own library): drop geometry.library (or the Include)")
    spec = g.get("template") if isinstance(g.get("template"), dict) else {}
    formulation = spec.get("formulation", "Magnetodynamics2D_av")
    system = spec.get("system", "A")
    forms = [f for i in range(len(toks)) if (f := _named(toks, i, "Type")) is not None
             and i + 4 < len(toks) and toks[i + 4][1] == "FemEquation"]
    deck = Path(pro).name
    if formulation not in forms:
        raise CaseError(source, "geometry.template.formulation", f"got {formulation!r}; {deck} (with its Includes) "
                        f"defines no such Formulation (it has {', '.join(forms) or 'none'})")
    systems = sorted({s for i in range(len(toks)) if (s := _named(toks, i, "NameOfFormulation")) is not None
                      and i + 4 < len(toks) and toks[i + 4][1] == formulation and _in_system_block(toks, i)})
    if system not in systems:
        raise CaseError(source, "geometry.template.system", f"got {system!r}; {deck} (with its Includes) has no "
                        f"System {system!r} on formulation {formulation} (systems on it: {', '.join(systems) or 'none'})")
    for i in range(len(toks)):
        if toks[i][1] == "Name" and i + 1 < len(toks) and toks[i + 1][1] in wrapper_names:
            where = next(f for f, tokens in files if toks[i] in tokens)
            raise CaseError(source, "geometry.pro", f"{where.name}:{toks[i][2]}: defines {toks[i + 1][1]}, a name of "
                            "pulseform's wrapper for template decks; rename it")


def remesh_air_error(deck: Any) -> str | None:
    """Why ``geometry.remesh_air`` of a user deck is wrong (one phrase), or None: every name must be the
    group of ``regions.air`` or ``regions.shell`` (a coil, conductor or curve is never re-triangulated)."""
    roles = {name: f"geometry.regions.{role}" for role, name in deck.regions.groups().items()}
    roles.update({c.group: f"geometry.coils[{i}].group" for i, c in enumerate(deck.coils)})
    air = {deck.regions.air, deck.regions.shell} - {None}
    for name in deck.remesh_air:
        if name not in air:
            what = (f"which is {roles[name]}" if name in roles
                    else "which is not the group of regions.air or regions.shell")
            return (f"got {name!r}, {what}; only the air ({', '.join(sorted(air))}) may be meshed again, every "
                    "other region keeps its elements")
    if len(set(deck.remesh_air)) != len(deck.remesh_air):
        return "names a group twice"
    return None
