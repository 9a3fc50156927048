"""Users' own EM decks: a case's own Gmsh ``.geo``/``.msh`` and GetDP ``.pro`` (``[geometry] type = "user_deck"``).

The runner

1. resolves ``mesh`` and ``pro`` against the case folder (and refuses paths outside it unless
   ``allow_outside = true``) when the case is loaded;
2. meshes a ``.geo`` with ``gmsh -2 -format msh22 -setnumber <parameters>`` (or reads the ``.msh``);
3. renumbers the physical groups named in ``[geometry.regions]`` to the runner's ids (1 air, 2 shell,
   101 coil, 201 workpiece, 202 die, 11 axis, 12 outer) and tells the deck these ids with
   ``-setnumber Phys_Air, Phys_Shell, Phys_Coil_1, Phys_Cond_1, Phys_Cond_2, Phys_Axis, Phys_Outer``;
4. runs getdp on the deck exactly like the built-in ``em_case.pro`` (every number of the library's
   ``DefineConstant`` list with ``-setnumber``, ``OutDir`` with ``-setstring``, resolution
   ``EM_Transient``), with the string ``PulseformLib`` (absolute path of ``Lib_PulsedForming.pro``)
   defined before the deck is read, and the case's ``parameters`` as extra ``-setnumber``;
5. checks the contract once before the run (one tiny step in ``em/contract_check/``): a getdp error
   or a missing output table becomes a one-line :class:`DeckContractError` naming what is missing.

The contract is documented in ``docs/workflow.md``.
"""

from __future__ import annotations

import logging
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np

from .caseio import CaseError

log = logging.getLogger(__name__)

#: role -> the runner's physical id, and the -setnumber name the deck receives it under
ROLE_IDS = {"air": 1, "shell": 2, "coil": 101, "workpiece": 201, "die": 202, "axis": 11, "outer": 12}
ROLE_NUMBERS = {"air": "Phys_Air", "shell": "Phys_Shell", "coil": "Phys_Coil_1", "workpiece": "Phys_Cond_1",
                "die": "Phys_Cond_2", "axis": "Phys_Axis", "outer": "Phys_Outer"}
SURFACE_ROLES, CURVE_ROLES = ("air", "shell", "coil", "workpiece", "die"), ("axis", "outer")
OPTIONAL_ROLES = ("shell", "die")


class DeckContractError(RuntimeError):
    """A user's deck or mesh does not fulfil the deck contract (one-line message naming what is missing)."""


# ----------------------------------------------------------------------------- case loading
def resolve_deck_paths(data: dict[str, Any], file: Path, source: str) -> None:
    """Make ``geometry.mesh`` / ``geometry.pro`` absolute (relative to the case file's folder) and
    check them: they must exist and lie inside the case folder unless ``allow_outside`` is true."""
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


# ----------------------------------------------------------------------------- mesh
def mesh_file(g, work: Path) -> Path:
    """The deck's MSH 2.2 file: the ``.msh`` itself, or the ``.geo`` meshed by gmsh into ``work``."""
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
    r = subprocess.run(argv, cwd=src.parent, capture_output=True, text=True)
    (work / "gmsh.log").write_text(r.stdout + r.stderr)
    errors = [ln for ln in (r.stdout + r.stderr).splitlines() if ln.startswith("Error")]
    if r.returncode != 0 or errors or not out.is_file():
        first = errors[0] if errors else f"exit code {r.returncode}"
        raise DeckContractError(f"{src}: gmsh failed: {first} (log: {work / 'gmsh.log'})")
    log.info("meshed %s -> %s", src, out)
    return out


