"""Compiled sums that round exactly like numpy's ``np.sum`` of a contiguous float64 array.

numpy sums a contiguous array in blocks of 8192 elements (its iterator's buffer), each block by
pairwise summation (8 partial sums below 128 elements, recursive halving above). The compiled
block path (:mod:`.block`) uses :func:`np_sum` for every ledger sum the Python path takes with
``np.sum``, so that both paths give the same bits.
"""
from __future__ import annotations

import numba
import numpy as np

__all__ = ["np_sum"]

_BLOCK = 8192
_PW = 128


@numba.njit(cache=True)
def _pairwise(a, lo, n):
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    if n <= _PW:
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
    n2 = n // 2
    n2 -= n2 % 8
    return _pairwise(a, lo, n2) + _pairwise(a, lo + n2, n - n2)


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
