"""The quadratic (six-node) triangle of the 2D bodies (``BodySpec.element = "tri6"``, issue 34 item 4): the
element that bends without locking in plane stress, plane strain and axisymmetry — the 2D counterpart of
:mod:`.tet10`, whose helpers it shares (:func:`.tet10.quadratic_cells`, :func:`.tet10.step_factor`).

A linear triangle has a constant strain: a sheet two or three of them thick is far too stiff in bending (shear
locking: docs/mechanics.md gives the figures of a plane-stress cantilever). The six-node triangle carries a linear
strain and bends.

Conventions
-----------
* Nodes 0-2 are the corners (the linear mesh's vertices, counter-clockwise), nodes 3-5 the midpoints of the edges
  (0, 1), (1, 2), (2, 0) (:data:`EDGES`; VTK's and XDMF's ``Triangle_6`` order). The body numbers the vertices
  first (the rows of the linear body), then one node per mesh edge.
* Isoparametric: positions and velocities interpolate with the same six shape functions.
* Three-point Gauss rule (degree 2: exact for the planar stiffness of a straight element). The stress, plastic
  strain and temperature live at the Gauss points: a body of ``nc`` cells carries ``nc * 3`` rows, cell-major
  (row ``3 e + q``). Axisymmetry: the hoop strain and the ring's 2 pi r at each Gauss point's own radius.
* Lumped mass by HRZ (Hinton, Rock and Zienkiewicz 1976): the diagonal of the consistent mass (r-weighted in
  axisymmetry), scaled to the element's mass; a straight planar cell gives a corner 1/19 and an edge node 16/57
  of rho V (row sums would give the corners zero).
* Boundary: each three-node edge (corners a b, middle m) is cut into the two segments (a, m), (m, b) with the
  orientation of the edge (the body's ``segments``: tributary areas, probes). A pressure load is integrated on
  the three-node edges themselves (:func:`edge_pressure_forces`: consistent, a straight planar edge's force 1/6
  at each corner and 2/3 at its middle; the two segments' split, 1/4 and 1/2, perturbs the displacement near the
  loaded face: +0.3 % at the bore of a thick cylinder, measured).
"""
from __future__ import annotations

import numpy as np

from .face_pressure import read_face_pressures
from .tet10 import step_factor

__all__ = ["EDGES", "N_QP", "QP_WEIGHTS", "QP_DERIVATIVES", "QP_VALUES", "shape_values", "shape_derivatives",
           "hrz_cell_masses", "hrz_lumped_mass", "hrz_shares",
           "three_node_edges", "split_edges", "edge_pressure_forces", "qp_measures",
           "critical_step_factor"]

#: corner pairs of the edge nodes 3..5
EDGES = ((0, 1), (1, 2), (2, 0))
#: quadrature points per cell
N_QP = 3
#: barycentric coordinates (L0, L1, L2) of the three Gauss points (degree 2, interior)
QP_BARY = np.array([[2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0], [1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0],
                    [1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0]])
#: their weights on the reference triangle (area 1/2): the area of a cell is sum_q w_q det J_q
QP_WEIGHTS = np.full(N_QP, 1.0 / 6.0)
#: the degree-5 seven-point rule (Dunavant 1985) of the mass integrals: barycentric points and weights (sum 1/2)
_A1, _A2 = 0.470142064105115, 0.101286507323456
_W1, _W2 = 0.132394152788506, 0.125939180544827
_MASS_BARY = np.array([[1 / 3, 1 / 3, 1 / 3], [_A1, _A1, 1 - 2 * _A1], [_A1, 1 - 2 * _A1, _A1],
                       [1 - 2 * _A1, _A1, _A1], [_A2, _A2, 1 - 2 * _A2], [_A2, 1 - 2 * _A2, _A2],
                       [1 - 2 * _A2, _A2, _A2]])
_MASS_W = 0.5 * np.array([0.225, _W1, _W1, _W1, _W2, _W2, _W2])


