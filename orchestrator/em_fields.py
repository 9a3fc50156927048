"""EM fields for ParaView: the moved EM mesh with region ids, force density, Joule power density and
B per element, one ``.vtu`` per output time plus a ``.pvd`` collection (open ``em.pvd``).

This module owns the meshio calls of the EM side.
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

from .results import atomic_write_text


class EMFieldWriter:
    """Write EM snapshots into ``folder`` as ``em_0000.vtu``, ... and ``em.pvd``."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.entries: list[tuple[float, str]] = []

    def write(self, t: float, points: np.ndarray, triangles: np.ndarray, cell_data: dict[str, np.ndarray]) -> Path:
        """One snapshot at time ``t`` (s); ``cell_data`` arrays have one row per triangle (SI units)."""
        name = f"em_{len(self.entries):04d}.vtu"
        pts = np.column_stack([points[:, :2], np.zeros(len(points))])
        mesh = meshio.Mesh(pts, [("triangle", triangles)],
                           cell_data={k: [np.asarray(v)] for k, v in cell_data.items()})
        tmp = self.folder / f".{name}.tmp.vtu"
        meshio.write(tmp, mesh, binary=True)
        tmp.replace(self.folder / name)
        self.entries.append((t, name))
        rows = "\n".join(f'    <DataSet timestep="{tt:.9g}" part="0" file={quoteattr(f)}/>' for tt, f in self.entries)
        atomic_write_text(self.folder / "em.pvd", '<?xml version="1.0"?>\n<VTKFile type="Collection" '
                          'version="0.1">\n  <Collection>\n' + rows + "\n  </Collection>\n</VTKFile>\n")
        return self.folder / name
