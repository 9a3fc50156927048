"""The demo's 3D sector case file (cases/emf_sheet_bulge_3d: a gmsh builder of its folder, sector_geometry.py, on
the general 3D geometry-file path) and its coarse set-up shared by the tests: a 5 degree sector (11.7k EM tets,
1.8k sheet tets), 1 mm over the coil, 2 layers through the sheet, 3 us (9 EM steps), a field output every 1 us.
The sector's angle is a parameter of the builder; its second meridian plane's normal [-sin a, cos a, 0] follows."""
from __future__ import annotations

import math
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
CASE = REPO / "cases/emf_sheet_bulge_3d"


def planes(angle_deg: float) -> str:
    """The ``symmetry`` override of a sector of ``angle_deg``: its meridian planes phi = 0 and phi = angle."""
    a = math.radians(angle_deg)
    return f"symmetry=[{{normal=[0.0, 1.0, 0.0]}}, {{normal=[{-math.sin(a)!r}, {math.cos(a)!r}, 0.0]}}]"


#: the coarse sector's mesh (key=value overrides)
MESH = ["geometry.parameters.angle_deg=5", planes(5.0), "geometry.parameters.h_sheet=1e-3",
        "geometry.parameters.sheet_layers=2", "geometry.parameters.h_coil=3e-3", "geometry.parameters.h_air=0.02"]
#: the coarse sector over 3 us
COARSE = MESH + ["time.end=3e-6", "output.field_interval=1e-6"]
#: the 2D demo's loaded surface (the sheet's lower face over the coil, r in [10, 34] mm at z = 1.5 mm) as a 3D box
#: (``pulseform compare --surface``)
SURFACE = "{rmin = 0.01, rmax = 0.034, zmin = 1.4999e-3, zmax = 1.5001e-3}"


def sets(overrides: list[str]) -> list[str]:
    """``--set`` arguments of ``overrides``."""
    out = []
    for s in overrides:
        out += ["--set", s]
    return out
