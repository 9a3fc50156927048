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

from .em_fields import PEAK_NAME, _pvd
from .results import atomic_write_text

log = logging.getLogger(__name__)

#: the folder under ``fields/`` (a resumed part: ``em3d_part<k>``) and the collection's name
FOLDER = "em3d"
SERIES = "sheet_em.pvd"


def write_tet_vtu(path: Path, points: np.ndarray, tets: np.ndarray, cell_data: dict[str, np.ndarray]) -> Path:
    """Tetrahedra (m) with per-cell data (SI), written atomically as a binary ``.vtu``."""
    path = Path(path)
    mesh = meshio.Mesh(np.asarray(points, float)[:, :3], [("tetra", np.asarray(tets))],
                       cell_data={k: [np.asarray(v)] for k, v in cell_data.items()})
    tmp = path.with_name(f".{path.stem}.tmp.vtu")
    meshio.write(tmp, mesh, binary=True)
    tmp.replace(path)
    return path


class EMFieldWriter3D:
    """The sheet's EM snapshots in ``folder``: ``sheet_em_0000.vtu``, ... and ``sheet_em.pvd``."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.entries: list[tuple[float, str]] = []

    def write(self, t: float, points: np.ndarray, tets: np.ndarray, cell_data: dict[str, np.ndarray]) -> Path:
        """One snapshot at output time ``t`` (s)."""
        name = f"sheet_em_{len(self.entries):04d}.vtu"
        write_tet_vtu(self.folder / name, points, tets, cell_data)
        self.entries.append((t, name))
        atomic_write_text(self.folder / SERIES, _pvd(self.entries))
        return self.folder / name


def write_peak_snapshot3d(folder: Path, t: float, current: float, points: np.ndarray, tets: np.ndarray,
                          cell_data: dict[str, np.ndarray]) -> Path:
    """The sheet at the EM step of the largest |coil current| so far (replaces an earlier one):
    ``em_peak_current.vtu`` + ``.pvd`` + ``.json`` (``time_s``, ``coil_current_A``)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = write_tet_vtu(folder / f"{PEAK_NAME}.vtu", points, tets, cell_data)
    atomic_write_text(folder / f"{PEAK_NAME}.pvd", _pvd([(t, path.name)]))
    atomic_write_text(folder / f"{PEAK_NAME}.json", json.dumps(
        {"time_s": float(t), "coil_current_A": float(current), "file": path.name}, indent=1) + "\n")
    return path


@dataclass
class TetSnapshot:
    """One sheet ``.vtu``: node positions (m), tetrahedra, cell data (SI), time (s), coil current (A)."""

    t: float
    points: np.ndarray
    tets: np.ndarray
    cells: dict[str, np.ndarray]
    current: float


def read_peak3d(root: Path) -> TetSnapshot | None:
    """The peak-current snapshot of a coupled 3D results folder, or None when there is none."""
    meta = Path(root) / "fields" / FOLDER / f"{PEAK_NAME}.json"
    try:
        d = json.loads(meta.read_text())
        mesh = meshio.read(meta.parent / d.get("file", f"{PEAK_NAME}.vtu"))
    except (OSError, ValueError, KeyError) as exc:
        log.info("3D EM pictures: no peak snapshot (%s)", exc)
        return None
    tets = np.concatenate([c.data for c in mesh.cells if c.type == "tetra"])
    cells = {k: np.concatenate([np.asarray(a) for a in v]) for k, v in mesh.cell_data.items()}
    return TetSnapshot(float(d["time_s"]), np.asarray(mesh.points), tets, cells, float(d["coil_current_A"]))
