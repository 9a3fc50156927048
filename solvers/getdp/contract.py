"""The user-deck contract of the GetDP runner, as data: the physical ids a deck's regions are
renumbered to and the ``-setnumber`` names the deck receives them under, and the output tables a deck
must print (checked by the orchestrator's deck check). The ids are those of :mod:`.mesh` (one
definition: ``AIR``, ``SHELL``, ``AXIS``, ``OUTER``, :func:`.mesh.coil_tag`, :func:`.mesh.conductor_tag`)."""

from __future__ import annotations

import re
from functools import lru_cache

from .mesh import AIR, AXIS, OUTER, SHELL, EMMesh, coil_tag, conductor_tag, physical_numbers
from .model import Circuit, Coil, Conductor, CurrentTable, DampedSine, EMModel
from .deck_numbers import model_deck_numbers
from .solver import DECK_DIR

__all__ = ["ROLE_IDS", "ROLE_NUMBERS", "SURFACE_ROLES", "CURVE_ROLES", "OPTIONAL_ROLES", "REQUIRED_TABLES",
           "CIRCUIT_TABLES", "RUN_PRO_LISTS", "COIL_NUMBERS", "coil_number_name", "coil_tables", "runner_number_names"]

#: role -> the runner's physical id, and the -setnumber name the deck receives it under
ROLE_IDS = {"air": AIR, "shell": SHELL, "coil": coil_tag(1), "workpiece": conductor_tag(1),
            "die": conductor_tag(2), "axis": AXIS, "outer": OUTER}
ROLE_NUMBERS = {"air": "Phys_Air", "shell": "Phys_Shell", "coil": "Phys_Coil_1", "workpiece": "Phys_Cond_1",
                "die": "Phys_Cond_2", "axis": "Phys_Axis", "outer": "Phys_Outer"}
SURFACE_ROLES, CURVE_ROLES = ("air", "shell", "coil", "workpiece", "die"), ("axis", "outer")
OPTIONAL_ROLES = ("shell", "die")
#: the family of -setnumber names of the coil ids: coil k (k = 1, 2, ...) is physical ``coil_tag(k)`` = 100 + k,
#: received as ``Phys_Coil_<k>`` (``Phys_Coil_1`` is the role ``coil``'s :data:`ROLE_NUMBERS` entry)
COIL_NUMBERS = "Phys_Coil_<k>"


def coil_number_name(k: int) -> str:
    """The ``-setnumber`` name under which a deck receives the physical id of coil ``k`` (1-based)."""
    if k < 1:
        raise ValueError(f"coil numbers start at 1, got {k}")
    return f"Phys_Coil_{k}"


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


def coil_tables(k: int) -> dict[str, str]:
    """The per-coil output tables of coil ``k`` (1-based) the contract requires, with what prints them
    (coil 1's are in :data:`REQUIRED_TABLES`)."""
    return {f"coil_I_{k}.txt": f"EM_Step: Print[I, OnRegion Coil_{k}]",
            f"coil_U_{k}.txt": f"EM_Step: Print[U, OnRegion Coil_{k}]",
            f"coil_P_{k}.txt": f"EM_Step: Print[P[Coil_{k}], OnGlobal]",
            f"coil_F_{k}.txt": f"EM_Step: Print[F[Coil_{k}], OnGlobal]"}


# ----------------------------------------------------------------------------- names a run sets
#: lists ``run.pro`` defines before the deck is included: the Init path's nodal values
#: (:meth:`GetDPSolver.step`), the coil current tables (:meth:`GetDPSolver._table_lines`), the B–H curves'
#: tables (:func:`.bh_curve.model_magnetic`) and the libraries' paths
RUN_PRO_LISTS = ("InitA_List", "InitA2_List", "Coil_Table_<k>", "Cond_BH_<k>", "Cond_BHw_<k>", "Core_BH_<k>",
                 "Core_BHw_<k>", "PulseformPersistentLib", "PulseformHarmonicLib", "PulseformMagneticLib")
#: the library decks whose ``DefineConstant`` inputs a run may set: the formulation, the persistent getdp, Newton's
#: constants and the magnetic block (``em_magnetic.pro``, a user deck's ``PulseformMagneticLib``)
RUNNER_DECKS = ("Lib_PulsedForming.pro", "Lib_Persistent.pro", "Lib_PersistentSigma.pro", "Lib_Newton.pro",
                "em_magnetic.pro")


def _indexed(name: str) -> str:
    """``Coil_Ns_1`` / ``Coil_Ns~{k}`` -> ``Coil_Ns_<k>`` (one entry per indexed family)."""
    return re.sub(r"(?:_\d+|~\{\w+\})$", "_<k>", name)


@lru_cache(maxsize=1)
def runner_number_names() -> tuple[str, ...]:
    """Every name a :class:`GetDPSolver` run defines in getdp, sorted; indexed families once as
    ``Coil_Ns_<k>`` (``<k>`` = 1, 2, ...).

    The union of (1) the ``DefineConstant`` inputs of the library decks :data:`RUNNER_DECKS`
    (the numbers and strings a step passes with ``-setnumber`` / ``-setstring``: ``TimeInit``,
    ``NbSteps``, ``Flag_*``, ``C_bank``, ``OutDir``, ...), (2) the numbers :func:`.deck_numbers.model_deck_numbers`
    computes from a model and mesh (evaluated here on small models with every option on: a
    circuit or a prescribed current, a shell, a probe, a coil and two conductors), (3) the physical
    ids the built-in deck receives (:func:`.mesh.physical_numbers`: ``Phys_Air``, ...,
    ``Phys_Coil_Base``) and (4) :data:`RUN_PRO_LISTS`.  A user deck's own parameters may not reuse
    any of them (``pulseform.orchestrator.case.deck_files``).
    """
    names = set()
    for deck in RUNNER_DECKS:
        lib = re.sub(r"//[^\n]*", "", (DECK_DIR / deck).read_text())
        for block in re.findall(r"DefineConstant\s*\[(.*?)\]\s*;", lib, flags=re.S):
            names.update(_indexed(n) for n in re.findall(r"([A-Za-z_]\w*(?:~\{\w+\})?)\s*=", block))
    pts = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    mesh = EMMesh(pts, [[0, 1, 2], [0, 2, 3], [0, 1, 3]], [coil_tag(1), conductor_tag(1), conductor_tag(2)],
                  [[0, 3]], [11])
    conductors = [Conductor(1.0), Conductor(1.0)]
    models = [EMModel(True, [Coil(1)], conductors, circuit=Circuit(1.0, 1.0), shell=(1.0, 2.0), probes=[(0.5, 0.5)]),
              EMModel(True, [Coil(1, waveform=DampedSine(1.0, 1.0, 1.0))], conductors),
              EMModel(True, [Coil(1, waveform=CurrentTable([0.0, 1.0], [0.0, 1.0]))], conductors)]
    for model in models:
        names.update(_indexed(n) for n in model_deck_numbers(model, mesh, {}))
    names.update(physical_numbers())
    names.update(RUN_PRO_LISTS)
    return tuple(sorted(names))