def read_deck_mesh(path: Path, regions) -> "EMMesh":  # noqa: F821
    """Read ``path`` (MSH 2.2 with named physical groups) and renumber the roles to the runner's ids.

    Every triangle must belong to a mapped surface group; curves of unmapped groups are dropped.
    """
    import meshio

    from pulseform.solvers.getdp import EMMesh

    m = meshio.read(path)
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
    deck passed the contract check (one tiny getdp step in ``em_dir/contract_check``)."""
    from .emf_geometry import EMGeometry

    g = case.geometry
    mesh = read_deck_mesh(mesh_file(g, work), g.regions)
    log.info("user EM mesh (%s): %d nodes, %d triangles", Path(g.mesh).name, mesh.n_nodes, len(mesh.triangles))
    check_contract(make_solver(case, user_em_model(case), Path(em_dir)), mesh, Path(em_dir) / "contract_check")
    return EMGeometry(mesh, {role: ROLE_IDS[role] for role in ("coil",) + g.conductor_roles()}, [])


def check_user_deck(case) -> None:
    """``pulseform check`` of a user deck: mesh it, map its groups to roles and run the contract
    check in a temporary folder, which is removed when the deck passes and kept (the error names its
    getdp log) when it does not. Raises :class:`DeckContractError` naming what is wrong."""
    import tempfile

    tmp = Path(tempfile.mkdtemp(prefix="pulseform_check_"))
    build_user_geometry(case, tmp / "em_mesh", tmp / "em")
    shutil.rmtree(tmp, ignore_errors=True)


# ----------------------------------------------------------------------------- getdp
def user_em_model(case):
    """EMModel of a user-deck case: one stranded coil, the workpiece as massive conductor 1 (a die 2)."""
    from .em_participant import em_model

    g = case.geometry
    shell = None if g.shell_inner_radius is None else (g.shell_inner_radius, g.shell_outer_radius)
    return em_model(case, shell)


def make_solver(case, model, work_dir: Path):
    """A GetDPSolver on the user's deck: role ids, the case's parameters and ``PulseformLib``."""
    from pulseform.solvers.getdp import GetDPSolver
    from pulseform.solvers.getdp.solver import DECK_DIR

    g = case.geometry
    numbers = {name: ROLE_IDS[role] for role, name in ROLE_NUMBERS.items()
               if role not in OPTIONAL_ROLES or getattr(g.regions, role) is not None}
    numbers.update({k: float(v) for k, v in (g.parameters or {}).items()})
    lib = (DECK_DIR / "Lib_PulsedForming.pro").resolve()
    return GetDPSolver(model, work_dir, deck=g.pro, extra_numbers=numbers, preamble=[f'PulseformLib = "{lib}";'],
                       time_scheme=case.em.time_scheme)


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


def check_contract(solver, mesh, work: Path) -> None:
    """One tiny getdp step on the deck; raise :class:`DeckContractError` naming what is missing."""
    from pulseform.solvers.getdp import GetDPError, run_getdp, write_msh22
    from pulseform.solvers.getdp.solver import RESOLUTION

    deck = Path(solver.deck)
    if work.exists():
        shutil.rmtree(work)
    out = work / "out"
    out.mkdir(parents=True)
    msh = write_msh22(mesh, work / "mesh.msh")
    numbers = solver._numbers(mesh)
    numbers.update(TimeInit=0.0, TimeFinal=1e-9, NbSteps=1, Flag_ElemOut=1)
    if solver.model.circuit is not None:
        numbers.update(Init_Vc=solver.model.circuit.V0, Init_I=0.0)
    wrapper = work / "run.pro"
    wrapper.write_text("// pulseform: deck contract check\n" + "\n".join(solver.preamble + solver._table_lines())
                       + f'\nInclude "{deck}";\n')
    try:
        run_getdp(wrapper, msh, work, resolution=RESOLUTION, numbers=numbers, strings={"OutDir": str(out) + "/"},
                  extra_args=list(solver.petsc_args), executable=solver.executable, timeout=120)
    except GetDPError as exc:
        log_text = (work / "getdp.log").read_text(errors="replace") if (work / "getdp.log").is_file() else str(exc)
        errs = [ln.strip() for ln in log_text.splitlines() if ln.lstrip().startswith("Error")] or \
            [ln.strip() for ln in str(exc).splitlines() if "rror" in ln] or [str(exc).splitlines()[0]]
        hint = ""
        if any("Resolution" in e and RESOLUTION in e for e in errs) or any("Unknown Resolution" in e for e in errs):
            hint = f"; the contract needs Resolution {RESOLUTION}"
        raise DeckContractError(f"deck {deck}: getdp failed on the contract check: {errs[0]}{hint} "
                                f"(log: {work / 'getdp.log'})") from None
    need = dict(REQUIRED_TABLES)
    if solver.model.circuit is not None:
        need.update(CIRCUIT_TABLES)
    for k in range(2, len(solver.model.conductors) + 1):  # a die: massive conductor 2
        need.update({f"cond_P_{k}.txt": f"EM_Step: Print[P[Cond_{k}], OnGlobal]",
                     f"cond_F_{k}.txt": f"EM_Step: Print[F[Cond_{k}], OnGlobal]"})
    missing = [f for f in need if not (out / f).is_file()]
    if missing:
        raise DeckContractError(f"deck {deck} breaks the deck contract: after one step OutDir lacks "
                                + ", ".join(f"{f} ({need[f]})" for f in missing))
    if not (work / "em.res").is_file():
        raise DeckContractError(f"deck {deck} breaks the deck contract: no em.res (Resolution {RESOLUTION} must "
                                "SaveSolution its system every sub-step; the runner passes -name)")
    log.info("deck %s passed the contract check", deck)


def user_deck_load(case, geometry, work_dir: Path, bodies, em_substeps: int):
    """The load provider of a user-deck case: GetDPLoad on the user's deck (checked by
    :func:`build_user_geometry`)."""
    from .em_participant import GetDPLoad

    class UserDeckLoad(GetDPLoad):
        """GetDPLoad whose solver runs the user's deck; user meshes are moved, never remeshed."""

        def _remesh(self, positions):
            raise DeckContractError("the EM mesh of a user deck degraded beyond em.remesh_quality and user meshes "
                                    "are not remeshed: refine the .geo around the workpiece, lower "
                                    "em.remesh_quality or shorten time.end")

    model = user_em_model(case)
    solver = make_solver(case, model, Path(work_dir))
    load = UserDeckLoad(geometry, model, work_dir, bodies, keep_runs=case.em.keep_runs,
                        remesh_quality=case.em.remesh_quality, sizes=(1.0, 1.0), em_substeps=em_substeps,
                        time_scheme=case.em.time_scheme)
    load.solver = solver
    load.state = solver.initial_state(0.0)
    return load
