"""The ``pulseform`` command line. Only this module prints.

Exit codes: 0 success, 1 a run that started and failed, 2 bad input (case file, overrides, usage).
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from . import __version__

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


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

    sweep = sub.add_parser("sweep", help="run a case over a grid of parameter values",
                           description="Run CASE for every combination of the --param values (full grid); "
                                       "each member is its own `pulseform run` process in OUT/<member>/. "
                                       "Writes OUT/sweep.csv and OUT/plots/sweep_*.png.")
    sweep.add_argument("case", metavar="CASE")
    sweep.add_argument("--param", metavar="KEY.PATH=V1,V2,...", action="append", required=True,
                       help="a swept key and its values (repeatable: full grid)")
    sweep.add_argument("--set", metavar="KEY.PATH=VALUE", action="append", default=[], dest="overrides",
                       help="override applied to every member")
    sweep.add_argument("--out", metavar="DIR", type=Path, help="sweep folder (default: results/<case>_sweep)")
    sweep.add_argument("--jobs", type=int, default=1, metavar="N", help="members run at the same time (default 1)")
    sweep.add_argument("--force", action="store_true", help="replace an existing sweep folder")

    sub.add_parser("info", help="versions and locations of getdp, gmsh, dolfinx, PETSc, meshio, numpy",
                   description="Print the versions of the external programs and libraries and where each comes from.")
    return p


class _ConsoleFilter(logging.Filter):
    """pulseform's own records from INFO (WARNING with --quiet); other libraries' from WARNING."""

    def __init__(self, quiet: bool) -> None:
        super().__init__()
        self.own_level = logging.WARNING if quiet else logging.INFO

    def filter(self, record: logging.LogRecord) -> bool:
        if record.name == "pulseform" or record.name.startswith("pulseform."):
            return record.levelno >= self.own_level
        return record.levelno >= logging.WARNING


def _setup_logging(quiet: bool) -> None:
    """One console handler on the root logger. Installed before dolfinx is imported, it also
    turns FFCx's ``logging.basicConfig()`` into a no-op, so JIT compiler chatter stays off the
    terminal (it still reaches run.log)."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(levelname)s: %(message)s"))
    handler.addFilter(_ConsoleFilter(quiet))
    logging.getLogger().addHandler(handler)
    logging.getLogger("pulseform").setLevel(logging.INFO)


def _error(msg: str, code: int) -> int:
    print(f"pulseform: error: {msg}", file=sys.stderr)
    return code


def _cmd_run(args: argparse.Namespace) -> int:
    from .caseio import CaseError, load_case
    from .results import ResultsExistError

    try:
        case, _ = load_case(args.case, args.overrides)
    except CaseError as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    out = args.out or Path("results") / case.case.name
    from .runner import ResumeError, RunFailed, run_case  # heavy imports (dolfinx) only when running

    try:
        metrics = run_case(case, out, force=args.force, resume=args.resume, quiet=args.quiet)
    except (ResultsExistError, ResumeError) as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    except RunFailed as exc:
        return _error(str(exc), EXIT_FAILED)
    if not args.quiet:
        print(f"results: {out}")
        for k in sorted(metrics):
            print(f"  {k} = {metrics[k]:.6g}")
    return EXIT_OK


def _cmd_check(args: argparse.Namespace) -> int:
    from .caseio import CaseError, case_to_toml, load_case

    try:
        case, file = load_case(args.case, args.overrides)
    except CaseError as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    print(f"# {file}: valid")
    print(case_to_toml(case), end="")
    return EXIT_OK


def _cmd_sweep(args: argparse.Namespace) -> int:
    from .caseio import CaseError, load_case
    from .results import ResultsExistError
    from .sweep import run_sweep

    if args.jobs < 1:
        return _error(f"--jobs: got {args.jobs}; must be >= 1", EXIT_BAD_INPUT)
    try:
        case, _ = load_case(args.case, args.overrides)
        out = args.out or Path("results") / f"{case.case.name}_sweep"
        todo = run_sweep(args.case, args.param, out, jobs=args.jobs, force=args.force, overrides=args.overrides)
    except (CaseError, ResultsExistError) as exc:
        return _error(str(exc), EXIT_BAD_INPUT)
    keys = list(todo[0].values)
    shown = ("max_deflection_mm", "force_impulse_Ns", "em_time_s", "mech_time_s", "wall_time_s")
    print("  ".join(f"{k:>14}" for k in keys + ["status", *shown]))
    for m in todo:
        status = "ok" if m.returncode == 0 else f"FAILED({m.returncode})"
        vals = [f"{m.metrics[k]:14.6g}" if k in m.metrics else f"{'-':>14}" for k in shown]
        print("  ".join([f"{m.values[k]:>14}" for k in keys] + [f"{status:>14}"] + vals))
    failed = [m for m in todo if m.returncode != 0]
    for m in failed:
        print(f"member {m.index} ({' '.join(m.overrides)}): {m.error}", file=sys.stderr)
    print(f"table: {out / 'sweep.csv'}")
    return EXIT_FAILED if failed else EXIT_OK


def _cmd_info(_: argparse.Namespace) -> int:
    from .info import collect

    for row in collect():
        print(f"{row.name:<10} {row.version:<28} {row.location}  [{row.source}]")
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``pulseform`` console script."""
    args = _parser().parse_args(argv)
    _setup_logging(getattr(args, "quiet", False))
    handlers = {"run": _cmd_run, "check": _cmd_check, "sweep": _cmd_sweep, "info": _cmd_info}
    try:
        return handlers[args.command](args)
    except KeyboardInterrupt:
        return _error("interrupted", EXIT_FAILED)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
