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
   101 coil, 201 workpiece, 202 die, 11 axis, 12 outer) -- or, with ``[[geometry.coils]]``, coil k of
   that list to 100 + k -- and tells the deck these ids with ``-setnumber Phys_Air, Phys_Shell,
   Phys_Coil_1 (Phys_Coil_2, ...), Phys_Cond_1, Phys_Cond_2, Phys_Axis, Phys_Outer``;
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
import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp import EMMesh, coil_tag
from pulseform.solvers.getdp.runner import run_logged
from pulseform.solvers.getdp.solver import DECK_DIR, MAGNETIC_BLOCK_LINE
from pulseform.solvers.getdp.contract import (CIRCUIT_TABLES, CURVE_ROLES, OPTIONAL_ROLES, REQUIRED_TABLES,  # noqa: F401
                                              ROLE_IDS, ROLE_NUMBERS, SURFACE_ROLES, coil_number_name)

from ..case.deck_files import (MAX_PARAMETER_NAME, check_parameters, deck_tokens, find_program_call,  # noqa: F401
                               is_reserved_parameter, reserved_listing, reserved_parameter_names,
                               resolve_deck_paths, short)
from ..mesh.em_geometry import EMGeometry
from .deck_check import DeckCheckReport, DeckContractError, DeckNames, check_deck  # noqa: F401  (DeckContractError: the API)
from .deck_sources import deck_current, deck_has_bank, sources_left_to_deck, unread_sources, with_deck_sources
from .template_deck import (UNREAD, DeckGeometry, check_deck_values, deck_constants, deck_physical_ids, deck_summary,
                            template_solver)
from .solver import em_model, factor_reuse, make_em_solver
from .user_remesh import UserDeckLoad, remesh_air_ids

log = logging.getLogger(__name__)



#: wall-time limits (s) when the case has no ``[limits]`` table (``limits.gmsh_time_limit_s``,
#: ``limits.getdp_time_limit_s`` otherwise): one gmsh run on the .geo, the contract check's getdp run
GMSH_TIME_LIMIT_S = 600.0
GETDP_TIME_LIMIT_S = 600.0


def time_limits(case) -> tuple[float, float]:
    """(gmsh, getdp) wall-time limits in seconds: the case's ``[limits]`` or the module defaults."""
    lim = getattr(case, "limits", None)
    return (float(getattr(lim, "gmsh_time_limit_s", None) or GMSH_TIME_LIMIT_S),
            float(getattr(lim, "getdp_time_limit_s", None) or GETDP_TIME_LIMIT_S))


# ----------------------------------------------------------------------------- mesh
def mesh_file(g, work: Path, time_limit: float = GMSH_TIME_LIMIT_S) -> Path:
    """The deck's MSH 2.2 file: the ``.msh`` itself, or the ``.geo`` meshed by gmsh into ``work``
    (log ``work/gmsh.log``). gmsh is stopped after ``time_limit`` seconds and never outlives
    pulseform (:func:`pulseform.solvers.getdp.runner.child_preexec`)."""
    src = Path(g.mesh)
    if src.suffix == ".msh":
        return src
    work = Path(work).resolve()  # gmsh runs in the .geo's folder: a relative -o would land there
    work.mkdir(parents=True, exist_ok=True)
    out = work / (src.stem + ".msh")
    exe = shutil.which("gmsh")
    if exe is None:
        raise DeckContractError("gmsh not found on PATH: needed to mesh " + str(src))
    argv = [exe, str(src), "-2", "-format", "msh22", "-o", str(out)]
    for k, v in (g.parameters or {}).items():
        argv += ["-setnumber", k, repr(float(v))]
    log_path = work / "gmsh.log"
    try:
        returncode, text = run_logged(argv, src.parent, log_path, time_limit)
    except subprocess.TimeoutExpired:
        raise DeckContractError(f"{src}: meshing with gmsh exceeded its time limit of {time_limit:g} s "
                                "(limits.gmsh_time_limit_s) and was stopped", log_path=log_path) from None
    except OSError as exc:
        raise DeckContractError(f"{src}: could not start gmsh: {exc}", log_path=log_path) from None
    errors = [ln for ln in text.splitlines() if ln.startswith("Error")]
    if returncode != 0 or errors or not out.is_file():
        first = errors[0] if errors else (f"killed by signal {-returncode}" if returncode < 0
                                          else f"exit code {returncode}")
        raise DeckContractError(f"{src}: gmsh failed: {short(first, 200)}", log_path=log_path)
    log.info("meshed %s -> %s", src, out)
    return out


