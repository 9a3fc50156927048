"""The check of a user's GetDP deck (issue 18): it solves the model, and it carries its state.

:func:`check_deck` runs the deck through the same :class:`~pulseform.solvers.getdp.GetDPSolver`
a run uses (so with the same ``-setnumber`` numbers: the model's, the role ids ``Phys_*`` and the
case's ``[geometry.parameters]``, and the same ``run.pro`` preamble) on the case's own mesh, a few
steps of :data:`CHECK_STEP_S`, implicit Euler:

1. **one step** ``0 -> dt`` (folder ``<work>``; its ``out/`` keeps the tables): getdp runs, the
   contract's tables and ``em.res`` exist, and the deck **solves the model**: exactly one time row
   at ``dt`` (a deck whose own ``TimeFinal``/``NbSteps`` override the runner's fails here), a
   non-zero finite magnetic energy and coil current, one force row per workpiece (and die) element
   and nothing else, a field state (``nodes_a.txt``) on every coil and conductor node;
2. **the state carry**: a second step ``dt -> 2 dt`` from the first one's state, through the Init
   path (``Flag_InitA = 1`` and ``InitA_List``, what every BDF2 step and every step on a new mesh
   does; folder ``<work>/carry_init``) and, for implicit-Euler cases, through the restart path
   (``-restart -res``, folder ``<work>/carry_restart``), must equal one two-step run ``0 -> 2 dt``
   (folder ``<work>/two_steps``) to :data:`CARRY_RTOL` in the magnetic energy, the coil current,
   the capacitor voltage, every element's force density and the nodal unknown.

The first failure is a one-line :class:`~pulseform.orchestrator.em.user_deck.DeckContractError`
naming the deck and what failed. Measured on ``cases/user_deck_sheet_bulge`` (1519 nodes): four
getdp runs in about 0.6 s, chained-carry difference 9e-13 (Init path, the tables' printed digits)
and 0 (restart path).
"""

from __future__ import annotations

import logging
import re
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pulseform.solvers.getdp.contract import CIRCUIT_TABLES, REQUIRED_TABLES, coil_tables

from ..case.deck_files import assignment_sites, short

if TYPE_CHECKING:
    from pulseform.solvers.getdp import EMMesh, EMState, EMStepResult, GetDPSolver

log = logging.getLogger(__name__)

#: the check's time step (s): of the order of a run's EM step
CHECK_STEP_S = 1e-7
#: the runner's time window: a deck's own plain assignment of one beats -setnumber (a template deck's are
#: assigned again after the deck, :func:`pulseform.solvers.getdp.template_guard.runner_guard_lines`)
WINDOW_NAMES = ("TimeInit", "TimeFinal", "NbSteps")
#: largest relative difference between two chained one-step runs and one two-step run (measured on
#: the example: 9e-13 through the Init path, whose nodal values travel as printed tables)
CARRY_RTOL = 1e-9


class DeckContractError(RuntimeError):
    """A user's deck or mesh does not fulfil the deck contract (one-line message naming what is missing).

    ``message`` is the line without the log; ``log_path`` the gmsh/getdp log it refers to, if any
    (``str()`` appends ``(log: <path>)``)."""

    def __init__(self, message: str, *, log_path: Path | None = None) -> None:
        self.message = message
        self.log_path = None if log_path is None else Path(log_path)
        super().__init__(message if log_path is None else f"{message} (log: {log_path})")


@dataclass(frozen=True)
class DeckNames:
    """What the case calls the things getdp names, for the check's messages.

    Attributes
    ----------
    regions : dict
        Physical id as getdp sees it (the runner's for a deck on pulseform's library, the mesh's own
        for a deck on GetDP's template) -> ``(physical-group name, case-file key)``.
    numbers : dict
        A runner number's name (``Val_Rint``, a ``[geometry.parameters]`` name, ...) -> the case-file
        key that gives it.
    """

    regions: dict[int, tuple[str, str]] = field(default_factory=dict)
    numbers: dict[str, str] = field(default_factory=dict)

    def region(self, pid: int) -> str:
        """``SHEET (physical 1200, geometry.regions.workpiece)``, or ``physical <pid>``."""
        if pid not in self.regions:
            return f"physical {pid}"
        group, key = self.regions[pid]
        return f"{group} (physical {pid}, {key})"


