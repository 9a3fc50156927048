"""The loaded area of a 2D workpiece mesh in `pulseform compare` (orchestrator/workflows/compare_area.py):
the frustum areas 2π r̄ L of the boundary edges in the box, i.e. what the pressure run's consistent
nodal forces integrate (transfer.pressure_to_nodal_forces gives Σ F = p × this area)."""

import math

import numpy as np
import pytest

from pulseform.orchestrator.coupling.transfer import pressure_to_nodal_forces
from pulseform.orchestrator.workflows.compare_area import boundary_edges, loaded_area_2d


def _strip(nr: int, nz: int, r0=0.0, r1=0.06, z0=0.0, z1=0.001):
    r, z = np.meshgrid(np.linspace(r0, r1, nr + 1), np.linspace(z0, z1, nz + 1), indexing="ij")
    pts = np.column_stack([r.ravel(), z.ravel()])
    idx = np.arange(len(pts)).reshape(nr + 1, nz + 1)
    tris = []
    for i in range(nr):
        for j in range(nz):
            a, b, c, d = idx[i, j], idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]
            tris += [[a, b, c], [a, c, d]]
    return pts, np.array(tris)


def test_annulus_on_nodes_is_exact_and_between_nodes_is_what_the_mesh_loads():
    pts, tris = _strip(120, 2)   # nodes every 0.5 mm in r
    box = {"xmin": 0.010, "xmax": 0.034, "ymin": -1e-9, "ymax": 1e-9}
    # the box's edges fall on nodes: the exact annulus pi (r2^2 - r1^2)
    assert loaded_area_2d(pts, tris, box, axisymmetric=True) == pytest.approx(math.pi * (0.034**2 - 0.010**2), rel=1e-12)
    # an outer edge between nodes (33.75 mm): the mesh loads up to the last node inside, 33.5 mm
    box2 = dict(box, xmax=0.03375)
    assert loaded_area_2d(pts, tris, box2, axisymmetric=True) == pytest.approx(math.pi * (0.0335**2 - 0.010**2),
                                                                              rel=1e-12)
    # planar: length x thickness
    assert loaded_area_2d(pts, tris, box, axisymmetric=False, thickness=0.2) == pytest.approx(0.024 * 0.2, rel=1e-12)


def test_area_is_the_pressure_runs_resultant_per_pascal():
    pts, tris = _strip(37, 3, r0=0.002, r1=0.05)
    box = {"xmin": 0.011, "xmax": 0.0333, "ymin": -1e-9, "ymax": 1e-9}
    e = boundary_edges(tris)
    inside = (pts[:, 0] >= box["xmin"]) & (pts[:, 0] <= box["xmax"]) & (np.abs(pts[:, 1]) <= 1e-9)
    facets = e[inside[e[:, 0]] & inside[e[:, 1]]]
    # orient so that the body is on the left of a -> b (outward normal -z on the lower face)
    facets = np.where((pts[facets[:, 1], 0] < pts[facets[:, 0], 0])[:, None], facets, facets[:, ::-1])
    f = pressure_to_nodal_forces(pts, facets, 1.0, axisymmetric=True)
    assert abs(f[:, 1].sum()) == pytest.approx(loaded_area_2d(pts, tris, box, axisymmetric=True), rel=1e-12)
