"""Compiled bucket (cell-list) search: the k nearest points within a radius.

Replaces the k-d tree that the contact pass rebuilt from Python every step. The grid is built in
O(points + cells) into preallocated arrays; a query scans the cells overlapping the search disc.
"""
from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["new_grid", "grid_build", "grid_nearest"]



def new_grid(max_points: int):
    """Scratch of a grid holding up to ``max_points`` points: (head, next, meta) arrays.

    ``meta`` holds [x0, y0, cell size, nx, ny]; at most 4 max_points + 16 cells are used.
    """
    ncell = 4 * max(max_points, 1) + 16
    return (np.full(ncell, -1, np.int64), np.full(max(max_points, 1), -1, np.int64), np.zeros(5))


@numba.njit(cache=True)
def grid_build(px, py, n, size, head, nxt, meta):
    """Bucket the points (px[i], py[i]), i < n, into square cells of side >= ``size`` (m).

    The cell side is doubled until the grid fits into ``head``. Points of a cell are linked in
    ``nxt`` (-1 ends a list).
    """
    x0 = 1e300
    y0 = 1e300
    x1 = -1e300
    y1 = -1e300
    for i in range(n):
        x0 = min(x0, px[i])
        y0 = min(y0, py[i])
        x1 = max(x1, px[i])
        y1 = max(y1, py[i])
    cs = size if size > 0.0 else 1.0
    if n > 0:
        span = max(x1 - x0, y1 - y0)
        if not span < 1e300:
            span = 0.0
        cs = max(cs, span * 1e-12, 1e-300)
    cap = head.shape[0]
    while True:
        nx = int(math.floor((x1 - x0) / cs)) + 1 if n > 0 else 1
        ny = int(math.floor((y1 - y0) / cs)) + 1 if n > 0 else 1
        if nx * ny <= cap:
            break
        cs *= 2.0
    for c in range(nx * ny):
        head[c] = -1
    for i in range(n - 1, -1, -1):
        cx = int(math.floor((px[i] - x0) / cs))
        cy = int(math.floor((py[i] - y0) / cs))
        c = min(cy, ny - 1) * nx + min(cx, nx - 1)
        nxt[i] = head[c]
        head[c] = i
    meta[0] = x0
    meta[1] = y0
    meta[2] = cs
    meta[3] = nx
    meta[4] = ny


@numba.njit(cache=True)
def grid_nearest(qx, qy, radius, px, py, head, nxt, meta, k, out_idx, out_d2):
    """Indices of up to ``k`` points nearest (qx, qy) with distance <= ``radius``, nearest first.

    Writes them into ``out_idx`` / squared distances into ``out_d2``; returns their number.
    """
    x0 = meta[0]
    y0 = meta[1]
    cs = meta[2]
    nx = int(meta[3])
    ny = int(meta[4])
    r2 = radius * radius
    cx0 = int(math.floor((qx - radius - x0) / cs))
    cx1 = int(math.floor((qx + radius - x0) / cs))
    cy0 = int(math.floor((qy - radius - y0) / cs))
    cy1 = int(math.floor((qy + radius - y0) / cs))
    if cx1 < 0 or cy1 < 0 or cx0 >= nx or cy0 >= ny:
        return 0
    cx0 = max(cx0, 0)
    cy0 = max(cy0, 0)
    cx1 = min(cx1, nx - 1)
    cy1 = min(cy1, ny - 1)
    m = 0
    for cy in range(cy0, cy1 + 1):
        for cx in range(cx0, cx1 + 1):
            j = head[cy * nx + cx]
            while j >= 0:
                dx = px[j] - qx
                dy = py[j] - qy
                d2 = dx * dx + dy * dy
                if d2 <= r2 and (m < k or d2 < out_d2[m - 1]):
                    if m < k:
                        m += 1
                    pos = m - 1
                    while pos > 0 and out_d2[pos - 1] > d2:
                        out_d2[pos] = out_d2[pos - 1]
                        out_idx[pos] = out_idx[pos - 1]
                        pos -= 1
                    out_d2[pos] = d2
                    out_idx[pos] = j
                j = nxt[j]
    return m
