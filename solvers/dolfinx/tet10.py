"""The quadratic (10-node) tetrahedron of the 3D bodies (``BodySpec.element = "tet10"``, issue 34 item 4): the
element that bends without locking.

A linear tetrahedron has a constant strain: a sheet two or three of them thick is far too stiff in bending
(shear locking: bench/cantilever_locking.py measures a 1 mm strip with three through its thickness, and
docs/mechanics.md gives the figures). Nodal-averaged pressure and F-bar cure the volumetric locking of nearly
incompressible plastic flow, not this; the quadratic tetrahedron carries a linear strain and bends.

Conventions
-----------
* Nodes 0-3 are the corners (the linear mesh's vertices, in its orientation), nodes 4-9 the edge midpoints of
  the edges (0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3) (:data:`EDGES`). The body numbers the vertices
  first (the rows of the linear body, unchanged), then one node per mesh edge.
* Isoparametric: positions and velocities interpolate with the same ten shape functions; the edge nodes move
  freely, so a deformed element is curved.
* Four-point Gauss rule (degree 2: exact for the stiffness of a straight element). The stress, plastic strain
  and temperature live at the quadrature points: a body of ``nc`` cells carries ``nc * 4`` rows, cell-major
  (row ``4 e + q``).
* Lumped mass by HRZ (Hinton, Rock and Zienkiewicz 1976): the consistent mass's diagonal scaled to the
  element's mass, a corner 1/36 and an edge node 4/27 of it (row sums would give the corners -1/20).
* Boundary faces are six-node triangles (corners a b c, then the edge nodes of ab, bc, ca). A uniform
  pressure's consistent nodal forces on one are 0 at the corners and 1/3 of its force at each edge node, so a
  wall's or a contact layer's nodal reactions, divided by node areas, do not read the pressure (a corner reads
  ~0, an edge node 4/3 of it): :func:`recover_face_pressure` reads them face by face instead.
"""
from __future__ import annotations

import numpy as np

from .face_pressure import read_face_pressures

__all__ = ["EDGES", "QP_WEIGHTS", "QP_DERIVATIVES", "N_QP", "quadratic_cells", "shape_derivatives",
           "hrz_lumped_mass", "six_node_faces", "split_faces", "recover_face_pressure", "face_pressure_forces",
           "corner_share", "HRZ_SHARES", "qp_jacobians", "qp_volumes", "critical_step_factor", "largest_eigenvalues",
           "step_factor"]

#: corner pairs of the edge nodes 4..9
EDGES = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))
#: quadrature points per cell
N_QP = 4
_A, _B = 0.5854101966249685, 0.1381966011250105
#: barycentric coordinates (L0, L1, L2, L3) of the four Gauss points (degree 2)
QP_BARY = np.array([[_A, _B, _B, _B], [_B, _A, _B, _B], [_B, _B, _A, _B], [_B, _B, _B, _A]])
#: their weights on the reference tetrahedron (volume 1/6): the volume of a cell is sum_q w_q det J_q
QP_WEIGHTS = np.full(N_QP, 1.0 / 24.0)
#: HRZ share of a corner node in the element mass (an edge node: (1 - 4 share) / 6 = 4/27)
corner_share = 1.0 / 36.0
#: each node's HRZ share of a straight cell's mass (corners 0-3, then edge nodes 4-9)
HRZ_SHARES = np.concatenate([np.full(4, corner_share), np.full(6, (1.0 - 4.0 * corner_share) / 6.0)])


