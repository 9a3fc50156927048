"""The ``pulseform`` command line. Only this module prints.

Exit codes: 0 success, 1 a run that started and failed, 2 bad input (case file, overrides, usage).
"""

from __future__ import annotations

import argparse
import functools
import logging
import os
import signal
import sys
from pathlib import Path

from . import __version__
from .cli_sweep import add_sweep_parser
from .console_log import setup_console_logging
from .run.interrupt import StudyInterrupted

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


@functools.cache  # once per process: building it costs ms (argparse's gettext); parse_args leaves it unchanged
def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="pulseform",
        description="Coupled GetDP + DOLFINx simulation of pulsed metal forming.")
    p.add_argument("--version", action="version", version=f"pulseform {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    run = sub.add_parser("run", help="run a case into a results folder",
                         description="Run CASE (a folder with case.toml, or a .toml file).")
    run.add_argument("case", metavar="CASE", help="case folder or case TOML file")
    run.add_argument("--out", metavar="DIR", type=Path,
                     help="results folder (default: results/<case name>)")
    run.add_argument("--set", metavar="KEY.PATH=VALUE", action="append", default=[], dest="overrides",
                     help="override a case key, e.g. --set time.end=1e-3 --set bodies.left.mesh_size=0.05 "
                          "(repeatable; validated like the file)")
    run.add_argument("--resume", action="store_true", help="continue an interrupted run in --out")
    run.add_argument("--force", action="store_true", help="replace an existing results folder")
    run.add_argument("--quiet", action="store_true", help="no progress bar, warnings only")

    check = sub.add_parser("check", help="validate a case file without running it",
                           description="Validate CASE and print the resolved case.")
    check.add_argument("case", metavar="CASE")
    check.add_argument("--set", metavar="KEY.PATH=VALUE", action="append", default=[], dest="overrides")

    add_sweep_parser(sub)

    conv = sub.add_parser("converge", help="run a case on refined meshes and report the grid convergence index",
                          description="Run CASE on LEVELS meshes (every element size divided by RATIO per level; or "
                                      "the EM step with --refine em_step), each a `pulseform run` (as sweep's members) in "
                                      "OUT/level_<k>/, and compute per metric the observed order, the extrapolated "
                                      "value and the GCI of the three finest (Celik et al. 2008). Writes "
                                      "OUT/converge.json, OUT/report.md and OUT/plots/converge_*.png.")
    conv.add_argument("case", metavar="CASE")
    conv.add_argument("--ratio", type=float, default=2.0, help="refinement ratio per level (default 2)")
    conv.add_argument("--levels", type=int, default=3, help="levels, >= 3 (default 3)")
    conv.add_argument("--refine", choices=("mesh", "em_step"), default="mesh",
                      help="what is refined: every element size (default) or the EM step (coupling.n)")
    conv.add_argument("--metric", action="append", default=[], metavar="NAME",
                      help="a metrics.json key to study (repeatable; default: the headline metrics the runs have)")
    conv.add_argument("--set", metavar="KEY.PATH=VALUE", action="append", default=[], dest="overrides",
                      help="override applied to every level")
    conv.add_argument("--out", metavar="DIR", type=Path, help="study folder (default: results/<case>_converge)")
    conv.add_argument("--jobs", type=int, default=1, metavar="N", help="levels run at the same time (default 1)")
    conv.add_argument("--force", action="store_true", help="replace an existing study folder")

    val = sub.add_parser("validate", help="run the validation registry and write a report",
                         description="Run the validation entries of a suite (each: a case or set-up, a quantity, "
                                     "a reference with provenance, a tolerance); write OUT/report.md, "
                                     "OUT/report.json and OUT/plots/*.png. Exit 1 if any entry fails.")
    val.add_argument("--suite", choices=("fast", "full"), default="fast", help="fast (CI, default) or full")
    val.add_argument("--out", metavar="DIR", type=Path, help="report folder (default: results/validation_<suite>)")
    val.add_argument("--only", metavar="PREFIX", action="append", default=[],
                     help="only entries whose name starts with PREFIX (repeatable)")
    val.add_argument("--reference-root", metavar="DIR", type=Path,
                     help="folder holding cases/<case>/reference/ (default: the repository)")
    val.add_argument("--list", action="store_true", help="list the suite's entries and exit")
    val.add_argument("--force", action="store_true", help="replace an existing report folder")

    cmp_ = sub.add_parser("compare", help="coupled GetDP load vs the pressure-pulse approximation",
                          description="Run CASE coupled, fit (or take from the case) an eq. (7)/(8) pressure pulse, "
                                      "run it through the same loop on the same mesh, and compare final shapes, "
                                      "speeds, die stresses, impulse and wall time. Writes OUT/compare.json and "
                                      "OUT/plots/. Exit 1 if a --fail-if condition holds.")
    cmp_.add_argument("case", metavar="CASE")
    cmp_.add_argument("--out", metavar="DIR", type=Path, help="folder (default: results/<case>_compare)")
    cmp_.add_argument("--set", metavar="KEY.PATH=VALUE", action="append", default=[], dest="overrides",
                      help="override applied to both runs")
    cmp_.add_argument("--pulse", choices=("sin2", "exp"), default="sin2",
                      help="fitted pulse: eq. (7) P0 e^-bt sin^2(wt) (default) or eq. (8) p0 e^-t/T")
    cmp_.add_argument("--pressure-case", metavar="FILE",
                      help="take the pressure pulses from this case's [[loads]] instead of fitting them")
    cmp_.add_argument("--surface", metavar="BOX",
                      help="3D models (geometry files): the loaded surface to fit the pulse on, a box as a TOML inline "
                           "table of bounds in m (xmin ... zmax, rmin/rmax about the z-axis), e.g. "
                           "'{rmin = 0.01, rmax = 0.034, zmin = 1.4999e-3, zmax = 1.5001e-3}': the loaded body's "
                           "exterior triangles with three nodes inside; the pressure pushes along their area vector")
    cmp_.add_argument("--body", metavar="NAME",
                      help="the loaded body (default: the workpiece, or a 3D model's only body)")
    cmp_.add_argument("--fail-if", metavar="METRIC>TOL", action="append", default=[], dest="fail_if",
                      help="e.g. 'shape_distance_max_mm>0.05' or 'impulse_rel_diff>0.01' (repeatable; > or <)")
    cmp_.add_argument("--force", action="store_true", help="replace an existing folder")

    plot = sub.add_parser("plot", help="draw every picture of a results folder again",
                          description="Draw every picture of RESULTS_DIR (a folder written by `pulseform run`) "
                                      "again into RESULTS_DIR/plots/ from its history.csv, metrics.json, case.toml "
                                      "and fields, also when the run had output.plots = false.")
    plot.add_argument("results", metavar="RESULTS_DIR", type=Path, help="a results folder of `pulseform run`")

    schema = sub.add_parser("schema", help="the JSON Schema of the case file (editor completion and checks)",
                            description="Print the JSON Schema (draft 2020-12) of the case file, or write it to FILE.")
    schema.add_argument("--out", metavar="FILE", type=Path, help="write it to FILE (atomically) instead of printing it")

    sub.add_parser("info", help="versions and locations of getdp, gmsh, dolfinx, PETSc, meshio, numpy",
                   description="Print the versions of the external programs and libraries and where each comes from.")
    return p


