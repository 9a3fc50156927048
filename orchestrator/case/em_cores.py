"""Case-file keys of the non-conducting magnetic cores of the ``coaxial_coils`` geometry (issue 35):
``[[geometry.cores]]``, each a set of rectangles of one material whose ``relative_permeability`` or ``bh_curve``
it takes (a laminated or powder core: no eddy current, no force on it, it does not move). GetDP meshes each
rectangle as a magnetic core region (physical 800 + k, :class:`pulseform.solvers.getdp.model.MagneticCore`).
Also the rectangle checks ``coaxial_coils`` applies to its windings, workpiece and cores. Units: m.
"""

from __future__ import annotations

from dataclasses import dataclass

from .schema import SchemaError, spec

__all__ = ["Box4", "CoaxialCore", "check_box", "boxes_meet", "check_placed", "check_cores", "check_core_materials"]

Box4 = tuple[float, float, float, float]


def check_box(box: Box4, path: str) -> None:
    """A rectangle [r0, z0, r1, z1] (m) in the half plane r >= 0 with positive extents."""
    r0, z0, r1, z1 = box
    if r0 < 0.0:
        raise SchemaError(path, f"got r0 = {r0:g}; must be >= 0 (the axis is r = 0) (m)")
    if r1 <= r0 or z1 <= z0:
        raise SchemaError(path, f"got [{r0:g}, {z0:g}, {r1:g}, {z1:g}]; need r1 > r0 and z1 > z0 (m)")


def boxes_meet(a: Box4, b: Box4, touching: bool) -> bool:
    """True if rectangles ``a`` and ``b`` overlap with positive area (or, with ``touching``, share any point)."""
    if touching:
        return a[0] <= b[2] and b[0] <= a[2] and a[1] <= b[3] and b[1] <= a[3]
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


@dataclass(frozen=True, kw_only=True)
class CoaxialCore:
    """A non-conducting magnetic core of ``coaxial_coils`` (a laminated or powder core): rectangles of one
    material, meshed at ``mesh_size_coil``; its material's ``relative_permeability`` or ``bh_curve`` sets its
    permeability (its conductivity is not used: no eddy current)."""

    name: str = spec(doc="the core's name (free text)")
    material: str = spec(doc="a [materials] entry with relative_permeability != 1 or a bh_curve")
    boxes: tuple[Box4, ...] = spec(unit="m", doc="its cross-sections [r0, z0, r1, z1], r >= 0 (one or more; they "
                                                 "may touch each other and the coils, not overlap)")


def check_placed(path: str, kind: str, items, boxes_of: str, placed: list[tuple[str, Box4]],
                 work: Box4) -> list[tuple[str, Box4]]:
    """One line for ``kind`` entries (``coils`` or ``cores``) with a repeated name or no boxes, or a box (the
    field ``boxes_of``: ``windings``, ``boxes``) that is no rectangle, overlaps another placed box, or touches the
    workpiece (it moves, coils and cores do not); the entries' boxes with their keys. ``placed``: the boxes
    placed before (key, box); ``work``: the workpiece's box."""
    names: list[str] = []
    out: list[tuple[str, Box4]] = []
    for i, c in enumerate(items):
        if c.name in names:
            raise SchemaError(f"{path}.{kind}[{i}].name", f"got {c.name!r}; {kind[:-1]} names must be unique")
        names.append(c.name)
        boxes = getattr(c, boxes_of)
        if not boxes:
            raise SchemaError(f"{path}.{kind}[{i}].{boxes_of}", "got an empty list; give at least one [r0, z0, r1, z1]")
        for j, box in enumerate(boxes):
            key = f"{path}.{kind}[{i}].{boxes_of}[{j}]"
            check_box(box, key)
            if boxes_meet(box, work, touching=True):
                raise SchemaError(key, f"overlaps or touches the workpiece; leave a gap (the workpiece moves, the "
                                       f"{kind} do not)")
            for other, b in placed + out:
                if boxes_meet(box, b, touching=False):
                    raise SchemaError(key, f"overlaps {other}")
            out.append((f"{kind}[{i}].{boxes_of}[{j}]", box))
    return out


def check_cores(path: str, cores: tuple[CoaxialCore, ...], placed: list[tuple[str, Box4]],
                work: Box4) -> list[tuple[str, Box4]]:
    """:func:`check_placed` for the cores' boxes (after the coils' windings, ``placed``)."""
    return check_placed(path, "cores", cores, "boxes", placed, work)


def check_core_materials(case) -> None:
    """Each core's material exists and is magnetic (μ_r != 1 or a B–H curve); one line naming the key."""
    for i, c in enumerate(getattr(case.geometry, "cores", ()) or ()):
        key = f"geometry.cores[{i}].material"
        mat = case.materials.get(c.material)
        if mat is None:
            raise SchemaError(key, f"got {c.material!r}; must be one of the [materials] entries: "
                                   f"{', '.join(sorted(case.materials)) or '(none)'}")
        if mat.bh_curve is None and mat.relative_permeability == 1.0:
            raise SchemaError(key, f"materials.{c.material} has relative_permeability = 1 and no bh_curve; a core "
                                   "needs a magnetic material (relative_permeability != 1 or [bh_curve])")
