"""BDF2 (second-order backward differentiation) for the one-getdp-run-per-EM-step setting.

The semi-discrete eddy-current + circuit system is M dx/dt + K x = b(t), with M singular
(only the conductor and coil nodal unknowns and the circuit's inductor current and capacitor
voltage enter a time derivative; the air field and the network equations are algebraic).
Variable-step BDF2 from t_{n-1} to t_n = t_{n-1} + dt, with w = dt / dt_prev, reads

    M [ (1 + 2w)/(1 + w) x_n - (1 + w) x_{n-1} + w^2/(1 + w) x_{n-2} ] / dt + K x_n = b(t_n),

which is exactly one implicit-Euler step of length ``gamma * dt`` ending at t_n,

    M (x_n - x_tilde) / (gamma dt) + K x_n = b(t_n),
    gamma = (1 + w)/(1 + 2w),   x_tilde = [(1 + w)^2 x_{n-1} - w^2 x_{n-2}] / (1 + 2w),

started from the synthetic state x_tilde.  Only M x_tilde matters, i.e. x_tilde on the
coil/conductor nodes and the two circuit states: exactly what GetDP's ``Init`` constraints set
(the material-coordinate Init path of :mod:`.solver`).  K is assembled on the current mesh and
the algebraic equations hold exactly at t_n, so a moved or remeshed mesh injects nothing that
could ring (unlike a theta-scheme with theta < 1, whose (1 - theta) K x_{n-1} term is assembled
with the new mesh's K on the old state).  GetDP's post-processing Dt[{a}] = (a_n - x_tilde) /
(gamma dt) is then the BDF2 derivative, so j = -sigma Dt[a] and f = j x B are second-order
values at t_n.  The first step (no x_{n-2}) is implicit Euler (w = 0: gamma = 1, x_tilde =
x_{n-1}), which keeps global second order.  With w = 1: gamma = 2/3, x_tilde = (4 x_{n-1} -
x_{n-2}) / 3.
"""
from __future__ import annotations

import numpy as np


def bdf2_coefficients(dt: float, dt_prev: float | None) -> tuple[float, float, float]:
    """(gamma, c1, c2): the step ``gamma * dt`` and x_tilde = c1 x_{n-1} - c2 x_{n-2}.

    Parameters
    ----------
    dt : float
        Length of this step (s), > 0.
    dt_prev : float or None
        Length of the previous step (s); None (or 0) for the first step: implicit Euler.
    """
    if not dt > 0:
        raise ValueError(f"dt must be > 0, got {dt}")
    if not dt_prev:
        return 1.0, 1.0, 0.0
    w = dt / dt_prev
    return (1.0 + w) / (1.0 + 2.0 * w), (1.0 + w) ** 2 / (1.0 + 2.0 * w), w ** 2 / (1.0 + 2.0 * w)


def trapezoid_mean(start: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Mean over [t0, t1] of a quantity known at t0 (``start``) and at n equal sub-steps.

    ``values`` has shape (n, ...), ``start`` the shape of one row.  The piecewise-linear
    (trapezoid) mean (start/2 + v_1 + ... + v_{n-1} + v_n/2) / n: second-order accurate,
    so the impulse it carries over the step matches a second-order time scheme.
    """
    n = values.shape[0]
    return (0.5 * start + values[:-1].sum(axis=0) + 0.5 * values[-1]) / n


def match_rows(points_now: np.ndarray, points_prev: np.ndarray, tol: float) -> np.ndarray | None:
    """Index into ``points_prev`` of each row of ``points_now`` (same points to ``tol``), or None.

    Used to carry per-element values of the previous step to this step's element order
    (element centroids in material coordinates).
    """
    if len(points_now) == len(points_prev) and np.abs(points_now - points_prev).max(initial=0.0) <= tol:
        return np.arange(len(points_now))
    if len(points_prev) == 0:
        return None
    from scipy.spatial import cKDTree

    d, idx = cKDTree(points_prev).query(points_now)
    return idx if np.all(d <= tol) else None
