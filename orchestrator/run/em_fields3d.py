"""EM fields of a coupled 3D run for ParaView: the sheet's tetrahedra at their moved positions with the
Lorentz force density (N/m^3, vector and magnitude) and the Joule power density (W/m^3) per
tetrahedron at the end of the EM step, one ``.vtu`` per output time plus a ``.pvd`` collection
(``fields/em3d/sheet_em.pvd``), and the snapshot at the peak coil current (``em_peak_current.vtu``,
its time and current in ``em_peak_current.json``). Written and read with meshio here.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path

import meshio
import numpy as np

from .em_fields import PEAK_NAME

log = logging.getLogger(__name__)

#: the folder under ``fields/`` (a resumed part: ``em3d_part<k>``) and the collection's name
FOLDER = "em3d"
SERIES = "sheet_em.pvd"
#: the snapshots' file stem (:class:`~.em_fields.EMFieldWriter`'s ``stem``)
STEM = "sheet_em"
#: every conductor (bodies and fixed conductors) at the peak coil current: ``<CONDUCTORS_PEAK>.vtu`` / ``.json``
CONDUCTORS_PEAK = "em_peak_current_conductors"


@dataclass
class TetSnapshot:
    """One sheet ``.vtu``: node positions (m), tetrahedra, cell data (SI), time (s), coil current (A)."""

    t: float
    points: np.ndarray
    tets: np.ndarray
    cells: dict[str, np.ndarray]
    current: float


def read_peak3d(root: Path, name: str = PEAK_NAME) -> TetSnapshot | None:
    """The peak-current snapshot of a coupled 3D results folder (``name``: the sheet's ``em_peak_current``, or
    :data:`CONDUCTORS_PEAK`), or None when there is none."""
    meta = Path(root) / "fields" / FOLDER / f"{name}.json"
    try:
        d = json.loads(meta.read_text())
        mesh = meshio.read(meta.parent / d.get("file", f"{name}.vtu"))
    except (OSError, ValueError, KeyError) as exc:
        log.info("3D EM pictures: no peak snapshot (%s)", exc)
        return None
    tets = np.concatenate([c.data for c in mesh.cells if c.type == "tetra"])
    cells = {k: np.concatenate([np.asarray(a) for a in v]) for k, v in mesh.cell_data.items()}
    return TetSnapshot(float(d["time_s"]), np.asarray(mesh.points), tets, cells, float(d["coil_current_A"]))
