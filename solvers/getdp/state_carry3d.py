"""Carry a 3D EM state (GetDP solution vectors of system A) to a new mesh that keeps the conductors and coils.

After an air remesh (:mod:`pulseform.orchestrator.mesh.remesh3d`) every conductor and coil tetrahedron is
kept node for node, but GetDP numbers its unknowns anew (edges, gauge tree, globals). The unknowns of the
lowest-order edge elements are the circulations of a along oriented edges, so a state travels by edge:

* :func:`edge_dofs` asks GetDP which unknown belongs to which edge and with which orientation: a
  calibration vector (unknown k holds the value k + 1) is post-processed on the conductor and coil
  tetrahedra (``Print[a, OnElementsOf ...]``, nodal values per element); at vertex i of a tetrahedron the
  Whitney basis gives a(x_i) . (x_j - x_i) = the circulation along i -> j exactly, so each edge reads back
  +-(k + 1) (0: a tree or Dirichlet edge, no unknown: its circulation is zero). Nothing is assumed about
  GetDP's internal edge numbering or orientation (tests/getdp/test_state_carry3d.py checks that
  GetDP orients an edge from the lower to the higher node number, the rule this calibration finds);
* :func:`carry_vector` maps a vector: conductor and coil edges by node pair (a reversed pair flips the
  sign), the other unknowns (coil currents and voltages, circuit: global quantities of the same regions)
  by their ``.pre`` key; edges of the air only get zero: sigma = 0 there and the only time derivatives
  of the formulation (``Lib_PulsedForming3D.pro``: DtDof sigma a in Vol_C_Mag, DtDof Ns/Sc CoilDir a in
  the coils) never read them.

The coils' edges lie in the non-conducting region where the tree-cotree gauge acts; a new tree gauges
other edges, so the coils' carried values are those of the old gauge (a tree edge of the new mesh drops
its value). The coils' flux linkage changes by the gauge's share of it (a discretisation-sized term,
measured in the remesh test).
"""
from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from .mesh3d import Mesh3D, read_msh22_tets
from .persistent_data import read_pre_dofs
from .runner import run_getdp
from .solver3d import DECK3D, EM3DModel, model_numbers
from .stepper3d import write_res_vector

log = logging.getLogger(__name__)

__all__ = ["EdgeDofs", "edge_dofs", "carry_vector", "CALIB_POST"]

#: the PostOperation appended to the calibration's wrapper: a at the nodes of the conductor and coil tetrahedra
CALIB_POST = ('PostOperation { { Name PF_EdgeCalib; NameOfPostProcessing EM_a3D;\n'
              '  Operation { Print[ a, OnElementsOf Region[{Vol_C_Mag, Vol_S_Mag}], Format Gmsh, '
              'File "calib_a.pos" ]; } } }')
_TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])


