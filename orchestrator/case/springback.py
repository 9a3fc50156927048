"""The case's ``[springback]`` table: a static release of the deformable bodies (after the run, or as a
``[[stages]]`` entry of kind ``"springback"``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from .schema import spec

__all__ = ["SpringbackTable"]


@dataclass(frozen=True, kw_only=True)
class SpringbackTable:
    """Springback after the run: a static equilibrium with the loads off, from the state at time.end."""

    supports: Literal["kept", "minimal"] = spec(
        "kept", doc="'kept': the bodies keep their [[bodies.fixed]] boundaries (clamps); 'minimal': they are "
                    "released onto statically determinate supports that stop rigid motion only (3-2-1 rule). "
                    "Loads are removed either way")
    contact: Literal["removed", "kept"] = spec(
        "removed", doc="'kept': the [[contact]] pairs between released bodies stay (elastic law of eq. (5), friction "
                       "and viscosity dropped): a press fit's residual contact pressure (springback_contact<i>_* "
                       "metrics); 'removed': the parts are separated")
    walls: Literal["removed", "kept"] = spec(
        "removed", doc="'kept': the [[walls]] stay (a part released inside its die); 'removed': out of the die")
    steps: int = spec(1, unit="-", ge=1, le=1000, doc="static steps over which the internal forces left "
                                                       "unbalanced by the removed loads and supports are released")
    bodies: tuple[str, ...] = spec((), doc="the bodies that spring back (default: every deformable body)")