#: what the template's functions give, for a region that lacks one (getdp: ``Function 'X' undefined``)
FUNCTION_MEANINGS = {"sigma": "its conductivity (S/m)", "nu": "its reluctivity 1/mu (m/H)",
                     "js0": "the coil's current density per ampere, Ns[]/Sc[] * Vector[0,0,1] (1/m^2)",
                     "Ns": "its turns", "Sc": "its cross-section (m^2)",
                     "CoefGeos": "2*Pi (axisymmetric) or 1 (planar)"}


@dataclass
class DeckCheckReport:
    """What :func:`check_deck` measured on a deck that passed.

    Attributes
    ----------
    magnetic_energy : float
        Magnetic energy (J, per radian in axisymmetry) after the first step.
    coil_current : float
        Coil current (A) after the first step (with several coils the one of largest magnitude).
    force_rows : int
        Per-element force rows of the first step (= workpiece and die elements).
    state_nodes : int
        Nodes of the field state (``nodes_a.txt``) after the first step.
    carry_difference : dict
        Carry path (``"init"``, ``"restart"``) -> largest relative difference to the two-step run.
    wall_time_s : float
        Wall time of the check's getdp runs (s).
    argv : list of str
        The first step's getdp command line (its ``-setnumber`` numbers are a run's).
    """

    magnetic_energy: float
    coil_current: float
    force_rows: int
    state_nodes: int
    carry_difference: dict[str, float] = field(default_factory=dict)
    wall_time_s: float = 0.0
    argv: list[str] = field(default_factory=list)


def check_deck(solver: GetDPSolver, mesh: EMMesh, work: Path, time_limit: float,
               carry_paths: tuple[str, ...] = ("init",), names: DeckNames | None = None) -> DeckCheckReport:
    """Check that the deck of ``solver`` solves the model on ``mesh`` and carries its state.

    Parameters
    ----------
    solver : GetDPSolver
        The run's solver on the user's deck (its model, deck, ``extra_numbers`` and ``preamble``
        are used; the check runs implicit Euler whatever the case's scheme).
    mesh : EMMesh
        The case's EM mesh, groups renumbered to the runner's ids.
    work : Path
        Folder of the first step (its ``out/`` holds the tables); the other runs go below it.
    time_limit : float
        Wall-time limit (s) of each getdp run.
    carry_paths : tuple of str
        ``"init"`` (``Flag_InitA``) and/or ``"restart"`` (``-restart -res``).
    names : DeckNames, optional
        The case's names of the physical ids and runner numbers (messages only).

    Returns
    -------
    DeckCheckReport
        The figures of a deck that passed.

    Raises
    ------
    DeckContractError
        One line naming the deck and the first thing that failed.
    """
    from pulseform.solvers.getdp import GetDPSolver

    work = Path(work).resolve()
    deck = Path(solver.deck)
    kwargs = dict(deck=deck, extra_numbers=solver.extra_numbers, preamble=solver.preamble,
                  petsc_args=solver.petsc_args, executable=solver.executable, timeout=time_limit, time_scheme="euler")
    if getattr(solver, "deck_ids", None) is not None:  # a deck on GetDP's template: the same wrapper and ids
        from pulseform.solvers.getdp.template import TemplateDeckSolver

        check = TemplateDeckSolver(solver.model, work.parent, spec=solver.spec, deck_ids=solver.deck_ids,
                                   check_currents=False, **kwargs)  # the values: template_deck.check_deck_values
    else:
        check = GetDPSolver(solver.model, work.parent, **kwargs)
    dt = CHECK_STEP_S
    start = time.perf_counter()
    state0 = check.initial_state(0.0)
    names = names or DeckNames()
    first, state1 = _run(check, mesh, state0, dt, 1, work.name, deck, names=names)
    report = _solves_the_model(check, mesh, work / "out", deck)
    _newton_table(check, work / "out", deck)
    report.argv = list(first.run.argv)
    two, state2 = _run(check, mesh, state0, 2 * dt, 2, f"{work.name}/two_steps", deck, names=names)
    for path in carry_paths:
        chained, chained_state = _run(check, mesh, state1, 2 * dt, 1, f"{work.name}/carry_{path}", deck,
                                      force_init_path=(path == "init"), names=names)
        diff, what = _largest_difference(chained, chained_state, two, state2)
        report.carry_difference[path] = diff
        if not diff <= CARRY_RTOL:
            how = ("Init path: Flag_InitA, InitA_List, Init_Vc, Init_I" if path == "init"
                   else "restart path: -restart -res em.res")
            raise DeckContractError(f"deck {deck.name} does not carry its state ({how}): a step chained after another "
                                    f"differs from one two-step run by {diff:.2g} in the {what} "
                                    f"(tolerance {CARRY_RTOL:g})")
    report.wall_time_s = time.perf_counter() - start
    log.info("deck %s solves the model: W = %.6g J, coil current %.6g A, %d force rows, %d state nodes; chained "
             "carry %s (%d getdp runs, %.2f s)", deck, report.magnetic_energy, report.coil_current, report.force_rows,
             report.state_nodes, ", ".join(f"{k} {v:.2g}" for k, v in report.carry_difference.items()),
             2 + len(carry_paths), report.wall_time_s)
    return report


