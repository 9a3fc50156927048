"""Compiled sums that round exactly like numpy's ``np.sum`` of a contiguous float64 array.

numpy sums a contiguous array in blocks of 8192 elements (its iterator's buffer), each block by
pairwise summation (8 partial sums below 128 elements, recursive halving above). The compiled
block path (:mod:`.block`) uses :func:`np_sum` for every ledger sum the Python path takes with
``np.sum``, so that both paths give the same bits.

The halving runs on an explicit stack, not by recursion: numba cannot link a cached recursive
function into a caller compiled in another process (``LLVM ERROR: Symbol not found:
.numba.unresolved$..._pairwise``, the process aborts), which happened whenever a caller of
:func:`np_sum` was compiled after ``np_sum`` itself had been cached on its own.
"""
from __future__ import annotations

import numba
import numpy as np

__all__ = ["np_sum"]

_BLOCK = 8192
_PW = 128
_STACK = 64  # halving depth of a block: log2(8192 / 64) + 1 = 8 levels; ample


@numba.njit(cache=True)
def _leaf(a, lo, n):
    """numpy's pairwise sum of a[lo:lo + n] for n <= 128 (no halving)."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0 = a[lo]
    r1 = a[lo + 1]
    r2 = a[lo + 2]
    r3 = a[lo + 3]
    r4 = a[lo + 4]
    r5 = a[lo + 5]
    r6 = a[lo + 6]
    r7 = a[lo + 7]
    i = 8
    stop = n - n % 8
    while i < stop:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@numba.njit(cache=True)
def _pairwise(a, lo, n):
    """numpy's pairwise sum of a[lo:lo + n]: above 128 elements the sum of the halves
    (n2 = n // 2 rounded down to a multiple of 8, then the rest), left + right; an explicit
    depth-first stack of (start, length, stage) frames and a stack of partial sums (no recursion)."""
    if n <= _PW:
        return _leaf(a, lo, n)
    f = np.empty((_STACK, 3), np.int64)  # frames: start, length, stage (0 new, 1 left done, 2 both)
    vals = np.empty(_STACK)  # partial sums of finished halves
    nv = 0
    top = 0
    f[0, 0] = lo
    f[0, 1] = n
    f[0, 2] = 0
    while top >= 0:
        s = f[top, 0]
        m = f[top, 1]
        if m <= _PW:
            vals[nv] = _leaf(a, s, m)
            nv += 1
            top -= 1
            continue
        m2 = m // 2
        m2 -= m2 % 8
        stage = f[top, 2]
        if stage == 0:  # the left half first
            f[top, 2] = 1
            top += 1
            f[top, 0] = s
            f[top, 1] = m2
            f[top, 2] = 0
        elif stage == 1:  # then the right half
            f[top, 2] = 2
            top += 1
            f[top, 0] = s + m2
            f[top, 1] = m - m2
            f[top, 2] = 0
        else:  # both done: left + right
            vals[nv - 2] = vals[nv - 2] + vals[nv - 1]
            nv -= 1
            top -= 1
    return vals[0]


@numba.njit(cache=True)
def np_sum(a, n):
    """Sum of the first ``n`` elements of the 1D float64 array ``a``, rounded as ``np.sum``."""
    res = 0.0
    lo = 0
    while lo < n:
        m = min(_BLOCK, n - lo)
        res += _pairwise(a, lo, m)
        lo += m
    return res