def _error(msg: str, code: int) -> int:
    """Print ``pulseform: error: <msg>`` as one line of at most ~300 characters; return ``code``."""
    from .case.io import MAX_MESSAGE, one_line

    print(f"pulseform: error: {one_line(msg, MAX_MESSAGE)}", file=sys.stderr)
    return code


def _cmd_run(args: argparse.Namespace) -> int:
    from .case.io import CaseError, load_case
    from .em.skin_depth import resolve_defaults
    from .run.results import ResultsExistError

    try:
        case, file = load_case(args.case, args.overrides)
        resolve_defaults(case, file, args.overrides)  # its errors are bad input; the run fills the defaults in
    except CaseError as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    from .em.deck_sources import resolve_deck_sources
    from .em.deck_check import DeckContractError

    try:  # a template deck's own bank or current, read through getdp: the run and its summary use it
        case = resolve_deck_sources(case)
    except DeckContractError as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    out = args.out or Path("results") / case.case.name
    from .run.runner import ResumeError, RunFailed, RunInterrupted, run_case  # heavy imports (dolfinx) only when running

    try:
        metrics = run_case(case, out, force=args.force, resume=args.resume, quiet=args.quiet,
                           native_stderr_to_log=True)
    except (ResultsExistError, ResumeError) as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    except RunInterrupted as exc:
        print(f"pulseform: {exc}", file=sys.stderr)
        return 128 + exc.signum
    except KeyboardInterrupt:
        print(f"pulseform: stopped at once (second interrupt); the last checkpoint in {out} stays: continue "
              "with --resume", file=sys.stderr)
        return 128 + signal.SIGINT
    except RunFailed as exc:
        from .case.guards import LimitExceeded
        from .em.deck_check import DeckContractError
        from .mesh.geometry3d import GeometryError

        # a user deck that breaks the contract, a 3D geometry file whose groups do not fit its role map, or a
        # mesh beyond [limits], is bad input found before the first step
        bad_input = isinstance(exc.__cause__, (DeckContractError, GeometryError, LimitExceeded))
        code = _error(str(exc), EXIT_BAD_INPUT if bad_input else EXIT_FAILED)
        if exc.details:  # the tail of the failing program's log
            print("  --- log tail ---\n" + "\n".join("  " + ln for ln in exc.details.splitlines()), file=sys.stderr)
        return code
    if not args.quiet:
        from .run.summary import summary_lines

        for line in summary_lines(case, metrics, out, args.case):
            print(line)
        print(f"results: {out}")
        for k in sorted(metrics):
            print(f"  {k} = {metrics[k]:.6g}")
    return EXIT_OK


