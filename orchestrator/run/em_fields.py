"""EM fields for ParaView: the moved EM mesh with region ids, force density, Joule power density and
B per element and the nodal potential (flux lines), one ``.vtu`` per output time plus a ``.pvd``
collection (open ``em.pvd``), and the snapshot at the peak coil current (``em_peak_current.vtu``,
its time and current in ``em_peak_current.json``; ``em_peak_current.pvd`` opens it with its time).

This module owns the meshio calls of the EM side.
"""

from __future__ import annotations

import json
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

from .results import atomic_write_text

PEAK_NAME = "em_peak_current"


def _pvd(entries: list[tuple[float, str]]) -> str:
    rows = "\n".join(f'    <DataSet timestep="{t:.9g}" part="0" file={quoteattr(f)}/>' for t, f in entries)
    return ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n  <Collection>\n' + rows
            + "\n  </Collection>\n</VTKFile>\n")


def write_vtu(path: Path, points: np.ndarray, triangles: np.ndarray, cell_data: dict[str, np.ndarray],
              point_data: dict[str, np.ndarray] | None = None) -> Path:
    """One EM mesh (z = 0) with per-triangle ``cell_data`` and per-node ``point_data``, written atomically."""
    path = Path(path)
    pts = np.column_stack([points[:, :2], np.zeros(len(points))])
    mesh = meshio.Mesh(pts, [("triangle", triangles)],
                       point_data={k: np.asarray(v) for k, v in (point_data or {}).items()},
                       cell_data={k: [np.asarray(v)] for k, v in cell_data.items()})
    tmp = path.with_name(f".{path.stem}.tmp.vtu")
    meshio.write(tmp, mesh, binary=True)
    tmp.replace(path)
    return path


class EMFieldWriter:
    """Write EM snapshots into ``folder`` as ``em_0000.vtu``, ... and ``em.pvd``."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.entries: list[tuple[float, str]] = []

    def write(self, t: float, points: np.ndarray, triangles: np.ndarray, cell_data: dict[str, np.ndarray],
              point_data: dict[str, np.ndarray] | None = None) -> Path:
        """One snapshot at time ``t`` (s); ``cell_data`` arrays have one row per triangle,
        ``point_data`` one per node (SI units)."""
        name = f"em_{len(self.entries):04d}.vtu"
        write_vtu(self.folder / name, points, triangles, cell_data, point_data)
        self.entries.append((t, name))
        atomic_write_text(self.folder / "em.pvd", _pvd(self.entries))
        return self.folder / name


def write_peak_snapshot(folder: Path, t: float, current: float, points: np.ndarray, triangles: np.ndarray,
                        cell_data: dict[str, np.ndarray], point_data: dict[str, np.ndarray] | None = None) -> Path:
    """The snapshot at the EM step of the largest |coil current| so far (replaces an earlier one):
    ``em_peak_current.vtu`` + ``.pvd`` (its time) + ``.json`` (``time_s``, ``coil_current_A``)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = write_vtu(folder / f"{PEAK_NAME}.vtu", points, triangles, cell_data, point_data)
    atomic_write_text(folder / f"{PEAK_NAME}.pvd", _pvd([(t, path.name)]))
    atomic_write_text(folder / f"{PEAK_NAME}.json", json.dumps(
        {"time_s": float(t), "coil_current_A": float(current), "file": path.name}, indent=1) + "\n")
    return path