def shape_values(bary: np.ndarray) -> np.ndarray:
    """The six shape functions at points of barycentric coordinates ``bary`` (n, 3): (n, 6)."""
    L = np.asarray(bary, dtype=float)
    out = np.empty((L.shape[0], 6))
    out[:, :3] = L * (2.0 * L - 1.0)
    for m, (i, j) in enumerate(EDGES):
        out[:, 3 + m] = 4.0 * L[:, i] * L[:, j]
    return out


def shape_derivatives(bary: np.ndarray) -> np.ndarray:
    """Derivatives of the six shape functions with respect to the reference coordinates (xi, eta) = (L1, L2) at
    points of barycentric coordinates ``bary`` (n, 3): (n, 6, 2)."""
    L = np.asarray(bary, dtype=float)
    dL = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])      # L0 = 1 - xi - eta
    out = np.zeros((L.shape[0], 6, 2))
    for k in range(3):
        out[:, k, :] = (4.0 * L[:, k] - 1.0)[:, None] * dL[k]
    for m, (i, j) in enumerate(EDGES):
        out[:, 3 + m, :] = 4.0 * (L[:, i, None] * dL[j] + L[:, j, None] * dL[i])
    return out


#: shape functions and their derivatives at the Gauss points, (3, 6) and (3, 6, 2)
QP_VALUES = shape_values(QP_BARY)
QP_DERIVATIVES = shape_derivatives(QP_BARY)


def _weights(x: np.ndarray, values: np.ndarray, axisymmetric: bool, thickness: float) -> np.ndarray:
    """The out-of-plane factor at points of shape-function ``values`` (n, 6) of cells ``x`` (nc, 6, 2): 2 pi r
    (axisymmetric) or the thickness (planar), m, (nc, n)."""
    if axisymmetric:
        return 2.0 * np.pi * np.einsum("qa,ca->cq", values, x[:, :, 0])
    return np.full((x.shape[0], values.shape[0]), float(thickness), dtype=x.dtype)


def qp_measures(cells6: np.ndarray, x: np.ndarray, axisymmetric: bool, thickness: float) -> np.ndarray:
    """The volume of each Gauss point, w_q det J_q times the thickness or 2 pi r_q (nc * 3,), m^3, cell-major
    (their sum over a cell is its volume to the rule's accuracy: exact for a straight planar cell)."""
    xe = x[cells6]
    det = np.linalg.det(np.einsum("cai,qaj->cqij", xe, QP_DERIVATIVES))
    return (QP_WEIGHTS * det * _weights(xe, QP_VALUES, axisymmetric, thickness)).ravel()


def hrz_cell_masses(cells6: np.ndarray, X: np.ndarray, density: float, axisymmetric: bool,
                    thickness: float) -> np.ndarray:
    """HRZ lumped masses (kg) of each node of each six-node cell at ``X`` (m), (nc, 6): the node's diagonal entry
    of the consistent mass rho int N_a^2 w dA (w the thickness, or 2 pi r in axisymmetry; a degree-5 rule, exact
    for straight cells), scaled so that the cell's entries sum to its mass rho int w dA. All positive."""
    xe = X[cells6]
    N = shape_values(_MASS_BARY)
    det = np.linalg.det(np.einsum("cai,qaj->cqij", xe, shape_derivatives(_MASS_BARY)))
    wv = _MASS_W * det * _weights(xe, N, axisymmetric, thickness)          # (nc, 7)
    diag = np.einsum("cq,qa->ca", wv, N * N)
    return density * diag * (wv.sum(axis=1) / diag.sum(axis=1))[:, None]


def hrz_lumped_mass(cells6: np.ndarray, X: np.ndarray, density: float, axisymmetric: bool,
                    thickness: float) -> np.ndarray:
    """HRZ lumped nodal masses (kg) of six-node cells at ``X`` (m): :func:`hrz_cell_masses` summed on the nodes;
    their sum is the body's mass."""
    m = hrz_cell_masses(cells6, X, density, axisymmetric, thickness)
    return np.bincount(cells6.ravel(), weights=m.ravel(), minlength=len(X))


