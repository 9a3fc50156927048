"""Small structured triangle meshes for tests (numpy only)."""

import numpy as np


def rect_mesh(nx: int, ny: int, x0=0.0, x1=1.0, y0=0.0, y1=1.0, jitter: float = 0.0, seed: int = 0):
    """(x, cells) of a rectangle split into 2·nx·ny counter-clockwise triangles."""
    xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    x = np.stack([X.ravel(), Y.ravel()], axis=1)
    if jitter:
        rng = np.random.default_rng(seed)
        inner = (x[:, 0] > x0) & (x[:, 0] < x1) & (x[:, 1] > y0) & (x[:, 1] < y1)
        h = min((x1 - x0) / nx, (y1 - y0) / ny)
        x[inner] += jitter * h * rng.uniform(-1, 1, (inner.sum(), 2))
    idx = lambda i, j: i * (ny + 1) + j  # noqa: E731
    cells = []
    for i in range(nx):
        for j in range(ny):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            cells += [(a, b, c), (a, c, d)]
    return x, np.array(cells, dtype=np.int64)
