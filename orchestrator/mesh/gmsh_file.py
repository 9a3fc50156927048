"""A 3D geometry file as a mesh with named physical groups (``[geometry] type = "geometry_3d"``): meshing it
and reading its groups; :mod:`.geometry3d` maps them onto the deck's roles.

1. :func:`mesh_file3d`: a ``.msh`` is read as it is; a ``.geo`` or a CAD file (``.step``/``.stp``, ``.brep``,
   ``.iges``/``.igs``) is meshed with tetrahedra by gmsh in a child process (``python -m
   pulseform.orchestrator.mesh.gmsh_file``: ``-setnumber`` parameters, the sizes of ``geometry.mesh_sizes`` on
   the points of each named volume group, ``geometry.mesh_size_factor`` on all, MSH 2.2) under
   ``limits.gmsh_time_limit_s``; a CAD file without physical groups gets one per volume and per surface, named
   by its CAD label or ``volume_<tag>`` / ``surface_<tag>``; a ``.py`` builder runs as ``python FILE OUT.msh
   name=value ...`` (it writes OUT.msh with named physical groups; :func:`builder_arguments` reads them).
2. :func:`read_groups`: the tetrahedra and triangles of every named group (meshio reads MSH 2.2 and 4.1).
"""

from __future__ import annotations

import json
import logging
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

log = logging.getLogger(__name__)

#: gmsh's element kinds of interest in meshio's names
_TETRA, _TRIANGLE = "tetra", "triangle"

class GeometryError(RuntimeError):
    """A 3D geometry file or its role map is not usable (one line naming the file and the key).

    ``log_path``: the gmsh log it refers to, if any."""

    def __init__(self, message: str, *, log_path: Path | None = None) -> None:
        self.message = message
        self.log_path = None if log_path is None else Path(log_path)
        super().__init__(message if log_path is None else f"{message} (log: {log_path})")


# ----------------------------------------------------------------------------- 1. meshing
def mesh_file3d(g, work: Path, time_limit: float = 600.0, max_cells: float = 2e6) -> Path:
    """The raw mesh of ``g`` (a :class:`~pulseform.orchestrator.case.geometry3d.GeometryFile3D`): the
    ``.msh`` itself or the file meshed by a child process into ``work/geometry.msh`` (log
    ``work/gmsh.log``); raises :class:`GeometryError` with the log's tail when meshing fails or exceeds
    ``time_limit`` (s), and before meshing when the case's sizes would give more than ``max_cells`` tetrahedra
    (``limits.max_cells``; estimated from the volumes: :func:`_too_many_cells`)."""
    from pulseform.solvers.getdp.runner import run_logged

    src = Path(g.file)
    if src.suffix.lower() == ".msh":
        return src
    work = Path(work).resolve()
    work.mkdir(parents=True, exist_ok=True)
    out = work / "geometry.msh"
    out.unlink(missing_ok=True)
    params = [f"{k}={float(v)!r}" for k, v in (g.parameters or {}).items()]
    factor = float(getattr(g, "mesh_size_factor", 1.0))
    if src.suffix.lower() == ".py":
        argv = [sys.executable, str(src), str(out)] + params + ([f"mesh_size_factor={factor!r}"] if factor != 1.0 else [])
        what = "the builder"
    else:
        argv = [sys.executable, "-m", __name__, str(src), str(out), json.dumps(g.mesh_sizes or {}), repr(factor),
                repr(float(max_cells))] + params
        what = "gmsh"
    log_path = work / "gmsh.log"
    try:
        code, text = run_logged(argv, src.parent, log_path, time_limit)
    except subprocess.TimeoutExpired:
        raise GeometryError(f"{src.name}: geometry.file: meshing exceeded its time limit of {time_limit:g} s "
                            "(limits.gmsh_time_limit_s) and was stopped", log_path=log_path) from None
    except OSError as exc:
        raise GeometryError(f"{src.name}: geometry.file: could not start {what}: {exc}", log_path=log_path) from None
    if code != 0 or not out.is_file():
        lines = [ln for ln in text.splitlines() if ln.strip()]
        last = next((ln for ln in reversed(lines) if "rror" in ln), lines[-1] if lines else f"exit code {code}")
        raise GeometryError(f"{src.name}: geometry.file: {what} failed: {last.strip()[:200]}", log_path=log_path)
    return out


class BuilderArgumentError(ValueError):
    """A gmsh builder script was called with arguments it does not know."""


