"""numba's cache folder follows the compiled sources (solvers/numba_cache.py): a changed source can
never run with machine code compiled from an older one (numba keys its cache on each function's
own file only: a cached caller kept a stale callee and crashed the process, twice in this repo)."""
import os
import subprocess
import sys
import time
from pathlib import Path

from pulseform.solvers import numba_cache


def _tree(root: Path) -> None:
    (root / "solvers" / "dolfinx").mkdir(parents=True)
    (root / "orchestrator").mkdir()
    (root / "solvers" / "dolfinx" / "k.py").write_text("import numba\n@numba.njit(cache=True)\ndef f(x):\n    return x + 1\n")
    (root / "orchestrator" / "plain.py").write_text("X = 1\n")


def test_hash_follows_the_compiled_sources_only(tmp_path):
    _tree(tmp_path)
    h0 = numba_cache.source_hash(tmp_path)
    (tmp_path / "orchestrator" / "plain.py").write_text("X = 2\n")          # no numba: same cache
    assert numba_cache.source_hash(tmp_path) == h0
    (tmp_path / "solvers" / "dolfinx" / "k.py").write_text("import numba\n@numba.njit(cache=True)\ndef f(x):\n    return x + 2\n")
    h1 = numba_cache.source_hash(tmp_path)
    assert h1 != h0 and len(h1) == 16
    (tmp_path / "orchestrator" / "plain.py").write_text("import numba\nY = 1\n")  # now compiled code
    assert numba_cache.source_hash(tmp_path) not in (h0, h1)


def _run(code: str, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)


def test_the_package_caches_in_the_folder_of_its_sources(tmp_path):
    """A process of pulseform compiles into $XDG_CACHE_HOME/pulseform/numba/<hash of its sources>;
    a child started with the parent's setting recomputes it; a user's NUMBA_CACHE_DIR wins."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", numba_cache._MARK)}
    env["XDG_CACHE_HOME"] = str(tmp_path / "home")
    code = ("import os\nfrom pulseform.solvers.dolfinx.cell_list import new_grid\n"
            "from pulseform.solvers.dolfinx.reductions import np_sum\nimport numpy as np\n"
            "print(np_sum(np.arange(5.0), 5))\nprint(os.environ['NUMBA_CACHE_DIR'])\n")
    r = _run(code, env)
    assert r.returncode == 0, r.stderr
    total, folder = r.stdout.split()
    assert float(total) == 10.0
    root = Path(numba_cache.__file__).resolve().parents[1]
    assert Path(folder) == tmp_path / "home" / "pulseform" / "numba" / numba_cache.source_hash(root)
    assert list(Path(folder).rglob("*.nbi")), "numba wrote no cache index into the folder"
    env_child = dict(env, NUMBA_CACHE_DIR=folder, **{numba_cache._MARK: folder})
    env_child["XDG_CACHE_HOME"] = str(tmp_path / "other")                   # recomputed, not inherited
    r = _run("import os, pulseform.solvers\nprint(os.environ['NUMBA_CACHE_DIR'])", env_child)
    assert r.stdout.strip() == str(tmp_path / "other" / "pulseform" / "numba" / Path(folder).name)
    user = str(tmp_path / "mine")
    r = _run("import os, pulseform.solvers\nprint(os.environ['NUMBA_CACHE_DIR'])", dict(env, NUMBA_CACHE_DIR=user))
    assert r.stdout.strip() == user


def test_old_cache_folders_are_pruned_but_recent_ones_kept(tmp_path):
    base = tmp_path / "pulseform" / "numba"
    old = []
    for i in range(numba_cache.KEEP + 3):
        d = base / f"{i:016x}"
        d.mkdir(parents=True)
        t = time.time() - (i + 1) * 2 * numba_cache.STALE_S                # all long unused
        os.utime(d, (t, t))
        old.append(d)
    recent = base / ("f" * 16)
    recent.mkdir()                                                          # used just now
    foreign = base / "notes"
    foreign.mkdir()                                                         # not one of ours
    os.utime(foreign, (0, 0))
    current = base / ("e" * 16)
    current.mkdir()
    numba_cache._prune(base, current)
    kept = sorted(p.name for p in base.iterdir())
    assert recent.name in kept and current.name in kept and "notes" in kept
    assert [d.name for d in old if d.exists()] == [d.name for d in old[:numba_cache.KEEP - 1]]
