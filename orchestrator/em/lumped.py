"""Lumped-circuit model of coaxial loops: the reference of the ring checks and the jumping ring.

A thin conducting ring coaxial with a coil, both idealised as circular filaments, couples through the
mutual inductance M(z) of two coaxial loops (Maxwell's formula with complete elliptic integrals); the
ring is an R-L circuit driven by -dPsi/dt = -d(M i_coil)/dt, and the axial force between the two is
i_coil i_ring dM/dz. For a ring whose skin depth is several times its section, this is the model the
finite-element solution must approach (issue 17): the ring's resistance R = 2 pi r / (sigma A) and its
self-inductance from Rosa's formula with the geometric mean distance of its section.

All quantities in SI units: lengths m, currents A, inductances H, resistances Ohm, forces N, time s.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.special import ellipe, ellipk

MU0 = 4e-7 * math.pi  # vacuum permeability, H/m (the value GetDP's decks use)

__all__ = ["MU0", "mutual_inductance", "mutual_inductance_gradient", "section_mutual_inductance", "ring_self_inductance",
           "ring_resistance", "coil_inductance", "RingCircuit", "phasor_ring_current"]


def _modulus(a, b, z):
    """k^2 of two coaxial loops of radii a, b (m) at axial distance z (m)."""
    return 4.0 * a * b / ((a + b) ** 2 + np.asarray(z, float) ** 2)


def mutual_inductance(a, b, z):
    """Mutual inductance (H) of two coaxial circular filaments of radii ``a`` and ``b`` (m; floats or
    arrays, broadcast with ``z``) whose
    planes are ``z`` (m) apart (Maxwell):

    M = mu0 sqrt(a b) [(2/k - k) K(k) - (2/k) E(k)],  k^2 = 4 a b / ((a + b)^2 + z^2).
    """
    m = _modulus(a, b, z)
    k = np.sqrt(m)
    return MU0 * np.sqrt(a * b) * ((2.0 / k - k) * ellipk(m) - (2.0 / k) * ellipe(m))


def mutual_inductance_gradient(a, b, z):
    """dM/dz (H/m) of :func:`mutual_inductance`: the axial force between the loops is
    ``i_a * i_b * dM/dz`` (N) on the loop at +z; negative (attraction) for currents in the same
    sense, repulsion for opposite ones, zero at z = 0:

    dM/dz = mu0 z k / (4 sqrt(a b) (1 - k^2)) [(2 - k^2) E(k) - 2 (1 - k^2) K(k)].
    """
    z = np.asarray(z, float)
    m = _modulus(a, b, z)
    k = np.sqrt(m)
    return -MU0 * z * k / (4.0 * np.sqrt(a * b) * (1.0 - m)) * ((2.0 - m) * ellipe(m) - 2.0 * (1.0 - m) * ellipk(m))


@functools.lru_cache(maxsize=16)
def _legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre points and weights on [-1, 1] (numpy's, computed once per n: an eigenvalue problem each)."""
    g, w = np.polynomial.legendre.leggauss(n)
    g.flags.writeable = False
    w.flags.writeable = False
    return g, w


