"""Biot–Savart field of a racetrack coil of rectangular turn sections (reference of the racetrack tests).

Written independently of the mesh and of test_em3d_racetrack's filament polygons: each turn is a
uniform current density over its section; the section is integrated with tensor Gauss–Legendre
rules on sub-cells; along the straight sides the field of each filament is the closed-form field of
a finite straight line; along the two half-circle ends the angle is integrated with composite
Gauss–Legendre rules. Counter-clockwise current seen from +z (along +y at x > 0). Units: m, A, T.
"""
from __future__ import annotations

import numpy as np

MU0 = 4e-7 * np.pi


def _section_rule(x0: float, x1: float, z0: float, z1: float, cells: int, order: int):
    """(x, z, weight) of a composite Gauss rule over [x0, x1] x [z0, z1], weights summing to 1."""
    g, w = np.polynomial.legendre.leggauss(order)

    def line(a, b):
        e = np.linspace(a, b, cells + 1)
        mid, half = 0.5 * (e[1:] + e[:-1]), 0.5 * (e[1:] - e[:-1])
        return (mid[:, None] + half[:, None] * g).ravel(), (half[:, None] * w).ravel() / (b - a)

    xs, wx = line(x0, x1)
    zs, wz = line(z0, z1)
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    return X.ravel(), Z.ravel(), np.outer(wx, wz).ravel()


def racetrack_b(points: np.ndarray, turns: list[tuple[float, float]], z: tuple[float, float], half_straight: float,
                current: float, *, cells: int = 1, order: int = 6, arc_cells: int = 16) -> np.ndarray:
    """B (n, 3) T at ``points`` (n, 3) m of racetrack turns carrying ``current`` A each.

    ``turns``: (inner, outer) distance of each turn from the centre line x = 0 (m); ``z`` = (bottom,
    top) of the turns (m); straight sides |y| <= ``half_straight`` (m); ends: half rings about
    (0, +-half_straight). ``cells`` x ``order`` Gauss points per section direction, ``arc_cells`` x
    ``order`` over each half circle.
    """
    p = np.atleast_2d(np.asarray(points, float))
    b = np.zeros_like(p)
    H = half_straight
    ga, wa = np.polynomial.legendre.leggauss(order)
    for r0, r1 in turns:
        rho, zz, w = _section_rule(r0, r1, z[0], z[1], cells, order)
        for xs, sgn in ((1.0, 1.0), (-1.0, -1.0)):      # side x > 0 carries +y, side x < 0 carries -y
            for xf, zf, wf in zip(xs * rho, zz, w):
                rx, rz = p[:, 0] - xf, p[:, 2] - zf
                d2 = rx * rx + rz * rz
                s = (H - p[:, 1]) / np.sqrt(d2 + (H - p[:, 1]) ** 2) + (H + p[:, 1]) / np.sqrt(d2 + (H + p[:, 1]) ** 2)
                f = sgn * MU0 * current * wf / (4 * np.pi) * s / d2    # |B| d / (unit), times (rz, 0, -rx)
                b[:, 0] += f * rz
                b[:, 2] -= f * rx
        e = np.linspace(0.0, np.pi, arc_cells + 1)
        mid, hw = 0.5 * (e[1:] + e[:-1]), 0.5 * (e[1:] - e[:-1])
        phi = (mid[:, None] + hw[:, None] * ga).ravel()
        wphi = (hw[:, None] * wa).ravel()
        for yc, off in ((H, 0.0), (-H, np.pi)):          # the end about (0, +H) from phi = 0 to pi, then the other
            ph = phi + off
            c, s_ = np.cos(ph), np.sin(ph)
            # all source points of this end at once: section rule x angle rule
            sx = (rho[:, None] * c).ravel()
            sy = (yc + rho[:, None] * s_).ravel()
            sz = np.repeat(zz, len(ph))
            dlx = (-(rho * w)[:, None] * s_ * wphi).ravel()     # current element (times the section weight)
            dly = ((rho * w)[:, None] * c * wphi).ravel()
            k = MU0 * current / (4 * np.pi)
            for i0 in range(0, len(p), 256):                     # field points in chunks
                q = p[i0:i0 + 256]
                Rx, Ry, Rz = q[:, 0:1] - sx, q[:, 1:2] - sy, q[:, 2:3] - sz
                inv = (Rx * Rx + Ry * Ry + Rz * Rz) ** -1.5
                b[i0:i0 + 256, 0] += k * (dly * Rz * inv).sum(1)
                b[i0:i0 + 256, 1] -= k * (dlx * Rz * inv).sum(1)
                b[i0:i0 + 256, 2] += k * ((dlx * Ry - dly * Rx) * inv).sum(1)
    return b


def tet_average(points: np.ndarray, tets: np.ndarray, field) -> np.ndarray:
    """Volume-weighted mean over the tetrahedra ``tets`` (rows into ``points``) of ``field(x) -> (n, 3)``,
    each tetrahedron by the 4-point degree-2 rule."""
    a, b = 0.5854101966249685, 0.1381966011250105
    bary = np.array([[a, b, b, b], [b, a, b, b], [b, b, a, b], [b, b, b, a]])
    x = points[tets]                                          # (m, 4, 3)
    q = np.einsum("qk,mkd->mqd", bary, x).reshape(-1, 3)
    vals = field(q).reshape(len(tets), 4, 3).mean(1)
    v = np.abs(np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0])) / 6
    return (vals * v[:, None]).sum(0) / v.sum()
