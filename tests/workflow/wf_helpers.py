"""Helpers of the workflow tests: run the ``pulseform`` console script as users do."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from warm_cli import pulseform_cli

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))  # the console script (runs that need a process of their own)


def pulseform(*args: str, timeout: float = 600, env: dict | None = None, cwd=None) -> subprocess.CompletedProcess:
    """``pulseform ARGS`` as users run it (a warm child unless ``env``: tests/warm_cli.py)."""
    return pulseform_cli(args, cwd=cwd, timeout=timeout, env=env)


def one_line_error(r: subprocess.CompletedProcess) -> str:
    """The CLI's error line; fails if the output holds a traceback."""
    assert "Traceback" not in r.stderr, r.stderr[-2000:]
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("pulseform: error:")]
    assert len(lines) == 1, r.stderr[-2000:]
    return lines[0]


def four_steps(solver, mesh) -> list:
    """Four 0.5 us steps of a GetDP solver (:class:`pulseform.solvers.getdp.solver.GetDPSolver`) from rest: its results."""
    state, results = solver.initial_state(0.0), []
    for k in range(1, 5):
        result, state = solver.step(mesh, state, k * 0.5e-6)
        results.append(result)
    return results


def worst_vs_plain_getdp(tmp_path: Path, deck: Path, results: list, name: str, *numbers: str) -> float:
    """Plain ``getdp deck -solve Magnetodynamics2D_av`` to 2 us on the mesh of :func:`four_steps`' ``results`` with
    the ``-setnumber`` arguments ``numbers``, in ``tmp_path / name``: the largest difference of the unknowns after
    each of the four steps, relative to the plain run's largest (the times asserted equal)."""
    from pulseform.solvers.getdp.template import read_solutions

    out = tmp_path / name
    out.mkdir()
    argv = [shutil.which("getdp"), str(deck), "-msh", str(Path(results[0].path) / "mesh.msh"),
            "-name", str(out / "plain"), *numbers, "-setnumber", "TimeFinal", "2e-6",
            "-solve", "Magnetodynamics2D_av", "-v", "2"]
    p = subprocess.run(argv, cwd=out, capture_output=True, text=True, timeout=300, check=False)
    assert p.returncode == 0 and "Error" not in p.stdout, p.stdout[-2000:]
    reference = read_solutions(out / "plain.res")
    assert len(reference) == len(results) == 4
    worst = 0.0
    for result, (t_ref, x_ref) in zip(results, reference):
        t, x = read_solutions(Path(result.path) / "em.res")[-1]
        assert t == pytest.approx(t_ref, rel=1e-12)
        worst = max(worst, float(np.abs(x - x_ref).max() / np.abs(x_ref).max()))
    return worst
