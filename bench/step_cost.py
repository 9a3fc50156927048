"""Wall time per explicit step on the case meshes of ``cases/corner_fill`` and
``cases/tube_press_fit``, split into the element work (the compiled element kernel over every
cell of every body, timed alone on the same state) and everything else (time integration, force
scatter, soft contact search and forces, walls, ledger, Python per block), and their ratio
(per-step cost / element work), all measured in one run.

Each case runs from its initial state (the pulse load of the case applied as held nodal forces,
so that the blank moves and the contact is active when it reaches the die) in blocks of
``--block`` steps through ``ExplicitSolver.advance``, alternately with the kernel-alone timing,
``--rounds`` times; the best round of each is reported (the machine is shared).

Usage: .venv/bin/python bench/step_cost.py [--steps 2000] [--block 50] [--rounds 5] [--python]

``--python`` also times the Python step loop (``compiled_steps=False``) for comparison.
Targets (issue 15): per-step cost <= 2x the element work; <= 0.25 ms per step on corner fill.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.mech.model import build_solver
from pulseform.orchestrator.mech.pulses import box_marker
from pulseform.solvers.dolfinx import ExplicitSolver
from pulseform.solvers.dolfinx.kernels import WORK_SIZE, element_step

REPO = Path(__file__).resolve().parents[1]
CASES = ("corner_fill", "tube_press_fit")


def _forces(solver: ExplicitSolver, case) -> dict:
    """The case's pulse loads at their amplitude as held nodal forces (N) on the initial faces."""
    out: dict = {}
    for ld in case.loads:
        f = solver.pressure_nodal_forces(ld.body, box_marker(ld.surface), ld.amplitude)
        out[ld.body] = out[ld.body] + f if ld.body in out else f
    return out


def kernel_time(solver: ExplicitSolver, reps: int) -> float:
    """Wall time (s) of one element-kernel pass over every body's cells on the current state."""
    dt = solver.stable_time_step()
    work = []
    for n, b in solver.bodies.items():
        work.append((b, solver._prm[n], b.cell_stress.copy(), b.eps_p.copy(), np.zeros_like(b.v)))
    acc = np.zeros(3)
    scratch = np.empty(WORK_SIZE)
    t0 = time.perf_counter()
    for _ in range(reps):
        for b, prm, st, ep, f in work:
            f[:] = 0.0
            element_step(b.cells, b.x, b.v, dt, prm, st, ep, f, acc, scratch, np.empty(0))
    return (time.perf_counter() - t0) / reps


def step_time(solver: ExplicitSolver, forces: dict, steps: int, block: int) -> float:
    """Wall time (s) per explicit step over ``steps`` steps in blocks of ``block``."""
    dt = solver.stable_time_step()
    t0 = time.perf_counter()
    done = 0
    while done < steps:
        k = min(block, steps - done)
        solver.advance(dt, k, forces)
        done += k
    return (time.perf_counter() - t0) / steps


def measure(name: str, steps: int, block: int, rounds: int, python: bool) -> dict:
    case, _ = load_case(REPO / "cases" / name)
    solver = build_solver(case)
    forces = _forces(solver, case)
    cells = sum(len(b.cells) for b in solver.bodies.values())
    solver.advance(solver.stable_time_step(), 2, forces)          # compile / warm up
    kernel_time(solver, 2)
    best_step, best_kern = np.inf, np.inf
    for _ in range(rounds):
        best_step = min(best_step, step_time(solver, forces, steps // rounds, block))
        best_kern = min(best_kern, kernel_time(solver, max(20, steps // rounds // 4)))
    out = {"cells": cells, "step": best_step, "kernel": best_kern, "steps": solver.step_count,
           "in_contact": sum(len(solver.contact_pressure(i)[0])
                             for i in range(len(solver.contact_pairs)))}
    if python:
        ref = build_solver(case, compiled_steps=False)
        fref = _forces(ref, case)
        ref.advance(ref.stable_time_step(), 2, fref)
        out["python_step"] = step_time(ref, fref, max(50, steps // 20), block)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000, help="steps per case (all rounds)")
    ap.add_argument("--block", type=int, default=50, help="steps per advance() call")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--python", action="store_true", help="also time the Python step loop")
    a = ap.parse_args()
    worst = 0.0
    corner_ms = np.nan
    for name in CASES:
        r = measure(name, a.steps, a.block, a.rounds, a.python)
        ratio = r["step"] / r["kernel"]
        worst = max(worst, ratio)
        if name == "corner_fill":
            corner_ms = r["step"] * 1e3
        print(f"{name}: {r['cells']} cells, {r['steps']} steps, {r['in_contact']} nodes in contact "
              f"at the end; per step {r['step'] * 1e3:.4f} ms = element work "
              f"{r['kernel'] * 1e3:.4f} ms + everything else "
              f"{(r['step'] - r['kernel']) * 1e3:.4f} ms; per-step / element = {ratio:.2f}"
              + (f"; Python step loop {r['python_step'] * 1e3:.4f} ms "
                 f"({r['python_step'] / r['step']:.1f}x)" if "python_step" in r else ""))
    print(f"corner_fill per step {corner_ms:.4f} ms (target 0.25)")
    print(f"bench: step_cost per_step_over_element={worst:.2f} target=2.0")


if __name__ == "__main__":
    main()
