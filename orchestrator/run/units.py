"""The unit of every ``history.csv`` / ``metrics.json`` column, and how plots show it.

One table (:data:`RULES`) maps column-name patterns to the unit the value is stored in and the unit
and scale a plot shows it in (m → mm, Pa → MPa, A → kA, ...). The first matching rule wins, so
exact names come before name endings, and longer endings before shorter ones (``_m_s`` before
``_s``). A column no rule matches has the unit ``"?"`` and plots label it ``[?]``: add a rule here
when a new column appears (``tests/foundation/test_units.py`` lists the columns of real runs).

Time axes are special: every time axis of one run uses the same unit, chosen from the run's length
(:func:`time_axis`: µs for pulses up to 5 ms, ms up to 5 s, s beyond).
"""

from __future__ import annotations

import re
from dataclasses import dataclass


@dataclass(frozen=True)
class Unit:
    """How a column is stored and shown.

    Attributes
    ----------
    stored : str
        Unit of the value in the file (SI unless the name says otherwise, e.g. ``_mm``).
    shown : str
        Unit plots show (``"-"``: dimensionless, ``"count"``: a number of things, ``"?"``: unknown).
    scale : float
        shown value = stored value × scale.
    """

    stored: str
    shown: str
    scale: float = 1.0

    @property
    def known(self) -> bool:
        """False for a column no rule matched."""
        return self.stored != "?"


def _u(stored: str, shown: str | None = None, scale: float = 1.0) -> Unit:
    return Unit(stored, shown or stored, scale)


DIMENSIONLESS = _u("-")
COUNT = _u("count")
UNKNOWN = _u("?")

_QUALIFIERS = r"(_(end|max|min|mean|top|final|segments))*"

#: (pattern of the whole column name, unit); first match wins
RULES: tuple[tuple[str, Unit], ...] = (
    # --- exact names (or families) whose ending alone would mislead
    (r"time_s", _u("s")),                                   # the time axis: see time_axis()
    (r"dt_s", _u("s", "µs", 1e6)),                          # mechanical time step
    (r"status", _u("text")),                                # metrics.json: ok / failed / interrupted
    (r"(step|substeps|iterations|em_remeshes|mech_steps|em_steps|n_final|coupling_iterations_(total|max)"
     r"|coupling_unconverged_steps|mech_rejected_steps|em_(getdp_)?(factorisations|corrections))", COUNT),
    (r".*_(iterations|closed_nodes)", COUNT),               # em_newton_iterations, springback_contact<i>_closed_nodes
    (r"status_ok", DIMENSIONLESS),                          # 1 / 0
    # ratios, fractions, qualities, plastic strains; optionally followed by qualifiers (_max, _end, ...)
    (r".*_(rel|rel_diff|ratio|fraction|quality|plastic_strain|eps_p)" + _QUALIFIERS, DIMENSIONLESS),
    (r"(.*_)?(fraction|eps_p|plastic_strain)" + _QUALIFIERS, DIMENSIONLESS),
    (r".*_over_[A-Za-z0-9]+|.*_to_[a-z]+", DIMENSIONLESS),   # clearance_over_R0, final_kinetic_to_elastic
    (r".*_flc_worst_element", COUNT),                       # the worst cell's index in the field file
    (r".*_flc_(margin|worst_zone|worst_minor_strain|worst_major_strain)" + _QUALIFIERS, DIMENSIONLESS),
    # --- endings: the unit is the end of the name (longer endings first)
    (r".*_m_s2", _u("m/s²")),
    (r".*_m_s", _u("m/s")),
    (r".*_Ns", _u("N·s")),
    (r".*_N_m3", _u("N/m³")),
    (r".*_W_m3", _u("W/m³")),
    (r".*_mm", _u("mm")),
    (r".*_MPa", _u("MPa")),
    (r".*_Pa", _u("Pa", "MPa", 1e-6)),
    (r".*_kA", _u("kA")),
    (r".*_A", _u("A", "kA", 1e-3)),
    (r".*_kV", _u("kV")),
    (r".*_V", _u("V", "kV", 1e-3)),
    (r".*_kg", _u("kg")),
    (r".*_kN", _u("kN")),
    (r".*_N", _u("N", "kN", 1e-3)),
    (r".*_J", _u("J")),
    (r".*_W", _u("W", "kW", 1e-3)),
    (r".*_K", _u("K")),
    (r".*_T", _u("T")),
    (r".*_ms", _u("ms")),
    (r".*_us", _u("µs")),
    (r".*_s", _u("s")),                                     # wall-clock times and simulated instants
    (r".*_m", _u("m", "mm", 1e3)),
)

_COMPILED = tuple((re.compile(p + r"\Z"), u) for p, u in RULES)


def unit_of(column: str) -> Unit:
    """The :class:`Unit` of a history / metrics column (:data:`UNKNOWN` if no rule matches)."""
    for pattern, unit in _COMPILED:
        if pattern.match(column):
            return unit
    return UNKNOWN


def label(column: str) -> str:
    """Axis label ``"<column> [<shown unit>]"``; an unknown unit shows as ``[?]``."""
    return f"{column} [{unit_of(column).shown}]"


def shown(column: str, values):
    """``values`` (stored unit) in the unit plots show."""
    return values * unit_of(column).scale


#: (largest run length in s, scale, unit) of the time axis, first fit wins
TIME_AXES: tuple[tuple[float, float, str], ...] = ((5e-3, 1e6, "µs"), (5.0, 1e3, "ms"), (float("inf"), 1.0, "s"))


@dataclass(frozen=True)
class TimeAxis:
    """The time unit of every time axis of one run: ``t_shown = t_s * scale``."""

    scale: float
    unit: str

    @property
    def label(self) -> str:
        """``"time [µs]"`` etc."""
        return f"time [{self.unit}]"


def time_axis(run_length_s: float) -> TimeAxis:
    """µs for runs up to 5 ms (pulses), ms up to 5 s, s beyond."""
    for limit, scale, unit in TIME_AXES:
        if run_length_s <= limit:
            return TimeAxis(scale, unit)
    return TimeAxis(1.0, "s")
