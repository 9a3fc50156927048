"""Die profile of the corner-filling cases (half model, symmetry plane x = 0), as case-file points.

:func:`die_polygon` gives the counter-clockwise polygon of the steel die: a 130-degree V groove (walls at 25 degrees to
the horizontal) of depth D below the flange, its apex rounded with radius R (the corner to fill), the
entry edge rounded with radius Re, a flat flange out to x_end, and a die block of thickness T below the
apex. The flange top lies at y = -gap (the blank's lower face is y = 0).
``studies/corner_fill/die.py`` prints it for ``[[bodies]] shape.points`` of cases/corner_fill*/case.toml.
"""

from __future__ import annotations

import math


def die_polygon(depth: float = 0.02, radius: float = 0.003, entry_radius: float = 0.005, x_end: float = 0.145,
                thickness: float = 0.02, gap: float = 1.5e-4, angle_deg: float = 130.0, arc_step: float = 5e-4,
                bottom_half_width: float = 0.0) -> list[tuple[float, float]]:
    """Counter-clockwise (x, y) vertices (m) of the half die.

    bottom_half_width = 0: a V groove whose included angle is ``angle_deg`` (walls at
    (180 - angle)/2 to the horizontal), apex rounded with ``radius``.
    bottom_half_width > 0: a trapezoidal groove, flat bottom out to x = bottom_half_width (the
    corner's vertex), walls making ``angle_deg`` with the bottom (inclined 180 - angle to the
    horizontal), bottom-wall corner rounded with ``radius``.
    """
    if bottom_half_width > 0.0:
        return _trapezoid(depth, radius, entry_radius, x_end, thickness, gap, angle_deg, arc_step,
                          bottom_half_width)
    a = math.radians((180.0 - angle_deg) / 2.0)  # wall inclination to the horizontal (25 deg)
    yf = -gap
    w = depth / math.tan(a)                      # half width of the groove at the flange level
    pts = _base_and_entry(a, w, yf, depth, thickness, x_end, entry_radius, arc_step)
    # apex arc tangent to both walls, centre on the symmetry line
    yc = yf - depth + radius / math.cos(a)
    n = _n(radius, a, arc_step)
    for i in range(n + 1):
        phi = -math.pi / 2 + a - (a * i / n)  # from the wall tangent point (-65 deg) down to -90 deg
        pts.append((radius * math.cos(phi) if i < n else 0.0, yc + radius * math.sin(phi)))
    pts.append((0.0, yc - radius - SIDE_STEP))
    return [(round(x, 7), round(y, 7)) for x, y in pts]


SIDE_STEP = 1e-3
"""An extra vertex on the symmetry side, 1 mm below the cavity: the blank's symmetry-line node moves
down the extension of that side, and the contact search accepts projections up to 2 % of a segment
beyond its end; with a long side segment (4 mm on coarse meshes) the node, 0.07 mm above the bottom,
was taken as lying on the side's extension (h = 0, a spurious penetration). A 1 mm segment keeps
that zone at 0.02 mm, below the gaps the contact layer leaves."""


def _n(radius: float, angle: float, step: float) -> int:
    """Arc segments: about ``step`` long (no die cells much smaller than the blank's: they would set
    the explicit time step), at least 2."""
    return max(2, int(math.ceil(radius * angle / step)))


def _base_and_entry(a: float, w: float, yf: float, depth: float, thickness: float, x_end: float,
                    entry_radius: float, arc_step: float) -> list[tuple[float, float]]:
    """Base, outer side and flange corner of the die, then the entry fillet (flange tangent point ->
    wall tangent point, centre below the flange) of a groove whose walls are inclined ``a`` to the
    horizontal and reach the flange level at x = ``w``."""
    yb = yf - depth - thickness
    pts = [(0.0, yb), (x_end, yb), (x_end, yf)]
    tlen = entry_radius * math.tan(a / 2.0)
    cx, cy = w + tlen, yf - entry_radius
    n = _n(entry_radius, a, arc_step)
    for i in range(n + 1):
        phi = math.pi / 2 + a * i / n
        pts.append((cx + entry_radius * math.cos(phi), cy + entry_radius * math.sin(phi)))
    return pts


def _trapezoid(depth: float, radius: float, entry_radius: float, x_end: float, thickness: float, gap: float,
               angle_deg: float, arc_step: float, xc: float) -> list[tuple[float, float]]:
    a = math.radians(180.0 - angle_deg)  # wall inclination to the horizontal (50 deg for 130)
    yf = -gap
    w = xc + depth / math.tan(a)
    pts = _base_and_entry(a, w, yf, depth, thickness, x_end, entry_radius, arc_step)
    # bottom corner: centre above the bottom, tangent to bottom and wall
    tl = radius * math.tan(a / 2.0)
    ccx, ccy = xc - tl, yf - depth + radius
    n = _n(radius, a, arc_step)
    for i in range(n + 1):
        phi = -math.pi / 2 + a * (1 - i / n)  # wall tangent point -> bottom tangent point
        pts.append((ccx + radius * math.cos(phi), ccy + radius * math.sin(phi)))
    pts.append((0.0, yf - depth))
    pts.append((0.0, yf - depth - SIDE_STEP))
    return [(round(x, 7), round(y, 7)) for x, y in pts]
