"""The grid convergence index (GCI) of a quantity computed on three systematically refined grids.

The procedure of Celik, Ghia, Roache, Freitas, Coleman and Raad, "Procedure for Estimation and
Reporting of Uncertainty Due to Discretization in CFD Applications", J. Fluids Eng. 130 (2008)
078001 (the ASME V&V 20 recommendation, after Roache 1994/1998): with grid sizes h1 < h2 < h3
(fine to coarse), ratios r21 = h2/h1, r32 = h3/h2, solutions φ1, φ2, φ3 and differences
ε21 = φ2 − φ1, ε32 = φ3 − φ2:

- the observed order p solves p = |ln|ε32/ε21| + q(p)| / ln r21 with
  q(p) = ln((r21^p − s) / (r32^p − s)), s = sign(ε32/ε21) (fixed-point iteration; q = 0 for a
  constant ratio);
- the extrapolated value φ_ext = (r21^p φ1 − φ2) / (r21^p − 1);
- the approximate relative error e_a = |(φ1 − φ2)/φ1|, the extrapolated one e_ext = |(φ_ext − φ1)/φ_ext|;
- the fine-grid convergence index GCI = Fs e_a / (r21^p − 1), safety factor Fs = 1.25 for three grids.

ε32/ε21 > 0 is monotone convergence; < 0 oscillatory convergence (the procedure then uses |·| and
s = −1, and the result is to be read with caution); ε21 = ε32 = 0 is a grid-independent ("constant")
quantity, one of them zero leaves p undefined.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Sequence

__all__ = ["GCIResult", "grid_convergence"]

#: safety factor of the three-grid GCI (Roache; Celik et al. 2008)
SAFETY_FACTOR = 1.25


@dataclass(frozen=True)
class GCIResult:
    """The GCI of one quantity (see the module docstring; relative errors as fractions, not %).

    Attributes
    ----------
    r21, r32 : float
        Refinement ratios h2/h1, h3/h2.
    order : float
        Observed order p (nan when undefined).
    extrapolated : float
        Richardson-extrapolated value φ_ext (nan when p is undefined).
    error_approx : float
        e_a = |(φ1 − φ2)/φ1|.
    error_extrapolated : float
        e_ext = |(φ_ext − φ1)/φ_ext|.
    gci_fine : float
        Fs e_a / (r21^p − 1): the fine grid's relative uncertainty band.
    convergence : str
        "monotone", "oscillatory", "constant" (the three values equal) or "undefined" (one zero difference).
    """

    r21: float
    r32: float
    order: float
    extrapolated: float
    error_approx: float
    error_extrapolated: float
    gci_fine: float
    convergence: str

    def to_dict(self) -> dict:
        """Plain data for JSON."""
        return asdict(self)


def _order(r21: float, r32: float, e21: float, e32: float, s: float, tol: float = 1e-12, max_iter: int = 200) -> float:
    """The observed order by fixed-point iteration of p = |ln|ε32/ε21| + q(p)| / ln r21."""
    ratio = math.log(abs(e32 / e21))
    # the constant-ratio value as the start (at least 0.5: with unequal ratios the answer may have
    # ln|ε32/ε21| = 0, where p = 0 would be a spurious fixed point, r^0 − s = 0)
    p = max(abs(ratio) / math.log(r21), 0.5)
    for _ in range(max_iter):
        num, den = r21 ** p - s, r32 ** p - s
        q = math.log(num / den) if num > 0 and den > 0 else 0.0
        p_new = abs(ratio + q) / math.log(r21)
        if abs(p_new - p) <= tol * max(1.0, p):
            return p_new
        p = p_new
    return math.nan  # no fixed point found: the order is undefined


def grid_convergence(h: Sequence[float], phi: Sequence[float], safety: float = SAFETY_FACTOR) -> GCIResult:
    """The GCI of a quantity ``phi`` = (φ1, φ2, φ3) on grids of sizes ``h`` = (h1, h2, h3), fine to
    coarse (any length unit, only the ratios matter; refinement ratios should exceed 1.3).

    Raises
    ------
    ValueError
        Not three strictly coarsening grids, or a non-finite value.
    """
    if len(h) != 3 or len(phi) != 3:
        raise ValueError(f"the GCI needs three grids and three values, got {len(h)} and {len(phi)}")
    h1, h2, h3 = (float(x) for x in h)
    p1, p2, p3 = (float(x) for x in phi)
    if not all(math.isfinite(x) for x in (h1, h2, h3, p1, p2, p3)):
        raise ValueError("the GCI needs finite grid sizes and values")
    if not 0.0 < h1 < h2 < h3:
        raise ValueError(f"grid sizes must be positive and coarsening (fine to coarse), got {h1:g}, {h2:g}, {h3:g}")
    r21, r32 = h2 / h1, h3 / h2
    e21, e32 = p2 - p1, p3 - p2
    e_a = abs((p1 - p2) / p1) if p1 != 0.0 else math.inf
    if e21 == 0.0 and e32 == 0.0:  # independent of the grid (e.g. a prescribed quantity): no error band
        return GCIResult(r21, r32, math.nan, p1, 0.0, 0.0, 0.0, "constant")
    if e21 == 0.0 or e32 == 0.0:
        nan = math.nan
        return GCIResult(r21, r32, nan, nan, e_a, nan, nan, "undefined")
    s = math.copysign(1.0, e32 / e21)
    p = _order(r21, r32, e21, e32, s)
    if not math.isfinite(p) or p <= 0.0:
        nan = math.nan
        return GCIResult(r21, r32, p, nan, e_a, nan, nan, "undefined")
    rp = r21 ** p
    ext = (rp * p1 - p2) / (rp - 1.0)
    e_ext = abs((ext - p1) / ext) if ext != 0.0 else math.inf
    return GCIResult(r21, r32, p, ext, e_a, e_ext, safety * e_a / (rp - 1.0),
                     "monotone" if s > 0 else "oscillatory")
