"""A deformable body: DOLFINx mesh and P1 vector space, nodal arrays, lumped mass, boundary segments,
ghost exchange. Nodal arrays are indexed by the *block* dofs of the P1 vector space (one row per
node, owned nodes first, then ghosts)."""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
import ufl
from dolfinx import cpp as _cpp
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector
from petsc4py import PETSc
from dolfinx import mesh as dmesh
from dolfinx.la import ScatterMode

from . import cell_fields, tri6
from .material import Material
from .tet10 import quadratic_cells

__all__ = ["BodySpec", "Body", "ELEMENTS", "ELEMENTS_2D", "ELEMENTS_3D"]

log = logging.getLogger(__name__)


@dataclass
class BodySpec:
    """Description of one body.

    Parameters
    ----------
    name : str
        Unique body name.
    mesh : dolfinx.mesh.Mesh
        2D mesh of P1 triangles (x = r, y = z in axisymmetry), m; or, for
        :class:`~.solver3d.ExplicitSolver3D`, a 3D mesh of P1 tetrahedra.
    material : Material
        Its material.
    initial_velocity : (float, float) or (float, float, float)
        Uniform initial velocity, m/s (three components in 3D).
    fixed : sequence
        Velocity constraints ``(marker, components)`` or ``(marker, components, value)``:
        ``marker(x) -> bool array`` over node coordinates of shape (3, N) (initial configuration),
        ``components`` a tuple of 0/1 (0/1/2 in 3D), ``value`` the prescribed velocity in m/s (float, or callable
        ``value(t) -> float``; default 0).
    motion : sequence
        Prescribed motions ``(marker, func)`` with ``func(X, t) -> x`` mapping reference coordinates
        (N, 2) to current positions (N, 2) at time t ((N, 3) in 3D); matched nodes follow it exactly.
    initial_stress : tuple of 4 (2D) or 6 (3D) floats, optional
        Uniform initial Cauchy stress [xx, yy, zz, xy] (3D: [xx, yy, zz, xy, yz, xz]), Pa.
    sliding : sequence
        3D only: symmetry planes of any orientation ``(marker, normal)``; the marked nodes slide in
        the plane (:mod:`.sliding`).
    element : {"tet4", "tet10", "tri6"}
        The element: "tet4" (default) the linear cells on the mesh's vertices (P1 tetrahedra in 3D, P1 triangles
        in 2D); "tet10" (3D) quadratic ten-node tetrahedra, "tri6" (2D) quadratic six-node triangles, with a node
        at the middle of every edge (:mod:`.tet10`, :mod:`.tri6`: thin parts that bend, one process).
    """

    name: str
    mesh: dmesh.Mesh
    material: Material
    initial_velocity: tuple = (0.0, 0.0)
    fixed: Sequence = ()
    motion: Sequence = ()
    initial_stress: Optional[tuple] = None
    sliding: Sequence = ()
    element: str = "tet4"


#: the elements of :attr:`BodySpec.element`, of 3D and of 2D bodies
ELEMENTS_3D = ("tet4", "tet10")
ELEMENTS_2D = ("tet4", "tri6")
ELEMENTS = ("tet4", "tet10", "tri6")
#: the quadratic elements: pressures on their boundary are read face by face (:meth:`Body.read_faces`)
QUADRATIC = ("tet10", "tri6")


