"""The designs of a study: which values of the swept case keys each member gets.

A parameter is ``--param key=v1,v2,...`` (a list of TOML literals) or ``--param key=lo:hi`` (a range of
numbers; both ends whole numbers written without a point or exponent: a whole-number parameter, the sampled
values rounded). Without ``sample`` the design is the **full grid** of the lists (a range is refused: it has
no values of its own). With ``sample = N`` it is ``N`` points of a **Latin hypercube** (``design = "lhs"``) or a
scrambled **Sobol sequence** (``design = "sobol"``) from :mod:`scipy.stats.qmc`, seeded (``seed``; the Latin
hypercube optimised for a low centred discrepancy, scipy's ``random-cd``): a range is
scaled onto its bounds, a list is sampled as equally likely choices. The same arguments give the same points
(hence the same members: :mod:`.study_store`); a Sobol design of 2N points starts with the N points of the
design of N (with the same seed), so doubling a Sobol study runs only the new half.
"""

from __future__ import annotations

import itertools
import math
import re
import warnings
from dataclasses import dataclass

from ..case.io import CaseError, parse_override

__all__ = ["Param", "parse_params", "design_points", "DESIGNS", "DesignError"]

#: the sampling designs (``--design``); the full grid is the design without ``--sample``
DESIGNS = ("lhs", "sobol")
#: significant digits of a sampled value (its TOML literal: the member's ``--set`` and folder name)
DIGITS = 6

_INT = re.compile(r"[+-]?\d+")


class DesignError(CaseError):
    """A design that cannot be made (one line: the argument, the key, what is allowed)."""


@dataclass(frozen=True)
class Param:
    """One swept case key: a list of values (TOML literals) or a numeric range [lo, hi]."""

    key: str
    values: tuple[str, ...] = ()
    lo: float | None = None
    hi: float | None = None
    integer: bool = False

    @property
    def is_range(self) -> bool:
        """True for ``key=lo:hi``."""
        return self.lo is not None

    def bounds(self) -> tuple[float, float] | None:
        """(lo, hi) of a range, else (min, max) of numeric values, else None (a parameter without a scale)."""
        if self.is_range:
            return self.lo, self.hi
        try:
            nums = [float(v) for v in self.values]
        except ValueError:
            return None
        return min(nums), max(nums)


def parse_params(params: list[str]) -> list[Param]:
    """``key=v1,v2,...`` or ``key=lo:hi`` strings -> parameters, each key once.

    Commas inside brackets belong to the value (``bodies.left.initial_velocity=[1,0],[2,0]``). Raises
    :class:`DesignError` for a malformed argument and the loader's ``CaseError`` for a value that is not a case
    key's literal.
    """
    out: list[Param] = []
    for text in params:
        if "=" not in text:
            raise DesignError(f"--param {text}", text, "expected key.path=v1,v2,... or key.path=lo:hi")
        key, raw = (s.strip() for s in text.split("=", 1))
        if any(p.key == key for p in out):
            raise DesignError(f"--param {text}", key, "the same key is swept twice")
        rng = _range(text, key, raw)
        if rng is not None:
            out.append(rng)
            parse_override(f"{key}={rng.lo!r}")  # the key path is well formed
            continue
        values = tuple(v.strip() for v in _split_top_level(raw) if v.strip())
        if not values:
            raise DesignError(f"--param {text}", key, "no values after '='")
        parse_override(f"{key}={values[0]}")
        out.append(Param(key, values))
    return out


def _range(text: str, key: str, raw: str) -> Param | None:
    """``lo:hi`` -> a range parameter; None when ``raw`` is not of that form (a list)."""
    if raw.count(":") != 1 or raw.startswith(("[", "{", '"', "'")):
        return None
    a, b = (s.strip() for s in raw.split(":"))
    try:
        lo, hi = float(a), float(b)
    except ValueError:
        raise DesignError(f"--param {text}", key, f"a range is lo:hi with two numbers; got {raw!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise DesignError(f"--param {text}", key, f"a range needs finite lo < hi; got {raw!r}")
    return Param(key, lo=lo, hi=hi, integer=bool(_INT.fullmatch(a) and _INT.fullmatch(b)))


def _split_top_level(raw: str) -> list[str]:
    parts, depth, cur = [], 0, ""
    for ch in raw:
        depth += ch in "[{"
        depth -= ch in "]}"
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    return parts


def design_points(params: list[Param], sample: int | None = None, design: str = "lhs",
                  seed: int = 1) -> list[dict[str, str]]:
    """The members' values (key -> TOML literal), in design order.

    Parameters
    ----------
    params : list of Param
        The swept keys.
    sample : int or None
        None: the full grid of the lists; N >= 2: N points of ``design``.
    design : {"lhs", "sobol"}
        Latin hypercube (:class:`scipy.stats.qmc.LatinHypercube`) or scrambled Sobol sequence
        (:class:`scipy.stats.qmc.Sobol`).
    seed : int
        The sampler's seed.
    """
    if sample is None:
        ranged = [p.key for p in params if p.is_range]
        if ranged:
            raise DesignError(f"--param {ranged[0]}=lo:hi", ranged[0],
                              "a range has no values of its own: add --sample N (with --design lhs|sobol) or give "
                              "a list v1,v2,...")
        return [dict(zip((p.key for p in params), combo)) for combo in itertools.product(*(p.values for p in params))]
    if design not in DESIGNS:
        raise DesignError(f"--design {design}", "design", f"allowed: {', '.join(DESIGNS)}")
    if sample < 2:
        raise DesignError(f"--sample {sample}", "sample", "must be >= 2")
    from scipy.stats import qmc

    d = len(params)
    if design == "lhs":
        # random-cd: pairs of the strata permuted to lower the centred discrepancy (Damblin et al. 2013), so that
        # no two columns are correlated by chance (which would blur the regression's sensitivities)
        unit = qmc.LatinHypercube(d=d, seed=seed, optimization="random-cd" if d > 1 else None).random(sample)
    else:
        with warnings.catch_warnings():  # a size that is not a power of 2 loses the balance, not the validity
            warnings.simplefilter("ignore", UserWarning)
            unit = qmc.Sobol(d=d, scramble=True, seed=seed).random(sample)
    return [{p.key: _value(p, u) for p, u in zip(params, row)} for row in unit]


def _value(p: Param, u: float) -> str:
    """The TOML literal of unit coordinate ``u`` in [0, 1) for parameter ``p``."""
    if not p.is_range:
        return p.values[min(int(u * len(p.values)), len(p.values) - 1)]
    if p.integer:  # each whole number of [lo, hi] equally likely
        n = int(p.hi - p.lo) + 1
        return str(int(p.lo) + min(int(u * n), n - 1))
    x = p.lo + u * (p.hi - p.lo)
    return repr(float(f"{x:.{DIGITS}g}"))
