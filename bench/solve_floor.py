"""The floor of an EM step's linear algebra, measured on GetDP's own system: getdp writes the matrix and
right-hand side of its solves (PETSc's ``-ksp_view_mat`` / ``-ksp_view_rhs``, binary; the last solve's
stay), and petsc4py factorises and solves them here with the same direct solver, timed in this process.

Used by bench/em_step.py (2D, UMFPACK) and bench/em_step3d.py (3D, MUMPS) to print the persistent getdp's
EM step with kept factors and with a factorisation per step against a bare factorisation + solve of the
same system outside GetDP (the issue's "floor"), and one solve with kept factors (what a correction adds).
"""
from __future__ import annotations

import statistics
import time
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc


def view_args(folder: Path) -> tuple[str, ...]:
    """PETSc options that make getdp write the matrix and right-hand side of each solve into ``folder``."""
    return ("-ksp_view_mat", f"binary:{Path(folder) / 'A.bin'}", "-ksp_view_rhs", f"binary:{Path(folder) / 'b.bin'}")


def _load(path: Path, kind):
    viewer = PETSc.Viewer().createBinary(str(path), "r", comm=MPI.COMM_SELF)
    obj = kind().create(MPI.COMM_SELF)
    obj.load(viewer)
    viewer.destroy()
    return obj


def _options(petsc_args) -> dict[str, str]:
    """``-name value`` pairs of getdp's PETSc command line (a flag without a value gets "")."""
    args, out, i = list(petsc_args), {}, 0
    while i < len(args):
        name = args[i].lstrip("-")
        value = args[i + 1] if i + 1 < len(args) and not args[i + 1].startswith("-") else ""
        out[name] = value
        i += 2 if value else 1
    return out


def floor_times(folder: Path, petsc_args, repeat: int = 3) -> dict[str, float]:
    """Median wall times (s) on the system written by :func:`view_args` into ``folder``, with getdp's own
    direct solver and its options (``petsc_args``, e.g. ``DEFAULT_PETSC_ARGS_3D``): ``factor_solve`` (the LU
    factorisation + one solve, the fresh step's linear algebra), ``solve`` (one more solve with those factors,
    of a dense right-hand side: what a GCR iteration applies; the system's own b is sparse, and a direct
    solver's iterative refinement stops at once on it), ``matvec`` (one product A x: a residual), and ``n``
    the unknowns."""
    A = _load(Path(folder) / "A.bin", PETSc.Mat)
    b = _load(Path(folder) / "b.bin", PETSc.Vec)
    x = b.duplicate()
    dense = b.duplicate()
    dense.setRandom()
    opts = PETSc.Options()
    given = _options(petsc_args)
    out: dict[str, list[float]] = {"factor_solve": [], "solve": [], "matvec": []}
    for _ in range(repeat):
        for name, value in given.items():
            opts[name] = value
        ksp = PETSc.KSP().create(MPI.COMM_SELF)
        ksp.setOperators(A)
        ksp.setFromOptions()
        for name in given:
            opts.delValue(name)
        c0 = time.perf_counter()
        ksp.solve(b, x)
        c1 = time.perf_counter()
        ksp.solve(dense, x)
        c2 = time.perf_counter()
        A.mult(x, b.duplicate())
        c3 = time.perf_counter()
        out["factor_solve"].append(c1 - c0)
        out["solve"].append(c2 - c1)
        out["matvec"].append(c3 - c2)
        ksp.destroy()
    res = {k: statistics.median(v) for k, v in out.items()}
    res["n"] = float(A.getSize()[0])
    return res