class Body:
    """Runtime state of a body (created by :class:`~.solver.ExplicitSolver`)."""

    def __init__(self, spec: BodySpec, axisymmetric: bool, thickness: float):
        if not isinstance(spec.name, str) or not spec.name:
            raise ValueError("BodySpec.name must be a non-empty string")
        msh = spec.mesh
        if msh.topology.dim != 2 or msh.topology.cell_type != dmesh.CellType.triangle:
            raise ValueError(f"body {spec.name!r}: need a 2D triangle mesh")
        if spec.sliding:
            raise ValueError(f"body {spec.name!r}: sliding planes are for 3D bodies (use fixed components in 2D)")
        if spec.element == "tet10":
            raise ValueError(f"body {spec.name!r}: element 'tet10' is for 3D bodies (2D bodies: {ELEMENTS_2D})")
        if spec.element not in ELEMENTS_2D:
            raise ValueError(f"body {spec.name!r}: element must be one of {ELEMENTS_2D} in 2D, got {spec.element!r}")
        if spec.element == "tri6" and msh.comm.size > 1:
            raise ValueError(f"body {spec.name!r}: element 'tri6' runs on one process (MPI: not done yet)")
        if msh.geometry.cmap.degree != 1:
            raise ValueError(f"body {spec.name!r}: need an affine (P1) geometry")
        self.name = spec.name
        self.spec = spec
        self.element = spec.element
        self.gdim = 2
        self.mesh = msh
        self.material = spec.material
        self.comm = msh.comm
        self.axisymmetric = axisymmetric
        self.thickness = thickness
        self.V = fem.VectorFunctionSpace(msh, ("Lagrange", 1))
        imap = self.V.dofmap.index_map
        self.n_owned = imap.size_local
        self.n_local = imap.size_local + imap.num_ghosts
        self.global_ids = np.asarray(imap.local_to_global(np.arange(self.n_local, dtype=np.int32)),
                                     dtype=np.int64)
        n_cells_owned = msh.topology.index_map(2).size_local
        dofs = self.V.dofmap.list.array.reshape(-1, 3)
        cells = np.array(dofs[:n_cells_owned], dtype=np.int32, copy=True)
        X = self.V.tabulate_dof_coordinates()[:, :2].copy()
        # orient every triangle counter-clockwise
        xe = X[cells]
        area2 = ((xe[:, 1, 0] - xe[:, 0, 0]) * (xe[:, 2, 1] - xe[:, 0, 1])
                 - (xe[:, 2, 0] - xe[:, 0, 0]) * (xe[:, 1, 1] - xe[:, 0, 1]))
        if self.element == "tri6":
            self._init_quadratic(spec, cells, X, area2, dofs)
        else:
            self._init_state(spec, cells, X, area2, 4)
            self.segments = self._exterior_segments(dofs)
        nc = self.cells.shape[0]
        if np.any(self.mass <= 0):
            raise ValueError(f"body {spec.name!r}: non-positive lumped mass (nodes on the axis with "
                             "no adjacent cell?)")
        self._constraints = self._build_constraints()
        X = self.X0
        self.axis_nodes = (np.flatnonzero(np.abs(X[:, 0]) <= 1e-12 * max(1.0, np.abs(X).max()))
                           if axisymmetric else np.zeros(0, dtype=np.int64))
        log.info("body %s: %d owned nodes, %d cells, mass %.6g kg", self.name, self.n_owned, nc,
                 self.total_mass())

    # ------------------------------------------------------------------ setup helpers
    def _init_quadratic(self, spec: BodySpec, cells: np.ndarray, X: np.ndarray, area2: np.ndarray,
                        dofs: np.ndarray) -> None:
        """The six-node body (one process, :mod:`.tri6`): the linear cells oriented, a node at every edge's middle
        appended after the vertices, the state per Gauss point, the boundary's three-node edges cut in two."""
        if np.any(area2 == 0.0):
            raise ValueError(f"body {spec.name!r}: degenerate cell")
        neg = area2 < 0
        cells[neg, 1], cells[neg, 2] = cells[neg, 2].copy(), cells[neg, 1].copy()
        corner_segments = self._exterior_segments(dofs, X)
        cells6, X6, edges = quadratic_cells(cells, X, tri6.EDGES)
        self.n_vertices = len(X)
        self.n_owned = self.n_local = len(X6)
        self.global_ids = np.arange(len(X6), dtype=np.int64)
        self._init_state(spec, cells6, X6, np.abs(area2), 4)
        nq = len(cells6) * tri6.N_QP
        self.cell_stress = np.repeat(self.cell_stress, tri6.N_QP, axis=0)
        self.eps_p = np.zeros(nq)
        self.temperature = np.full(nq, float(spec.material.initial_temperature))
        edge_node = {(int(a), int(b)): len(X) + k for k, (a, b) in enumerate(edges)}
        self.edges3 = tri6.three_node_edges(corner_segments, edge_node)
        self.segments = tri6.split_edges(self.edges3)

    def _init_state(self, spec: BodySpec, cells: np.ndarray, X: np.ndarray, signed: np.ndarray,
                    n_stress: int) -> None:
        """Orient the cells (``signed``: their signed area or volume; vertices 1 and 2 of a negative one
        are swapped; a zero one is an error), then the reference and current positions ``X`` (m), the
        initial velocity (m/s) and stress (Pa, ``n_stress`` components), zero acceleration and plastic
        strain, and the lumped mass (kg): the state every body starts from, 2D or 3D."""
        if np.any(signed == 0.0):
            raise ValueError(f"body {spec.name!r}: degenerate cell")
        neg = signed < 0
        cells[neg, 1], cells[neg, 2] = cells[neg, 2].copy(), cells[neg, 1].copy()
        self.cells = cells
        self.X0 = X
        self.x = X.copy()
        dim = X.shape[1]
        self.v = np.zeros((self.n_local, dim))
        self.v[:] = np.asarray(spec.initial_velocity, dtype=float)
        self.a = np.zeros((self.n_local, dim))
        nc = cells.shape[0]
        self.cell_stress = np.zeros((nc, n_stress))
        if spec.initial_stress is not None:
            self.cell_stress[:] = np.asarray(spec.initial_stress, dtype=float)
        self.eps_p = np.zeros(nc)
        #: temperature per cell, K (updated only for a material with a specific heat)
        self.temperature = np.full(nc, float(spec.material.initial_temperature))
        self._buf = fem.Function(self.V)
        self.mass = self._lumped_mass()

    def _lumped_mass(self) -> np.ndarray:
        """Row-sum lumped mass via DOLFINx assembly (r-weighted with 2 pi in axisymmetry), kg; six-node cells: HRZ
        (:func:`.tri6.hrz_lumped_mass`)."""
        if self.element == "tri6":
            return tri6.hrz_lumped_mass(self.cells, self.X0, self.material.density, bool(self.axisymmetric),
                                        float(self.thickness))
        w = ufl.TestFunction(self.V)
        xs = ufl.SpatialCoordinate(self.mesh)
        weight = 2.0 * np.pi * xs[0] if self.axisymmetric else fem.Constant(self.mesh, self.thickness)
        one = ufl.as_vector((1.0, 1.0))
        form = fem.form(self.material.density * weight * ufl.inner(one, w) * ufl.dx)
        vec = assemble_vector(form)
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with vec.localForm() as loc:
            m = loc.array.reshape(-1, 2)[:, 0].copy()
        vec.destroy()
        return m

    def _exterior_segments(self, dofs: np.ndarray, X0: Optional[np.ndarray] = None) -> np.ndarray:
        """Owned exterior facets as (n, 2) node rows, oriented with the body on the left (for the vertex
        positions ``X0``, m; default the body's), so that the outward normal of segment a->b is
        (yb - ya, xa - xb) / length."""
        X0 = self.X0 if X0 is None else X0
        msh = self.mesh
        top = msh.topology
        top.create_connectivity(1, 2)
        facets = dmesh.exterior_facet_indices(top).astype(np.int32)
        f2c = top.connectivity(1, 2)
        # geometry nodes and P1 dofs share the per-cell (reference) ordering
        gd = msh.geometry.dofmap.array.reshape(-1, 3)
        geo2dof = np.full(msh.geometry.x.shape[0], -1, dtype=np.int64)
        geo2dof[gd.ravel()] = dofs.ravel()
        fg = _cpp.mesh.entities_to_geometry(msh._mesh, 1, facets, False)
        segs = geo2dof[fg].astype(np.int32).reshape(-1, 2)
        cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int64)
        cd = dofs[cells] if len(facets) else np.zeros((0, 3), np.int64)
        third = np.array([[d for d in row if d not in sg][0] for row, sg in zip(cd, segs)],
                         dtype=np.int64)
        if len(facets):
            pa, pb, pc = X0[segs[:, 0]], X0[segs[:, 1]], X0[third]
            cross = ((pb[:, 0] - pa[:, 0]) * (pc[:, 1] - pa[:, 1])
                     - (pb[:, 1] - pa[:, 1]) * (pc[:, 0] - pa[:, 0]))
            flip = cross < 0
            segs[flip] = segs[flip][:, ::-1]
        return np.ascontiguousarray(segs)

    def _build_constraints(self):
        X3 = np.zeros((3, self.n_local))
        X3[:self.gdim] = self.X0.T
        out = []
        for entry in self.spec.fixed:
            if len(entry) == 2:
                marker, comps = entry
                value = 0.0
            elif len(entry) == 3:
                marker, comps, value = entry
            else:
                raise ValueError("fixed entries are (marker, components[, value])")
            comps = tuple(int(c) for c in comps)
            if not comps or any(not 0 <= c < self.gdim for c in comps):
                raise ValueError(f"fixed components must be in 0..{self.gdim - 1}, got {comps}")
            nodes = np.flatnonzero(np.asarray(marker(X3), dtype=bool))
            out.append(("fix", nodes, comps, value))
        for marker, func in self.spec.motion:
            nodes = np.flatnonzero(np.asarray(marker(X3), dtype=bool))
            out.append(("motion", nodes, func, None))
        return out

    # ------------------------------------------------------------------ runtime helpers
    def apply_velocity_constraints(self, t_new: float, dt: float) -> None:
        """Impose the velocity constraints on the half-step velocity for a step ending at t_new."""
        for kind, nodes, a, b in self._constraints:
            if nodes.size == 0:
                continue
            if kind == "fix":
                val = b(t_new) if callable(b) else b
                for c in a:
                    self.v[nodes, c] = val
            else:
                target = np.asarray(a(self.X0[nodes], t_new), dtype=float)
                self.v[nodes] = (target - self.x[nodes]) / dt
        if self.axis_nodes.size:
            self.v[self.axis_nodes, 0] = 0.0
        if self.sliding is not None:
            self.sliding.project(self.v)

    #: the body's :class:`~.sliding.SlidingPlanes` (3D bodies with oblique symmetry planes), or None
    sliding = None

    def project_sliding(self, arr: np.ndarray) -> None:
        """Remove the plane-normal components of nodal vectors ``arr`` (accelerations) in place."""
        if self.sliding is not None:
            self.sliding.project(arr)

    def constrained_mask(self) -> np.ndarray:
        """(N, gdim) bool: components whose velocity is prescribed."""
        m = np.zeros((self.n_local, self.gdim), dtype=bool)
        for kind, nodes, a, _ in self._constraints:
            if kind == "fix":
                for c in a:
                    m[nodes, c] = True
            else:
                m[nodes] = True
        if self.axis_nodes.size:
            m[self.axis_nodes, 0] = True
        return m

    def complete_nodal(self, f: np.ndarray) -> np.ndarray:
        """Sum ghost contributions into owners, then copy owners' totals back to ghosts (in place)."""
        if self.comm.size == 1:
            return f
        arr = self._buf.x.array
        arr[:] = f.ravel()
        self._buf.x.scatter_reverse(ScatterMode.add)
        self._buf.x.scatter_forward()
        f[:] = arr.reshape(-1, self.gdim)
        return f

    def total_mass(self) -> float:
        """Total mass of the body, kg."""
        return self.comm.allreduce(float(self.mass[: self.n_owned].sum()))

    def segment_weights(self, segs: np.ndarray, x: np.ndarray):
        """Per-segment end-node areas (wa, wb), m^2 (planar: half length x thickness;
        axisymmetric: the consistent int N_a 2 pi r ds), and outward unit normals (S, 2)."""
        pa, pb = x[segs[:, 0]], x[segs[:, 1]]
        t = pb - pa
        ln = np.linalg.norm(t, axis=1)
        if self.axisymmetric:
            wa = 2 * np.pi * ln * (2 * pa[:, 0] + pb[:, 0]) / 6.0
            wb = 2 * np.pi * ln * (pa[:, 0] + 2 * pb[:, 0]) / 6.0
        else:
            wa = wb = 0.5 * ln * self.thickness
        with np.errstate(invalid="ignore", divide="ignore"):
            nrm = np.stack([t[:, 1], -t[:, 0]], axis=1) / ln[:, None]
        return wa, wb, nrm

    def tributary_areas(self, segs: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Per-node tributary boundary area of the given segments at positions x, m^2 (planar:
        times thickness; axisymmetric: the full 2 pi ring, consistent int N_a 2 pi r ds)."""
        wa, wb, _ = self.segment_weights(segs, x)
        n = x.shape[0]
        return (np.bincount(segs[:, 0], weights=wa, minlength=n)
                + np.bincount(segs[:, 1], weights=wb, minlength=n))

    def wall_tributary_areas(self, x: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """Per-node area (m^2) that turns a rigid wall's reaction into a pressure: in 2D the full
        tributary area of the boundary segments (:meth:`tributary_areas`; ``normal`` unused);
        :class:`~.body3d.Body3D` projects it on the wall."""
        return self.tributary_areas(self.segments, x)

    def wall_pressures(self, rows: np.ndarray, force: np.ndarray, x: np.ndarray,
                       normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A rigid wall's pressures from its normal forces ``force`` (N, compressive positive) on the nodes
        ``rows`` at positions ``x`` (m): each force over its node's wall area (:meth:`wall_tributary_areas`,
        completed over the ranks: a collective under MPI). Returns (node rows, pressures Pa); a quadratic body
        (six-node triangles, ten-node tetrahedra) reads them on its loaded faces, at every node of them
        (:meth:`read_faces`: a corner's own reaction of a uniform pressure is ~0 there)."""
        if self.element in QUADRATIC:
            f = np.zeros(len(x))
            f[rows] = force
            return self.read_faces(self.quadratic_faces, x, f, normal)
        area = self.wall_tributary_areas(x, normal)
        area = self.complete_nodal(np.repeat(area[:, None], self.gdim, axis=1))[:, 0]
        return rows, force / area[rows]

    def contact_pressures(self, rows: np.ndarray, pressure: np.ndarray,
                          x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The contact stress (Pa) of the nodes ``rows`` in soft contact as read on this body: the law's nodal
        value; a quadratic body: read on its boundary faces whose nodes are all in contact (:meth:`read_faces`)
        from the nodal contact forces p A, A the node's share of those faces' split pieces (a contact area: faces
        beside the contact, e.g. a side of the body at an edge node, give it nothing), the law's value at a node
        on no such face. Returns (rows, pressures)."""
        if self.element not in QUADRATIC:
            return rows, pressure
        inside = np.zeros(len(x), dtype=bool)
        inside[rows] = True
        faces = self.quadratic_faces[np.all(inside[self.quadratic_faces], axis=1)]
        law = np.full(len(x), np.nan)
        law[rows] = pressure
        f = np.nan_to_num(law) * self.tributary_areas(self.split_faces(faces), x)
        nodes, p = self.read_faces(faces, x, f)
        law[nodes] = p
        out = np.union1d(rows, nodes)
        return out, law[out]

    @property
    def quadratic_faces(self) -> np.ndarray:
        """A six-node body's three-node boundary edges (:func:`.tri6.three_node_edges`)."""
        return self.edges3

    @staticmethod
    def split_faces(faces: np.ndarray) -> np.ndarray:
        """Quadratic boundary faces as the linear pieces of :attr:`segments` (:func:`.tri6.split_edges`)."""
        return tri6.split_edges(faces)

    def read_faces(self, faces: np.ndarray, x: np.ndarray, force: np.ndarray,
                   normal: Optional[np.ndarray] = None) -> tuple[np.ndarray, np.ndarray]:
        """Pressures (Pa) read face by face from nodal normal forces (N) on quadratic boundary faces
        (:func:`.tri6.recover_edge_pressure`; areas projected on a wall of unit ``normal``). Returns (nodes,
        pressures)."""
        return tri6.recover_edge_pressure(faces, x, force, bool(self.axisymmetric), float(self.thickness), normal)

    def pressure_forces(self, facet_marker, pressure: float) -> np.ndarray:
        """Consistent nodal forces (N) of a uniform follower pressure (Pa, positive pushes into
        the body) on the exterior facets whose two vertices satisfy ``facet_marker`` (evaluated on
        current coordinates (3, N)); complete on every local row (ghosts too). Six-node bodies: on their
        three-node edges (:func:`.tri6.edge_pressure_forces`)."""
        b = self
        if self.element == "tri6":     # integrated on the three-node edges whose corners are marked
            x3 = np.zeros((3, b.n_local))
            x3[:2] = b.x.T
            mark = np.asarray(facet_marker(x3), dtype=bool)
            e = self.edges3[mark[self.edges3[:, 0]] & mark[self.edges3[:, 1]]]
            return tri6.edge_pressure_forces(e, b.x, pressure, bool(b.axisymmetric), float(b.thickness))
        segs = b.segments
        f = np.zeros((b.n_local, 2))
        if segs.shape[0]:
            x3 = np.zeros((3, b.n_local))
            x3[:2] = b.x.T
            mark = np.asarray(facet_marker(x3), dtype=bool)
            segs = segs[mark[segs[:, 0]] & mark[segs[:, 1]]]
        if segs.shape[0]:
            pa, pb = b.x[segs[:, 0]], b.x[segs[:, 1]]
            t = pb - pa
            ln = np.linalg.norm(t, axis=1)
            nout = np.stack([t[:, 1], -t[:, 0]], axis=1) / ln[:, None]
            if b.axisymmetric:
                wa = 2 * np.pi * ln * (2 * pa[:, 0] + pb[:, 0]) / 6.0
                wb = 2 * np.pi * ln * (pa[:, 0] + 2 * pb[:, 0]) / 6.0
            else:
                wa = wb = 0.5 * ln * b.thickness
            for c in range(2):
                f[:, c] -= pressure * (np.bincount(segs[:, 0], weights=wa * nout[:, c],
                                                   minlength=b.n_local)
                                       + np.bincount(segs[:, 1], weights=wb * nout[:, c],
                                                     minlength=b.n_local))
        return b.complete_nodal(f)

    # ------------------------------------------------------------------ derived fields
    @property
    def u(self) -> np.ndarray:
        """Displacement x - X, m, (N, 2)."""
        return self.x - self.X0

    @property
    def von_mises(self) -> np.ndarray:
        """Von Mises stress per owned cell (six-node cells: per Gauss point), Pa."""
        return cell_fields.von_mises(self.cell_stress)

    def cell_means(self, arr: np.ndarray) -> np.ndarray:
        """Per-cell values of a per-row array (``cell_stress``, ``eps_p``, ...): itself for linear cells, the
        mean over each cell's Gauss points for six-node cells."""
        if self.element == "tri6":
            return arr.reshape((len(self.cells), tri6.N_QP) + arr.shape[1:]).mean(axis=1)
        return arr

    def cell_volumes(self) -> np.ndarray:
        """Current cell volumes (planar: area x thickness; axisymmetric: 2 pi r_c area), m^3; six-node cells: the
        volume of each Gauss point (the rows of ``cell_stress``)."""
        if self.element == "tri6":
            return tri6.qp_measures(self.cells, self.x, bool(self.axisymmetric), float(self.thickness))
        return cell_fields.cell_volumes(self.cells, self.x, bool(self.axisymmetric),
                                        float(self.thickness))

    def elastic_energy(self) -> float:
        """Elastic strain energy of the owned cells, sum of (s:s / 4G + p^2 / 2K) V, J."""
        w = cell_fields.elastic_energy_density(self.cell_stress, float(self.material.shear_modulus),
                                               float(self.material.bulk_modulus))
        return float(np.dot(w, self.cell_volumes()))

    def sync_mesh_geometry(self) -> None:
        """Write the current node positions into ``mesh.geometry.x`` (it holds the reference
        configuration otherwise), e.g. before using DOLFINx forms on the deformed mesh."""
        gdofs = self.mesh.geometry.dofmap.array.reshape(-1, 3)
        vd = self.V.dofmap.list.array.reshape(-1, 3)
        gx = self.mesh.geometry.x
        gx[gdofs.ravel(), :2] = self.x[vd.ravel()]       # the vertices: the first rows (six-node bodies too)
