"""Gmsh builder of the racetrack / sheet / grooved-die quarter model (a 3D geometry file of
``cases/emf_racetrack_groove``): ``python racetrack_geometry.py OUT.msh [name=value ...]``.

It writes OUT.msh with the named physical groups the case's role map uses: "air", "shell", "coil" with its
terminals "coil_in" (on y = 0) and "coil_out" (on x = 0), "sheet", "die" (and their skins, "symmetry",
"outer", which the runner recomputes). The names ``name=value`` are the fields of
:class:`pulseform.solvers.getdp.racetrack_mesh.RacetrackGroove` (m; ``turns`` and ``sheet_layers`` integers;
``h_coil``, ``h_sheet``, ``h_die``, ``h_air`` the element sizes, ``grading`` the growth of the size per metre
away from the coil's footprint); ``mesh_size_factor`` (pulseform's ``geometry.mesh_size_factor``) multiplies the
sizes and divides the sheet's layers (:meth:`RacetrackGroove.scaled`: the air's size at the sphere only refined). The mesher is pulseform's OpenCASCADE build of this geometry (the sheet
extruded in layers through its thickness), so the mesh is the one of the study's reference run
(studies/emf_racetrack_groove).
"""

import sys
from dataclasses import fields

from pulseform.orchestrator.mesh.gmsh_file import BuilderArgumentError, builder_arguments
from pulseform.solvers.getdp.racetrack_mesh import RacetrackGroove, racetrack_groove_mesh


def main(argv: list[str]) -> int:
    try:
        out, values, factor = builder_arguments(argv, [f.name for f in fields(RacetrackGroove)],
                                                integers=("turns", "sheet_layers"))
        g = RacetrackGroove(**values)
        racetrack_groove_mesh(out, g if factor == 1.0 else g.scaled(factor))
    except (BuilderArgumentError, ValueError) as exc:   # an unknown name, an inconsistent geometry
        print(f"Error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
