"""EM fields for ParaView: the moved EM mesh with region ids, force density, Joule power density and
B per element and the nodal potential (flux lines), one ``.vtu`` per output time plus a ``.pvd``
collection (open ``em.pvd``), and the snapshot at the peak coil current (``em_peak_current.vtu``,
its time and current in ``em_peak_current.json``; ``em_peak_current.pvd`` opens it with its time).

The reader (:func:`read_snapshot`, :func:`output_series`, :func:`peak_file`) is here too: this module
owns the meshio calls of the EM side.
"""

from __future__ import annotations

import json
import logging
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

from pulseform.solvers.getdp.mesh import AIR

from .results import atomic_write_text

log = logging.getLogger(__name__)

PEAK_NAME = "em_peak_current"


def _pvd(entries: list[tuple[float, str]]) -> str:
    rows = "\n".join(f'    <DataSet timestep="{t:.9g}" part="0" file={quoteattr(f)}/>' for t, f in entries)
    return ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n  <Collection>\n' + rows
            + "\n  </Collection>\n</VTKFile>\n")


def write_vtu(path: Path, points: np.ndarray, cells: np.ndarray, cell_data: dict[str, np.ndarray],
              point_data: dict[str, np.ndarray] | None = None) -> Path:
    """One EM mesh with per-cell ``cell_data`` and per-node ``point_data``, written atomically: triangles
    (points (n, 2), written at z = 0) or tetrahedra (points (n, 3))."""
    path = Path(path)
    cells = np.asarray(cells)
    if cells.shape[1] == 4:
        kind, pts = "tetra", np.asarray(points, float)[:, :3]
    else:
        kind, pts = "triangle", np.column_stack([points[:, :2], np.zeros(len(points))])
    mesh = meshio.Mesh(pts, [(kind, cells)],
                       point_data={k: np.asarray(v) for k, v in (point_data or {}).items()},
                       cell_data={k: [np.asarray(v)] for k, v in cell_data.items()})
    tmp = path.with_name(f".{path.stem}.tmp.vtu")
    meshio.write(tmp, mesh, binary=True)
    tmp.replace(path)
    return path


class EMFieldWriter:
    """Write EM snapshots into ``folder`` as ``<stem>_0000.vtu``, ... and ``<stem>.pvd`` (``em``; a coupled
    3D run's sheet: ``sheet_em``)."""

    def __init__(self, folder: Path, stem: str = "em") -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.stem = stem
        self.entries: list[tuple[float, str]] = []

    def write(self, t: float, points: np.ndarray, triangles: np.ndarray, cell_data: dict[str, np.ndarray],
              point_data: dict[str, np.ndarray] | None = None) -> Path:
        """One snapshot at time ``t`` (s); ``cell_data`` arrays have one row per triangle (tetrahedron),
        ``point_data`` one per node (SI units)."""
        name = f"{self.stem}_{len(self.entries):04d}.vtu"
        write_vtu(self.folder / name, points, triangles, cell_data, point_data)
        self.entries.append((t, name))
        atomic_write_text(self.folder / f"{self.stem}.pvd", _pvd(self.entries))
        return self.folder / name


def write_peak_snapshot(folder: Path, t: float, current: float, points: np.ndarray, triangles: np.ndarray,
                        cell_data: dict[str, np.ndarray], point_data: dict[str, np.ndarray] | None = None, *,
                        name: str = PEAK_NAME) -> Path:
    """The snapshot at the EM step of the largest |coil current| so far (replaces an earlier one):
    ``<name>.vtu`` + ``.pvd`` (its time) + ``.json`` (``time_s``, ``coil_current_A``); ``name`` default
    ``em_peak_current``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = write_vtu(folder / f"{name}.vtu", points, triangles, cell_data, point_data)
    atomic_write_text(folder / f"{name}.pvd", _pvd([(t, path.name)]))
    atomic_write_text(folder / f"{name}.json", json.dumps(
        {"time_s": float(t), "coil_current_A": float(current), "file": path.name}, indent=1) + "\n")
    return path


# ----------------------------------------------------------------------------- reading them back
@dataclass
class Snapshot:
    """One EM ``.vtu``: moved mesh (m), cell and point data (SI), its time (s) and coil current (A)."""

    t: float
    points: np.ndarray
    triangles: np.ndarray
    cells: dict[str, np.ndarray]
    nodes: dict[str, np.ndarray] = field(default_factory=dict)
    current: float | None = None
    label: str = ""

    @property
    def region(self) -> np.ndarray:
        return self.cells["region"]

    @property
    def potential(self) -> tuple[str, np.ndarray] | None:
        for name in ("r_a_phi_Wb", "a_z_Wb_m"):
            if name in self.nodes:
                return name, self.nodes[name]
        return None

    def b_everywhere(self) -> bool:
        """B written on every cell (not only on the conductors)."""
        b = np.abs(self.cells["flux_density_T"][:, :2]).sum(axis=1)
        return bool(np.any(b[self.region == AIR] > 0))

    def magnitude(self, name: str) -> np.ndarray:
        return np.linalg.norm(self.cells[name][:, :2], axis=1)


def read_snapshot(path: Path, t: float, current: float | None = None, label: str = "") -> Snapshot:
    """The EM ``.vtu`` at ``path`` (time ``t`` s, coil ``current`` A) as a :class:`Snapshot`."""
    mesh = meshio.read(path)
    blocks = [i for i, c in enumerate(mesh.cells) if c.type == "triangle"]
    triangles = np.concatenate([mesh.cells[i].data for i in blocks])
    cells = {k: np.concatenate([np.asarray(v[i]) for i in blocks]) for k, v in mesh.cell_data.items()}
    nodes = {k: np.asarray(v) for k, v in mesh.point_data.items()}
    return Snapshot(t, np.asarray(mesh.points)[:, :2], triangles, cells, nodes, current, label)


def output_series(root: Path) -> list[tuple[float, Path]]:
    """(time, file) of every EM snapshot of ``fields/em*/em.pvd`` (resumed parts too), by time."""
    found: dict[float, Path] = {}
    for pvd in sorted((root / "fields").glob("em*/em.pvd")):
        try:
            for ds in ET.parse(pvd).getroot().iter("DataSet"):
                path = pvd.parent / ds.get("file")
                if path.is_file():
                    found[round(float(ds.get("timestep")), 15)] = path
        except (ET.ParseError, OSError, TypeError, ValueError) as exc:
            log.info("EM pictures: %s unreadable (%s)", pvd, exc)
    return sorted(found.items())


def peak_file(root: Path) -> tuple[float, float, Path] | None:
    """(time, coil current, file) of ``fields/em/em_peak_current.vtu``, or None."""
    meta = root / "fields" / "em" / "em_peak_current.json"
    try:
        d = json.loads(meta.read_text())
        path = meta.parent / d.get("file", "em_peak_current.vtu")
        return (float(d["time_s"]), float(d["coil_current_A"]), path) if path.is_file() else None
    except (OSError, ValueError, KeyError, TypeError):
        return None