def _check_geometry_3d(case, file: Path) -> list[str] | int:
    """Mesh a 3D geometry file in a temporary folder and map its roles: the lines ``check`` prints (its
    groups, tetrahedra, coils and conductors), or the exit code of a one-line refusal."""
    import tempfile

    from .case.guards import LimitExceeded, check_steps_of_meshes
    from .em.model3d import em_model3d
    from .mesh.geometry3d import GeometryError, build_geometry3d, stable_step_estimate
    from pulseform.solvers.getdp.solver3d import model_numbers

    with tempfile.TemporaryDirectory(prefix="pulseform_check3d_") as tmp:
        try:
            geo = build_geometry3d(case, Path(tmp))
            model_numbers(em_model3d(case, geo), geo.mesh)   # what the deck would refuse
            check_steps_of_meshes(case, stable_step_estimate(case, geo))   # explicit and EM steps vs [limits]
        except GeometryError as exc:
            return _error(f"{file}: {exc.message}", EXIT_BAD_INPUT)
        except LimitExceeded as exc:
            return _error(f"{file}: {exc}", EXIT_BAD_INPUT)
        except ValueError as exc:
            return _error(f"{file}: {Path(case.geometry.file).name}: geometry: {exc}", EXIT_BAD_INPUT)
    m = geo.mesh
    return [f"# {case.geometry.file}: {m.n_tets} tetrahedra, {m.n_nodes} nodes; groups: {geo.groups}",
            f"# coils (physical 100 + k): {geo.coils}; conductors (200 + k): {geo.conductors}; symmetry factor "
            f"{360.0 / m.sector_deg:g}" + (f"; shell radii {geo.shell[0]:.6g}, {geo.shell[1]:.6g} m" if geo.shell else "")]