def builder_arguments(argv: Sequence[str], known: Sequence[str], integers: Sequence[str] = ()
                      ) -> tuple[str, dict[str, float | int], float]:
    """The arguments a ``.py`` builder receives (``python FILE OUT.msh name=value ... [mesh_size_factor=f]``):
    (OUT.msh, the values by name -- ints for ``integers`` --, the mesh size factor, 1.0 when not given).
    A builder script calls this on ``sys.argv[1:]``; raises :class:`BuilderArgumentError` naming an unknown name
    (the builder prints it as an ``Error:`` line, which pulseform quotes)."""
    if not argv:
        raise BuilderArgumentError("usage: python BUILDER.py OUT.msh [name=value ...]")
    values: dict[str, float | int] = {}
    factor = 1.0
    for item in argv[1:]:
        name, _, text = item.partition("=")
        if name == "mesh_size_factor":   # pulseform's refinement (geometry.mesh_size_factor)
            factor = float(text)
        elif name in known:
            values[name] = int(float(text)) if name in integers else float(text)
        else:
            raise BuilderArgumentError(f"unknown parameter {name!r}; known: {', '.join(sorted(known))}")
    return argv[0], values, factor


#: tetrahedra per h^3 of volume at element size h, taken low (a regular tetrahedron of edge h holds h^3 / 8.49,
#: gmsh's elements scatter about the size): the estimate before meshing is a lower one
TETS_PER_H3 = 8.49 / 2.0


def _too_many_cells(gmsh, names: dict, sizes: dict[str, float], factor: float, max_cells: float) -> str | None:
    """Before meshing: the line refusing sizes that would give more than ``max_cells`` tetrahedra (a lower estimate:
    :data:`TETS_PER_H3` per (h x factor)^3 of each sized volume group's volume; the whole model's volume at gmsh's
    Mesh.MeshSizeMax x factor, the largest size any element may have), None when they fit. Volumes from
    OpenCASCADE (a built-in-kernel volume is not estimated)."""
    def volume(tags) -> float:
        try:
            return float(sum(gmsh.model.occ.getMass(3, int(t)) for t in tags))
        except Exception:   # a built-in kernel entity: no mass
            return 0.0

    for group, h in sizes.items():
        n = TETS_PER_H3 * volume(gmsh.model.getEntitiesForPhysicalGroup(3, names[group][1])) / (h * factor) ** 3
        if n > max_cells:
            key = f"geometry.mesh_sizes.{group}" + (" x geometry.mesh_size_factor" if factor != 1.0 else "")
            return (f"Error: {key}: ~{n:.3g} tetrahedra at {h:g} m" + (f" x {factor:g}" if factor != 1.0 else "")
                    + f", above limits.max_cells = {max_cells:.3g}; coarsen it (or raise the limit)")
    h_max = gmsh.option.getNumber("Mesh.MeshSizeMax")
    if 0.0 < h_max < 1e22:
        n = TETS_PER_H3 * volume([t for _, t in gmsh.model.getEntities(3)]) / (h_max * factor) ** 3
        if n > max_cells:
            return (f"Error: geometry.mesh_size_factor: ~{n:.3g} tetrahedra at least (the file's largest size "
                    f"{h_max:g} m x {factor:g}), above limits.max_cells = {max_cells:.3g}")
    return None


def _child(src: str, out: str, sizes_json: str, factor: float, max_cells: float, params: Sequence[str]) -> int:
    """The meshing child (module docstring, 1.): open ``src`` with ``params`` (``name=value``), size the
    named volume groups, every size times ``factor``, refuse sizes that would exceed ``max_cells`` tetrahedra
    (:func:`_too_many_cells`), mesh in 3D, write MSH 2.2 to ``out``. Prints gmsh's messages (the log)."""
    import gmsh

    argv = ["gmsh"]
    for p in params:
        name, value = p.split("=", 1)
        argv += ["-setnumber", name, value]
    gmsh.initialize(argv, readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 1)
        try:
            gmsh.open(src)
        except Exception as exc:   # a parse error or the file's own Error(...): its message, not the traceback's
            log.error("Error: %s", exc)
            return 3
        if Path(src).suffix.lower() != ".geo" and not gmsh.model.getPhysicalGroups():
            _name_cad_entities(gmsh)
        names = {gmsh.model.getPhysicalName(d, t): (d, t) for d, t in gmsh.model.getPhysicalGroups()}
        for group, h in json.loads(sizes_json).items():
            if group not in names or names[group][0] != 3:
                vols = sorted(n for n, (d, _) in names.items() if d == 3)
                log.error("Error: geometry.mesh_sizes: no physical volume group %r; the file's: %s", group, vols)
                return 3
            ents = gmsh.model.getEntitiesForPhysicalGroup(3, names[group][1])
            pts = gmsh.model.getBoundary([(3, int(e)) for e in ents], combined=False, oriented=False, recursive=True)
            gmsh.model.mesh.setSize([p for p in pts if p[0] == 0], float(h))
        if gmsh.model.getDimension() < 3 or not gmsh.model.getEntities(3):
            log.error("Error: the geometry has no volume")
            return 3
        refusal = _too_many_cells(gmsh, names, json.loads(sizes_json), factor, max_cells)
        if refusal is not None:
            log.error("%s", refusal)
            return 3
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.option.setNumber("Mesh.Optimize", 1)
        if factor != 1.0:
            gmsh.option.setNumber("Mesh.MeshSizeFactor", factor)
        gmsh.model.mesh.generate(3)
        gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(out)
    finally:
        gmsh.finalize()
    return 0


