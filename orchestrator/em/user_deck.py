"""Users' own EM decks: a case's own Gmsh ``.geo``/``.msh`` and GetDP ``.pro`` (``[geometry] type = "user_deck"``).

The runner

1. when the case is loaded: resolves ``mesh`` and ``pro`` against the case folder (and refuses
   paths outside it unless ``allow_outside = true``), checks the ``parameters`` (identifiers, finite
   numbers, none of the names the runner sets) and refuses decks that run programs (``SystemCall``
   ... in the .geo, ``SystemCommand`` ... in the .pro, also in their ``Include`` files) unless
   ``allow_system_calls = true``: all before any gmsh or getdp run;
2. meshes a ``.geo`` with ``gmsh -2 -format msh22 -setnumber <parameters>`` under a time limit
   (``limits.gmsh_time_limit_s``), or reads the ``.msh``;
3. renumbers the physical groups named in ``[geometry.regions]`` to the runner's ids (1 air, 2 shell,
   101 coil, 201 workpiece, 202 die, 11 axis, 12 outer) and tells the deck these ids with
   ``-setnumber Phys_Air, Phys_Shell, Phys_Coil_1, Phys_Cond_1, Phys_Cond_2, Phys_Axis, Phys_Outer``;
4. runs getdp on the deck exactly like the built-in ``em_case.pro`` (every number of the library's
   ``DefineConstant`` list with ``-setnumber``, ``OutDir`` with ``-setstring``, resolution
   ``EM_Transient``), with the string ``PulseformLib`` (absolute path of ``Lib_PulsedForming.pro``)
   defined before the deck is read, and the case's ``parameters`` as extra ``-setnumber``;
5. checks the deck once before the run (:mod:`.deck_check`: a few one-step getdp runs in
   ``em/contract_check/`` with the run's numbers): a getdp error, a missing output table, a time
   window that is not the runner's, a hollow model (zero energy or coil current, missing force rows
   or field state) or a state carry that does not reproduce a continuous run becomes a one-line
   :class:`DeckContractError` naming what failed.

The contract is documented in ``docs/workflow.md``.
"""

from __future__ import annotations

import logging
import math
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np

from ..case import io as caseio
from ..case.io import CaseError

log = logging.getLogger(__name__)

#: role -> the runner's physical id, and the -setnumber name the deck receives it under
ROLE_IDS = {"air": 1, "shell": 2, "coil": 101, "workpiece": 201, "die": 202, "axis": 11, "outer": 12}
ROLE_NUMBERS = {"air": "Phys_Air", "shell": "Phys_Shell", "coil": "Phys_Coil_1", "workpiece": "Phys_Cond_1",
                "die": "Phys_Cond_2", "axis": "Phys_Axis", "outer": "Phys_Outer"}
SURFACE_ROLES, CURVE_ROLES = ("air", "shell", "coil", "workpiece", "die"), ("axis", "outer")
OPTIONAL_ROLES = ("shell", "die")


#: wall-time limits (s) when the case has no ``[limits]`` table (``limits.gmsh_time_limit_s``,
#: ``limits.getdp_time_limit_s`` otherwise): one gmsh run on the .geo, the contract check's getdp run
GMSH_TIME_LIMIT_S = 600.0
GETDP_TIME_LIMIT_S = 600.0


class DeckContractError(RuntimeError):
    """A user's deck or mesh does not fulfil the deck contract (one-line message naming what is missing).

    ``message`` is the line without the log; ``log_path`` the gmsh/getdp log it refers to, if any
    (``str()`` appends ``(log: <path>)``)."""

    def __init__(self, message: str, *, log_path: Path | None = None) -> None:
        self.message = message
        self.log_path = None if log_path is None else Path(log_path)
        super().__init__(message if log_path is None else f"{message} (log: {log_path})")


def time_limits(case) -> tuple[float, float]:
    """(gmsh, getdp) wall-time limits in seconds: the case's ``[limits]`` or the module defaults."""
    lim = getattr(case, "limits", None)
    return (float(getattr(lim, "gmsh_time_limit_s", None) or GMSH_TIME_LIMIT_S),
            float(getattr(lim, "getdp_time_limit_s", None) or GETDP_TIME_LIMIT_S))