def _gauss_points(rect: tuple[float, float, float, float], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Radii, heights and weights (summing to 1) of n x n Gauss points on (r0, z0, r1, z1) (m)."""
    g, w = _legendre(n)
    r0, z0, r1, z1 = rect
    r = 0.5 * (r0 + r1) + 0.5 * (r1 - r0) * g
    z = 0.5 * (z0 + z1) + 0.5 * (z1 - z0) * g
    rr, zz = np.meshgrid(r, z, indexing="ij")
    return rr.ravel(), zz.ravel(), np.outer(w, w).ravel() / 4.0


def section_mutual_inductance(coil: tuple[float, float, float, float], ring: tuple[float, float, float, float],
                              n: int = 6) -> tuple[float, float]:
    """(M, dM/dz) (H, H/m) between two coaxial windings of rectangular sections ``(r0, z0, r1, z1)`` (m),
    one turn each, each carrying its current uniformly over its section: Maxwell's filament formula
    averaged over n x n Gauss points of both sections (dM/dz: the ``ring`` moving along +z). Exact
    for the stranded coil's uniform current density; for a thin ring at low frequency to O((w/r)^2)
    (its current density falls as 1/r)."""
    ra, za, wa = _gauss_points(coil, n)
    rb, zb, wb = _gauss_points(ring, n)
    # every pair at once (row i: the coil's point i), each row summed alone and the rows added in turn: the
    # same sums, bit for bit, as a loop over the coil's points (a check of a case calls this per pair of turns)
    w = wa[:, None] * wb[None, :]
    dz = zb[None, :] - za[:, None]
    m = dm = 0.0
    for row_m, row_dm in zip(np.sum(w * mutual_inductance(ra[:, None], rb[None, :], dz), axis=1),
                             np.sum(w * mutual_inductance_gradient(ra[:, None], rb[None, :], dz), axis=1)):
        m += float(row_m)
        dm += float(row_dm)
    return m, dm


def ring_self_inductance(radius: float, width: float, height: float) -> float:
    """Low-frequency self-inductance (H) of a ring of mean radius ``radius`` (m) and rectangular
    section ``width`` x ``height`` (m): Rosa's formula L = mu0 R (ln(8 R / g) - 2) with the geometric
    mean distance of the rectangle g = 0.2235 (width + height) (Rosa & Grover; good to O((section /
    R)^2), i.e. for a thin ring)."""
    if not (radius > 0.0 and width > 0.0 and height > 0.0):
        raise ValueError(f"ring radius, width and height must be > 0 m, got {radius}, {width}, {height}")
    g = 0.2235 * (width + height)
    return MU0 * radius * (math.log(8.0 * radius / g) - 2.0)


def coil_inductance(turns: list[tuple[float, float, float, float]], counts: list[float] | None = None) -> float:
    """Low-frequency inductance (H) of coaxial windings in series, each ``(r0, z0, r1, z1)`` (m) with
    ``counts`` turns (signed: −1 turns a winding the other way; default one each), each carrying its
    current uniformly over its section: Σ_a n_a² L_a + Σ_(a≠b) n_a n_b M_ab, with Rosa's self-inductance
    of each section and Maxwell's mutual inductance averaged over the sections."""
    n = [1.0] * len(turns) if counts is None else [float(c) for c in counts]
    pairs = [(i, j) for i in range(len(turns)) for j in range(i + 1, len(turns))]
    mutual = iter(_pair_mutuals([turns[i] for i, _ in pairs], [turns[j] for _, j in pairs], 4))
    total = 0.0
    for i, a in enumerate(turns):
        total += n[i] ** 2 * ring_self_inductance(0.5 * (a[0] + a[2]), a[2] - a[0], a[3] - a[1])
        for j in range(i + 1, len(turns)):
            total += 2.0 * n[i] * n[j] * next(mutual)
    return total


def _pair_mutuals(coils: list, rings: list, n: int) -> list[float]:
    """:func:`section_mutual_inductance`'s M (H) of each pair ``(coils[p], rings[p])`` on n x n points, all pairs
    in one evaluation, summed in the same order (bit for bit the same values)."""
    if not coils:
        return []
    pts = [(_gauss_points(c, n), _gauss_points(r, n)) for c, r in zip(coils, rings)]
    ra = np.array([a[0] for a, _ in pts])[:, :, None]
    za = np.array([a[1] for a, _ in pts])[:, :, None]
    wa = np.array([a[2] for a, _ in pts])[:, :, None]
    rb = np.array([b[0] for _, b in pts])[:, None, :]
    zb = np.array([b[1] for _, b in pts])[:, None, :]
    wb = np.array([b[2] for _, b in pts])[:, None, :]
    rows = np.sum((wa * wb) * mutual_inductance(ra, rb, zb - za), axis=2)
    out = []
    for pair in rows:
        m = 0.0
        for row in pair:
            m += float(row)
        out.append(m)
    return out


def ring_resistance(radius: float, width: float, height: float, sigma: float) -> float:
    """DC resistance (Ohm) around a ring of mean radius ``radius`` and section ``width`` x ``height``
    (m) of conductivity ``sigma`` (S/m): 2 pi R / (sigma w h) (thin ring: the 1/r current
    distribution of a thick one is neglected)."""
    return 2.0 * math.pi * radius / (sigma * width * height)


def phasor_ring_current(omega: float, mutual: float, resistance: float, inductance: float) -> complex:
    """Steady-state ring current per unit coil current (complex, A/A) at angular frequency
    ``omega`` (rad/s): i_ring = -j omega M / (R + j omega L) i_coil."""
    return -1j * omega * mutual / (resistance + 1j * omega * inductance)


@dataclass
class RingCircuit:
    """A ring (R, L) coupled to a coil of given current i_coil(t) (A) through M(z) of coaxial loops
    of radii ``coil_radius`` and ``ring_radius`` (m); the ring, of mass ``mass`` (kg), may move along
    the axis under the magnetic force and gravity ``gravity`` (m/s^2, acting towards -z).

    State (z, w, i): ring height over the coil plane (m), its axial velocity (m/s), ring current (A).
    The ring's circuit: L di/dt + R i = -d(M(z) i_coil)/dt = -(M i_coil' + dM/dz w i_coil).
    ``coupling(z)``, when given, returns (M, dM/dz) (H, H/m) instead of the filaments' formula (e.g.
    :func:`section_mutual_inductance` for windings of finite section).
    """

    coil_radius: float
    ring_radius: float
    resistance: float
    inductance: float
    mass: float = float("inf")
    gravity: float = 0.0
    coupling: Callable[[float], tuple[float, float]] | None = None

    def mutual(self, z) -> tuple[float, float]:
        """(M, dM/dz) at height ``z`` (m)."""
        if self.coupling is not None:
            return self.coupling(z)
        return (mutual_inductance(self.coil_radius, self.ring_radius, z),
                mutual_inductance_gradient(self.coil_radius, self.ring_radius, z))

    def force(self, z, i_coil, i_ring):
        """Axial magnetic force on the ring (N)."""
        return i_coil * i_ring * self.mutual(z)[1]

    def rhs(self, t: float, y: np.ndarray, coil: Callable[[float], tuple[float, float]]) -> np.ndarray:
        """d(z, w, i)/dt; ``coil(t)`` returns (i_coil, di_coil/dt) in A and A/s."""
        z, w, i = y
        ic, dic = coil(t)
        m, dm = self.mutual(z)
        di = (-(m * dic + dm * w * ic) - self.resistance * i) / self.inductance
        if math.isinf(self.mass):
            return np.array([0.0, 0.0, di])
        return np.array([w, ic * i * dm / self.mass - self.gravity, di])

    def solve(self, coil: Callable[[float], tuple[float, float]], t_end: float, z0: float, *,
              w0: float = 0.0, i0: float = 0.0, t_eval: np.ndarray | None = None,
              rtol: float = 1e-10, atol: float | None = None):
        """Integrate to ``t_end`` (s) from height ``z0`` (m), velocity ``w0`` (m/s), ring current
        ``i0`` (A) with a stiff-safe implicit Runge-Kutta (Radau); returns scipy's solution object
        (``t``, ``y`` = rows z, w, i)."""
        from scipy.integrate import solve_ivp

        scale = np.array([max(abs(z0), self.ring_radius), 1.0, 1.0])
        return solve_ivp(self.rhs, (0.0, t_end), [z0, w0, i0], method="Radau", args=(coil,), t_eval=t_eval,
                         rtol=rtol, atol=atol if atol is not None else 1e-12 * scale, dense_output=t_eval is None)
