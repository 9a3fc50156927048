"""The user-deck contract of the GetDP runner, as data: the physical ids a deck's regions are
renumbered to and the ``-setnumber`` names the deck receives them under, and the output tables a deck
must print (checked by the orchestrator's deck check). The ids are those of :mod:`.mesh` (one
definition: ``AIR``, ``SHELL``, ``AXIS``, ``OUTER``, :func:`.mesh.coil_tag`, :func:`.mesh.conductor_tag`)."""

from __future__ import annotations

from .mesh import AIR, AXIS, OUTER, SHELL, coil_tag, conductor_tag
from .solver import runner_number_names

__all__ = ["ROLE_IDS", "ROLE_NUMBERS", "SURFACE_ROLES", "CURVE_ROLES", "OPTIONAL_ROLES", "REQUIRED_TABLES",
           "CIRCUIT_TABLES", "runner_number_names"]

#: role -> the runner's physical id, and the -setnumber name the deck receives it under
ROLE_IDS = {"air": AIR, "shell": SHELL, "coil": coil_tag(1), "workpiece": conductor_tag(1),
            "die": conductor_tag(2), "axis": AXIS, "outer": OUTER}
ROLE_NUMBERS = {"air": "Phys_Air", "shell": "Phys_Shell", "coil": "Phys_Coil_1", "workpiece": "Phys_Cond_1",
                "die": "Phys_Cond_2", "axis": "Phys_Axis", "outer": "Phys_Outer"}
SURFACE_ROLES, CURVE_ROLES = ("air", "shell", "coil", "workpiece", "die"), ("axis", "outer")
OPTIONAL_ROLES = ("shell", "die")


#: output tables the contract requires after one step (k = 1: one coil, one conductor)
REQUIRED_TABLES = {
    "W.txt": "EM_Step: Print[W[...], OnGlobal, Format Table] (magnetic energy)",
    "coil_I_1.txt": "EM_Step: Print[I, OnRegion Coil_1]", "coil_U_1.txt": "EM_Step: Print[U, OnRegion Coil_1]",
    "coil_P_1.txt": "EM_Step: Print[P[Coil_1], OnGlobal]", "coil_F_1.txt": "EM_Step: Print[F[Coil_1], OnGlobal]",
    "cond_P_1.txt": "EM_Step: Print[P[Cond_1], OnGlobal]", "cond_F_1.txt": "EM_Step: Print[F[Cond_1], OnGlobal]",
    "elem_f.txt": "EM_Elem: Print[f, OnElementsOf Vol_C_Mag, Depth 0]",
    "elem_F.txt": "EM_Elem: Print[F, OnElementsOf Vol_C_Mag, Depth 0]",
    "elem_P.txt": "EM_Elem: Print[P, OnElementsOf Vol_C_Mag, Depth 0]",
    "elem_b.txt": "EM_Elem: Print[b, OnElementsOf Vol_C_Mag, Depth 0]",
    "nodes_a.txt": "EM_State: Print[raz, OnElementsOf Vol_CS_Mag, Format NodeTable]",
}
CIRCUIT_TABLES = {"cir_U.txt": "EM_Step: Print[U, OnRegion Capacitance_Cir]",
                  "cir_I.txt": "EM_Step: Print[I, OnRegion Capacitance_Cir]"}