def group_map(regions, coils: Sequence = ()) -> list[tuple[str, str, int, int]]:
    """(case-file key, physical-group name, dimension, the runner's id) of every mapped group: the
    roles of ``regions`` that are given, then coil k of ``coils`` (``[[geometry.coils]]``, k = 1, 2, ...)
    as physical ``coil_tag(k)`` = 100 + k (``regions.coil``, when given, is coil 1 = 101)."""
    out = []
    for role in SURFACE_ROLES + CURVE_ROLES:
        group = getattr(regions, role)
        if group is not None:
            out.append((f"geometry.regions.{role}", group, 2 if role in SURFACE_ROLES else 1, ROLE_IDS[role]))
    out += [(f"geometry.coils[{i}].group", c.group, 2, coil_tag(i + 1)) for i, c in enumerate(coils)]
    return out


def read_deck_mesh(path: Path, regions, name: str | Path | None = None, coils: Sequence = ()) -> EMMesh:
    """Read ``path`` (MSH 2.2 with named physical groups) and renumber the roles to the runner's ids
    (:func:`group_map`: ``regions`` and the coil roles ``coils``, ``[[geometry.coils]]``).

    Every triangle must belong to a mapped surface group; curves of unmapped groups are dropped.
    Messages name ``name`` (the user's .geo when ``path`` is the mesh made from it), else ``path``,
    and the case-file key of the group (``geometry.regions.<role>``, ``geometry.coils[<i>].group``).
    """
    import meshio

    m = meshio.read(path, file_format="gmsh")  # by extension meshio tries ansys first and prints its failure
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
    for key, name, want, new_id in group_map(regions, coils):
        role = key.rsplit(".", 1)[-1] if key.startswith("geometry.regions.") else "coil"
        if name not in names:
            raise DeckContractError(f"{path}: {key}: no physical group named {name!r} "
                                    f"(the mesh has {', '.join(sorted(names)) or 'no named groups'})")
        pid, dim = names[name]
        if dim != want:
            raise DeckContractError(f"{path}: {key}: group {name!r} has dimension {dim}; "
                                    f"the {role} must be a physical {'surface' if want == 2 else 'curve'}")
        sel = (ttags == pid) if want == 2 else (ltags == pid)
        if not sel.any():
            raise DeckContractError(f"{path}: {key}: group {name!r} has no elements")
        (new_t if want == 2 else new_l)[sel] = new_id
    if (new_t == 0).any():
        left = sorted({int(t) for t in ttags[new_t == 0]})
        inv = {v[0]: k for k, v in names.items() if v[1] == 2}
        raise DeckContractError(f"{path}: triangles of physical group(s) "
                                f"{', '.join(inv.get(t, str(t)) for t in left)} have no role in geometry.regions "
                                f"(nor a coil of [[geometry.coils]])")
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
    """The EM geometry of a user deck (no turn rectangles: the built-in remesh does not apply), after the
    deck passed the check (:func:`check_contract`, getdp runs in ``em_dir/contract_check``). gmsh and
    getdp run under the case's time limits (:func:`time_limits`). A deck on GetDP's template
    (``library = "getdp_template"``) gets a :class:`~.template_deck.DeckGeometry` with its own
    physical ids, and its own values are compared with the case's (:mod:`.template_deck`)."""
    g = case.geometry
    gmsh_limit, getdp_limit = time_limits(case)
    msh = mesh_file(g, work, gmsh_limit)
    mesh = read_deck_mesh(msh, g.regions, name=g.mesh, coils=g.coils)
    log.info("user EM mesh (%s): %d nodes, %d triangles, %d coil(s)", Path(g.mesh).name, mesh.n_nodes,
             len(mesh.triangles), len(g.coil_groups()))
    template = getattr(g, "library", "pulseform") == "getdp_template"
    deck_ids = deck_physical_ids(msh, group_map(g.regions, g.coils)) if template else None
    model = user_em_model(case)
    left = template and sources_left_to_deck(case)  # the deck's own bank or current (.deck_sources)
    if left and deck_has_bank(make_solver(case, model, Path(em_dir), deck_ids=deck_ids), mesh,
                              Path(em_dir) / "bank_probe", getdp_limit):
        model = user_em_model(case, bank=True)  # its values read by the check
    report = check_contract(make_solver(case, model, Path(em_dir), deck_ids=deck_ids), mesh,
                            Path(em_dir) / "contract_check", time_limit=getdp_limit, names=deck_names(case, deck_ids))
    # coils 2, 3, ... (physical 102, ...) have no turn rectangles either (a user mesh is remeshed only in its
    # geometry.remesh_air groups), but the mesh motion keeps every coil's nodes fixed (EMGeometry.coil_turns lists their ids)
    regions = {role: ROLE_IDS[role] for role in ("coil",) + g.conductor_roles()}
    more = [[] for _ in g.coil_groups()[1:]]
    if template:
        constants = deck_constants(Path(g.pro), report.argv, Path(em_dir) / "constants", getdp_limit)
        values = check_deck_values(case, model, Path(em_dir) / "contract_check" / "out", constants)
        if left and model.circuit is None:  # the deck prescribes the coil's current: sampled through getdp
            values.update(deck_current(make_solver(case, model, Path(em_dir), deck_ids=deck_ids), mesh, g.regions.coil))
        return DeckGeometry(mesh, regions, [], more_coils=more, deck_ids=deck_ids, planar=g.planar,
                            deck_values=values, deck_constants=constants)
    return EMGeometry(mesh, regions, [], more_coils=more, planar=g.planar)