# ----------------------------------------------------------------------------- case loading
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
    ids ``Phys_*`` (:data:`ROLE_NUMBERS`), the string ``PulseformLib`` and every name of a getdp run
    (:func:`pulseform.solvers.getdp.solver.runner_number_names`; ``X_<k>`` stands for X_1, X_2, ...)."""
    from pulseform.solvers.getdp.solver import runner_number_names

    return tuple(ROLE_NUMBERS.values()) + ("PulseformLib",) + runner_number_names()


def is_reserved_parameter(name: str) -> bool:
    """True if ``name`` is one of :func:`reserved_parameter_names` (``X_<k>``: any X_1, X_2, ...)."""
    for r in reserved_parameter_names():
        if r == name or (r.endswith("_<k>") and re.fullmatch(re.escape(r[:-4]) + r"_\d+", name)):
            return True
    return False


#: characters of a one-line case error (``caseio.MAX_MESSAGE``, which shortens longer ones in the middle)
_MESSAGE_ROOM = getattr(caseio, "MAX_MESSAGE", 280)


def reserved_listing(room: int = 10_000) -> str:
    """The reserved names in short form (the role ids as ``Phys_*``, families with braces:
    ``Flag_{Axi,Circuit,...}``, ``Coil_{I0,Ns,...}_<k>``), cut to ``room`` characters (``, ...``)."""
    groups: dict[str, list[str]] = {}
    for n in reserved_parameter_names():
        if n in ROLE_NUMBERS.values():
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


def _short(text: str, n: int = 40) -> str:
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
            raise CaseError(source, f"geometry.parameters.{_short(name)!r}", "a parameter name must be an "
                            f"identifier ([A-Za-z_][A-Za-z0-9_]*, at most {MAX_PARAMETER_NAME} characters): gmsh "
                            "and getdp receive it with -setnumber")
        if is_reserved_parameter(name):
            key = f"geometry.parameters.{name}"
            text = f"the runner sets {name}; rename it. Reserved: {{}} (docs/workflow.md)"
            room = _MESSAGE_ROOM - len(f"{_short(source, 120)}: {key}: ") - len(text) + 2
            raise CaseError(source, key, text.format(reserved_listing(room)))
        number = None
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            try:
                number = float(value)
            except OverflowError:
                number = None
        if number is None or not math.isfinite(number):
            raise CaseError(source, f"geometry.parameters.{name}", f"got {_short(repr(value), 30)}; must be a "
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


def _file_argument(tokens: list, i: int) -> str | None:
    """The string literal right after ``tokens[i]`` (past one ``[`` or ``(``), or None."""
    j = i + 1
    if j < len(tokens) and tokens[j][0] == "other" and tokens[j][1] in "[(":
        j += 1
    return tokens[j][1] if j < len(tokens) and tokens[j][0] == "str" else None


#: names of the runner's own deck libraries (absolute paths the runner defines) a .pro may Include
RUNNER_LIBRARIES = ("PulseformLib", "PulseformPersistentLib")
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
        return path, deck_tokens(path.read_text(errors="replace"))
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
                    shown = "a computed file name" if name is None else repr(_short(name))
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


# ----------------------------------------------------------------------------- mesh
def mesh_file(g, work: Path, time_limit: float = GMSH_TIME_LIMIT_S) -> Path:
    """The deck's MSH 2.2 file: the ``.msh`` itself, or the ``.geo`` meshed by gmsh into ``work``
    (log ``work/gmsh.log``). gmsh is stopped after ``time_limit`` seconds and never outlives
    pulseform (:func:`pulseform.solvers.getdp.runner.child_preexec`)."""
    from pulseform.solvers.getdp.runner import child_preexec

    src = Path(g.mesh)
    if src.suffix == ".msh":
        return src
    work.mkdir(parents=True, exist_ok=True)
    out = work / (src.stem + ".msh")
    exe = shutil.which("gmsh")
    if exe is None:
        raise DeckContractError("gmsh not found on PATH: needed to mesh " + str(src))
    argv = [exe, str(src), "-2", "-format", "msh22", "-o", str(out)]
    for k, v in (g.parameters or {}).items():
        argv += ["-setnumber", k, repr(float(v))]
    log_path = work / "gmsh.log"
    with open(log_path, "w") as fh:
        fh.write("# argv: " + " ".join(argv) + "\n")
        fh.flush()
        try:
            r = subprocess.run(argv, cwd=src.parent, stdout=fh, stderr=subprocess.STDOUT, timeout=time_limit,
                               check=False, preexec_fn=child_preexec)
        except subprocess.TimeoutExpired:
            raise DeckContractError(f"{src}: meshing with gmsh exceeded its time limit of {time_limit:g} s "
                                    "(limits.gmsh_time_limit_s) and was stopped", log_path=log_path) from None
        except OSError as exc:
            raise DeckContractError(f"{src}: could not start gmsh: {exc}", log_path=log_path) from None
    text = log_path.read_text(errors="replace").split("\n", 1)[-1]
    errors = [ln for ln in text.splitlines() if ln.startswith("Error")]
    if r.returncode != 0 or errors or not out.is_file():
        first = errors[0] if errors else (f"killed by signal {-r.returncode}" if r.returncode < 0
                                          else f"exit code {r.returncode}")
        raise DeckContractError(f"{src}: gmsh failed: {_short(first, 200)}", log_path=log_path)
    log.info("meshed %s -> %s", src, out)
    return out


def read_deck_mesh(path: Path, regions, name: str | Path | None = None) -> "EMMesh":  # noqa: F821
    """Read ``path`` (MSH 2.2 with named physical groups) and renumber the roles to the runner's ids.

    Every triangle must belong to a mapped surface group; curves of unmapped groups are dropped.
    Messages name ``name`` (the user's .geo when ``path`` is the mesh made from it), else ``path``.
    """
    import meshio

    from pulseform.solvers.getdp import EMMesh

    m = meshio.read(path)
    path = path if name is None else name
    names = {name: (int(v[0]), int(v[1])) for name, v in m.field_data.items()}
    phys = m.cell_data_dict.get("gmsh:physical", {})
    tri = m.get_cells_type("triangle")
    if not len(tri) or "triangle" not in phys:
        raise DeckContractError(f"{path}: no triangles with physical groups")
    lines = m.get_cells_type("line")
    ltags = np.asarray(phys.get("line", np.zeros(len(lines), np.int64)))
    ttags = np.asarray(phys["triangle"])
    new_t, new_l = np.zeros_like(ttags), np.zeros_like(ltags)
    for role in SURFACE_ROLES + CURVE_ROLES:
        name = getattr(regions, role)
        if name is None:
            continue
        if name not in names:
            raise DeckContractError(f"{path}: geometry.regions.{role}: no physical group named {name!r} "
                                    f"(the mesh has {', '.join(sorted(names)) or 'no named groups'})")
        pid, dim = names[name]
        want = 2 if role in SURFACE_ROLES else 1
        if dim != want:
            raise DeckContractError(f"{path}: geometry.regions.{role}: group {name!r} has dimension {dim}; "
                                    f"the {role} must be a physical {'surface' if want == 2 else 'curve'}")
        sel = (ttags == pid) if want == 2 else (ltags == pid)
        if not sel.any():
            raise DeckContractError(f"{path}: geometry.regions.{role}: group {name!r} has no elements")
        (new_t if want == 2 else new_l)[sel] = ROLE_IDS[role]
    if (new_t == 0).any():
        left = sorted({int(t) for t in ttags[new_t == 0]})
        inv = {v[0]: k for k, v in names.items() if v[1] == 2}
        raise DeckContractError(f"{path}: triangles of physical group(s) "
                                f"{', '.join(inv.get(t, str(t)) for t in left)} have no role in geometry.regions")
    keep = new_l > 0
    pts = np.asarray(m.points)[:, :2]
    mesh = EMMesh(pts, tri.astype(np.int64), new_t, lines[keep].astype(np.int64), new_l[keep])
    neg = mesh.areas() < 0
    mesh.triangles[neg] = mesh.triangles[neg][:, [0, 2, 1]]
    used = np.unique(np.concatenate([mesh.triangles.ravel(), mesh.lines.ravel()]))
    if len(used) != len(pts):  # drop orphan nodes (construction points)
        remap = np.full(len(pts), -1, np.int64)
        remap[used] = np.arange(len(used))
        mesh = EMMesh(pts[used], remap[mesh.triangles], mesh.tri_tags, remap[mesh.lines], mesh.line_tags)
    return mesh


def build_user_geometry(case, work: Path, em_dir: Path):
    """The EM geometry of a user deck (no turn rectangles: user meshes are not remeshed), after the
    deck passed the check (:func:`check_contract`, getdp runs in ``em_dir/contract_check``). gmsh and
    getdp run under the case's time limits (:func:`time_limits`)."""
    from ..mesh.em_geometry import EMGeometry

    g = case.geometry
    gmsh_limit, getdp_limit = time_limits(case)
    mesh = read_deck_mesh(mesh_file(g, work, gmsh_limit), g.regions, name=g.mesh)
    log.info("user EM mesh (%s): %d nodes, %d triangles", Path(g.mesh).name, mesh.n_nodes, len(mesh.triangles))
    check_contract(make_solver(case, user_em_model(case), Path(em_dir)), mesh, Path(em_dir) / "contract_check",
                   time_limit=getdp_limit)
    return EMGeometry(mesh, {role: ROLE_IDS[role] for role in ("coil",) + g.conductor_roles()}, [])


def log_summary(path: Path, n: int = 2, width: int = 160) -> str:
    """The last ``n`` non-empty lines of a gmsh/getdp log, joined with `` | `` and shortened."""
    try:
        lines = [ln.strip() for ln in Path(path).read_text(errors="replace").splitlines()
                 if ln.strip() and not ln.startswith("# argv:")]
    except OSError:
        return ""
    return _short(" | ".join(lines[-n:]), width)


def check_user_deck(case) -> None:
    """``pulseform check`` of a user deck: mesh it, map its groups to roles and run the contract
    check in a temporary folder, which is removed whether the deck passes or not. Raises
    :class:`DeckContractError` naming what is wrong; when that names a gmsh/getdp log of the
    temporary folder, the message carries the log's last lines instead (an ``Error`` line of the
    log is in the message already)."""
    import tempfile

    tmp = Path(tempfile.mkdtemp(prefix="pulseform_check_"))
    try:
        build_user_geometry(case, tmp / "em_mesh", tmp / "em")
    except DeckContractError as exc:
        if exc.log_path is None or not exc.log_path.is_relative_to(tmp):
            raise
        tail = "" if "Error" in exc.message else log_summary(exc.log_path)
        raise DeckContractError(exc.message + (f"; log ends: {tail}" if tail else "")) from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# ----------------------------------------------------------------------------- getdp
def user_em_model(case):
    """EMModel of a user-deck case: one stranded coil, the workpiece as massive conductor 1 (a die 2)."""
    from .participant import em_model

    g = case.geometry
    shell = None if g.shell_inner_radius is None else (g.shell_inner_radius, g.shell_outer_radius)
    return em_model(case, shell)


def make_solver(case, model, work_dir: Path, getdp_process: str = "per_step"):
    """The EM solver on the user's deck (role ids, the case's parameters and ``PulseformLib``): one
    getdp process per EM step, or with ``getdp_process = "persistent"`` one for the run (the deck
    needs Resolution ``EM_Persistent``, which a deck on ``PulseformLib`` has)."""
    from pulseform.solvers.getdp.solver import DECK_DIR

    from .participant import make_em_solver

    g = case.geometry
    numbers = {name: ROLE_IDS[role] for role, name in ROLE_NUMBERS.items()
               if role not in OPTIONAL_ROLES or getattr(g.regions, role) is not None}
    numbers.update({k: float(v) for k, v in (g.parameters or {}).items()})
    lib = (DECK_DIR / "Lib_PulsedForming.pro").resolve()
    return make_em_solver(model, work_dir, case.em.time_scheme, getdp_process, deck=g.pro, extra_numbers=numbers,
                          preamble=[f'PulseformLib = "{lib}";'])


#: output tables the contract requires after one step (k = 1: one coil, one conductor)
REQUIRED_TABLES = {
    "W.txt": "EM_Step: Print[W[...], OnGlobal, Format Table] (magnetic energy)",
    "coil_I_1.txt": "EM_Step: Print[I, OnRegion Coil_1]", "coil_U_1.txt": "EM_Step: Print[U, OnRegion Coil_1]",
    "coil_P_1.txt": "EM_Step: Print[P[Coil_1], OnGlobal]", "coil_F_1.txt": "EM_Step: Print[F[Coil_1], OnGlobal]",
    "cond_P_1.txt": "EM_Step: Print[P[Cond_1], OnGlobal]", "cond_F_1.txt": "EM_Step: Print[F[Cond_1], OnGlobal]",
    "elem_f.txt": "EM_Elem: Print[f, OnElementsOf Vol_C_Mag, Depth 0]",
    "elem_F.txt": "EM_Elem: Print[F, OnElementsOf Vol_C_Mag, Depth 0]",
    "elem_P.txt": "EM_Elem: Print[P, OnElementsOf Vol_C_Mag, Depth 0]",
    "elem_b.txt": "EM_Elem: Print[b, OnElementsOf Vol_C_Mag, Depth 0]",
    "nodes_a.txt": "EM_State: Print[raz, OnElementsOf Vol_CS_Mag, Format NodeTable]",
}
CIRCUIT_TABLES = {"cir_U.txt": "EM_Step: Print[U, OnRegion Capacitance_Cir]",
                  "cir_I.txt": "EM_Step: Print[I, OnRegion Capacitance_Cir]"}


def check_contract(solver, mesh, work: Path, time_limit: float = GETDP_TIME_LIMIT_S) -> "DeckCheckReport":  # noqa: F821
    """The deck check (:func:`pulseform.orchestrator.em.deck_check.check_deck`): a few one-step getdp
    runs on the deck with the run's numbers (each stopped after ``time_limit`` s) prove that it
    fulfils the contract, solves the model and carries its state, the first step's tables left in
    ``work/out``. The carry is checked through the Init path (``Flag_InitA``), and through the
    restart path too when ``solver`` steps implicit Euler (BDF2 runs use only the Init path).
    Returns the :class:`~pulseform.orchestrator.em.deck_check.DeckCheckReport`; raises
    :class:`DeckContractError` (one line) naming what failed."""
    from .deck_check import check_deck

    paths = ("init",) if getattr(solver, "time_scheme", "euler") == "bdf2" else ("init", "restart")
    return check_deck(solver, mesh, Path(work), time_limit, carry_paths=paths)


def user_deck_load(case, geometry, work_dir: Path, bodies, em_substeps: int):
    """The load provider of a user-deck case: GetDPLoad on the user's deck (checked by
    :func:`build_user_geometry`)."""
    from .participant import GetDPLoad

    class UserDeckLoad(GetDPLoad):
        """GetDPLoad whose solver runs the user's deck; user meshes are moved, never remeshed."""

        def _remesh(self, positions):
            raise DeckContractError("the EM mesh of a user deck degraded beyond em.remesh_quality and user meshes "
                                    "are not remeshed: refine the .geo around the workpiece, lower "
                                    "em.remesh_quality or shorten time.end")

    model = user_em_model(case)
    mode = case.em.getdp_process
    if mode == "auto":  # the deck selects: the persistent getdp (BDF2 only) where it has EM_Persistent
        mode = "per_step"
        if case.em.time_scheme == "bdf2":
            persistent = make_solver(case, model, Path(work_dir), "persistent")
            persistent.timeout = case.limits.getdp_time_limit_s
            if persistent.probe(geometry.mesh):
                mode = "persistent"
    solver = make_solver(case, model, Path(work_dir), mode)
    if mode == "persistent" and case.em.getdp_process == "persistent":
        solver.timeout = case.limits.getdp_time_limit_s
        if not solver.probe(geometry.mesh):
            raise DeckContractError(f"deck {case.geometry.pro}: em.getdp_process = 'persistent' needs Resolution "
                                    "EM_Persistent (Include PulseformLib provides it), or set getdp_process = 'per_step'")
    log.info("user deck: %s", "one persistent getdp process" if mode == "persistent" else "a getdp process per EM step")
    load = UserDeckLoad(geometry, model, work_dir, bodies, keep_runs=case.em.keep_runs,
                        remesh_quality=case.em.remesh_quality, sizes=(1.0, 1.0), em_substeps=em_substeps,
                        time_scheme=case.em.time_scheme)
    load.solver = solver
    load.state = solver.initial_state(0.0)
    return load
