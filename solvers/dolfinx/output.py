"""Field output: one XDMF + HDF5 pair per body, one mesh with every field at each output time.

File layout (``<prefix>_<body>.h5``; h5py reads it by name, no XDMF needed)::

    /                     attrs: format, body, formulation, coordinates ("r z" or "x y"),
                                 stress_components
    /Mesh/points          (N, 3) float64, m: reference coordinates (x, y, 0); x = r, y = z in axisymmetry
    /Mesh/triangles       (C, 3) int64: node indices of each triangle (2D bodies), or
    /Mesh/tetrahedra      (C, 4) int64: node indices of each tetrahedron (3D bodies,
                          formulation "3d", coordinates "x y z", points (x, y, z)), or
    /Mesh/tetrahedra10    (C, 10) int64: of each ten-node tetrahedron (``element = "tet10"``; corners, then
                          the edge nodes of edges 01 12 02 03 13 23: VTK's and XDMF's order); its cell
                          fields are the means over the cell's four Gauss points
    /Mesh/triangles6      (C, 6) int64: of each six-node triangle (``element = "tri6"``; corners, then the
                          edge nodes of edges 01 12 20: VTK's and XDMF's ``Triangle_6``); cell fields: the means
                          over the cell's three Gauss points
    /times                (T,) float64, s: the output times (exact: milestones rounded to 12 digits)
    /Step_0000/           attrs: time (s); one group per output time, in time order
        displacement_m    (N, 3) at nodes: (u_x, u_y, 0) = current - reference position ((u_x, u_y, u_z) in 3D)
        velocity_m_s      (N, 3) at nodes: (v_x, v_y, 0) (the solver's last half-step velocity)
        stress_Pa         (C, 6) per cell: Cauchy stress, components xx, yy, zz, xy, yz, xz
                          (ParaView's order and names XX YY ZZ XY YZ XZ for a symmetric tensor;
                          zz is the hoop stress in axisymmetry, the out-of-plane stress in plane
                          strain, 0 in plane stress; yz = xz = 0), equal to ``Body.cell_stress``
                          (3D: all six, the solver's own order)
        von_mises_Pa      (C,) per cell
        plastic_strain    (C,) per cell: equivalent plastic strain (-)
        temperature_K     (C,) per cell, only for a body whose material carries a temperature
                          (``Material.specific_heat``)
        ...               (C,) per cell: any further fields the writer's ``cell_fields`` gives
                          (e.g. the orchestrator's forming-limit check: minor_strain, major_strain,
                          flc_margin, flc_zone)

The ``.xdmf`` beside it is a temporal collection of uniform grids, all on the same mesh datasets,
each with all its point and cell attributes: ParaView (Xdmf3ReaderS) reads one unstructured grid
with every array at every time, and ``meshio.xdmf.TimeSeriesReader`` reads points, cells and, per
step, all point and cell data. The XDMF is rewritten atomically after every output and the HDF5
file is flushed, so a run that stops leaves readable files up to its last output.

MPI: rank 0 gathers every body's owned nodes (in the global node numbering of the P1 space) and
owned cells (rank by rank) and writes the files alone; the other ranks write nothing.
"""
from __future__ import annotations

import errno
import logging
import os
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

__all__ = ["FieldWriter", "STRESS_COMPONENTS", "output_time", "FORMAT"]

log = logging.getLogger(__name__)

FORMAT = "pulseform mechanical fields 1"
#: component names of ``stress_Pa`` (and the solver's ``cell_stress`` order for the first four)
STRESS_COMPONENTS = ("xx", "yy", "zz", "xy", "yz", "xz")
#: free space kept on the disk beyond twice the bytes of a write (HDF5 metadata, the XDMF, the log)
SPACE_MARGIN = 1 << 20
POINT_FIELDS = ("displacement_m", "velocity_m_s")
CELL_FIELDS = ("stress_Pa", "von_mises_Pa", "plastic_strain")


def output_time(t: float) -> float:
    """An output time as stored: rounded to 12 significant digits, so that a milestone reached by
    summed steps (6.0000000000000035e-05) is stored as the milestone (6e-05)."""
    return float(f"{float(t):.12g}")


def _vec3(a: np.ndarray) -> np.ndarray:
    out = np.zeros((a.shape[0], 3))
    out[:, :a.shape[1]] = a
    return out


def _tensor6(s: np.ndarray) -> np.ndarray:
    out = np.zeros((s.shape[0], 6))
    out[:, :s.shape[1]] = s  # the 2D solver's [xx, yy, zz, xy]; the 3D solver's six
    return out


