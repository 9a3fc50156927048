"""The area a pressure run of ``pulseform compare`` actually loads on a 2D workpiece mesh: the
boundary edges with both nodes in the loaded box, as the pressure run's consistent nodal forces see
them (axisymmetric: the frustum 2π r̄ L of each edge; planar: L × the case's thickness). Dividing
the coupled force by this area, not by the nominal annulus or strip, gives the pressure run the
coupled impulse: a mesh has no node at the box's edge in general (the demo's 0.5 mm sheet mesh
loads 32.11 cm² of the nominal 33.18 cm², 3.2 % less)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)


def boundary_edges(triangles: np.ndarray) -> np.ndarray:
    """Edges (E, 2) of the triangles that belong to one triangle only."""
    e = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    key, idx, cnt = np.unique(np.sort(e, axis=1), axis=0, return_index=True, return_counts=True)
    return e[idx[cnt == 1]]


def loaded_area_2d(points: np.ndarray, triangles: np.ndarray, box: dict, *, axisymmetric: bool,
                   thickness: float = 1.0) -> float:
    """Reference area (m²) of the boundary edges of a triangle mesh (``points`` (N, ≥2) in m, x = r,
    y = z in axisymmetry) with both nodes inside ``box`` (xmin, xmax, ymin, ymax; inclusive)."""
    x, y = points[:, 0], points[:, 1]
    inside = (x >= box["xmin"]) & (x <= box["xmax"]) & (y >= box["ymin"]) & (y <= box["ymax"])
    e = boundary_edges(np.asarray(triangles))
    e = e[inside[e[:, 0]] & inside[e[:, 1]]]
    a, b = points[e[:, 0], :2], points[e[:, 1], :2]
    length = np.linalg.norm(b - a, axis=1)
    if axisymmetric:
        return float(np.sum(np.pi * (a[:, 0] + b[:, 0]) * length))
    return float(np.sum(length) * thickness)


def mesh_area(case, folder: Path, body: str, box: dict, nominal: float) -> float:
    """The loaded area (m²) of the 2D workpiece mesh of the coupled run in ``folder`` (the nominal one,
    logged, when its fields cannot be read)."""
    from ..run.mech_fields import FieldFileError, read_fields
    from .compare import CompareError

    try:
        bf = read_fields(folder)[body]
    except (FieldFileError, KeyError) as exc:
        log.warning("compare: no mesh of %r in %s (%s): the nominal area %.4g cm^2", body, folder, exc, nominal * 1e4)
        return nominal
    area = loaded_area_2d(bf.points, bf.triangles, box, axisymmetric=case.mechanics.formulation == "axisymmetric",
                          thickness=case.mechanics.thickness)
    if area <= 0.0:
        raise CompareError(f"compare: the loaded surface {box} holds no boundary edge of {body!r}")
    log.info("compare: loaded area %.6g cm^2 on the mesh (nominal %.6g cm^2)", area * 1e4, nominal * 1e4)
    return area