def _name_cad_entities(gmsh) -> None:
    """A CAD file without physical groups: make its volumes conforming (one fragment) and give every volume
    and surface a physical group named by its CAD label or ``volume_<tag>`` / ``surface_<tag>``."""
    vols = gmsh.model.getEntities(3)
    if len(vols) > 1:
        gmsh.model.occ.fragment(vols[:1], vols[1:])
        gmsh.model.occ.synchronize()
    for dim, what in ((3, "volume"), (2, "surface")):
        used: set[str] = set()
        for _, tag in gmsh.model.getEntities(dim):
            label = gmsh.model.getEntityName(dim, tag).split("/")[-1].strip()
            name = label if label and label not in used else f"{what}_{tag}"
            used.add(name)
            p = gmsh.model.addPhysicalGroup(dim, [tag])
            gmsh.model.setPhysicalName(dim, p, name)


# ----------------------------------------------------------------------------- 2. reading
@dataclass
class RawGroups:
    """A raw 3D mesh by named physical group: ``points`` (n, 3) m (only nodes of tetrahedra, file order);
    ``tets`` (m, 4) node rows, ``tet_group`` the group name of each; ``surfaces`` name -> (f, 3) node rows;
    ``volumes`` the volume groups' names; ``path`` the file."""

    points: np.ndarray
    tets: np.ndarray
    tet_group: np.ndarray
    surfaces: dict[str, np.ndarray]
    volumes: list[str]
    path: Path

    def listing(self) -> str:
        """The groups for a message: volumes then surfaces, each quoted."""
        return ("volumes " + ", ".join(repr(v) for v in self.volumes) + "; surfaces "
                + (", ".join(repr(s) for s in self.surfaces) or "(none)"))


def read_groups(path: Path, label: str) -> RawGroups:
    """Read a MSH file's tetrahedra and triangles by physical-group name (``label``: the file named in
    messages). Unnamed groups are named by their number. Nodes used by no tetrahedron are dropped (the
    order of the others kept)."""
    import meshio

    try:
        m = meshio.read(path)
    except Exception as exc:  # meshio raises many kinds for a file that is not a mesh
        raise GeometryError(f"{label}: geometry.file: not a readable mesh: {str(exc)[:150]}") from None
    names = {}
    for name, (tag, dim) in ((k, (int(v[0]), int(v[1]))) for k, v in (m.field_data or {}).items()):
        names[(dim, tag)] = name
    phys = m.cell_data.get("gmsh:physical")
    if phys is None:
        raise GeometryError(f"{label}: geometry.file: the mesh has no physical groups; name its volumes and "
                            "surfaces (Physical Volume(\"air\") = {...}; ...)")
    tets, tet_tag, tris = [], [], {}
    for block, tags in zip(m.cells, phys):
        if block.type == _TETRA:
            tets.append(block.data)
            tet_tag.append(np.asarray(tags, int))
        elif block.type == _TRIANGLE:
            for t in np.unique(tags):
                name = names.get((2, int(t)), str(int(t)))
                tris.setdefault(name, []).append(block.data[np.asarray(tags) == t])
    if not tets:
        raise GeometryError(f"{label}: geometry.file: the mesh has no tetrahedra in a physical volume group")
    tets_a, tag_a = np.concatenate(tets).astype(np.int64), np.concatenate(tet_tag)
    used = np.unique(tets_a)
    new = np.full(len(m.points), -1, dtype=np.int64)
    new[used] = np.arange(len(used))
    group_of = np.array([names.get((3, int(t)), str(int(t))) for t in np.unique(tag_a)], dtype=object)
    lookup = dict(zip(np.unique(tag_a).tolist(), group_of.tolist()))
    surfaces = {}
    for name, parts in tris.items():
        t = np.concatenate(parts).astype(np.int64)
        if np.all(new[t] >= 0):
            surfaces[name] = new[t]
    volumes = sorted(set(lookup.values()))
    return RawGroups(points=np.asarray(m.points[used], float)[:, :3].copy(), tets=new[tets_a],
                     tet_group=np.array([lookup[t] for t in tag_a.tolist()], dtype=object), surfaces=surfaces,
                     volumes=volumes, path=Path(path))


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m pulseform.orchestrator.mesh.gmsh_file SRC OUT SIZES_JSON FACTOR MAX_CELLS [name=value ...]``: the
    meshing child."""
    logging.basicConfig(stream=sys.stdout, format="%(message)s", level=logging.INFO)   # the child's log: gmsh.log
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) < 5:
        log.error("usage: python -m pulseform.orchestrator.mesh.gmsh_file SRC OUT SIZES_JSON FACTOR MAX_CELLS "
                  "[name=value ...]")
        return 2
    return _child(args[0], args[1], args[2], float(args[3]), float(args[4]), args[5:])


if __name__ == "__main__":
    sys.exit(main())