def _run(solver: GetDPSolver, mesh: EMMesh, state: EMState, t_end: float, n_sub: int, run_name: str, deck: Path,
         *, force_init_path: bool = False, names: DeckNames | None = None) -> tuple[EMStepResult, EMState]:
    """(result, state) of one :meth:`GetDPSolver.step` in ``solver.work_dir / run_name``; a getdp
    failure, a template deck's coil or conductor outside its group or in two of them
    (:func:`_group_problem`), a missing table, wrong time rows or unreadable (hollow) output become
    one line (:class:`DeckContractError`)."""
    names = names or DeckNames()
    from pulseform.solvers.getdp import GetDPError

    run_dir = solver.work_dir / run_name
    try:
        result = solver.step(mesh, state, t_end, n_sub, run_name=run_name, force_init_path=force_init_path)
        error = None
    except GetDPError as exc:
        raise _getdp_failure(deck, run_dir, exc, names, _group_problem(solver, run_dir / "out", names)) from None
    except (RuntimeError, ValueError, OSError, IndexError) as exc:  # the solver could not read the output
        result, error = None, exc
    problem = _group_problem(solver, run_dir / "out", names)
    if problem is not None:
        raise DeckContractError(f"deck {deck.name}: {problem}")
    text = short((str(error) or type(error).__name__).splitlines()[0], 200) if error is not None else ""
    if error is not None and not (run_dir / "getdp.log").is_file():  # refused before getdp ran
        raise DeckContractError(f"deck {deck.name}: the check could not start getdp: {text}")
    _contract_tables(solver, run_dir, deck)
    _time_rows(run_dir / "out", deck, state.t, t_end, n_sub)
    if error is not None:
        _solves_the_model(solver, mesh, run_dir / "out", deck)  # names what is hollow, if that is why
        raise DeckContractError(f"deck {deck.name}: its output cannot be read ({text})", log_path=run_dir / "getdp.log")
    return result


def where_assigned(deck: Path, names: list[str] | tuple[str, ...]) -> tuple[str, str, str] | None:
    """(name, ``file:line``, right-hand side) of the first plain assignment of one of ``names`` in ``deck``
    or its Includes (:func:`~pulseform.orchestrator.case.deck_files.assignment_sites`), or None; the
    file is named relative to the deck's folder when it lies inside it."""
    sites = assignment_sites(deck, names)
    if not sites:
        return None
    name, file, line, rhs = sites[0]
    return name, f"{_shown(deck, file)}:{line}", rhs


def _shown(deck: Path, file: Path) -> str:
    """``file`` named relative to the deck's folder when it lies inside it."""
    return str(file.relative_to(deck.parent) if file.is_relative_to(deck.parent) else file)