#: cell dataset and XDMF topology by vertices per cell
_CELLS = {3: ("triangles", "Triangle"), 4: ("tetrahedra", "Tetrahedron"), 10: ("tetrahedra10", "Tetrahedron_10"),
          6: ("triangles6", "Triangle_6")}


class _BodyFile:
    """Rank-0 side of one body's HDF5 file and XDMF index."""

    def __init__(self, path_xdmf: Path, body: str, formulation: str, points: np.ndarray,
                 triangles: np.ndarray):
        import h5py

        self.xdmf = path_xdmf
        self.h5_path = path_xdmf.with_suffix(".h5")
        self.body = body
        self.n_points, self.n_cells = points.shape[0], triangles.shape[0]
        self.n_vertices = triangles.shape[1]
        self.cell_set, self.topology = _CELLS[self.n_vertices]
        _ensure_space(self.h5_path, points.nbytes + triangles.nbytes)
        self.h5 = h5py.File(self.h5_path, "w")
        a = self.h5.attrs
        a["format"] = FORMAT
        a["body"] = body
        a["formulation"] = formulation
        a["coordinates"] = {"axisymmetric": "r z", "3d": "x y z"}.get(formulation, "x y")
        a["stress_components"] = " ".join(STRESS_COMPONENTS)
        pts = self.h5.create_dataset("Mesh/points", data=points)
        pts.attrs["unit"] = "m"
        pts.attrs["description"] = "reference (initial) coordinates; current = points + displacement_m"
        self.h5.create_dataset(f"Mesh/{self.cell_set}", data=triangles.astype(np.int64))
        self.h5.create_dataset("times", shape=(0,), maxshape=(None,), dtype="f8").attrs["unit"] = "s"
        self.times: list[float] = []
        self.h5.flush()

    def write(self, t: float, point: dict[str, np.ndarray], cell: dict[str, np.ndarray]) -> None:
        _ensure_space(self.h5_path, sum(a.nbytes for a in (*point.values(), *cell.values())))
        k = len(self.times)
        g = self.h5.create_group(f"Step_{k:04d}")
        g.attrs["time"] = t
        for name, arr in {**point, **cell}.items():
            d = g.create_dataset(name, data=arr)
            if name == "stress_Pa":
                d.attrs["components"] = " ".join(STRESS_COMPONENTS)
        self.times.append(t)
        ds = self.h5["times"]
        ds.resize((k + 1,))
        ds[k] = t
        self.h5.flush()
        self._write_xdmf(point, cell)

    def _write_xdmf(self, point: dict[str, np.ndarray], cell: dict[str, np.ndarray]) -> None:
        h5 = self.h5_path.name

        def item(parent, path: str, shape, dtype):
            kind, prec = ("Int", "8") if np.dtype(dtype).kind in "iu" else ("Float", "8")
            e = ET.SubElement(parent, "DataItem", DataType=kind, Precision=prec, Format="HDF",
                              Dimensions=" ".join(str(n) for n in shape))
            e.text = f"{h5}:{path}"

        def kind_of(arr):
            if arr.ndim == 1:
                return "Scalar"
            return {3: "Vector", 6: "Tensor6"}[arr.shape[1]]

        root = ET.Element("Xdmf", Version="3.0")
        domain = ET.SubElement(root, "Domain")
        coll = ET.SubElement(domain, "Grid", Name=self.body, GridType="Collection",
                             CollectionType="Temporal")
        for k, t in enumerate(self.times):
            grid = ET.SubElement(coll, "Grid", Name=self.body if k == 0 else f"{self.body}_{k:04d}",
                                 GridType="Uniform")
            topo = ET.SubElement(grid, "Topology", TopologyType=self.topology,
                                 NumberOfElements=str(self.n_cells))
            item(topo, f"/Mesh/{self.cell_set}", (self.n_cells, self.n_vertices), np.int64)
            geo = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
            item(geo, "/Mesh/points", (self.n_points, 3), np.float64)
            ET.SubElement(grid, "Time", Value=repr(t))
            for centre, fields in (("Node", point), ("Cell", cell)):
                for name, arr in fields.items():
                    att = ET.SubElement(grid, "Attribute", Name=name, AttributeType=kind_of(arr),
                                        Center=centre)
                    item(att, f"/Step_{k:04d}/{name}", arr.shape, arr.dtype)
        ET.indent(root)
        tmp = self.xdmf.with_name(f".{self.xdmf.name}.tmp")
        with open(tmp, "w", encoding="utf-8") as f:  # the user's umask, like the .h5
            f.write('<?xml version="1.0" encoding="utf-8"?>\n')
            f.write(ET.tostring(root, encoding="unicode"))
            f.write("\n")
        os.replace(tmp, self.xdmf)

    def close(self) -> None:
        try:
            self.h5.close()
        except (OSError, RuntimeError) as exc:  # e.g. a full disk: keep the error that stopped the run
            log.warning("closing %s: %s", self.h5_path, exc)