@dataclass
class EdgeDofs:
    """The unknowns of system A of one mesh, by edge.

    ``edges`` (K, 2) node rows of the mesh (first < second) of every edge of a conductor or coil
    tetrahedron; ``dof`` (K,) the 0-based unknown of each (-1: none, the circulation is zero);
    ``sign`` (K,) x[dof] = sign * circulation from ``edges[:, 0]`` to ``edges[:, 1]``; ``globals``
    (NumType, Entity, Harmonic) of ``.pre`` -> unknown, the unknowns that are not edges; ``n_dofs``;
    ``system`` the DofData number of A.
    """

    edges: np.ndarray
    dof: np.ndarray
    sign: np.ndarray
    globals: dict[tuple[int, int, int], int]
    n_dofs: int
    system: int

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The map as arrays for a checkpoint (``.npz``); :meth:`from_arrays` reads them back exactly."""
        glob = np.array([[*k, d] for k, d in self.globals.items()], dtype=np.int64).reshape(-1, 4)
        return {"edges": self.edges.copy(), "dof": self.dof.copy(), "sign": self.sign.copy(), "globals": glob,
                "sizes": np.array([self.n_dofs, self.system], dtype=np.int64)}

    @classmethod
    def from_arrays(cls, d: dict[str, np.ndarray]) -> "EdgeDofs":
        """A map written by :meth:`to_arrays`."""
        glob = {(int(t), int(e), int(h)): int(k) for t, e, h, k in np.asarray(d["globals"], np.int64).reshape(-1, 4)}
        n_dofs, system = (int(v) for v in d["sizes"])
        return cls(np.array(d["edges"], np.int64), np.array(d["dof"], np.int64), np.array(d["sign"], np.int64), glob,
                   n_dofs, system)

    def circulations(self, x: np.ndarray) -> np.ndarray:
        """Circulation (Wb) of the vector ``x`` along each of :attr:`edges`."""
        out = np.zeros(len(self.edges))
        on = self.dof >= 0
        out[on] = self.sign[on] * np.asarray(x, float)[self.dof[on]]
        return out


def edge_dofs(model: EM3DModel, mesh: Mesh3D, work: Path, *, resolution: str, system: int,
              msh: Path | None = None, pre: Path | None = None, lines_before: tuple[str, ...] = (),
              timeout: float | None = 600.0) -> EdgeDofs:
    """Which unknown of system A (DofData ``system``) of ``mesh`` belongs to which edge (module
    docstring), with two getdp runs in ``work`` (``-pre resolution`` unless ``pre`` gives the ``.pre``
    of the process to read, then ``-pos``) on the file ``msh`` (default ``mesh.path``: the same
    connectivity, any node positions). ``lines_before``: lines of the wrapper before the model's (e.g.
    the persistent library's name, so that the systems are those of the process)."""
    if model.order != 1:
        raise ValueError(f"edge_dofs: order {model.order}; the carry knows only Whitney edge unknowns (order 1)")
    work = Path(work).resolve()
    work.mkdir(parents=True, exist_ok=True)
    msh = Path(msh if msh is not None else mesh.path).resolve()
    points = read_msh22_tets(msh)[0]
    numbers, lines = model_numbers(model, mesh)
    (work / "calib.pro").write_text("\n".join(list(lines_before) + lines + [f'Include "{DECK3D}";', CALIB_POST, ""]))
    if pre is None:
        run_getdp(work / "calib.pro", msh, work, resolution=resolution, numbers=numbers, pre_only=True,
                  log_name="pre.log", timeout=timeout)
    elif Path(pre).resolve() != work / "em.pre":
        (work / "em.pre").write_bytes(Path(pre).read_bytes())
    text = (work / "em.pre").read_text()
    systems = sorted({int(s) for s in re.findall(r"\$DofData /\* #(\d+) \*/", text)})
    rows = {s: read_pre_dofs(work / "em.pre", s) for s in systems}
    n = {s: int(r[np.isin(r[:, 3], (1, 5)), 4].max()) if len(r) else 0 for s, r in rows.items()}
    # a calibration solution for every system (post-processing loads them all); only A's is read back
    body = []
    for s in systems:
        values = np.arange(1, n[s] + 1, dtype=float) if s == system else np.zeros(n[s])
        body.append(write_res_vector(work / f"calib_{s}.res", str(s), 0.0, values).read_text())
    (work / "calib.res").write_text(body[0] + "".join(b.split("$EndResFormat\n", 1)[1] for b in body[1:]))
    (work / "calib_a.pos").unlink(missing_ok=True)
    run_getdp(work / "calib.pro", msh, work, resolution=resolution, numbers=numbers, post_operation="PF_EdgeCalib",
              extra_args=["-res", str(work / "calib.res")], log_name="pos.log", timeout=timeout)
    xyz, a = _read_vs(work / "calib_a.pos")
    scale = float(np.ptp(points, axis=0).max())
    dist, node = cKDTree(points).query(xyz.reshape(-1, 3))
    if dist.max() > 1e-9 * scale:
        raise RuntimeError(f"{work}: a calibration point is {dist.max():.3g} m from every mesh node")
    node = node.reshape(-1, 4)
    i, j = node[:, _TET_EDGES[:, 0]], node[:, _TET_EDGES[:, 1]]
    a_i = a[:, _TET_EDGES[:, 0]]
    c = np.einsum("tek,tek->te", a_i, points[j] - points[i])   # circulation i -> j
    lo, hi = np.minimum(i, j).ravel(), np.maximum(i, j).ravel()
    c = np.where(i < j, c, -c).ravel()
    k = np.rint(c)
    if np.abs(c - k).max() > 1e-3 or np.abs(k).max() > n[system]:
        raise RuntimeError(f"{work}: the calibration circulations are not integers (max error "
                           f"{np.abs(c - k).max():.3g}): not lowest-order edge elements?")
    key, first = np.unique(lo * len(points) + hi, return_index=True)
    kk = k[first]
    inv = np.searchsorted(key, lo * len(points) + hi)
    if np.any(k != kk[inv]):
        raise RuntimeError(f"{work}: an edge reads different unknowns in two tetrahedra")
    edges = np.stack([lo[first], hi[first]], axis=1)
    dof = np.abs(kk).astype(np.int64) - 1
    sign = np.sign(kk).astype(np.int64)
    r = rows[system]
    unknown = r[np.isin(r[:, 3], (1, 5))]
    # the basis functions of the edges (NumType of the unknowns seen on edges); the other unknowns are the
    # global quantities (regions: coil currents and voltages, circuit); an edge unknown seen on no
    # conductor or coil edge is an air edge (left at zero by the carry)
    edge_types = set(unknown[np.isin(unknown[:, 4] - 1, dof[dof >= 0]), 0].tolist())
    glob = {(int(t), int(e), int(h)): int(d) - 1 for t, e, h, _, d in unknown if int(t) not in edge_types}
    log.debug("edge dofs of %s: %d edges (%d unknowns), %d other unknowns of %d", Path(msh).name, len(edges),
              int((dof >= 0).sum()), len(glob), n[system])
    return EdgeDofs(edges, dof, sign, glob, n[system], system)