def _override_line(deck: Path, name: str, deck_value: float, runner_value: float, source: str | None) -> str:
    """The line of a deck whose own plain assignment of a runner's number (``source``: the case-file key
    that gives it) differs from the runner's value: where, and the one-line fix."""
    site = where_assigned(deck, [name])
    rhs = site[2] if site and site[2] else f"{deck_value:.6g}"
    where = (f"deck {site[1]}" if site and site[1].startswith(deck.name + ":") else
             f"deck {deck.name}: {site[1]}" if site else f"deck {deck.name} (or a file it includes)")
    given = f" ({source})" if source else ""
    return (f"{where} assigns {name} = {rhs}; the runner's -setnumber {name} = {runner_value:.6g}{given} loses "
            f"to a plain assignment: write DefineConstant[ {name} = {rhs} ]; instead (the case's value then reaches "
            "the deck)")


def _group_problem(solver: GetDPSolver, out: Path, names: DeckNames) -> str | None:
    """Why a template deck's groups cannot hold the case's coils and conductors (the first run's
    ``groups.txt``, :data:`pulseform.solvers.getdp.template.GROUPS_TABLE`), or None: a conductor must be
    in ``Vol_C_Mag`` (massive) and not in ``Vol_S_Mag`` (stranded), a coil the other way round, both in
    ``Vol_Mag``. None too for a deck on pulseform's library or a run that wrote no table."""
    from pulseform.solvers.getdp.template import GROUPS_TABLE, MEMBERSHIP_GROUPS

    deck_ids = getattr(solver, "deck_ids", None)
    if deck_ids is None or not (out / GROUPS_TABLE).is_file():
        return None
    from pulseform.solvers.getdp import coil_tag, conductor_tag

    for row in (out / GROUPS_TABLE).read_text().splitlines():
        parts = row.split()
        if len(parts) != 1 + len(MEMBERSHIP_GROUPS):
            continue
        kind, _, k = parts[0].partition("_")
        outside = dict(zip(MEMBERSHIP_GROUPS, (float(v) > 0 for v in parts[1:])))
        pid = deck_ids.get(coil_tag(int(k)) if kind == "coil" else conductor_tag(int(k)))
        what = names.region(pid)
        own, other = ("Vol_S_Mag", "Vol_C_Mag") if kind == "coil" else ("Vol_C_Mag", "Vol_S_Mag")
        kinds = {"Vol_S_Mag": "stranded conductors", "Vol_C_Mag": "massive conductors"}
        if outside["Vol_Mag"] and outside[own]:
            return f"no group of the deck holds {what}: its Region[]s must use the mesh's own ids"
        if outside[own]:
            return f"{what} is not in the deck's {own} (the template's {kinds[own]}): add it to {own}"
        if not outside[other]:
            return f"{what} is in both {own} and {other}: a group has one role; remove it from {other}"
    return None