def _cmd_check(args: argparse.Namespace) -> int:
    from .case.io import CaseError, case_to_toml, load_case
    from .em.skin_depth import default_sizes, mesh_advice, resolve_defaults

    try:
        loaded, file = load_case(args.case, args.overrides)
        case = resolve_defaults(loaded, file, args.overrides)
    except CaseError as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    filled = default_sizes(loaded)
    if case.geometry is not None and case.geometry.type == "user_deck":
        from .em.template_deck import DeckValueConflict
        from .em.user_deck import DeckContractError, check_user_deck

        try:  # mesh the deck, map its groups and run one tiny getdp step (in a temporary folder)
            deck_lines = check_user_deck(case)
        except DeckContractError as exc:  # a value of the case against the deck's: both files named
            return _error(f"{file.name}: {exc}" if isinstance(exc, DeckValueConflict) else str(exc), EXIT_BAD_INPUT)
        print(f"# {case.geometry.pro}: honours the deck contract")
        for line in deck_lines or ():  # a template deck's constants, the values the case takes from it
            print(line)
    geometry_lines: list[str] = []
    if case.geometry is not None and case.geometry.type == "geometry_3d":
        lines = _check_geometry_3d(case, file)
        if isinstance(lines, int):
            return lines
        geometry_lines = lines
    try:
        advice = mesh_advice(case)
    except (ArithmeticError, ValueError) as exc:  # an extreme but valid case: no advice rather than a failure
        logging.getLogger(__name__).debug("no mesh advice: %s", exc)
        advice = []
    for line in advice:  # advice never stops a check
        print(f"pulseform: warning: {line}", file=sys.stderr)
    print(f"# {file}: valid")
    for line in geometry_lines:
        print(line)
    for d in filled:
        print(f"# {d.text()}")
    print(case_to_toml(case), end="")
    return EXIT_OK


def _cmd_sweep(args: argparse.Namespace) -> int:
    from .case.io import CaseError, load_case
    from .run.results import ResultsExistError
    from .workflows.executors import ExecutorError
    from .workflows.study_answer import AnswerError
    from .workflows.sweep import StudySpec, run_sweep

    if args.jobs < 1:
        return _error(f"--jobs: got {args.jobs}; must be >= 1", EXIT_BAD_INPUT)
    if args.retry_failed and not args.resume:
        return _error("--retry-failed: only with --resume (a new study has no failed member)", EXIT_BAD_INPUT)
    if args.resume and args.force:
        return _error("--resume and --force: choose one (continue the study, or replace it)", EXIT_BAD_INPUT)
    if args.scheduler and args.executor != "dask":
        return _error("--scheduler: only with --executor dask", EXIT_BAD_INPUT)
    executor = "mpi" if args.mpi else args.executor
    if executor == "mpi":
        from mpi4py import MPI

        if MPI.COMM_WORLD.Get_size() < 2:
            return _error("--executor mpi: start the sweep under mpirun with at least 2 ranks (rank 0 manages, the "
                          "others run members), e.g. mpirun -n 3 pulseform sweep CASE --mpi --param ...; "
                          "without mpirun use --jobs N", EXIT_BAD_INPUT)
        if MPI.COMM_WORLD.Get_rank() > 0:  # mpirun -n N: ranks > 0 are the sweep's workers
            from .workflows.sweep import serve_mpi_workers

            serve_mpi_workers()
            return EXIT_OK
    spec = StudySpec(args.param, sample=args.sample, design=args.design, seed=args.seed, executor=executor,
                     jobs=args.jobs, address=args.scheduler, resume=args.resume, retry_failed=args.retry_failed,
                     metrics=args.metric, objective=args.objective, constraints=args.constraint, quiet=args.quiet)
    try:
        case, _ = load_case(args.case, args.overrides)
        out = args.out or Path("results") / f"{case.case.name}_sweep"
        todo = run_sweep(args.case, spec, out, force=args.force, overrides=args.overrides)
    except (CaseError, ResultsExistError, ExecutorError, AnswerError) as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    from .workflows.study_answer import summary_lines

    for line in summary_lines(todo, out):
        print(line)
    failed = [m for m in todo if m.returncode not in (0, None)]
    for m in failed:
        print(f"member {m.index} ({' '.join(m.overrides)}): {m.error}", file=sys.stderr)
    print(f"table: {out / 'sweep.csv'}")
    return EXIT_FAILED if failed else EXIT_OK


