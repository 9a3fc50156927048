"""Compiled geometry queries of the corner-fill analysis (one history row each): distances from
die points to the blank's boundary segments and the blank's speed and kinetic sums.

The point-to-segment distance rounds exactly as the numpy expressions it replaced
(``corner_fill._segment_distances`` / ``_point_segment_distance``: same operations, same order,
no fastmath); sums are left to numpy.

The bounded search (:func:`distances_within`) takes the minimum over *every* blank segment whose
midpoint lies within the bound (found through the cell-list grid of
:mod:`pulseform.solvers.dolfinx.cell_list`); the k-d tree it replaced took it over the 8 nearest
midpoints only, which can miss the nearest segment. Wherever the 8 nearest held it, both give the
same bits (checked on every history row of the three corner-fill cases).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from pulseform.solvers.dolfinx.cell_list import grid_build

__all__ = ["segment_distance", "profile_samples", "build_midpoint_grid", "distances_within", "min_distances",
           "blank_motion"]


@numba.njit(cache=True)
def segment_distance(px: float, py: float, ax: float, ay: float, bx: float, by: float) -> float:
    """Distance (m) of the point (px, py) to the segment a-b, rounded as ``_segment_distances``:
    xi = clip((p - a) . t / max(|t|^2, 1e-300), 0, 1), q = a + xi t, |p - q| with t = b - a."""
    t0 = bx - ax
    t1 = by - ay
    L2 = max(t0 * t0 + t1 * t1, 1e-300)
    xi = ((px - ax) * t0 + (py - ay) * t1) / L2
    xi = min(max(xi, 0.0), 1.0)
    d0 = px - (ax + xi * t0)
    d1 = py - (ay + xi * t1)
    return math.sqrt(d0 * d0 + d1 * d1)


@numba.njit(cache=True)
def profile_samples(x: np.ndarray, ia: np.ndarray, ib: np.ndarray, xi: np.ndarray, out: np.ndarray) -> None:
    """Points a + xi (b - a) (m) with a = x[ia[k]], b = x[ib[k]] into ``out[k]``, rounded as the
    numpy expression ``a + xi[:, None] * (b - a)``."""
    for k in range(ia.shape[0]):
        i = ia[k]
        j = ib[k]
        for c in range(2):
            out[k, c] = x[i, c] + xi[k] * (x[j, c] - x[i, c])


@numba.njit(cache=True)
def build_midpoint_grid(x: np.ndarray, segs: np.ndarray, size: float, mx: np.ndarray, my: np.ndarray,
                        head: np.ndarray, nxt: np.ndarray, meta: np.ndarray) -> None:
    """Midpoints 0.5 (x_a + x_b) (m) of the segments ``segs`` (M, 2 node rows of x) into ``mx``,
    ``my`` and their cell-list grid (cells >= ``size`` m; scratch of
    :func:`~pulseform.solvers.dolfinx.cell_list.new_grid` for M points)."""
    m = segs.shape[0]
    for s in range(m):
        i = segs[s, 0]
        j = segs[s, 1]
        mx[s] = 0.5 * (x[i, 0] + x[j, 0])
        my[s] = 0.5 * (x[i, 1] + x[j, 1])
    grid_build(mx, my, m, size, head, nxt, meta)


@numba.njit(cache=True)
def distances_within(q: np.ndarray, x: np.ndarray, segs: np.ndarray, bound: float, mx: np.ndarray,
                     my: np.ndarray, head: np.ndarray, nxt: np.ndarray, meta: np.ndarray,
                     out: np.ndarray) -> None:
    """Per point q[k] (m): the smallest distance (m) to a segment whose midpoint lies within
    ``bound`` (m) of it (``inf`` if none), over the grid of :func:`build_midpoint_grid`."""
    x0 = meta[0]
    y0 = meta[1]
    cs = meta[2]
    nx = int(meta[3])
    ny = int(meta[4])
    b2 = bound * bound
    for k in range(q.shape[0]):
        qx = q[k, 0]
        qy = q[k, 1]
        best = np.inf
        # one cell more on each side than the disc needs: no midpoint at the bound is lost to rounding
        cx0 = max(int(math.floor((qx - bound - x0) / cs)) - 1, 0)
        cx1 = min(int(math.floor((qx + bound - x0) / cs)) + 1, nx - 1)
        cy0 = max(int(math.floor((qy - bound - y0) / cs)) - 1, 0)
        cy1 = min(int(math.floor((qy + bound - y0) / cs)) + 1, ny - 1)
        for cy in range(cy0, cy1 + 1):
            for cx in range(cx0, cx1 + 1):
                s = head[cy * nx + cx]
                while s >= 0:
                    dx = mx[s] - qx
                    dy = my[s] - qy
                    if dx * dx + dy * dy <= b2:
                        i = segs[s, 0]
                        j = segs[s, 1]
                        d = segment_distance(qx, qy, x[i, 0], x[i, 1], x[j, 0], x[j, 1])
                        if best == best and not d >= best:  # a NaN sticks, as in numpy's min
                            best = d
                    s = nxt[s]
        out[k] = best


@numba.njit(cache=True)
def min_distances(q: np.ndarray, x: np.ndarray, segs: np.ndarray, out: np.ndarray) -> None:
    """Per point q[k] (m): the distance (m) to the nearest of all segments ``segs`` (``inf`` for
    none), as ``_point_segment_distance`` (NaN if a distance is NaN, as numpy's ``min``)."""
    for k in range(q.shape[0]):
        qx = q[k, 0]
        qy = q[k, 1]
        best = np.inf
        for s in range(segs.shape[0]):
            i = segs[s, 0]
            j = segs[s, 1]
            d = segment_distance(qx, qy, x[i, 0], x[i, 1], x[j, 0], x[j, 1])
            if best == best and not d >= best:  # a NaN sticks, as in numpy's min
                best = d
        out[k] = best


@numba.njit(cache=True)
def blank_motion(x: np.ndarray, v: np.ndarray, mass: np.ndarray, n: int, cx: float, cy: float,
                 radius: float, mv2: np.ndarray, mv2_near: np.ndarray) -> tuple[float, int]:
    """Speed and kinetic terms of nodes i < n (positions x m, velocities v m/s, masses kg).

    Writes m_i |v_i|^2 (kg m^2/s^2) of every node into ``mv2[:n]`` and, in node order, of the
    nodes with |x_i - c| < ``radius`` (c = (cx, cy), m) into ``mv2_near[:k]``: their numpy sums
    (``mv2[:n].sum()``) round as ``np.sum(m * np.sum(v ** 2, axis=1))`` of the arrays. (The sums
    are left to numpy: a cached numba function calling the recursive ``reductions.np_sum`` can
    fail to link in a process that compiles it after loading np_sum from the cache.)

    Returns
    -------
    speed_max : float
        Largest |v_i|, m/s (NaN if one is NaN, as numpy's ``max``).
    k : int
        Number of nodes near c.
    """
    speed = -np.inf
    k = 0
    for i in range(n):
        w = v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1]
        s = math.sqrt(w)
        if speed == speed and not s <= speed:  # a NaN sticks, as in numpy's max
            speed = s
        e = mass[i] * w
        mv2[i] = e
        dx = x[i, 0] - cx
        dy = x[i, 1] - cy
        if math.sqrt(dx * dx + dy * dy) < radius:
            mv2_near[k] = e
            k += 1
    return speed, k