def _getdp_failure(deck: Path, run_dir: Path, exc: Exception, names: DeckNames | None = None,
                   problem: str | None = None) -> DeckContractError:
    """A getdp error of a check run as one line quoting the log's first ``Error`` line, with its cause
    where known: a runner number the deck overrides (:func:`_override_line`), ``problem`` (a template
    deck's groups, :func:`_group_problem`), the case's bank on a deck without a circuit, a function
    undefined in a region (named by ``names``); a line of the generated ``run.pro`` is quoted (the
    check's folder may be gone when the line is read)."""
    from pulseform.solvers.getdp.solver import RESOLUTION
    from pulseform.solvers.getdp.template import NO_CIRCUIT_ERROR
    from pulseform.solvers.getdp.template_guard import OVERRIDE_ERROR

    names = names or DeckNames()
    log_file = run_dir / "getdp.log"
    text = log_file.read_text(errors="replace") if log_file.is_file() else str(exc)
    errs = [ln.strip() for ln in text.splitlines() if ln.lstrip().startswith("Error")] or \
        [ln.strip() for ln in str(exc).splitlines() if "rror" in ln] or [str(exc).splitlines()[0]]
    over = re.search(re.escape(OVERRIDE_ERROR) + r" (\w+) = (\S+), runner (\S+)", errs[0])
    if over:
        return DeckContractError(_override_line(deck, over.group(1), float(over.group(2)), float(over.group(3)),
                                                names.numbers.get(over.group(1))))  # complete: no log needed
    if NO_CIRCUIT_ERROR in errs[0]:
        why = errs[0].split(NO_CIRCUIT_ERROR, 1)[1].strip()
        return DeckContractError(
            f"deck {deck.name} has no circuit for the case's capacitor bank {why}: add the template's circuit "
            "(Flag_CircuitCoupling = 1, Capacitance_Cir, Resistance_Cir, Inductance_Cir, ElectricalCircuit: "
            "cases/template_sheet_bulge) or use em.current")
    first = re.sub(r"^(Error|Critical)\s*:\s*", r"\1: ", _quote_run_pro(errs[0], run_dir))
    hint = ""
    if any("Resolution" in e and RESOLUTION in e for e in errs) or any("Unknown Resolution" in e for e in errs):
        hint = f"; the contract needs Resolution {RESOLUTION}"
    coil = re.search(r"Unknown Group: Coil_(\d+)", errs[0])
    if coil:  # a deck with fewer coil groups than the case's coil roles
        k = coil.group(1)
        hint = (f"; the case has coil {k} ([[geometry.coils]]): define Coil_{k} = Region[{{Phys_Coil_{k}}}] "
                "and its Ns, Sc, sigma")
    undefined = re.search(r"Function '(\w+)' undefined in Region (\d+)", errs[0])
    if problem is not None:  # the cause: the getdp error is its symptom
        return DeckContractError(f"deck {deck.name}: getdp failed on the contract check ({short(first, 90)}): "
                                 f"{problem}", log_path=log_file)
    if undefined:
        func, pid = undefined.group(1), int(undefined.group(2))
        meaning = FUNCTION_MEANINGS.get(func, "its value")
        hint = f"; {names.region(pid)} has no {func}[]: define {func}[] on its group in the deck, {meaning}"
    return DeckContractError(f"deck {deck.name}: getdp failed on the contract check: {short(first, 200)}{hint}",
                             log_path=log_file)


def _quote_run_pro(error: str, run_dir: Path) -> str:
    """``error`` with a location in the generated ``run.pro`` replaced by the line itself (``run.pro``,
    line 59: ``<text>``): the check's temporary folder is removed before the message is read."""
    m = re.search(r"'([^']*run\.pro)', line (\d+)", error)
    if m is None:
        return error
    try:
        line = Path(m.group(1)).read_text(errors="replace").splitlines()[int(m.group(2)) - 1].strip()
    except (OSError, IndexError):
        return error
    return error.replace(m.group(0), f"pulseform's generated run.pro, line {m.group(2)} ({short(line, 80)})")


def _contract_tables(solver: GetDPSolver, run_dir: Path, deck: Path) -> None:
    """Every table of the contract (and ``em.res``) exists after a run, else one line naming the missing ones."""
    from pulseform.solvers.getdp.solver import RESOLUTION

    out = run_dir / "out"
    need = dict(REQUIRED_TABLES)
    if solver.model.circuit is not None:
        need.update(CIRCUIT_TABLES)
    for k in range(2, len(solver.model.coils) + 1):  # coils 2, 3, ... of [[geometry.coils]]
        need.update(coil_tables(k))
    for k in range(2, len(solver.model.conductors) + 1):  # a die: massive conductor 2
        need.update({f"cond_P_{k}.txt": f"EM_Step: Print[P[Cond_{k}], OnGlobal]",
                     f"cond_F_{k}.txt": f"EM_Step: Print[F[Cond_{k}], OnGlobal]"})
    missing = [f for f in need if not (out / f).is_file()]
    if missing:
        raise DeckContractError(f"deck {deck.name} breaks the deck contract: after one step OutDir lacks "
                                + ", ".join(f"{f} ({need[f]})" for f in missing))
    if not (run_dir / "em.res").is_file():
        raise DeckContractError(f"deck {deck.name} breaks the deck contract: no em.res (Resolution {RESOLUTION} must "
                                "SaveSolution its system every sub-step; the runner passes -name)")