def _read_vs(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(node coordinates (m, 4, 3), vector values (m, 4, 3)) of the VS records of a parsed Gmsh ``.pos``."""
    text = Path(path).read_text()
    recs = re.findall(r"VS\(([^)]*)\)\{([^}]*)\}", text)
    if not recs:
        raise RuntimeError(f"{path}: no tetrahedron (VS) in the calibration output")
    xyz = np.array([r[0].split(",") for r in recs], dtype=float).reshape(-1, 4, 3)
    val = np.array([r[1].split(",") for r in recs], dtype=float).reshape(-1, 4, 3)
    return xyz, val


def carry_vector(x_old: np.ndarray, old: EdgeDofs, old_to_new: np.ndarray, new: EdgeDofs) -> np.ndarray:
    """The vector ``x_old`` (numbered as ``old``) in the numbering of ``new`` (module docstring);
    ``old_to_new`` (old node rows -> new node rows, -1: removed). Every conductor and coil edge of
    the new mesh must be an edge of the old one (its tetrahedra were kept)."""
    circ = old.circulations(x_old)
    a, b = old_to_new[old.edges[:, 0]], old_to_new[old.edges[:, 1]]
    ok = (a >= 0) & (b >= 0)
    a, b, circ = a[ok], b[ok], circ[ok]
    circ = np.where(a < b, circ, -circ)
    n_nodes = int(max(old_to_new.max(), new.edges.max())) + 1
    key_old = np.minimum(a, b) * n_nodes + np.maximum(a, b)
    order = np.argsort(key_old)
    key_old, circ = key_old[order], circ[order]
    key_new = new.edges[:, 0] * n_nodes + new.edges[:, 1]
    pos = np.clip(np.searchsorted(key_old, key_new), 0, max(len(key_old) - 1, 0))
    found = key_old[pos] == key_new
    if not found.all():
        raise ValueError(f"{int((~found).sum())} conductor or coil edges of the new mesh are not edges of the old one")
    x = np.zeros(new.n_dofs)
    on = new.dof >= 0
    x[new.dof[on]] = new.sign[on] * circ[pos[on]]
    if set(new.globals) != set(old.globals):
        raise ValueError(f"the global unknowns differ: old {sorted(old.globals)}, new {sorted(new.globals)}")
    for key, d in new.globals.items():
        x[d] = float(np.asarray(x_old)[old.globals[key]])
    return x
