"""Shared fixtures. Markers (slow, getdp, mpi, docs) are defined once, in pyproject.toml."""

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo() -> Path:
    """The repository root."""
    return REPO


@pytest.fixture(scope="session")
def sector_compare(tmp_path_factory):
    """``pulseform compare`` of the coarse 3D sector (tests/coupling/sector_case.py: 5 degrees, 3 us) with the
    loaded surface ``SURFACE`` and two --fail-if conditions, one that cannot hold and one that must (exit 1
    naming the second), run once per session (by the first xdist worker that asks: tests/worker_share.py): (out folder, compare.json, the finished
    process). Its coupled run ``out / "coupled"`` is the coarse sector's ``pulseform run`` (the same command
    and overrides, plus --force), shared by tests/workflow/test_compare_3d.py and
    tests/coupling/test_case_3d_sector.py. A study's members skip their pictures unless asked
    (orchestrator/run/warm.py): ``output.plots=true`` here, the driver's pictures are tested on this run."""
    import json
    import subprocess
    import sys

    from coupling.sector_case import CASE, COARSE, SURFACE, sets
    from worker_share import once

    argv = [str(Path(sys.executable).with_name("pulseform")), "compare", str(CASE), "--out", "c",
            *sets(COARSE + ["output.plots=true"]), "--surface", SURFACE, "--body", "sheet", "--fail-if", "impulse_rel_diff>1e9",
            "--fail-if", "wall_time_coupled_s>0.001"]

    def make(folder: Path) -> dict:
        r = subprocess.run(argv, cwd=folder, capture_output=True, text=True, timeout=600)
        return {"returncode": r.returncode, "stdout": r.stdout, "stderr": r.stderr}

    folder, info = once(tmp_path_factory, "sector_compare " + " ".join(argv[1:]), make)
    r = subprocess.CompletedProcess(argv, info["returncode"], info["stdout"], info["stderr"])
    print(r.stdout, r.stderr[-2000:])
    out = folder / "c"
    return out, json.loads((out / "compare.json").read_text()), r