def _newton_table(solver: GetDPSolver, out: Path, deck: Path) -> None:
    """Newton's table ``newton.txt`` (``Lib_Newton.pro``) after one step exists exactly when the case has a B–H
    curve: one without it runs Newton's iterations the runner would not read (a ``Vol_NL_Mag`` of the deck's
    own), a curve without it never reached the deck (no ``Include PulseformMagneticLib``); else one line."""
    has = (out / "newton.txt").is_file()
    if has and not solver.model.is_nonlinear:
        raise DeckContractError(f"deck {deck.name} runs Newton's iterations (newton.txt: a Vol_NL_Mag of its own) but "
                                "the case has no B-H curve: give it in the case file (materials.<name>.bh_curve) and "
                                "Include PulseformMagneticLib in place of the deck's nu[]")
    if solver.model.is_nonlinear and not has:
        raise DeckContractError(f"deck {deck.name} does not run the case's B-H curve (no newton.txt after one step): "
                                "Include PulseformMagneticLib in place of its nu[], and Include PulseformLib")


def _read_rows(path: Path) -> np.ndarray:
    """A getdp global table as a 2-D array (no rows: shape (0, 2))."""
    text = path.read_text(errors="replace").strip()
    if not text:
        return np.zeros((0, 2))
    rows = np.fromstring(text.replace("\n", " "), sep=" ")
    ncol = len(text.splitlines()[0].split())
    return rows.reshape(-1, ncol) if ncol and rows.size % ncol == 0 else np.zeros((0, 2))


def _time_rows(out: Path, deck: Path, t0: float, t_end: float, n_sub: int) -> None:
    """``W.txt`` and ``coil_I_1.txt`` hold one row per sub-step at the runner's times, else one line
    (a deck whose own ``TimeInit``/``TimeFinal``/``NbSteps``/time loop wins over ``-setnumber``)."""
    want = t0 + (t_end - t0) * np.arange(1, n_sub + 1) / n_sub
    for name in ("W.txt", "coil_I_1.txt"):
        if not (out / name).is_file():
            continue
        t = _read_rows(out / name)[:, 0]
        if len(t) != n_sub or not np.all(np.abs(t - want) <= 1e-6 * (t_end - t0) / n_sub):
            got = f"{len(t)} row(s) ending at t = {t[-1]:.3g} s" if len(t) else "no rows"
            fix = "(TimeInit, TimeFinal, NbSteps are the runner's)"
            sites = assignment_sites(deck, WINDOW_NAMES)
            if sites:
                where = ", ".join(dict.fromkeys(_shown(deck, file) + f":{line}" for _, file, line, _ in sites))
                own = ", ".join(f"{n} = {rhs}" for n, _, _, rhs in sites if rhs)
                fix = f"({where} assigns it: write DefineConstant[ {own} ]; instead)"
            raise DeckContractError(f"deck {deck.name} overrides the time window: {name} has {got}, the runner asked for "
                                    f"{n_sub} ending at {t_end:.3g} s {fix}")


