"""A mechanical 3D body that is an EM conductor region of the 3D GetDP load (:mod:`.participant3d`): its nodes in the
EM mesh and, for a ten-node body, the EM tetrahedron of each of its cells."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..mesh.shared3d import ConductorMesh3D
from ..mesh.shared import em_rows_of_cells

__all__ = ["ConductorBody3D"]


@dataclass
class ConductorBody3D:
    """A mechanical 3D body that is an EM conductor region (shared nodes): its ``name``, EM physical
    id ``tag`` (201, ...), the region cut from the EM mesh ``sub`` and ``body_to_em``, the EM node of
    each of the body's vertex rows (its first rows: all of a linear body's).

    A ten-node body (``element = "tet10"``) also gives ``cells10``, its cells (nc, 10) as body rows (corners, then
    the edge nodes after the vertex rows, :mod:`pulseform.solvers.dolfinx.tet10`); :meth:`match_cells` finds the
    EM tetrahedron of each (``em_rows``): the EM mesh moves with the vertex rows, the edge nodes follow the
    mechanics only, and the force of each EM tetrahedron goes to its cell's ten nodes
    (:func:`~pulseform.orchestrator.coupling.transfer3d.body_forces`).
    """

    name: str
    tag: int
    sub: ConductorMesh3D
    body_to_em: np.ndarray
    cells10: np.ndarray | None = None
    em_rows: np.ndarray | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        self.match_cells()

    @property
    def n_nodes(self) -> int:
        """The body's node rows: its vertices, and a ten-node body's edge nodes."""
        return len(self.body_to_em) if self.cells10 is None else int(self.cells10.max()) + 1

    def vertices(self, x: np.ndarray) -> np.ndarray:
        """The vertex rows (n, 3) of a body's nodal array ``x`` (its first rows; the EM mesh's nodes)."""
        return np.asarray(x)[:len(self.body_to_em), :3]

    def match_cells(self) -> None:
        """A ten-node body: the row of the EM mesh's tetrahedra of each of its cells (``em_rows``), from ``sub``
        and ``body_to_em`` (again after the air is meshed again: the conductors' tetrahedra are kept node for node
        but renumbered). ValueError when a cell has none."""
        if self.cells10 is not None:
            self.em_rows = em_rows_of_cells(self.name, self.sub, self.body_to_em, self.cells10)