def _cmd_converge(args: argparse.Namespace) -> int:
    from .case.io import CaseError, load_case
    from .run.results import ResultsExistError
    from .workflows.converge import ConvergeError, run_converge

    if args.jobs < 1:
        return _error(f"--jobs: got {args.jobs}; must be >= 1", EXIT_BAD_INPUT)
    try:
        case, _ = load_case(args.case, args.overrides)
        out = args.out or Path("results") / f"{case.case.name}_converge"
        report = run_converge(args.case, out, ratio=args.ratio, levels=args.levels, refine=args.refine,
                              metrics=args.metric or None, jobs=args.jobs, force=args.force, overrides=args.overrides)
    except (CaseError, ConvergeError, ResultsExistError) as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    print(f"{'metric':<28} {'fine':>12} {'medium':>12} {'coarse':>12} {'order':>7} {'extrapolated':>13} {'GCI':>8}")
    for name, r in report["metrics"].items():
        if "error" in r:
            print(f"{name:<28} {r['error']}")
            continue
        v = r["values"]
        print(f"{name:<28} {v[0]:12.6g} {v[1]:12.6g} {v[2]:12.6g} {r['order']:7.3g} {r['extrapolated']:13.6g} "
              f"{100 * r['gci_fine']:7.3g}%  {r['convergence']}")
    failed = [lv for lv in report["levels"] if lv["returncode"] != 0]
    for lv in failed:
        print(f"level {lv['level']}: {lv['error']}", file=sys.stderr)
    print(f"report: {out / 'report.md'}")
    return EXIT_FAILED if failed else EXIT_OK


def _cmd_validate(args: argparse.Namespace) -> int:
    from .run.results import ResultsExistError
    from .workflows.validate import SelectionError, criterion, run_validation, select

    try:
        entries = select(args.suite, args.only)
    except SelectionError as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    if args.list:
        for e in entries:
            tol = f"tol {e.tolerance:g}" if e.gci is None else criterion(e)
            print(f"{e.name:<48} {e.quantity} [{e.unit}]  {tol}  ref {e.reference.describe()}")
        return EXIT_OK
    if args.reference_root is not None and not args.reference_root.is_dir():
        return _error(f"--reference-root: {args.reference_root} is not a folder", EXIT_BAD_INPUT)
    out = args.out or Path("results") / f"validation_{args.suite}"
    kw = {} if args.reference_root is None else {"reference_root": args.reference_root.resolve()}
    try:
        outcomes = run_validation(entries, out, force=args.force, **kw)
    except ResultsExistError as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    for o in outcomes:
        err = "-" if o.error is None else f"{o.error:.3g}"
        tol = f"tol {o.entry.tolerance:g}" if o.entry.gci is None else criterion(o.entry)
        print(f"{o.status:<5} {o.entry.name:<48} error {err:<10} {tol}"
              + (f"  ({o.message})" if o.message and not o.passed else ""))
    failed = [o for o in outcomes if not o.passed]
    known = sum(1 for o in outcomes if o.passed and not o.met)
    print(f"report: {out / 'report.md'} ({len(outcomes) - len(failed) - known}/{len(outcomes)} passed"
          + (f", {known} known deviation(s) (xfail)" if known else "") + ")")
    return EXIT_FAILED if failed else EXIT_OK


def _cmd_compare(args: argparse.Namespace) -> int:
    from .case.io import CaseError, load_case
    from .workflows.compare import CompareError, parse_conditions, run_compare
    from .workflows.compare3d import parse_surface
    from .run.results import ResultsExistError

    try:
        conditions = parse_conditions(args.fail_if)
        surface = parse_surface(args.surface) if args.surface is not None else None
    except (CompareError, ValueError) as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    try:
        case, _ = load_case(args.case, args.overrides)
        out = args.out or Path("results") / f"{case.case.name}_compare"
        report = run_compare(args.case, out, overrides=args.overrides, pulse=args.pulse,
                             pressure_case=args.pressure_case, force=args.force, surface=surface, body=args.body)
    except (CaseError, ResultsExistError, CompareError) as exc:
        return _error(str(exc), EXIT_BAD_INPUT if not getattr(exc, "run_failed", False) else EXIT_FAILED)
    for k in ("shape_distance_max_mm", "max_speed_coupled_m_s", "max_speed_pressure_m_s", "impulse_coupled_Ns",
              "impulse_pressure_Ns", "impulse_rel_diff", "die_von_mises_max_coupled_MPa",
              "die_von_mises_max_pressure_MPa", "wall_time_coupled_s", "wall_time_pressure_s"):
        if k in report["metrics"]:
            print(f"  {k} = {report['metrics'][k]:.6g}")
    print(f"pulse: {report['pulse']['description']}")
    tripped = [c.text for c in conditions if c.holds(report["metrics"])]
    missing = [c.metric for c in conditions if c.metric not in report["metrics"]]
    print(f"report: {out / 'compare.json'}")
    if missing:
        return _error(f"--fail-if: unknown metric {', '.join(missing)}; known: "
                      + ", ".join(sorted(report["metrics"])), EXIT_BAD_INPUT)
    for t in tripped:
        print(f"pulseform: compare: --fail-if {t} holds", file=sys.stderr)
    return EXIT_FAILED if tripped else EXIT_OK


