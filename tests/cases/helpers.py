"""Run paper cases through ``pulseform run`` (subprocesses, several at once) for the case tests."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from warm_cli import pulseform_cli

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))

# coarse corner-fill meshes for the default tier: the blank keeps its 0.5 mm cells (two layers
# through the 1 mm thickness: one layer of linear triangles locks in bending and moved the fill
# threshold above 30 MPa), the die goes from 2 mm to 4 mm cells
CORNER_COARSE = ["--set", "bodies.die.mesh_size=4e-3"]
# coarse press-fit meshes: 0.5 mm cells (4 through the inner tube's 2 mm wall) instead of 0.25 mm
TUBE_COARSE = ["--set", "bodies.inner.mesh_size=5e-4", "--set", "bodies.outer.mesh_size=5e-4"]


def run_many(jobs: dict[str, tuple[str, list[str]]], root: Path) -> dict[str, dict]:
    """Run ``{label: (case folder, extra args)}`` one after the other (label: a folder name under ``root``);
    metrics.json per label (asserts exit 0).

    Not concurrently: the tests already run on every core (pytest-xdist), and on a cold numba cache (a fresh
    clone, CI) concurrent runs would each compile the same kernels; one after the other, the first compiles and
    the rest load its cache."""
    results = {}
    for label, (case, extra) in jobs.items():
        out = root / label
        p = pulseform_cli(["run", str(REPO / case), "--out", str(out), "--quiet", "--force", *extra])
        assert p.returncode == 0, f"{label}: exit {p.returncode}\n{p.stderr[-3000:]}"
        results[label] = json.loads((out / "metrics.json").read_text())
        results[label]["_out"] = str(out)
    return results


def tube_clearance(c_percent: float) -> list[str]:
    """--set arguments for a radial clearance of c % of R0 (studies/tube_press_fit/clearance_sweep.py)."""
    from pulseform.orchestrator.run.analyses.tube_press_fit import outer_sets

    return outer_sets(c_percent)
