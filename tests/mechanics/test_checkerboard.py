"""The checkerboard index of a cell field (orchestrator/mech/checkerboard.py) on structured tetrahedra (a box cut
into cubes of six Kuhn tetrahedra).

References: (1) a constant field departs from nothing: index 0 to round-off; (2) a smooth field (linear, the
cells' centroid values) departs from its neighbours' mean by at most O(h |grad p|): the index falls at least as h
(fitted on three meshes: rate 1.4, since inside the mesh the neighbours nearly surround a cell and only the
boundary's cells, a fraction h of them, keep the O(h) one-sided departure: h^1.5 in the RMS); (3) a field that alternates between neighbouring cells (the
smooth one times 1 ± 1/2, the sign random per cell) keeps an index of order one on every mesh."""
import numpy as np
import pytest

from pulseform.orchestrator.mech.checkerboard import checkerboard_index, face_neighbours

#: the six tetrahedra of the unit cube's Kuhn split (corner k: bits x, y, z of k)
KUHN = ((0, 1, 3, 7), (0, 1, 5, 7), (0, 2, 3, 7), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 6, 7))


def box(n: int):
    """(points, tets) of the unit cube, n^3 cubes of six tetrahedra."""
    g = np.arange(n + 1)
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()]) / n
    idx = lambda i, j, k: (i * (n + 1) + j) * (n + 1) + k  # noqa: E731
    tets = []
    for i in range(n):
        for j in range(n):
            for k in range(n):
                c = [idx(i + (q & 1), j + (q >> 1 & 1), k + (q >> 2 & 1)) for q in range(8)]
                tets += [[c[a] for a in t] for t in KUHN]
    return pts, np.array(tets)


def test_face_neighbours_of_a_cube():
    pts, tets = box(1)
    pairs = face_neighbours(tets)
    assert len(pairs) == 6   # the Kuhn cube: six tetrahedra around the diagonal, each shares two faces


def test_index_is_small_for_smooth_fields_and_large_for_checkerboards():
    rng = np.random.default_rng(0)
    smooth, alternating, hs = [], [], []
    for n in (4, 8, 16):
        pts, tets = box(n)
        c = pts[tets].mean(axis=1)
        p = 1.0 + c[:, 0] + 0.5 * c[:, 1]
        assert checkerboard_index(pts, tets, np.full(len(tets), 0.3)) == pytest.approx(0.0, abs=1e-14)
        smooth.append(checkerboard_index(pts, tets, p))
        alternating.append(checkerboard_index(pts, tets, p * (1.0 + 0.5 * rng.choice([-1.0, 1.0], len(tets)))))
        hs.append(1.0 / n)
    rate = np.polyfit(np.log(hs), np.log(smooth), 1)[0]
    print(f"\ncheckerboard index, h = 1/4, 1/8, 1/16: smooth {', '.join(f'{s:.4f}' for s in smooth)} (rate {rate:.2f}); "
          f"alternating {', '.join(f'{a:.3f}' for a in alternating)}")
    assert rate > 0.9
    assert min(alternating) > 0.3 and max(smooth) < 0.1
