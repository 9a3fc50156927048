"""``reductions.np_sum`` rounds as ``np.sum`` and links from numba's cache into callers compiled in
another process (its halving was a recursive function: a caller compiled after ``np_sum`` alone had
been cached aborted the process with ``LLVM ERROR: Symbol not found: .numba.unresolved$..._pairwise``,
e.g. a run after a script that summed first)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np

from pulseform.solvers.dolfinx.reductions import np_sum


def test_np_sum_rounds_as_numpy():
    rng = np.random.default_rng(8)
    sizes = [*range(0, 300), 1000, 1023, 1024, 1025, 4095, 8191, 8192, 8193, 16384, 20000, 50001]
    for n in sizes:
        a = rng.standard_normal(n + 5) * 10.0 ** rng.uniform(-8, 8, n + 5)
        assert np_sum(a, n) == np.sum(a[:n]), n


_FIRST = """
import numpy as np
from pulseform.solvers.dolfinx.reductions import np_sum
assert np_sum(np.ones(300), 300) == 300.0
"""

_THEN = """
import numba
import numpy as np
from pulseform.solvers.dolfinx.reductions import np_sum

@numba.njit(cache=True)
def caller(x, n, squares, positive):  # several np_sum calls: the recursive version failed to link here
    k = 0
    for i in range(n):
        squares[i] = x[i] * x[i]
        if x[i] > 0:
            positive[k] = x[i]
            k += 1
    return np_sum(squares, n), np_sum(x, n), np_sum(positive, k)

n = 20000
x = np.random.default_rng(0).standard_normal(n)
got = caller(x, n, np.empty(n), np.empty(n))
assert got == (np.sum(x * x), np.sum(x), np.sum(x[x > 0])), got
print("ok")
"""


def test_np_sum_links_from_the_cache_into_a_new_caller(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    script = tmp_path / "then.py"  # a file: numba caches only functions defined in files
    script.write_text(_THEN)
    first = subprocess.run([sys.executable, "-c", _FIRST], env=env, capture_output=True, text=True)
    assert first.returncode == 0, first.stderr[-2000:]
    for _ in range(2):  # compiled against the cached np_sum, then everything from the cache
        r = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True)
        assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-2000:]