def _cmd_plot(args: argparse.Namespace) -> int:
    from .run.plots import NotAResultsFolder, check_results_folder, draw_all

    try:
        root = check_results_folder(args.results)
    except NotAResultsFolder as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    drawn = draw_all(root)
    print(f"pictures: {root / 'plots'} ({len(drawn.paths)})")
    for p in drawn.paths:
        print(f"  {p.relative_to(root / 'plots') if p.is_relative_to(root / 'plots') else p}")
    if drawn.failed:
        return _error(f"{len(drawn.failed)} picture group(s) failed: " + "; ".join(drawn.failed), EXIT_FAILED)
    return EXIT_OK


def _cmd_info(_: argparse.Namespace) -> int:
    from .workflows.info import collect

    for row in collect():
        print(f"{row.name:<10} {row.version:<28} {row.location}  [{row.source}]")
    return EXIT_OK


def _cmd_schema(args: argparse.Namespace) -> int:
    from .case.json_schema import case_json_schema_text
    from .run.results import atomic_write_text

    text = case_json_schema_text()
    if args.out is None:
        print(text, end="")
        return EXIT_OK
    try:
        atomic_write_text(args.out, text)
    except OSError as exc:
        return _error(f"--out: cannot write {args.out}: {exc.strerror or exc}", EXIT_BAD_INPUT)
    print(f"schema: {args.out}")
    return EXIT_OK


def entry() -> int:
    """The ``pulseform`` console script (and ``python -m pulseform.orchestrator``): :func:`main` in a
    process of its own. Started by itself (not by ``mpirun``), the process's MPI is a singleton: Open
    MPI's settings for an isolated singleton (the ones getdp runs with, ``FAST_MPI_ENV``) cut its start
    from ~0.4 s to ~0.07 s (measured: ``from mpi4py import MPI``). Set before mpi4py is imported, and
    only where the user has not set them; under ``mpirun`` nothing changes."""
    launched = any(k in os.environ for k in ("OMPI_COMM_WORLD_SIZE", "PMI_RANK", "PMIX_RANK", "PMI_SIZE"))
    if not launched and "mpi4py.MPI" not in sys.modules:
        from pulseform.solvers.getdp.runner import FAST_MPI_ENV

        for key, value in FAST_MPI_ENV.items():
            os.environ.setdefault(key, value)
    return main()


def main(argv: list[str] | None = None) -> int:
    """The ``pulseform`` command with arguments ``argv`` (default: the command line)."""
    args = _parser().parse_args(argv)
    setup_console_logging(getattr(args, "quiet", False))
    handlers = {"run": _cmd_run, "check": _cmd_check, "sweep": _cmd_sweep, "converge": _cmd_converge, "info": _cmd_info,
                "validate": _cmd_validate, "compare": _cmd_compare, "plot": _cmd_plot, "schema": _cmd_schema}
    try:
        return handlers[args.command](args)
    except (KeyboardInterrupt, StudyInterrupted) as exc:  # StudyInterrupted: a sweep / converge stopped by a signal
        print(f"pulseform: {exc if isinstance(exc, StudyInterrupted) else 'interrupted'}", file=sys.stderr)
        return 128 + getattr(exc, "signum", signal.SIGINT)
    except MemoryError:
        return _error("out of memory (coarsen the mesh, shorten the run or use a larger machine)", EXIT_FAILED)
    except Exception as exc:  # never a traceback on the terminal; PULSEFORM_TRACEBACK=1 shows it
        if os.environ.get("PULSEFORM_TRACEBACK"):
            raise
        text = " ".join(str(exc).split()) or "no message"
        return _error(f"internal error: {type(exc).__name__}: {text[:300]} (set PULSEFORM_TRACEBACK=1 to see "
                      "where; please report it)", EXIT_FAILED)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
