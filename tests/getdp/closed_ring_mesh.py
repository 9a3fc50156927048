"""A closed (360 degree) ring coil of rectangular section with a cut, optionally a disk above it:
the meshes of the cut-coil tests (``test_em3d_cut``). gmsh's OpenCASCADE kernel; MSH 2.2 via
:func:`~pulseform.solvers.getdp.mesh3d.generate_tets`.

The cut is the face y = 0, x > 0 of the ring (r0 <= x <= r1, z0 <= z <= z1): a rectangle fragmented
together with the ring and the air, so that the tetrahedra on both sides are conforming with it. Its
triangles' normal is +y or -y as gmsh writes them; ``flip_cut`` reverses the node order of every cut
triangle in the written file (the same surface, the opposite normal).
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp.mesh import AIR, OUTER, SHELL, Rect, coil_tag, conductor_tag, gmsh_session
from pulseform.solvers.getdp.mesh3d import Mesh3D, cut_tag, generate_tets, read_mesh3d, skin_tag

log = logging.getLogger(__name__)


def closed_ring_mesh(path: str | Path, ring: Rect | list[Rect], *, disk: Rect | None = None, r_air: float = 0.1,
                     r_shell: float | None = 0.125, h_coil: float = 2e-3, h_disk: float = 2e-3, h_air: float = 0.02,
                     h_centre: float | None = None, grading: float = 0.3, flip_cut: bool = False) -> Mesh3D:
    """Whole-model mesh (``sector_deg`` 360, no symmetry plane) of the ring ``Rect(r0, z0, r1, z1)`` (m)
    about the z-axis, or of several such rings (the turns of one coil: disjoint volumes in one region):
    coil 101 with its cut 701 (the faces y = 0, x > 0 inside the rings), the massive disk
    or ring ``disk`` (m; conductor 201 with its skin 401), air 1 (sphere ``r_air``), shell 2 to ``r_shell``,
    outer boundary 12. Sizes h_* (m); ``h_centre`` refines about the origin (growing by ``grading``)."""
    path = Path(path).resolve()
    with gmsh_session("closed_ring") as gmsh:
        occ = gmsh.model.occ
        turns = [ring] if isinstance(ring, Rect) else list(ring)
        coils, cuts = [], []
        for t in turns:
            outer = occ.addCylinder(0, 0, t.y0, 0, 0, t.y1 - t.y0, t.x1)
            inner = occ.addCylinder(0, 0, t.y0, 0, 0, t.y1 - t.y0, t.x0)
            coils.append(occ.cut([(3, outer)], [(3, inner)])[0][0][1])
            # the rectangle [x0, x1] x [z0, z1] of the plane y = 0: drawn in z = 0 with y = -z, turned about x
            cuts.append(occ.addRectangle(t.x0, -t.y1, 0, t.x1 - t.x0, t.y1 - t.y0))
            occ.rotate([(2, cuts[-1])], 0, 0, 0, 1, 0, 0, np.pi / 2)
        cond = None
        if disk is not None:
            cond = occ.addCylinder(0, 0, disk.y0, 0, 0, disk.y1 - disk.y0, disk.x1)
            if disk.x0 > 0:
                hole = occ.addCylinder(0, 0, disk.y0, 0, 0, disk.y1 - disk.y0, disk.x0)
                cond = occ.cut([(3, cond)], [(3, hole)])[0][0][1]
        objects = [(3, occ.addSphere(0, 0, 0, r_air))]
        if r_shell:
            objects.append((3, occ.addSphere(0, 0, 0, r_shell)))
        nt = len(turns)
        tools = [(3, c) for c in coils] + [(2, c) for c in cuts] + ([(3, cond)] if cond is not None else [])
        out, out_map = occ.fragment(objects, tools)
        occ.synchronize()
        model = gmsh.model
        n_obj = len(objects)
        shell_parts = ({t for d, t in out_map[1] if d == 3} - {t for d, t in out_map[0] if d == 3}) if r_shell else set()
        coil_parts = [t for m in out_map[n_obj:n_obj + nt] for d, t in m if d == 3]
        cut_parts = [t for m in out_map[n_obj + nt:n_obj + 2 * nt] for d, t in m if d == 2]
        cond_parts = [t for d, t in out_map[n_obj + 2 * nt] if d == 3] if cond is not None else []
        used = set(coil_parts) | set(cond_parts) | shell_parts
        air_parts = [t for d, t in out if d == 3 and t not in used]
        if len(coil_parts) != nt or len(cut_parts) < nt:
            raise RuntimeError(f"fragment: coil parts {coil_parts}, cut parts {cut_parts}")
        model.addPhysicalGroup(3, air_parts, AIR)
        if shell_parts:
            model.addPhysicalGroup(3, sorted(shell_parts), SHELL)
        model.addPhysicalGroup(3, coil_parts, coil_tag(1))
        model.addPhysicalGroup(2, cut_parts, cut_tag(1))
        if cond_parts:
            model.addPhysicalGroup(3, cond_parts, conductor_tag(1))
            skin = model.getBoundary([(3, t) for t in cond_parts], combined=True, oriented=False)
            model.addPhysicalGroup(2, [abs(t) for d, t in skin], skin_tag(1))
        outer_faces = model.getBoundary([(3, t) for d, t in out if d == 3], combined=True, oriented=False)
        model.addPhysicalGroup(2, [abs(t) for d, t in outer_faces], OUTER)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h_air)
        for tags, h in ((air_parts + sorted(shell_parts), h_air), (coil_parts, h_coil), (cond_parts, h_disk)):
            if tags:
                pts = model.getBoundary([(3, t) for t in tags], combined=False, oriented=False, recursive=True)
                model.mesh.setSize([p for p in pts if p[0] == 0], h)
        if h_centre is not None:
            f = model.mesh.field.add("MathEval")
            model.mesh.field.setString(f, "F", f"{h_centre} + {grading} * Sqrt(x*x + y*y + z*z)")
            model.mesh.field.setAsBackgroundMesh(f)
        generate_tets(gmsh, path)
    if flip_cut:
        flip_physical_triangles(path, cut_tag(1))
    mesh = read_mesh3d(path, 360.0, {})
    log.info("closed ring mesh %s: %d tetrahedra, %d nodes", path.name, mesh.n_tets, mesh.n_nodes)
    return mesh


def flip_physical_triangles(path: Path, tag: int) -> None:
    """Reverse the orientation (swap the last two nodes) of every triangle of physical group ``tag`` in
    the MSH 2.2 file ``path``, in place."""
    head, rest = path.read_text().split("$Elements\n", 1)
    body, tail = rest.split("$EndElements", 1)
    count, rows = body.split("\n", 1)
    out = []
    for line in rows.splitlines():
        r = line.split()
        if len(r) > 3 and r[1] == "2" and int(r[3]) == tag:
            r[-2], r[-1] = r[-1], r[-2]
            line = " ".join(r)
        out.append(line)
    path.write_text(f"{head}$Elements\n{count}\n" + "\n".join(out) + f"\n$EndElements{tail}")
