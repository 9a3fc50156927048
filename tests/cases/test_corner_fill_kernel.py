"""The corner-fill analysis's compiled queries (analyses/corner_fill_kernel.py) give the bits of the
numpy expressions they replaced: point-to-segment distances, the bounded search (against a brute
force over every segment whose midpoint is within the bound), the blank's speed and kinetic sums,
the die's largest von Mises stress, and the driver's per-body extremes of every history row."""

from __future__ import annotations

import numpy as np

from pulseform.orchestrator.run.analyses.corner_fill import _point_segment_distance, _segment_distances
from pulseform.orchestrator.run.analyses.corner_fill_kernel import (blank_motion, build_midpoint_grid,
                                                                distances_within, min_distances)
from pulseform.solvers.dolfinx.cell_fields import nodal_extremes, von_mises, von_mises_max
from pulseform.solvers.dolfinx.cell_list import new_grid


def _boundary(rng: np.random.Generator, n: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """A wavy closed polyline of n nodes (m), segments of uneven length, and its segments."""
    s = np.sort(rng.uniform(0.0, 2 * np.pi, n))
    r = 0.05 + 0.004 * np.sin(7 * s) + rng.uniform(0, 1e-3, n)
    x = np.column_stack([r * np.cos(s), 0.3 * r * np.sin(s)])
    segs = np.column_stack([np.arange(n), (np.arange(n) + 1) % n]).astype(np.int64)
    return x, segs


def test_min_distances_bitwise_as_numpy():
    rng = np.random.default_rng(1)
    x, segs = _boundary(rng)
    q = rng.uniform(-0.06, 0.06, (300, 2))
    q[:20] = x[segs[:20, 0]]  # on a node
    q[20:40] = 0.5 * (x[segs[20:40, 0]] + x[segs[20:40, 1]])  # on a segment
    out = np.empty(len(q))
    min_distances(q, x, segs, out)
    ref = _point_segment_distance(q, x[segs[:, 0]], x[segs[:, 1]])
    assert np.array_equal(out, ref)
    # against the (P, K) form too, each point with its own K segments
    j = rng.integers(0, len(segs), (len(q), 8))
    ref_k = _segment_distances(q, x[segs[j, 0]], x[segs[j, 1]]).min(axis=1)
    got_k = np.empty(len(q))
    for k in range(len(q)):
        one = np.empty(1)
        min_distances(q[k:k + 1], x, segs[j[k]], one)
        got_k[k] = one[0]
    assert np.array_equal(got_k, ref_k)


def test_bounded_search_is_the_minimum_over_midpoints_within_the_bound():
    rng = np.random.default_rng(2)
    x, segs = _boundary(rng)
    a, b = x[segs[:, 0]], x[segs[:, 1]]
    mids = 0.5 * (a + b)
    q = np.vstack([rng.uniform(-0.06, 0.06, (400, 2)), mids[:50] + rng.normal(0, 2e-4, (50, 2))])
    for bound in (3e-4, 2e-3, 1e-2):
        mx, my, grid = np.empty(len(segs)), np.empty(len(segs)), new_grid(len(segs))
        build_midpoint_grid(x, segs, bound, mx, my, *grid)
        assert np.array_equal(mx, mids[:, 0]) and np.array_equal(my, mids[:, 1])
        out = np.empty(len(q))
        distances_within(q, x, segs, bound, mx, my, *grid, out)
        d_mid = np.sqrt(((q[:, None, :] - mids[None]) ** 2).sum(axis=2))
        shape = (len(q), len(segs), 2)
        d_seg = _segment_distances(q, np.broadcast_to(a, shape), np.broadcast_to(b, shape))
        ref = np.where(d_mid <= bound, d_seg, np.inf).min(axis=1)
        assert np.array_equal(out, ref), bound
        assert np.isfinite(out).any()
        if bound < 1e-2:
            assert np.isinf(out).any()


def test_blank_motion_bitwise_as_numpy():
    rng = np.random.default_rng(3)
    n = 20000  # more than one of numpy's 8192-element summation blocks
    x = rng.uniform(-0.1, 0.1, (n + 7, 2))
    v = rng.normal(0, 50, (n + 7, 2))
    mass = rng.uniform(1e-6, 1e-4, n + 7)
    c = np.array([0.01, -0.02])
    mv2, near = np.empty(n), np.empty(n)
    speed, k = blank_motion(x, v, mass, n, c[0], c[1], 0.03, mv2, near)
    x, v, mass = x[:n], v[:n], mass[:n]
    assert speed == float(np.sqrt((v ** 2).sum(axis=1)).max())
    assert mv2[:n].sum() == (mass * (v ** 2).sum(axis=1)).sum()
    sel = np.linalg.norm(x - c[None], axis=1) < 0.03
    assert 0 < k == sel.sum() < n
    assert near[:k].sum() == (mass[sel] * (v[sel] ** 2).sum(axis=1)).sum()
    v[5] = np.nan
    assert np.isnan(blank_motion(x, v, mass, n, c[0], c[1], 0.03, mv2, near)[0])


def test_von_mises_max_bitwise():
    rng = np.random.default_rng(4)
    stress = rng.normal(0, 3e8, (5000, 4))
    assert von_mises_max(stress) == float(von_mises(stress).max())
    stress[17, 2] = np.nan
    assert np.isnan(von_mises_max(stress))


def test_history_row_extremes_bitwise_as_numpy():
    """extremes.body_extremes / max_von_mises: the compiled passes give numpy's bits."""
    from pulseform.orchestrator.run.extremes import max_von_mises

    rng = np.random.default_rng(7)
    stress = rng.normal(0, 3e8, (7000, 4))
    tr = stress[:, 0] + stress[:, 1] + stress[:, 2]
    q = np.einsum("ij,ij->i", stress, stress) + stress[:, 3] * stress[:, 3] - tr * tr / 3.0
    assert max_von_mises(stress) == float(np.sqrt(1.5 * max(float(q.max()), 0.0)))
    X0 = rng.uniform(-0.1, 0.1, (9000, 2))
    x = X0 + rng.normal(0, 1e-3, X0.shape)
    v = rng.normal(0, 30, X0.shape)
    n = 8500
    u = x - X0
    got = nodal_extremes(x, X0, v, n)
    assert got == (float(np.abs(u[:n, 0]).max()), float(np.abs(u[:n, 1]).max()),
                   float(np.sqrt((v[:n] ** 2).sum(axis=1)).max()))
    v[3, 1] = np.nan
    assert np.isnan(nodal_extremes(x, X0, v, n)[2])
