"""Fill numba's on-disk cache before the test tier starts, when it is cold (``scripts/test.sh``).

The kernels are ``@numba.njit(cache=True)``: compiled once, they are loaded from the cache folder of the
current sources (``solvers/numba_cache.py``) by every later process. On a cold cache (a fresh clone, CI, or any
edit of a source that uses numba) the tier's two workers start with the same kind of test (2D cases) and each
compiles the same kernels at the same time (~55 s of CPU for the 2D family), and so do the CLI runs they start
before either has written the cache. Here, when the cache lacks the 2D or the 3D kernels, two processes (one per
family, in parallel) run a few short cases in-process (``pulseform run``, no pictures) so that each family is
compiled once; the tier's processes then load it. A warm cache: nothing is run (~0.4 s of CPU to find out).
"Cold" includes a cache whose index files are stale: numba keys them on each source file's modification time, so
a fresh checkout of unchanged sources recompiles everything (the folder, named by the sources' contents, exists).

``python tests/numba_prewarm.py``: check and warm; ``--family 2d|3d``: run one family's cases (the children).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

#: short runs that compile each family's kernels (explicit steps, contact, pulse loads, compiled blocks, probes,
#: the analyses' helpers); the tests' many variants compile what is left
_SHORT = ["--set", "output.plots=false"]
FAMILIES: dict[str, list[list[str]]] = {
    "2d": [
        ["cases/corner_fill", "--set", "bodies.die.mesh_size=4e-3", "--set", "time.end=2e-5",
         "--set", "output.field_interval=1e-5"],
        ["cases/tube_press_fit", "--set", "bodies.inner.mesh_size=5e-4", "--set", "bodies.outer.mesh_size=5e-4",
         "--set", "time.end=2e-5", "--set", "output.field_interval=1e-5"],
        ["cases/bar_impact", "--set", "time.end=4e-5", "--set", "output.field_interval=2e-5"],
    ],
    "3d": [
        ["cases/bar_impact_3d", "--set", "time.end=4e-5", "--set", "output.field_interval=2e-5"],
        ["cases/bar_impact_3d/two_bodies.toml", "--set", "time.end=4e-5", "--set", "output.field_interval=2e-5"],
    ],
}


def _fresh(index: Path, source: Path, version: str) -> bool:
    """Whether numba would use the index file ``index``: its numba version and its source stamp (the source file's
    modification time and size, numba's ``IndexDataCacheFile._load_index``) are the current ones. A checkout
    (a new worktree, a branch switched) gives the sources new times: the cache folder (named by their contents)
    is the same, but numba recompiles every kernel of a file whose time changed."""
    import pickle

    try:
        with open(index, "rb") as f:
            if pickle.load(f) != version:
                return False
            stamp, _ = pickle.loads(f.read())
        st = source.stat()
    except Exception:  # unreadable or of another layout: treat as cold
        return False
    return tuple(stamp) == (st.st_mtime, st.st_size)


def cold_families() -> list[str]:
    """The families whose main kernel has no fresh index file in numba's cache folder for this checkout (found the
    way numba's cache locators name it, without importing the kernels: ~0.4 s)."""
    import pulseform.solvers  # points NUMBA_CACHE_DIR at the current sources' folder (solvers/numba_cache.py)
    import numba
    from numba.core.caching import _CacheLocator

    out = []
    for family, stem, fn in (("2d", "kernels", "element_critical_dt"), ("3d", "tet_kernel", "tet_critical_dt")):
        py = Path(pulseform.solvers.__file__).parent / "dolfinx" / f"{stem}.py"
        if numba.config.CACHE_DIR:
            folder = Path(numba.config.CACHE_DIR) / _CacheLocator.get_suitable_cache_subpath(str(py))
        else:  # numba's default: __pycache__ beside the sources
            folder = py.parent / "__pycache__"
        if not any(_fresh(index, py, numba.__version__) for index in folder.glob(f"{stem}.{fn}-*.nbi")):
            out.append(family)
    return out


def run_family(family: str) -> None:
    from pulseform.orchestrator.cli import main

    with tempfile.TemporaryDirectory(prefix=f"pulseform-prewarm-{family}-") as tmp:
        for k, (case, *sets) in enumerate(FAMILIES[family]):
            rc = main(["run", str(REPO / case), "--out", str(Path(tmp) / str(k)), "--quiet", "--force", *sets, *_SHORT])
            if rc:  # not fatal: the tests compile what is missing (and report what fails)
                print(f"pulseform prewarm: {case} exit {rc}", file=sys.stderr)


def main() -> int:
    if sys.argv[1:2] == ["--family"]:
        run_family(sys.argv[2])
        return 0
    t0 = time.perf_counter()
    cold = cold_families()
    if not cold:
        return 0
    env = dict(os.environ, OMP_NUM_THREADS="1")
    procs = [subprocess.Popen([sys.executable, __file__, "--family", f], env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True) for f in cold]
    outs = [p.communicate() for p in procs]  # the runs' warnings: shown only where a family's process failed
    for p, (_, err) in zip(procs, outs):
        if p.returncode or "prewarm:" in err:
            print(err[-3000:], file=sys.stderr)
    print(f"pulseform prewarm: numba cache was cold ({', '.join(cold)}): compiled in {time.perf_counter() - t0:.0f} s",
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