def log_summary(path: Path, n: int = 2, width: int = 160) -> str:
    """The last ``n`` non-empty lines of a gmsh/getdp log, joined with `` | `` and shortened."""
    try:
        lines = [ln.strip() for ln in Path(path).read_text(errors="replace").splitlines()
                 if ln.strip() and not ln.startswith("# argv:")]
    except OSError:
        return ""
    return short(" | ".join(lines[-n:]), width)


def check_user_deck(case) -> list[str]:
    """``pulseform check`` of a user deck: mesh it, map its groups to roles and run the contract
    check in a temporary folder, which is removed whether the deck passes or not. Returns the lines
    the check shows of a deck on GetDP's template (:func:`.template_deck.deck_summary`: its constants,
    the values the case takes from it; none for a deck on pulseform's library). Raises
    :class:`DeckContractError` naming what is wrong; when that names a gmsh/getdp log of the
    temporary folder, the message carries the log's last lines instead (an ``Error`` line of the
    log is in the message already)."""
    geometry = checked_in_temporary(case)
    return deck_summary(case, geometry) if isinstance(geometry, DeckGeometry) else []


def checked_in_temporary(case) -> EMGeometry:
    """:func:`build_user_geometry` in a temporary folder, which is removed whether the deck passes or not
    (what :func:`check_user_deck` and :func:`.deck_sources.resolve_deck_sources` do). Raises
    :class:`DeckContractError`: a message naming a log of the temporary folder carries the log's last
    lines instead."""
    import tempfile

    tmp = Path(tempfile.mkdtemp(prefix="pulseform_check_"))
    try:
        return build_user_geometry(case, tmp / "em_mesh", tmp / "em")
    except DeckContractError as exc:
        if exc.log_path is None or not exc.log_path.is_relative_to(tmp):
            raise
        tail = "" if "Error" in exc.message else log_summary(exc.log_path)
        raise DeckContractError(exc.message + (f"; log ends: {tail}" if tail else "")) from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# ----------------------------------------------------------------------------- getdp