def _solves_the_model(solver: GetDPSolver, mesh: EMMesh, out: Path, deck: Path) -> DeckCheckReport:
    """The first step solved the model: non-zero energy and coil current, one force row per
    conductor element, a field state on every coil and conductor node; else one line listing
    everything that is hollow."""
    from pulseform.solvers.getdp import conductor_tag
    from pulseform.solvers.getdp.files import read_element_table

    model = solver.model
    problems: list[str] = []
    w_rows = _read_rows(out / "W.txt")
    w = float(w_rows[-1, 1]) if len(w_rows) and w_rows.shape[1] > 1 else 0.0
    if not (np.isfinite(w) and w != 0.0):
        problems.append(f"W = {w:g}")
    cur = 0.0  # the largest |current| of any coil (a coil's source may switch on later)
    for k in range(1, max(len(model.coils), 1) + 1):
        i_rows = _read_rows(out / f"coil_I_{k}.txt") if (out / f"coil_I_{k}.txt").is_file() else np.zeros((0, 2))
        value = float(i_rows[-1, -1]) if len(i_rows) else 0.0
        if not np.isfinite(value) or abs(value) > abs(cur):
            cur = value
    if not (np.isfinite(cur) and cur != 0.0):
        problems.append(f"coil current {cur:g} A")
    tags = [conductor_tag(k) for k in range(1, len(model.conductors) + 1)]
    want = np.flatnonzero(np.isin(mesh.tri_tags, tags)) + 1
    roles = "workpiece and die" if len(tags) > 1 else "workpiece"
    try:
        ids, _ = read_element_table(out / "elem_f.txt", 3, 1)
    except (RuntimeError, ValueError, OSError):
        ids = np.zeros(0, np.int64)
    if len(ids) != len(want) or not np.array_equal(np.sort(ids), want):
        extra = len(np.setdiff1d(ids, want))
        problems.append(f"force rows for {len(np.intersect1d(ids, want))} of {len(want)} {roles} elements"
                        + (f" (+{extra} elsewhere)" if extra else ""))
    _, nodes = solver.conductor_nodes(mesh)
    d = _read_rows(out / "nodes_a.txt") if (out / "nodes_a.txt").is_file() else np.zeros((0, 2))
    state_nodes = np.unique(d[:, 0].astype(np.int64)) - 1 if len(d) else np.zeros(0, np.int64)
    if not np.isin(nodes, state_nodes).all():
        problems.append(f"field state on {int(np.isin(nodes, state_nodes).sum())} of {len(nodes)} nodes")
    if problems:
        regions_hollow = any(p.startswith(("force rows", "field state")) for p in problems)
        ids = ("its groups must hold the mesh's own physical ids" if getattr(solver, "deck_ids", None) is not None
               else "its Region[]s must use the ids Phys_* the runner passes")
        drive = ("nothing drives the coil: give the deck a circuit (Flag_CircuitCoupling = 1: "
                 "cases/template_sheet_bulge) or a Current_2D value on its coil, or state em.circuit or em.current "
                 "in case.toml"
                 if getattr(solver, "deck_ids", None) is not None
                 else "the coil must be driven by the case's circuit or current (Flag_Circuit, Init_Vc, Coil_I0_1)")
        hint = ids if regions_hollow else drive
        raise DeckContractError(f"deck {deck.name} is hollow: after one step " + ", ".join(problems) + "; " + hint)
    return DeckCheckReport(magnetic_energy=w, coil_current=cur, force_rows=len(ids), state_nodes=len(state_nodes))


def _largest_difference(res_a: EMStepResult, state_a: EMState, res_b: EMStepResult, state_b: EMState
                        ) -> tuple[float, str]:
    """Largest relative difference between two runs' end values, and what it is in."""
    pairs = {"magnetic energy": (res_a.magnetic_energy[-1], res_b.magnetic_energy[-1]),
             "coil current": (res_a.coil_current[-1], res_b.coil_current[-1]),
             "force density": (res_a.force_density[-1], res_b.force_density[-1]),
             "nodal unknown": (state_a.a_values, state_b.a_values)}
    if res_b.capacitor_voltage is not None:
        pairs["capacitor voltage"] = (res_a.capacitor_voltage[-1], res_b.capacitor_voltage[-1])
    worst, where = 0.0, "none"
    for name, (a, b) in pairs.items():
        a, b = np.asarray(a, float), np.asarray(b, float)
        if a.shape != b.shape:
            return float("inf"), f"{name} ({a.size} values against {b.size})"
        scale = float(np.abs(b).max()) if b.size else 0.0
        diff = float(np.abs(a - b).max()) / scale if b.size and scale > 0 else float(np.abs(a - b).max(initial=0.0))
        if not np.isfinite(diff) or diff > worst:
            worst, where = (float("inf") if not np.isfinite(diff) else diff), name
    return worst, where