def hrz_shares(cells6: np.ndarray, X: np.ndarray, axisymmetric: bool) -> np.ndarray:
    """The part of its cell's mass each node of a six-node cell carries (HRZ, :func:`hrz_cell_masses`), (nc, 6),
    each row summing to one: a straight planar cell 1/19 at a corner and 16/57 at an edge node; in axisymmetry
    the nodes farther from the axis carry more. A volume force shared out in these proportions accelerates every
    node alike when its density is uniform (the coupled force transfer's shares)."""
    m = hrz_cell_masses(cells6, X, 1.0, axisymmetric, 1.0)
    return m / m.sum(axis=1, keepdims=True)


def three_node_edges(segments: np.ndarray, edge_node: dict) -> np.ndarray:
    """The three-node boundary edges (n, 3) of a six-node body: its corner segments (n, 2, oriented with the body
    on the left), then each edge's middle node; ``edge_node`` maps a sorted vertex pair to its node row."""
    out = np.empty((len(segments), 3), dtype=np.int32)
    for k, (a, b) in enumerate(segments):
        out[k] = (a, b, edge_node[(min(a, b), max(a, b))])
    return out


def split_edges(edges3: np.ndarray) -> np.ndarray:
    """The boundary of a six-node body as two-node segments: each three-node edge (a, b, m) cut into (a, m) and
    (m, b) (rows ``2 k`` and ``2 k + 1``), oriented as the edge (the body on the left)."""
    e = np.asarray(edges3, dtype=np.int32).reshape(-1, 3)
    return np.stack([e[:, [0, 2]], e[:, [2, 1]]], axis=1).reshape(-1, 2)


