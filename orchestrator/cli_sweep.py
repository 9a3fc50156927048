"""The ``pulseform sweep`` command's arguments (the command itself: :func:`.cli._cmd_sweep`)."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_sweep_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add ``sweep`` and its arguments to the CLI's subcommands; returns its parser."""
    sweep = sub.add_parser("sweep", help="run a case over a grid or a sampled design of parameter values",
                           description="Run CASE for every combination of the --param lists (full grid), or for --sample "
                                       "N points of a Latin hypercube / Sobol design over --param ranges; each member a "
                                       "`pulseform run` in OUT/<values>_<hash>/ (the hash of its resolved case: an "
                                       "interrupted or extended study run again with --resume runs only the members it "
                                       "lacks), without pictures unless --set output.plots=true. Writes OUT/sweep.csv, "
                                       "OUT/study.json and OUT/report.md (sensitivities, response surface, best member) "
                                       "and OUT/plots/.")
    sweep.add_argument("case", metavar="CASE")
    sweep.add_argument("--param", metavar="KEY.PATH=V1,V2,...|LO:HI", action="append", required=True,
                       help="a swept key and its values, or its range lo:hi with --sample (repeatable)")
    sweep.add_argument("--sample", type=int, metavar="N", help="N members of a sampled design instead of the full grid")
    sweep.add_argument("--design", choices=("lhs", "sobol"), default="lhs",
                       help="with --sample: Latin hypercube (default) or scrambled Sobol sequence (scipy.stats.qmc)")
    sweep.add_argument("--seed", type=int, default=1, help="the sampled design's seed (default 1)")
    sweep.add_argument("--set", metavar="KEY.PATH=VALUE", action="append", default=[], dest="overrides",
                       help="override applied to every member")
    sweep.add_argument("--out", metavar="DIR", type=Path, help="sweep folder (default: results/<case>_sweep)")
    sweep.add_argument("--jobs", type=int, default=1, metavar="N",
                       help="members run at the same time (local; dask: the LocalCluster's workers; default 1)")
    sweep.add_argument("--force", action="store_true", help="replace an existing sweep folder")
    sweep.add_argument("--resume", action="store_true",
                       help="continue (or extend) the study in --out: run only the members without a result")
    sweep.add_argument("--retry-failed", action="store_true", dest="retry_failed",
                       help="with --resume: run the members that failed again")
    sweep.add_argument("--executor", choices=("local", "mpi", "dask"), default="local",
                       help="where members run: local processes (default), mpi4py.futures under mpirun, or "
                            "dask.distributed (a LocalCluster of --jobs workers, or --scheduler)")
    sweep.add_argument("--scheduler", metavar="ADDRESS|FILE",
                       help="--executor dask: a running cluster's scheduler (tcp://host:8786 or a scheduler file)")
    sweep.add_argument("--mpi", action="store_true", help="the same as --executor mpi")
    sweep.add_argument("--metric", action="append", default=[], metavar="NAME",
                       help="a metrics.json key to analyse (repeatable; default: the headline metrics the members have)")
    sweep.add_argument("--objective", metavar="max:NAME|min:NAME", help="report the best member for this metric")
    sweep.add_argument("--constraint", action="append", default=[], metavar="NAME<LIMIT",
                       help="with --objective: a member qualifies only if it holds, e.g. 'max_deflection_mm<20'")
    sweep.add_argument("--quiet", action="store_true", help="no progress bar, warnings only")
    return sweep