def user_em_model(case, deck_values: dict | None = None, bank: bool = False):
    """EMModel of a user-deck case: its stranded coils (``regions.coil``, or ``[[geometry.coils]]`` in their
    order), the workpiece as massive conductor 1 (a die 2).

    A deck on GetDP's template keeps its own numbers: a conductor whose material leaves
    ``electrical_conductivity`` unset (0) and a coil without ``geometry.turns`` take the deck's values
    ``deck_values`` (:func:`.template_deck.deck_values`, ``sigma_<k>``, ``turns_<k>``, read by the deck
    check), or :data:`.template_deck.UNREAD` before the deck has been read (the runner's ``-setnumber``
    numbers of the template path do not use them). A case that leaves its source to such a deck
    (:func:`.deck_sources.sources_left_to_deck`) gets the deck's (``deck_values``, :func:`.deck_sources.with_deck_sources`)
    or, before the deck has been read, a bank (``bank``) or a prescribed current of unread values
    (:func:`.deck_sources.unread_sources`)."""
    g = case.geometry
    shell = None if g.shell_inner_radius is None else (g.shell_inner_radius, g.shell_outer_radius)
    if sources_left_to_deck(case):
        own = deck_values or {}
        case = with_deck_sources(case, own) if ("C" in own or "I0" in own) else unread_sources(case, bank)
    model = em_model(case, shell)
    if getattr(g, "library", "pulseform") == "getdp_template":
        own = deck_values or {}
        for k, c in enumerate(model.conductors, start=1):
            if c.sigma <= 0.0:
                c.sigma = float(own.get(f"sigma_{k}", UNREAD))
        for k, c in enumerate(model.coils, start=1):
            if c.turns is None:
                c.turns = float(own.get(f"turns_{k}", UNREAD))
    return model


def make_solver(case, model, work_dir: Path, getdp_process: str = "per_step", deck_ids: dict[int, int] | None = None):
    """The EM solver on the user's deck (role ids, the case's parameters, ``PulseformLib`` and the magnetic
    block ``PulseformMagneticLib``, ``decks/em_magnetic.pro``): one
    getdp process per EM step, or with ``getdp_process = "persistent"`` one for the run (the deck
    needs Resolution ``EM_Persistent``, which a deck on ``PulseformLib`` has). Coil k's id is
    ``Phys_Coil_<k>`` = 100 + k (``Phys_Coil_1`` = 101 for ``regions.coil`` or the first of
    ``[[geometry.coils]]``); ``NbCoils`` and the per-coil numbers come from the model. With
    ``deck_ids`` (a deck on GetDP's template: runner's id -> the deck's own) the solver is a
    :class:`~pulseform.solvers.getdp.template.TemplateDeckSolver` (per step, implicit Euler)."""
    g = case.geometry
    numbers = {name: ROLE_IDS[role] for role, name in ROLE_NUMBERS.items()
               if role not in OPTIONAL_ROLES or getattr(g.regions, role) is not None}
    numbers.update({coil_number_name(k): coil_tag(k) for k in range(2, len(g.coil_groups()) + 1)})
    numbers.update({k: float(v) for k, v in (g.parameters or {}).items()})
    if deck_ids is not None:  # a deck on GetDP's template: pulseform's wrapper, the deck's own ids
        return template_solver(case, model, work_dir, deck_ids, numbers)
    lib = (DECK_DIR / "Lib_PulsedForming.pro").resolve()
    preamble = [f'PulseformLib = "{lib}";', f'PulseformNewtonLib = "{lib.parent / "Lib_Newton.pro"}";',
                MAGNETIC_BLOCK_LINE]
    return make_em_solver(model, work_dir, case.em.time_scheme, getdp_process, deck=g.pro, extra_numbers=numbers,
                          preamble=preamble, factor_reuse=factor_reuse(case))