def _ensure_space(path: Path, nbytes: int) -> None:
    """Refuse a write (OSError ENOSPC) that would fill the disk, before HDF5 starts it: HDF5 that
    ran out of space mid-write leaves the file and the library in a state that crashes the process at
    exit (h5py 3.7 / HDF5 1.10, Debian 12)."""
    free = shutil.disk_usage(path.parent).free
    if free < 2 * nbytes + SPACE_MARGIN:
        raise OSError(errno.ENOSPC, f"No space left on device for {nbytes} bytes of fields "
                      f"({free} bytes free)", str(path))


class FieldWriter:
    """Write displacement and velocity (nodes) and stress tensor, von Mises stress and equivalent
    plastic strain (cells; the temperature of a body that carries one) of every body: one mesh, all
    fields, per output time (see the module docstring for the file layout).

    The mesh is stored in the reference configuration; warp it by ``displacement_m`` to see the
    deformed shape.

    Parameters
    ----------
    solver : ExplicitSolver or ExplicitSolver3D
        The solver whose bodies are written.
    path_prefix : str or Path
        Files are ``<path_prefix>_<body>.xdmf`` + ``.h5``.
    cell_fields : callable, optional
        ``cell_fields(name, body) -> {field: (C,) array}``: further per-cell fields of body ``name`` on this
        rank (its owned cells, in ``body.cells`` order), written beside the others; the same names at every
        output time.
    """

    def __init__(self, solver, path_prefix, cell_fields=None):
        self.solver = solver
        self.cell_fields = cell_fields
        self.comm = solver.comm
        self._files: dict[str, _BodyFile] = {}
        prefix = Path(path_prefix)
        self._gids = {}
        for n, b in solver.bodies.items():
            own = b.global_ids[: b.n_owned]
            self._gids[n] = own
            parts = self.comm.gather((own, b.X0[: b.n_owned], b.global_ids[b.cells]), root=0)
            if self.comm.rank == 0:
                n_glob = len(b.X0) if getattr(b, "element", "tet4") in ("tet10", "tri6") else b.V.dofmap.index_map.size_global
                X = np.zeros((n_glob, b.X0.shape[1]))
                for gid, x, _ in parts:
                    X[gid] = x
                nv = b.cells.shape[1]
                tris = np.vstack([c.reshape(-1, nv) for _, _, c in parts]).astype(np.int64)
                path = prefix.parent / f"{prefix.name}_{n}.xdmf"
                self._files[n] = _BodyFile(path, n, solver.formulation, _vec3(X), tris)

    def write(self, t: float) -> None:
        """Write all fields of every body at time ``t`` (s; stored as :func:`output_time` (t))."""
        t = output_time(t)
        for n, b in self.solver.bodies.items():
            own = slice(0, b.n_owned)
            extra = self.cell_fields(n, b) if self.cell_fields is not None else {}
            cm = getattr(b, "cell_means", lambda a: a)      # per cell (a ten-node body: its Gauss points' means)
            local = (self._gids[n], b.u[own], b.v[own], cm(b.cell_stress), cm(b.von_mises), cm(b.eps_p), extra,
                     cm(b.temperature) if b.material.thermal else None)
            parts = self.comm.gather(local, root=0)
            if self.comm.rank != 0:
                continue
            f = self._files[n]
            u = np.zeros((f.n_points, b.x.shape[1]))
            v = np.zeros((f.n_points, b.x.shape[1]))
            for gid, ui, vi, *_ in parts:
                u[gid] = ui
                v[gid] = vi
            s = np.vstack([p[3].reshape(-1, b.cell_stress.shape[1]) for p in parts])
            vm = np.concatenate([p[4] for p in parts])
            ep = np.concatenate([p[5] for p in parts])
            cells = {"stress_Pa": _tensor6(s), "von_mises_Pa": vm.astype(float), "plastic_strain": ep.astype(float)}
            if b.material.thermal:
                cells["temperature_K"] = np.concatenate([p[7] for p in parts]).astype(float)
            cells.update({k: np.concatenate([p[6][k] for p in parts]).astype(float) for k in extra})
            f.write(t, {"displacement_m": _vec3(u), "velocity_m_s": _vec3(v)}, cells)

    def close(self) -> None:
        """Close the files."""
        for f in self._files.values():
            f.close()
        self._files = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