def shape_derivatives(bary: np.ndarray) -> np.ndarray:
    """Derivatives of the ten shape functions with respect to the reference coordinates (xi, eta, zeta) =
    (L1, L2, L3) at points of barycentric coordinates ``bary`` (n, 4): (n, 10, 3)."""
    L = np.asarray(bary, dtype=float)
    # dL_k / dxi_j: L0 = 1 - xi - eta - zeta
    dL = np.array([[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    out = np.zeros((L.shape[0], 10, 3))
    for k in range(4):                       # corner: L (2 L - 1)
        out[:, k, :] = (4.0 * L[:, k] - 1.0)[:, None] * dL[k]
    for m, (i, j) in enumerate(EDGES):       # edge: 4 L_i L_j
        out[:, 4 + m, :] = 4.0 * (L[:, i, None] * dL[j] + L[:, j, None] * dL[i])
    return out


#: shape-function derivatives at the Gauss points, (4, 10, 3)
QP_DERIVATIVES = shape_derivatives(QP_BARY)


def quadratic_cells(cells: np.ndarray, X: np.ndarray,
                    edges_of_cell: tuple = EDGES) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The quadratic cells of a linear simplex mesh: one new node at the middle of every edge (ten-node
    tetrahedra; six-node triangles with ``edges_of_cell`` = :data:`.tri6.EDGES`).

    Parameters
    ----------
    cells : int array (nc, 4) or (nc, 3)
        Positively oriented linear tetrahedra or triangles (node rows of ``X``).
    X : ndarray (N, dim)
        Vertex positions, m.
    edges_of_cell : tuple of (int, int)
        The corner pairs of the cell's edge nodes, in their order (default :data:`EDGES`).

    Returns
    -------
    cells_q : int32 array (nc, 10) or (nc, 6)
        Corners then the edge nodes of ``edges_of_cell``; the edge nodes are rows ``N ..`` in the order of their
        first appearance.
    X_q : ndarray (N + n_edges, dim)
        Vertex positions followed by the edge midpoints, m.
    edges : int64 array (n_edges, 2)
        The vertices of each edge node.
    """
    ne = len(edges_of_cell)
    pairs = np.stack([np.sort(cells[:, [i, j]], axis=1) for i, j in edges_of_cell], axis=1)   # (nc, ne, 2)
    flat = pairs.reshape(-1, 2).astype(np.int64)
    _, first, inverse = np.unique(flat[:, 0] * (len(X) + 1) + flat[:, 1], return_index=True, return_inverse=True)
    order = np.argsort(first)                # number the edges by first appearance (deterministic, local)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    edges = flat[first[order]]
    cells10 = np.concatenate([cells, len(X) + rank[inverse].reshape(-1, ne)], axis=1).astype(np.int32)
    X10 = np.concatenate([X, 0.5 * (X[edges[:, 0]] + X[edges[:, 1]])], axis=0)
    return cells10, X10, edges


def hrz_lumped_mass(cells10: np.ndarray, volumes: np.ndarray, density: float | np.ndarray,
                    n_nodes: int) -> np.ndarray:
    """HRZ lumped nodal masses (kg) of straight ten-node cells of ``volumes`` (m^3) and ``density`` (kg/m^3, one
    or per cell: selective mass scaling, :mod:`.mass_scaling`): a corner 1/36, an edge node 4/27 of rho V (all
    positive; their sum is the body's mass)."""
    m = density * np.asarray(volumes, dtype=float)
    return np.bincount(cells10.ravel(), weights=(m[:, None] * HRZ_SHARES).ravel(), minlength=n_nodes)


def six_node_faces(tris: np.ndarray, edge_node: dict) -> np.ndarray:
    """The six-node boundary faces (nf, 6) of a ten-node body: corners ``tris`` (nf, 3, outward oriented), then
    the edge nodes of ab, bc, ca; ``edge_node`` maps a sorted vertex pair to its edge node row."""
    out = np.empty((len(tris), 6), dtype=np.int32)
    for f, (a, b, c) in enumerate(tris):
        out[f] = (a, b, c, edge_node[(min(a, b), max(a, b))], edge_node[(min(b, c), max(b, c))],
                  edge_node[(min(c, a), max(c, a))])
    return out


def split_faces(faces6: np.ndarray) -> np.ndarray:
    """The boundary of a ten-node body as linear triangles: each six-node face (:func:`six_node_faces`) cut into
    four (three at the corners, one in the middle, rows ``4 f .. 4 f + 3``) with the orientation of the face, so
    that walls, pressure loads and contact see every boundary node."""
    f = np.asarray(faces6, dtype=np.int32).reshape(-1, 6)
    a, b, c, ab, bc, ca = f.T
    return np.stack([np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))],
                    axis=1).reshape(-1, 3)


def recover_face_pressure(faces6: np.ndarray, x: np.ndarray, force: np.ndarray,
                          normal: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Nodal pressures on six-node faces from nodal normal forces, read face by face
    (:func:`.face_pressure.read_face_pressures`).

    A uniform pressure is read exactly at corners and edge nodes alike, whether its nodal forces are the
    quadratic face's consistent ones (0 at the corners, 1/3 of a face's force at each edge node: a force over a
    node area would read ~0 at a corner and 4/3 of the pressure at an edge node) or a quarter-triangle split
    (1/12 and 1/4).

    Parameters
    ----------
    faces6 : int array (nf, 6)
        Six-node faces (:func:`six_node_faces`), node rows of ``x``.
    x : ndarray (N, 3)
        Node positions, m (a face's area: the sum of its four corner/middle triangles').
    force : ndarray (N,)
        Normal force on each node, N (compressive positive; zero where nothing acts).
    normal : (3,) array, optional
        A rigid wall's unit normal (into the body's side): the face areas are then projected on the wall,
        -A_f n_f . normal, as the wall's pressure is per projected area.

    Returns
    -------
    nodes : int64 array (M,)
        The nodes of the loaded faces, sorted.
    pressure : ndarray (M,)
        Their pressures, Pa.
    """
    faces6 = np.asarray(faces6, dtype=np.int64).reshape(-1, 6)
    tri = split_faces(faces6).reshape(-1, 4, 3)
    av = 0.5 * np.cross(x[tri[:, :, 1]] - x[tri[:, :, 0]], x[tri[:, :, 2]] - x[tri[:, :, 0]]).sum(axis=1)
    area = np.linalg.norm(av, axis=1)
    facing = area if normal is None else -(av @ np.asarray(normal, float))
    return read_face_pressures(faces6, area, facing, force)


#: a six-point rule of degree 4 on the reference triangle (Dunavant 1985; weights sum to its area 1/2): exact for a
#: curved six-node face's int N_a (x_r x x_s) (degree 2 times degree 2)
_FACE_A, _FACE_B = 0.445948490915965, 0.091576213509771
FACE_QP = np.array([[_FACE_A, _FACE_A], [1 - 2 * _FACE_A, _FACE_A], [_FACE_A, 1 - 2 * _FACE_A],
                    [_FACE_B, _FACE_B], [1 - 2 * _FACE_B, _FACE_B], [_FACE_B, 1 - 2 * _FACE_B]])
FACE_WEIGHTS = 0.5 * np.array([0.223381589678011] * 3 + [0.109951743655322] * 3)


def _face_shapes(rs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Six-node triangle (corners a b c, then ab bc ca) at reference points ``rs`` (q, 2): N (q, 6), dN/dr, dN/ds."""
    r, t = rs[:, 0], rs[:, 1]
    L = np.stack([1.0 - r - t, r, t], axis=1)
    dL = np.array([[-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])            # dL_a / dr, dL_a / ds
    pairs = ((0, 1), (1, 2), (2, 0))
    N = np.concatenate([L * (2 * L - 1), np.stack([4 * L[:, a] * L[:, b] for a, b in pairs], axis=1)], axis=1)
    d = []
    for k in range(2):
        dc = (4 * L - 1) * dL[k]
        de = np.stack([4 * (dL[k, a] * L[:, b] + L[:, a] * dL[k, b]) for a, b in pairs], axis=1)
        d.append(np.concatenate([dc, de], axis=1))
    return N, d[0], d[1]


_FACE_N, _FACE_DR, _FACE_DS = _face_shapes(FACE_QP)


def face_pressure_forces(faces6: np.ndarray, x: np.ndarray, pressure: float) -> np.ndarray:
    """Consistent nodal forces (N, 3), N, of a uniform follower pressure (Pa, positive pushes into the body) on
    six-node faces (:func:`six_node_faces`, outward oriented) at positions ``x`` (m): f_a = -p int N_a n dA over
    each (possibly curved) face, by a six-point rule of degree 4 (exact). A straight face's: 0 at the corners and
    -p A n / 3 at each edge node (Zienkiewicz & Taylor, vol. 1, the six-node triangle's load vector): the loads under
    which a ten-node body carries a uniform stress exactly (the patch test)."""
    f6 = np.asarray(faces6, dtype=np.int64).reshape(-1, 6)
    xe = x[f6]                                                                       # (n, 6, 3)
    xr = np.einsum("qk,nki->nqi", _FACE_DR, xe)
    xs = np.einsum("qk,nki->nqi", _FACE_DS, xe)
    fk = -pressure * np.einsum("q,qk,nqi->nki", FACE_WEIGHTS, _FACE_N, np.cross(xr, xs))
    out = np.zeros((len(x), 3))
    for c in range(3):
        out[:, c] = np.bincount(f6.ravel(), weights=fk[:, :, c].ravel(), minlength=len(x))
    return out


def qp_jacobians(x: np.ndarray) -> np.ndarray:
    """Jacobians J[c, q, i, j] = d x_i / d xi_j (nc, 4, 3, 3) of ten-node cells at positions ``x`` (nc, 10, 3),
    m (real, or complex under a complex step)."""
    return np.einsum("cai,qaj->cqij", x, QP_DERIVATIVES)


def qp_volumes(cells10: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The volume of each quadrature point, w_q det J_q (nc * 4,), m^3, cell-major (their sum over a cell is its
    volume)."""
    J = qp_jacobians(x[cells10])
    return (QP_WEIGHTS * np.linalg.det(J)).ravel()


def largest_eigenvalues(xe: np.ndarray, dN: np.ndarray, wq: np.ndarray, share: np.ndarray, shear_modulus: float,
                        bulk_modulus: float) -> np.ndarray:
    """The largest eigenvalue omega^2 (1/s^2, density 1 kg/m^3) of each cell's small-strain elastic stiffness
    under its HRZ lumped mass, for isoparametric cells of any dimension (ten-node tetrahedra, six-node triangles:
    plane strain, the stiffest planar model).

    Parameters
    ----------
    xe : ndarray (nc, nn, dim)
        The cells' node positions, m.
    dN : ndarray (nq, nn, dim)
        Shape-function derivatives at the quadrature points (reference coordinates).
    wq : ndarray (nq,)
        Quadrature weights on the reference cell.
    share : ndarray (nn,)
        Each node's HRZ share of the cell's mass.
    shear_modulus, bulk_modulus : float
        G and K, Pa.
    """
    G, K = float(shear_modulus), float(bulk_modulus)
    lam = K - 2.0 * G / 3.0
    nc, nn, dim = xe.shape
    J = np.einsum("cai,qaj->cqij", xe, dN)
    det = np.linalg.det(J)
    g = np.einsum("qaj,cqji->cqai", dN, np.linalg.inv(J))
    vq = wq * det
    gg = np.einsum("cq,cqai,cqbi->cab", vq, g, g)
    Kij = lam * np.einsum("cq,cqai,cqbj->caibj", vq, g, g) + G * np.einsum("cq,cqaj,cqbi->caibj", vq, g, g)
    Kij += G * np.einsum("cab,ij->caibj", gg, np.eye(dim))
    Kf = Kij.reshape(nc, nn * dim, nn * dim)
    m = np.repeat(vq.sum(axis=1)[:, None] * share, dim, axis=1).reshape(nc, nn * dim)   # HRZ, rho = 1
    s_m = 1.0 / np.sqrt(m)
    return np.linalg.eigvalsh(s_m[:, :, None] * Kf * s_m[:, None, :])[:, -1]


def critical_step_factor(cells10: np.ndarray, X: np.ndarray, shear_modulus: float, bulk_modulus: float) -> float:
    """The ratio of the ten-node cells' critical step to the linear kernel's estimate, smallest over the cells
    (dimensionless): 2 / omega_e, omega_e the largest frequency of the cell's elastic stiffness under its HRZ mass
    (an upper bound of the mesh's by the element eigenvalue inequality), over h_e / c, h_e the corner
    tetrahedron's smallest altitude and c = sqrt((K + 4 G / 3) / rho) (the density cancels).

    Parameters
    ----------
    cells10 : int array (nc, 10)
        Ten-node cells.
    X : ndarray (N, 3)
        Node positions (reference configuration), m.
    shear_modulus, bulk_modulus : float
        G and K, Pa.
    """
    return step_factor(cells10, X, QP_DERIVATIVES, QP_WEIGHTS, HRZ_SHARES, shear_modulus, bulk_modulus,
                       _corner_altitude, 4096)


def _corner_altitude(xe: np.ndarray) -> np.ndarray:
    """The smallest altitude (m) of each cell's corner tetrahedron (xe (nc, >= 4, 3))."""
    a, b, cc = (xe[:, k] - xe[:, 0] for k in (1, 2, 3))
    n1, n2, n3 = np.cross(b, cc), np.cross(cc, a), np.cross(a, b)
    area = np.max(np.stack([np.einsum("ni,ni->n", n, n) for n in (n1 + n2 + n3, n1, n2, n3)]), axis=0)
    return np.einsum("ni,ni->n", a, n1) / np.sqrt(area)


def step_factor(cells: np.ndarray, X: np.ndarray, dN: np.ndarray, wq: np.ndarray, share: np.ndarray,
                shear_modulus: float, bulk_modulus: float, altitude, chunk: int) -> float:
    """The smallest ratio over ``cells`` of 2 / omega_e (:func:`largest_eigenvalues`) to h_e / c, h_e =
    ``altitude(xe)`` (m) the linear kernel's length of the corner cell and c = sqrt((K + 4 G / 3) / rho) (the density
    cancels); cells taken ``chunk`` at a time. The quadratic elements' critical-step factor (tet10, tri6)."""
    c2 = float(bulk_modulus) + 4.0 * float(shear_modulus) / 3.0      # rho c^2 (rho = 1: it cancels)
    worst = np.inf
    for s in range(0, len(cells), chunk):
        xe = X[cells[s:s + chunk]]
        lam_max = largest_eigenvalues(xe, dN, wq, share, shear_modulus, bulk_modulus)
        worst = min(worst, float(np.min(2.0 / np.sqrt(lam_max) / (altitude(xe) / np.sqrt(c2)))))
    return worst
