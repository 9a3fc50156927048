"""The arithmetic of a study's answer: sensitivities, a response surface and its cross-validated error.

- :func:`standardised_regression` -- **standardised regression coefficients** (SRC) of a metric on the
  parameters, from the members themselves, with the fit's R². For a response that is close to linear (R² near
  1) SRC_i² is the share of the metric's variance due to parameter i (Saltelli et al., *Global Sensitivity
  Analysis: The Primer*, 2008, sec. 1.2.5); a low R² says the linear ranking is not to be trusted.
- :class:`QuadraticSurface` -- a least-squares **response surface**, the full quadratic in the parameters scaled
  to [0, 1] (linear when the members are too few for it), with its **leave-one-out** cross-validated error
  (the PRESS residuals e_i / (1 - h_ii) of the hat matrix: exact for least squares, no refits).
- :func:`sobol_indices` -- first-order and total **Sobol indices** of any function over a box, by the
  Saltelli (2010) estimator for S_i and Jansen's (1999) for S_Ti on scrambled Sobol matrices A, B
  (:class:`scipy.stats.qmc.Sobol`). A study has too few members to estimate them from the runs, so it applies
  them to its response surface: the indices of the surface, as good as the surface's cross-validated error.
  Checked on the Ishigami function (tests/foundation/test_study_sensitivity.py).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["standardised_regression", "QuadraticSurface", "sobol_indices"]


def standardised_regression(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    """SRC of ``y`` (n,) on the columns of ``x`` (n, d) and the linear fit's R².

    SRC_i = b_i σ(x_i) / σ(y) with b the least-squares coefficients of y = b0 + Σ b_i x_i. A constant
    column gets 0. Raises ValueError with fewer than d + 2 samples (no residual left to judge the fit)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    n, d = x.shape
    if n < d + 2:
        raise ValueError(f"{n} samples for {d} parameters: the linear fit needs at least {d + 2}")
    sx, sy = x.std(axis=0), y.std()
    keep = sx > 0
    a = np.column_stack([np.ones(n), x[:, keep]])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    src = np.zeros(d)
    if sy > 0:
        src[keep] = coef[1:] * sx[keep] / sy
    resid = y - a @ coef
    r2 = 1.0 - float(resid @ resid) / float(((y - y.mean()) ** 2).sum()) if sy > 0 else 1.0
    return src, r2


@dataclass
class QuadraticSurface:
    """A least-squares polynomial (degree 2, or 1 with too few samples) in the parameters scaled to [0, 1].

    Attributes
    ----------
    lo, hi : ndarray
        The box the parameters are scaled from.
    degree : int
        2 (constant, linear, squares and products) or 1.
    coef : ndarray
        The fitted coefficients of :meth:`_terms`.
    loo_rmse : float
        Leave-one-out root-mean-square error, in the metric's unit (nan when every sample is needed).
    loo_max : float
        Largest leave-one-out error magnitude.
    r2 : float
        The fit's coefficient of determination on the samples.
    """

    lo: np.ndarray
    hi: np.ndarray
    degree: int
    coef: np.ndarray
    loo_rmse: float
    loo_max: float
    r2: float

    @classmethod
    def fit(cls, x: np.ndarray, y: np.ndarray, lo: np.ndarray | None = None,
            hi: np.ndarray | None = None) -> "QuadraticSurface":
        """Fit ``y`` (n,) on ``x`` (n, d); the quadratic when n exceeds its term count by at least 2, else linear."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        lo = x.min(axis=0) if lo is None else np.asarray(lo, float)
        hi = x.max(axis=0) if hi is None else np.asarray(hi, float)
        d = x.shape[1]
        degree = 2 if len(y) >= 1 + 2 * d + d * (d - 1) // 2 + 2 else 1
        surf = cls(lo, hi, degree, np.zeros(0), float("nan"), float("nan"), float("nan"))
        a = surf._terms(x)
        coef, *_ = np.linalg.lstsq(a, y, rcond=None)
        surf.coef = coef
        resid = y - a @ coef
        ss = float(((y - y.mean()) ** 2).sum())
        surf.r2 = 1.0 - float(resid @ resid) / ss if ss > 0 else 1.0
        h = np.einsum("ij,ji->i", a, np.linalg.pinv(a))  # the hat matrix's diagonal
        if len(y) > a.shape[1] and np.all(h < 1 - 1e-9):
            press = resid / (1.0 - h)
            surf.loo_rmse = float(np.sqrt(np.mean(press ** 2)))
            surf.loo_max = float(np.abs(press).max())
        return surf

    def _terms(self, x: np.ndarray) -> np.ndarray:
        u = (np.asarray(x, float) - self.lo) / np.where(self.hi > self.lo, self.hi - self.lo, 1.0)
        cols = [np.ones(len(u))] + [u[:, i] for i in range(u.shape[1])]
        if self.degree == 2:
            cols += [u[:, i] * u[:, j] for i, j in itertools.combinations_with_replacement(range(u.shape[1]), 2)]
        return np.column_stack(cols)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """The surface at ``x`` (m, d)."""
        return self._terms(np.atleast_2d(x)) @ self.coef


def sobol_indices(f: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, n: int = 2 ** 14,
                  seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """First-order and total Sobol indices (S, S_T) of ``f`` over the box [lo, hi] (independent uniform inputs).

    ``f`` maps (m, d) points to (m,) values; it is called on 2 + d matrices of ``n`` points: A and B, the first
    and second d columns of a scrambled Sobol sample of dimension 2d, and each AB_i (A with column i from B).
    S_i = mean(f(B) (f(AB_i) - f(A))) / V (Saltelli et al. 2010, Comput. Phys. Commun. 181, 259, table 2 (b));
    S_Ti = mean((f(A) - f(AB_i))²) / (2 V) (Jansen 1999, table 2 (f)); V the variance of f over A and B.
    """
    from scipy.stats import qmc

    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    d = len(lo)
    ab = qmc.scale(qmc.Sobol(d=2 * d, scramble=True, seed=seed).random(n), np.r_[lo, lo], np.r_[hi, hi])
    a, b = ab[:, :d], ab[:, d:]
    fa, fb = np.asarray(f(a), float), np.asarray(f(b), float)
    var = float(np.var(np.r_[fa, fb]))
    s, st = np.zeros(d), np.zeros(d)
    if var <= 0:
        return s, st
    for i in range(d):
        abi = a.copy()
        abi[:, i] = b[:, i]
        fabi = np.asarray(f(abi), float)
        s[i] = float(np.mean(fb * (fabi - fa))) / var
        st[i] = float(np.mean((fa - fabi) ** 2)) / (2 * var)
    return s, st
