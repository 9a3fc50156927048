"""What ``pulseform compare`` does differently on a coupled 3D sector (``mechanics.formulation = "3d"``).

- The pressure: the coupled run's axial force on the sector's sheet (``force_z_N``, the sector's) over
  the loaded area of the sector's mesh: the reference area of the boundary triangles whose three nodes
  lie in the loaded surface's (r, z) box (the triangles the pressure run loads,
  :mod:`~..mech.sector_pulses`), read from the coupled run's sheet mesh in ``fields/``. The fitted
  pulse p(t) = F_z,sector / A_sector = F_z,device / A_device (A_device = A_sector × 360 / angle) then
  carries the coupled impulse on exactly the area the pressure run loads; the nominal annulus
  π(r2² − r1²) is reported beside it (the mesh's triangles straddling r1 and r2 are not loaded).
- The final shapes: the 3D final positions of the same nodes (the two runs mesh the same sector);
  the picture is the meridian profile (r, z) of the sheet's lower surface of both runs.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..case.model import Box, Case
from ..mech.sector_pulses import loaded_triangles, rz_marker


def boundary_triangles(tets: np.ndarray) -> np.ndarray:
    """The faces (n, 3) of a tetrahedral mesh's cells (m, 4) that belong to one cell only."""
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 2, 3]], tets[:, [0, 1, 3]], tets[:, [0, 1, 2]]])
    key = np.sort(faces, axis=1)
    _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
    return faces[first[count == 1]]


def triangle_areas(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Areas (m²) of triangles (n, 3 node rows) of ``points`` (N, 3) m."""
    p0 = points[tris[:, 0]]
    return 0.5 * np.linalg.norm(np.cross(points[tris[:, 1]] - p0, points[tris[:, 2]] - p0), axis=1)


def sector_loaded_area(points: np.ndarray, tets: np.ndarray, box: Box | dict) -> float:
    """Reference area (m²) of the boundary triangles of the tetrahedral mesh (``points`` (N, 3) m,
    ``tets`` (m, 4)) with their three nodes in ``box`` read in (r, z)."""
    box = Box(**box) if isinstance(box, dict) else box
    tris = loaded_triangles(boundary_triangles(tets), rz_marker(box, points))
    return float(triangle_areas(points, tris).sum())


def sector_loading(case: Case, folder: Path, body: str, box: dict) -> tuple[float, float]:
    """(The sector's loaded area A_sector (m²) on the coupled run's sheet mesh in ``folder``, the
    symmetry factor 360 / angle)."""
    from ..run.mech_fields import FieldFileError, read_fields
    from .compare import CompareError

    try:
        bf = read_fields(folder)[body]
    except (FieldFileError, KeyError) as exc:
        raise CompareError(f"compare: no sheet mesh of body {body!r} in {folder / 'fields'} ({exc})",
                           run_failed=True) from None
    area = sector_loaded_area(bf.points, bf.triangles, box)
    if area <= 0.0:
        raise CompareError(f"compare: the loaded surface {box} holds no boundary triangle of {body!r}")
    return area, 360.0 / case.sector.angle_deg


def nominal_area(box: dict) -> float:
    """The loaded annulus π(r2² − r1²) of an (r, z) box (m²), the whole device's."""
    return math.pi * (box["xmax"] ** 2 - box["xmin"] ** 2)


def meridian_profile(x: np.ndarray, u: np.ndarray, z0: float, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """(r, z) (m) of the deformed nodes of the surface z = ``z0`` (reference, within ``tol`` m) of a 3D
    body (reference ``x`` and displacement ``u``, (N, 3) m), in the order of their reference radius."""
    on = np.abs(x[:, 2] - z0) <= tol
    y = x[on] + u[on]
    order = np.argsort(np.hypot(x[on, 0], x[on, 1]), kind="stable")
    return np.hypot(y[order, 0], y[order, 1]), y[order, 2]


def plot_meridian(ax, shape_c, shape_p, z0: float, tol: float) -> None:
    """The lower surface's meridian profile (r, z in mm) of both runs on ``ax``: ``shape_*`` are
    (reference, displacement) (N, 3) arrays (m)."""
    for (x, u), lab, st in ((shape_c, "coupled", ".-"), (shape_p, "pressure", "x--")):
        r, z = meridian_profile(x, u, z0, tol)
        ax.plot(r * 1e3, z * 1e3, st, ms=2.5, lw=0.8, label=lab)
    ax.set(xlabel="r (mm)", ylabel="z (mm)")
