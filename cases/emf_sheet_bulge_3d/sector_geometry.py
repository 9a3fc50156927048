"""Gmsh builder of a thin sector of the demo's flat-coil / sheet set-up (a 3D geometry file of
``cases/emf_sheet_bulge_3d``): ``python sector_geometry.py OUT.msh [name=value ...]``.

The sector 0 <= phi <= ``angle_deg`` about the z-axis of the axisymmetric demo (cases/emf_sheet_bulge): the
coil's ``turns`` rings (``coil_inner_radius``, ``turn_width`` x ``turn_height``, ``turn_gap`` apart, their top at
z = 0) as one coil, the sheet (radius ``sheet_radius``, ``sheet_thickness`` thick, ``coil_gap`` above the coil)
as its sector face extruded in ``sheet_layers`` layers, in-plane size ``h_sheet`` over the coil (to its outer
radius + 5 mm, graded 0.3 m/m beyond) and ``h_sheet_out`` elsewhere, the air sphere ``air_radius`` (size
``h_air``) and the shell to ``shell_radius``. It writes OUT.msh with the named groups "air", "shell", "coil",
"sheet" (and "symmetry", "outer", "coil_in", "coil_out", "sheet_skin"). Lengths in m, the angle in degrees;
``mesh_size_factor`` (pulseform's ``geometry.mesh_size_factor``) multiplies the sizes (the air's at the sphere
only when it refines: a coarser faceted sphere would reach into the shell) and divides the sheet's layers.
The mesher is pulseform's ring-sector builder (:func:`pulseform.solvers.getdp.mesh3d.ring_sector_mesh`), so the
mesh is that of the sector's reference runs.
"""

import math
import sys

from pulseform.orchestrator.mesh.gmsh_file import BuilderArgumentError, builder_arguments
from pulseform.solvers.getdp.mesh import Rect
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh

DEFAULTS = {"angle_deg": 1.25, "turns": 5, "coil_inner_radius": 10e-3, "turn_width": 4e-3, "turn_height": 3e-3,
            "turn_gap": 1e-3, "coil_gap": 1.5e-3, "sheet_radius": 60e-3, "sheet_thickness": 1e-3, "air_radius": 0.15,
            "shell_radius": 0.20, "h_sheet": 0.35e-3, "h_sheet_out": 1.5e-3, "sheet_layers": 8, "h_coil": 1.5e-3,
            "h_air": 0.015}
INTEGERS = ("turns", "sheet_layers")
#: the sheet's fine region reaches this far beyond the coil's outer radius (m)
FINE_MARGIN = 5e-3


def build(out: str, p: dict) -> None:
    """Mesh the sector of the parameters ``p`` into ``out``."""
    turns = []
    for k in range(p["turns"]):
        r0 = p["coil_inner_radius"] + k * (p["turn_width"] + p["turn_gap"])
        turns.append(Rect(r0, -p["turn_height"], r0 + p["turn_width"], 0.0))
    sheet = Rect(0.0, p["coil_gap"], p["sheet_radius"], p["coil_gap"] + p["sheet_thickness"])
    alpha = math.radians(p["angle_deg"])
    r_coil = max(t.x1 for t in turns)
    box = ((0.0, r_coil + FINE_MARGIN, -1e-3, r_coil * math.sin(alpha) + 1e-3, 0.0, sheet.y1), p["h_sheet"])
    ring_sector_mesh(out, turns, [sheet], sector_deg=p["angle_deg"], r_air=p["air_radius"], r_shell=p["shell_radius"],
                     h_coil=p["h_coil"], h_conductor=p["h_sheet_out"], h_air=p["h_air"],
                     conductor_layers=p["sheet_layers"], fine_box=box, conductor_names=("sheet",))


def main(argv: list[str]) -> int:
    try:
        out, values, factor = builder_arguments(argv, list(DEFAULTS), integers=INTEGERS)
    except BuilderArgumentError as exc:
        print(f"Error: {exc}", file=sys.stderr)
        return 2
    p = {**DEFAULTS, **values}
    if not 0 < p["angle_deg"] < 180:
        print(f"Error: angle_deg must lie in (0, 180) degrees, got {p['angle_deg']}", file=sys.stderr)
        return 2
    if factor != 1.0:   # every size times the factor (the air's at the sphere only refined), the layers over it
        p.update({k: p[k] * factor for k in ("h_sheet", "h_sheet_out", "h_coil")}, h_air=p["h_air"] * min(factor, 1.0),
                 sheet_layers=max(1, round(p["sheet_layers"] / factor)))
    build(out, p)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