def deck_names(case, deck_ids: dict[int, int] | None = None) -> DeckNames:
    """The case's names of what getdp names in a user deck's messages (:class:`~.deck_check.DeckNames`):
    every mapped group by the physical id getdp sees (``deck_ids``: the runner's id -> a template deck's
    own), and the runner numbers a deck may override (``[geometry.parameters]``, the shell radii)."""
    g = case.geometry
    regions = {(deck_ids or {}).get(rid, rid): (name, key) for key, name, _, rid in group_map(g.regions, g.coils)}
    numbers = {k: f"geometry.parameters.{k}" for k in (g.parameters or {})}
    numbers.update(Val_Rint="geometry.shell_inner_radius", Val_Rext="geometry.shell_outer_radius",
                   Flag_FrequencyDomain="pulseform's transient solve")
    return DeckNames(regions, numbers)


def check_contract(solver, mesh, work: Path, time_limit: float = GETDP_TIME_LIMIT_S,
                   names: DeckNames | None = None) -> DeckCheckReport:
    """The deck check (:func:`pulseform.orchestrator.em.deck_check.check_deck`): a few one-step getdp
    runs on the deck with the run's numbers (each stopped after ``time_limit`` s) prove that it
    fulfils the contract, solves the model and carries its state, the first step's tables left in
    ``work/out``. The carry is checked through the Init path (``Flag_InitA``), and through the
    restart path too when ``solver`` steps implicit Euler (BDF2 runs use only the Init path).
    Returns the :class:`~pulseform.orchestrator.em.deck_check.DeckCheckReport`; raises
    :class:`DeckContractError` (one line) naming what failed, in the case's ``names`` (:func:`deck_names`)."""
    paths = ("init",) if getattr(solver, "time_scheme", "euler") == "bdf2" else ("init", "restart")
    if getattr(solver, "deck_ids", None) is not None:  # a template deck: its state travels by -restart only
        paths = ("restart",)
    return check_deck(solver, mesh, Path(work), time_limit, carry_paths=paths, names=names)


def user_deck_load(case, geometry, work_dir: Path, bodies, em_substeps: int):
    """The load provider of a user-deck case: :class:`~.user_remesh.UserDeckLoad` on the user's deck (checked by
    :func:`build_user_geometry`), its ``geometry.remesh_air`` groups meshed again when the mesh degrades."""
    model = user_em_model(case, getattr(geometry, "deck_values", None))
    mode = case.em.getdp_process
    deck_ids = getattr(geometry, "deck_ids", None)
    if deck_ids is not None:  # a template deck: per step (the case loader refused the persistent getdp)
        solver = make_solver(case, model, Path(work_dir), deck_ids=deck_ids)
        log.info("user deck on GetDP's template: a getdp process per EM step (-restart carry)")
        mode = None
    elif mode == "auto":  # the deck selects: the persistent getdp (BDF2 only) where it has EM_Persistent
        mode = "per_step"
        if case.em.time_scheme == "bdf2":
            persistent = make_solver(case, model, Path(work_dir), "persistent")
            persistent.timeout = case.limits.getdp_time_limit_s
            if persistent.probe(geometry.mesh):
                mode = "persistent"
    if mode is not None:
        solver = make_solver(case, model, Path(work_dir), mode)
    if mode == "persistent" and case.em.getdp_process == "persistent":
        solver.timeout = case.limits.getdp_time_limit_s
        if not solver.probe(geometry.mesh):
            raise DeckContractError(f"deck {Path(case.geometry.pro).name}: em.getdp_process = 'persistent' needs Resolution "
                                    "EM_Persistent (Include PulseformLib provides it), or set getdp_process = 'per_step'")
    if mode is not None:
        log.info("user deck: %s", "one persistent getdp process" if mode == "persistent" else "a getdp process per EM step")
    load = UserDeckLoad(geometry, model, work_dir, bodies, keep_runs=case.em.keep_runs,
                        remesh_quality=case.em.remesh_quality, sizes=(1.0, 1.0), em_substeps=em_substeps,
                        time_scheme=case.em.time_scheme,
                        air_ids=remesh_air_ids(case.geometry.regions, case.geometry.remesh_air))
    load.gmsh_time_limit = time_limits(case)[0]
    load.solver = solver
    load.state = solver.initial_state(0.0)
    return load
