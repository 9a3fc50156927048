"""Remeshing a user deck's EM mesh: its named air groups meshed again, everything else kept.

A user deck's mesh (``[geometry] type = "user_deck"``) degrades like a built-in one as the bodies
move; with ``geometry.remesh_air`` (the physical groups of ``regions.air`` / ``regions.shell`` that may
be meshed again) :class:`UserDeckLoad` re-triangulates only those groups around the bodies' current
shapes (:func:`pulseform.orchestrator.mesh.air_remesh.retriangulate_air`): every coil, conductor and
other element keeps its nodes, coordinates and physical id, the boundary line groups keep their node
pairs, and the deck's physical names and ids are untouched (the deck itself is never read or
changed). The EM state then travels as after a built-in remesh, through the Init path with the
nodes' material coordinates (:meth:`GetDPSolver.step` with ``force_init_path``, or a new persistent
getdp seeded with both BDF2 history states): the coil and conductor nodes are the same nodes, so their
values are carried without interpolation. A deck on GetDP's template carries its state by
``-restart`` only: its last ``.res`` is renumbered to the new mesh's dofs
(:meth:`~pulseform.solvers.getdp.template.TemplateDeckSolver.carry_to_mesh`) and the restarts go on.
Without ``remesh_air`` a degraded user mesh stops the run with a one-line message, as before.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from pulseform.solvers.getdp.contract import ROLE_IDS

from ..mesh.air_remesh import AirRemeshError, SizeField, retriangulate_air
from ..mesh.shared import ConductorMesh
from .deck_check import DeckContractError
from .participant import GetDPLoad

log = logging.getLogger(__name__)


def remesh_air_ids(regions, names: Sequence[str]) -> list[int]:
    """The runner's physical ids (1 air, 2 shell) of the ``geometry.remesh_air`` group names."""
    by_name = {regions.air: ROLE_IDS["air"]}
    if regions.shell is not None:
        by_name[regions.shell] = ROLE_IDS["shell"]
    return [by_name[n] for n in names]


class UserDeckLoad(GetDPLoad):
    """:class:`GetDPLoad` whose solver runs the user's deck; its mesh is moved, and remeshed only in the
    air groups ``air_ids`` (the runner's ids; empty: a degraded mesh stops the run).

    Parameters
    ----------
    *args, **kwargs
        Those of :class:`GetDPLoad`.
    air_ids : sequence of int
        Runner's physical ids of the groups that may be re-triangulated.
    """

    def __init__(self, *args, air_ids: Sequence[int] = (), **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.air_ids = [int(t) for t in air_ids]
        # element sizes of every remesh: the deck's fresh air mesh's (no drift over repeated remeshes)
        self.air_sizes = SizeField(self.geometry.mesh, self.air_ids) if self.air_ids else None

    @property
    def init_after_remesh(self) -> bool:
        """False for a template deck: its remesh carries the ``.res`` and the restarts go on (also after a
        resume, which restores the remeshed mesh and the state's ``.res``)."""
        return getattr(self.solver, "carry_to_mesh", None) is None

    def _remesh(self, positions: dict[str, np.ndarray]) -> None:
        """Re-triangulate the air groups around the bodies' current shapes and keep everything else."""
        if not self.air_ids:
            raise DeckContractError("the EM mesh of a user deck degraded beyond em.remesh_quality and the case "
                                    "names no geometry.remesh_air: name the air group(s) that may be meshed again "
                                    "(e.g. remesh_air = [\"AIR\"]), refine the .geo around the workpiece, lower "
                                    "em.remesh_quality or shorten time.end")
        u = np.zeros_like(self.x_ref)
        for b in self.bodies:
            u[b.body_to_em] = b.vertices(positions[b.name]) - self.x_ref[b.body_to_em]
        moved = self.geometry.mesh.with_points(self.x_ref + self.mover.displace(u))
        try:
            mesh, node_map, row_map = retriangulate_air(moved, self.air_ids, time_limit=self.gmsh_time_limit,
                                                         sizes=self.air_sizes)
        except AirRemeshError as exc:
            raise DeckContractError(f"the user mesh's air could not be meshed again: {exc}") from None
        carry = getattr(self.solver, "carry_to_mesh", None)  # a template deck: its .res renumbered to the new mesh
        if carry is not None:
            old_node = np.full(len(mesh.points), -1, dtype=np.int64)
            old_node[node_map[node_map >= 0]] = np.flatnonzero(node_map >= 0)
            self.state = carry(self.state, moved, mesh, old_node, f"remesh_{self.remeshes + 1:03d}")
        material = mesh.points.copy()  # new air nodes: their current position (air values carry no state)
        kept = node_map >= 0
        material[node_map[kept]] = self.material[kept]
        for b in self.bodies:
            b.body_to_em = node_map[b.body_to_em]
            b.sub = ConductorMesh(row_map[b.sub.rows], node_map[b.sub.em_nodes], b.sub.points, b.sub.cells)
            b.match_cells()   # a six-node body: its cells' EM triangles (renumbered)
        self.material = material
        self._set_mesh(mesh)
        self.remeshes += 1