def recover_edge_pressure(edges3: np.ndarray, x: np.ndarray, force: np.ndarray, axisymmetric: bool,
                          thickness: float, normal: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Nodal pressures on three-node edges from nodal normal forces, read edge by edge
    (:func:`.face_pressure.read_face_pressures`): a uniform pressure is read exactly at corners and middle nodes
    alike, whether its nodal forces are the quadratic edge's consistent ones (1/6, 1/6, 2/3 of its force on a
    straight planar edge: a force over a node's tributary area would read 2/3 of the pressure at a corner and
    4/3 at the middle) or a half-segment split (1/4, 1/4, 1/2).

    Parameters
    ----------
    edges3 : int array (ne, 3)
        Three-node edges (:func:`three_node_edges`), node rows of ``x``, the body on the left of a -> b.
    x : ndarray (N, 2)
        Node positions, m (an edge's area: the sum of its two half segments', times ``thickness`` or 2 pi r).
    force : ndarray (N,)
        Normal force on each node, N (compressive positive; zero where nothing acts).
    axisymmetric : bool
        Areas of the full 2 pi ring (x[:, 0] = r) instead of ``thickness`` (m) times length.
    thickness : float
        Out-of-plane thickness of a planar body, m.
    normal : (2,) array, optional
        A rigid wall's unit normal (into the body's side): areas projected on the wall.

    Returns
    -------
    nodes : int64 array (M,)
        The nodes of the loaded edges, sorted.
    pressure : ndarray (M,)
        Their pressures, Pa.
    """
    e = np.asarray(edges3, dtype=np.int64).reshape(-1, 3)
    seg = split_edges(e).reshape(-1, 2, 2)
    pa, pb = x[seg[:, :, 0]], x[seg[:, :, 1]]                      # (ne, 2 halves, 2)
    t = pb - pa
    w = np.pi * (pa[:, :, 0] + pb[:, :, 0]) if axisymmetric else np.full(t.shape[:2], float(thickness))
    av = (np.stack([t[:, :, 1], -t[:, :, 0]], axis=2) * w[:, :, None]).sum(axis=1)   # outward area vectors
    area = (np.linalg.norm(t, axis=2) * w).sum(axis=1)
    facing = area if normal is None else -(av @ np.asarray(normal, float))
    return read_face_pressures(e, area, facing, force)


#: three-point Gauss rule on an edge's parameter s in [0, 1] (degree 5): points and weights
_EDGE_S = 0.5 + 0.5 * np.sqrt(0.6) * np.array([-1.0, 0.0, 1.0])
_EDGE_W = np.array([5.0, 8.0, 5.0]) / 18.0


def edge_pressure_forces(edges3: np.ndarray, x: np.ndarray, pressure: float, axisymmetric: bool,
                         thickness: float) -> np.ndarray:
    """Consistent nodal forces (N, 2), N, of a uniform follower pressure (Pa, positive pushes into the body) on
    three-node boundary edges (:func:`three_node_edges`: corners a b, middle m, the body on the left of a -> b) at
    positions ``x`` (m): f_k = -p int N_k n w ds over each (possibly curved) edge, w the thickness or 2 pi r,
    by a three-point Gauss rule (exact for a straight edge)."""
    e = np.asarray(edges3, dtype=np.int64).reshape(-1, 3)
    s = _EDGE_S
    N = np.stack([(1 - s) * (1 - 2 * s), s * (2 * s - 1), 4 * s * (1 - s)], axis=1)        # (3 points, 3 nodes)
    dN = np.stack([4 * s - 3, 4 * s - 1, 4 - 8 * s], axis=1)
    xe = x[e]                                                                             # (n, 3, 2)
    t = np.einsum("qk,nki->nqi", dN, xe)                                                  # dx/ds
    nds = np.stack([t[:, :, 1], -t[:, :, 0]], axis=2)                                     # outward n |dx/ds|
    w = (2.0 * np.pi * np.einsum("qk,nk->nq", N, xe[:, :, 0]) if axisymmetric
         else np.full(t.shape[:2], float(thickness)))
    fk = -pressure * np.einsum("q,qk,nq,nqi->nki", _EDGE_W, N, w, nds)                   # (n, 3, 2)
    f = np.zeros((len(x), 2))
    for c in range(2):
        f[:, c] = np.bincount(e.ravel(), weights=fk[:, :, c].ravel(), minlength=len(x))
    return f


def critical_step_factor(cells6: np.ndarray, X: np.ndarray, shear_modulus: float, bulk_modulus: float) -> float:
    """The ratio of the six-node cells' critical step to the linear kernel's estimate, smallest over the cells
    (dimensionless): 2 / omega_e, omega_e the largest frequency of the cell's plane-strain elastic stiffness under
    its HRZ mass (an upper bound of the mesh's by the element eigenvalue inequality; plane strain is the stiffest
    planar model; the axisymmetric hoop term is left out, as the linear kernel's estimate leaves it out), over
    h_e / c, h_e the corner triangle's altitude on its longest edge and c = sqrt((K + 4 G / 3) / rho).

    Parameters
    ----------
    cells6 : int array (nc, 6)
        Six-node cells.
    X : ndarray (N, 2)
        Node positions (reference configuration), m.
    shear_modulus, bulk_modulus : float
        G and K, Pa.
    """
    share = np.array([1.0 / 19.0] * 3 + [16.0 / 57.0] * 3)          # HRZ of a straight planar cell
    return step_factor(cells6, X, QP_DERIVATIVES, QP_WEIGHTS, share, shear_modulus, bulk_modulus,
                       _corner_altitude, 8192)


def _corner_altitude(xe: np.ndarray) -> np.ndarray:
    """The altitude (m) of each cell's corner triangle on its longest edge (xe (nc, >= 3, 2))."""
    a, b = xe[:, 1] - xe[:, 0], xe[:, 2] - xe[:, 0]
    area2 = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    lmax = np.sqrt(np.max(np.stack([np.sum(a * a, 1), np.sum(b * b, 1), np.sum((b - a) ** 2, 1)]), axis=0))
    return area2 / lmax
