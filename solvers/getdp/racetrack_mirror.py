"""The half model of a racetrack quarter mesh as the quarter and its mirror image about x = 0.

The check of the symmetry plane x = 0 (n x a = 0) needs two models that discretise the same device
in the same way: the quarter (planes x = 0 and y = 0) and the half (plane y = 0 only, the mesh of
the quarter and its mirror image, joined on x = 0). Any difference between their solutions is then
the boundary condition's, not the meshes'. Works on the MSH 2.2 files of
:func:`.racetrack_mesh.racetrack_groove_mesh` (physical ids of :mod:`.mesh3d`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .mesh3d import ELEC_IN_BASE, ELEC_OUT_BASE, SKIN_BASE, SYM_A, Mesh3D, read_msh22_tets


def mirror_quarter(quarter: Mesh3D, path: str | Path) -> Mesh3D:
    """Write the half model (sector 180 degrees) made of ``quarter`` and its mirror about x = 0 to ``path``.

    Nodes on x = 0 (to 1e-12 of the model's size; put exactly on it) are shared; faces on x = 0 leave the
    symmetry group (14), the skins (400 + k) and the outlet electrode (601); the inlet electrode's
    mirror image (on y = 0, x < 0) becomes the outlet electrode.
    """
    text = Path(quarter.path).read_text()
    head, rest = text.split("$Nodes\n", 1)
    nodes = np.array(rest.split("$EndNodes", 1)[0].split("\n", 1)[1].split(), dtype=float).reshape(-1, 4)
    body = text.split("$Elements\n", 1)[1].split("$EndElements", 1)[0].split("\n", 1)[1]
    ids = nodes[:, 0].astype(np.int64)
    offset = int(ids.max())
    scale = np.abs(nodes[:, 1:]).max()
    on_plane = np.abs(nodes[:, 1]) <= 1e-12 * scale
    nodes[on_plane, 1] = 0.0
    image = {int(i): int(i) if p else int(i) + offset for i, p in zip(ids, on_plane)}
    zero = set(ids[on_plane].tolist())
    new_nodes = [f"{int(i)} {x!r} {y!r} {z!r}" for i, x, y, z in nodes.tolist()]
    new_nodes += [f"{int(i) + offset} {-x!r} {y!r} {z!r}" for (i, x, y, z), p in zip(nodes.tolist(), on_plane) if not p]
    rows = [r.split() for r in body.splitlines() if r.strip()]
    out = []

    def add(kind: str, ntag: int, tags: list[str], conn: list[int]) -> None:
        out.append(" ".join([str(len(out) + 1), kind, str(ntag)] + tags + [str(c) for c in conn]))

    for r in rows:
        kind, ntag = r[1], int(r[2])
        tags, conn = r[3:3 + ntag], [int(c) for c in r[3 + ntag:]]
        phys = int(tags[0])
        mirrored = [image[c] for c in conn]
        if kind == "4":
            add(kind, ntag, tags, conn)
            add(kind, ntag, tags, mirrored[:1] + mirrored[2:3] + mirrored[1:2] + mirrored[3:])   # keep orientation
            continue
        if kind != "2":
            raise ValueError(f"{quarter.path}: unexpected element type {kind}")
        in_plane = all(c in zero for c in conn)
        if in_plane and (phys in (SYM_A, ELEC_OUT_BASE + 1) or SKIN_BASE < phys < ELEC_IN_BASE):
            continue
        if phys == ELEC_OUT_BASE + 1:
            raise ValueError(f"{quarter.path}: an outlet electrode face off the plane x = 0")
        add(kind, ntag, tags, conn)
        mtags = list(tags)
        if phys == ELEC_IN_BASE + 1:
            mtags[0] = str(ELEC_OUT_BASE + 1)
        add(kind, ntag, mtags, mirrored)
    path = Path(path).resolve()
    path.write_text(f"{head}$Nodes\n{len(new_nodes)}\n" + "\n".join(new_nodes) + "\n$EndNodes\n"
                    f"$Elements\n{len(out)}\n" + "\n".join(out) + "\n$EndElements\n")
    points, tets, eids, tags = read_msh22_tets(path)
    return Mesh3D(points=points, tets=tets, tet_ids=eids, tet_tags=tags, path=path, sector_deg=180.0,
                  electrode_area=dict(quarter.electrode_area or {}))


__all__ = ["mirror_quarter"]
