"""Case-file keys of 3D cases (``mechanics.formulation = "3d"``, issue 20): solid shapes meshed with
tetrahedra, symmetry planes, and the checks that keep 2D-only keys out of 3D cases and 3D-only keys
out of 2D cases.

3D mechanics cases: the explicit solver on tetrahedra, rigid walls, symmetry planes, soft contact
between bodies; coupled 3D cases are 3D geometry files (:mod:`.geometry3d`). A body's ``shape`` is a
``box`` or a ``cylinder`` (a sector of one with ``angle``), vectors (velocities, wall points and
normals, probe points) take three components, and ``[[symmetry]]`` planes cut a quarter or a sector.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

from .schema import SchemaError, spec
from .geometry3d import validate_geometry_3d

Vec3 = tuple[float, float, float]

#: the formulation value of 3D cases
FORMULATION_3D = "3d"


@dataclass(frozen=True, kw_only=True)
class SolidBox:
    """Axis-aligned box (3D cases), meshed with tetrahedra by gmsh (OpenCASCADE)."""

    type: Literal["box"] = spec(doc="shape kind (3D)")
    origin: Vec3 = spec((0.0, 0.0, 0.0), unit="m", doc="corner with the smallest x, y, z")
    size: Vec3 = spec(unit="m", gt=0.0, doc="extents along x, y, z")

    def volume(self) -> float:
        """Volume, m^3."""
        return self.size[0] * self.size[1] * self.size[2]

    def thinnest(self) -> float:
        """Smallest extent, m."""
        return min(self.size)


@dataclass(frozen=True, kw_only=True)
class SolidCylinder:
    """Circular cylinder or a sector of one (3D cases), meshed with tetrahedra by gmsh (OpenCASCADE);
    a sector starts at OpenCASCADE's local x direction (for an axis along z: from +x towards +y)."""

    type: Literal["cylinder"] = spec(doc="shape kind (3D)")
    base: Vec3 = spec((0.0, 0.0, 0.0), unit="m", doc="centre of the base face")
    axis: Vec3 = spec(unit="m", doc="axis vector: direction and length of the cylinder")
    radius: float = spec(unit="m", gt=0.0, doc="radius")
    angle: float = spec(2.0 * math.pi, unit="rad", gt=0.0, le=2.0 * math.pi,
                        doc="sector angle about the axis (2π: the whole cylinder; π/2: a quarter)")

    def validate(self, path: str) -> None:
        if math.hypot(*self.axis) == 0.0:
            raise SchemaError(f"{path}.axis", "got [0, 0, 0]; must be a non-zero vector (m)")

    def volume(self) -> float:
        """Volume, m^3."""
        return 0.5 * self.angle * self.radius ** 2 * math.hypot(*self.axis)

    def thinnest(self) -> float:
        """Smallest extent, m."""
        return min(self.radius, math.hypot(*self.axis))


@dataclass(frozen=True, kw_only=True)
class SymmetryPlane:
    """A symmetry plane of a 3D model (a quarter, a sector): boundary nodes on it keep their normal
    velocity at zero (a frictionless roller). Any orientation: a plane normal to x, y or z holds one
    velocity component, an oblique one (the second face of a sector) projects the nodes' velocity
    and acceleration onto the plane (``BodySpec.sliding``)."""

    point: Vec3 = spec((0.0, 0.0, 0.0), unit="m", doc="a point on the plane")
    normal: Vec3 = spec(unit="-", doc="normal (any non-zero vector), e.g. [0, 1, 0] or [-sin(a), cos(a), 0]")
    bodies: tuple[str, ...] = spec((), doc="bodies it acts on (empty = all)")
    field: Literal["b_tangential", "b_normal"] = spec(
        "b_tangential", doc="coupled 3D geometry files, its EM condition: 'b_tangential' (n x a = 0: the currents "
                            "cross the plane at right angles, B lies in it) or 'b_normal' (n x h = 0: the currents "
                            "run along the plane, B crosses it)")

    def validate(self, path: str) -> None:
        if len(self.normal) != 3 or math.hypot(*self.normal) == 0.0:
            raise SchemaError(f"{path}.normal", f"got {list(self.normal)}; must be a non-zero vector [nx, ny, nz]")

    def axis_aligned(self) -> bool:
        """True for a plane normal to x, y or z."""
        return sum(1 for c in self.normal if c != 0.0) == 1

    def component(self) -> int:
        """The axis (0, 1, 2) the plane is normal to (axis-aligned planes)."""
        return next(i for i, c in enumerate(self.normal) if c != 0.0)


SOLID_TYPES = ("box", "cylinder")

#: Keys of ``[mechanics]`` that only plane and axisymmetric models have, and why.
TWO_D_ONLY_KEYS = {"thickness": "the out-of-plane thickness of plane models",
                   "gravity": "the 2D gravity of rigid bodies"}


def check_explicit_2d_keys(data: dict[str, Any]) -> None:
    """Refuse, in the raw case mapping, 2D-only keys whose defaults are harmless but whose presence in a
    3D case says the user means a 2D model (``mechanics.thickness``, ``mechanics.gravity``)."""
    mech = data.get("mechanics")
    if not isinstance(mech, dict) or mech.get("formulation") != FORMULATION_3D:
        return
    for key, why in TWO_D_ONLY_KEYS.items():
        if key in mech:
            raise SchemaError(f"mechanics.{key}", f"a 2D-only key ({why}); a 3D case "
                              "(mechanics.formulation = '3d') has none: remove it")


def validate_dimension(case) -> None:
    """2D-only keys in a 3D case and 3D-only keys in a 2D case: one :class:`SchemaError` naming the key."""
    if case.mechanics.formulation == FORMULATION_3D:
        _validate_3d(case)
    else:
        _validate_2d(case)


def _validate_3d(case) -> None:
    file3d = case.case.kind == "coupled" and getattr(case.geometry, "type", None) == "geometry_3d"
    if file3d:
        validate_geometry_3d(case)  # the user's own geometry file (.geometry3d)
    elif case.case.kind == "coupled":
        if case.geometry is None:
            raise SchemaError("geometry", "missing required table [geometry] for case.kind = 'coupled' (a 3D geometry "
                              "file: type = 'geometry_3d', docs/geometry3d.md)")
        got = case.geometry.type
        raise SchemaError("geometry.type", f"got {got!r}; a coupled 3D case is a 3D geometry file: geometry.type = "
                          "'geometry_3d' with its file and role map (docs/geometry3d.md)")
    mo = case.mechanics
    if tuple(mo.gravity) != (0.0, 0.0):
        raise SchemaError("mechanics.gravity", "a 2D-only key (rigid bodies of coupled cases); remove it")
    if mo.mass_scaling_dt is not None:
        _check_mass_scaling(case)
    if case.loads and case.case.kind != "coupled":  # a coupled 3D geometry file's: .geometry3d
        raise SchemaError("loads", "pressure pulses are 2D-only for now; a 3D case takes initial velocities, "
                          "rigid walls and symmetry planes")
    if case.analysis:
        raise SchemaError("analysis", f"got {list(case.analysis)}; the case analyses are 2D-only for now")
    for i, b in enumerate(case.bodies):
        if b.shape is not None and b.shape.type not in SOLID_TYPES:
            raise SchemaError(f"bodies[{i}].shape.type", f"got {b.shape.type!r}, a 2D shape; a 3D case "
                              f"(mechanics.formulation = '3d') allows: {', '.join(map(repr, SOLID_TYPES))}")
        if b.element == "tri6":
            raise SchemaError(f"bodies[{i}].element", "got 'tri6', a 2D element; with mechanics.formulation = '3d' "
                              "allowed: 'tet4', 'tet10'")
        if b.fixed and not file3d:
            raise SchemaError(f"bodies[{i}].fixed", "a key of 2D cases and 3D geometry files (geometry.type = "
                              "'geometry_3d'); in this 3D case hold the body with [[symmetry]] planes or [[walls]]")
        if len(b.initial_velocity) != 3 and any(b.initial_velocity):
            raise SchemaError(f"bodies[{i}].initial_velocity", f"got {len(b.initial_velocity)} components; a 3D "
                              "case needs [vx, vy, vz] (m/s)")
    for i, w in enumerate(case.walls):
        for key in ("point", "normal"):
            if len(getattr(w, key)) != 3:
                raise SchemaError(f"walls[{i}].{key}", f"got {len(getattr(w, key))} components; a 3D case needs "
                                  "[x, y, z]")
    for i, p in enumerate(case.probes):
        if len(p.point) != 3:
            raise SchemaError(f"probes[{i}].point", f"got {len(p.point)} components; a 3D case needs [x, y, z] (m)")
    names = [b.name for b in case.bodies]
    for i, s in enumerate(case.symmetry):
        for j, n in enumerate(s.bodies):
            if n not in names:
                raise SchemaError(f"symmetry[{i}].bodies[{j}]", f"got {n!r}; allowed: "
                                  + ", ".join(repr(x) for x in names))
        _check_plane_touches(case, i, s)


def _check_mass_scaling(case) -> None:
    """Selective mass scaling (``mechanics.mass_scaling_dt``) is for quasi-static explicit runs of ten-node bodies
    in mechanics-only cases (one line naming the key otherwise)."""
    mo, key = case.mechanics, "mechanics.mass_scaling_dt"
    if case.case.kind != "mechanics":
        raise SchemaError(key, "given in a coupled case; added mass changes a pulse's dynamics: mechanics-only cases "
                          "with kinetic or mass damping (quasi-static) take it")
    if mo.integrator != "explicit":
        raise SchemaError(key, "given with integrator = 'implicit', which has no stable step to lengthen; remove it")
    if mo.kinetic_damping_until <= 0.0 and mo.mass_damping <= 0.0:
        raise SchemaError(key, "given without mechanics.kinetic_damping_until or mechanics.mass_damping: added mass "
                          "changes the dynamics; it is for quasi-static runs relaxed to rest")
    for i, b in enumerate(case.bodies):
        if not b.rigid and b.element != "tet10":
            raise SchemaError(f"bodies[{i}].element", f"got {b.element!r} with mechanics.mass_scaling_dt; selective "
                              "mass scaling is done for ten-node bodies: allowed 'tet10'")


def _check_plane_touches(case, i: int, plane: SymmetryPlane) -> None:
    """A symmetry plane must lie on a face of a box it acts on (a cylinder or an oblique plane is taken
    on trust)."""
    if not plane.axis_aligned():
        return
    c = plane.component()
    v = plane.point[c]
    faces = []
    for b in case.bodies:
        if plane.bodies and b.name not in plane.bodies:
            continue
        if not isinstance(b.shape, SolidBox):
            return
        lo, hi = b.shape.origin[c], b.shape.origin[c] + b.shape.size[c]
        tol = 1e-9 * max(abs(lo), abs(hi), 1.0)
        if abs(v - lo) <= tol or abs(v - hi) <= tol:
            return
        faces.append(f"{b.name!r}: {lo:g}, {hi:g}")
    raise SchemaError(f"symmetry[{i}].point", f"the plane {'xyz'[c]} = {v:g} m touches no body it acts on "
                      f"(box faces along {'xyz'[c]}: {'; '.join(faces)} m): move it onto a face or set its bodies")


def _validate_2d(case) -> None:
    f = case.mechanics.formulation
    if case.symmetry:
        raise SchemaError("symmetry", f"a 3D-only key; with mechanics.formulation = {f!r} use [[bodies.fixed]] "
                          "or set mechanics.formulation = '3d'")
    for i, b in enumerate(case.bodies):
        if b.shape is not None and b.shape.type in SOLID_TYPES:
            raise SchemaError(f"bodies[{i}].shape.type", f"got {b.shape.type!r}, a 3D shape; with "
                              f"mechanics.formulation = {f!r} allowed: 'rectangle', 'polygon' (or set "
                              "mechanics.formulation = '3d')")
        if b.element == "tet10":
            raise SchemaError(f"bodies[{i}].element", f"got 'tet10', a 3D element; with mechanics.formulation = "
                              f"{f!r} allowed: 'tet4' (linear triangles), 'tri6' (six-node triangles) (or set "
                              "mechanics.formulation = '3d')")
        if len(b.initial_velocity) != 2:
            raise SchemaError(f"bodies[{i}].initial_velocity", f"got 3 components, a 3D vector; with "
                              f"mechanics.formulation = {f!r} give [vx, vy] (m/s)")
        for name in ("offset", "gravity"):
            v = getattr(b, name)
            if v is not None and len(v) != 2:
                raise SchemaError(f"bodies[{i}].{name}", f"got {len(v)} components, a 3D vector; with "
                                  f"mechanics.formulation = {f!r} give [x, y]")
        for name, values in (("moves", b.moves or ()), ("stops", [st.component for st in b.stops])):
            for c, comp in enumerate(values):
                if comp > 1:
                    where = f"moves[{c}]" if name == "moves" else f"stops[{c}].component"
                    raise SchemaError(f"bodies[{i}].{where}", f"got {comp}: z is 3D only; with mechanics.formulation "
                                      f"= {f!r} allowed: 0 (x or r), 1 (y or z)")
        for j, fx in enumerate(b.fixed):
            key = f"bodies[{i}].fixed[{j}]"
            if fx.group is not None:
                raise SchemaError(f"{key}.group", f"a key of 3D geometry files; with mechanics.formulation = {f!r} "
                                  "give where (a box)")
            if fx.where.has_z():
                raise SchemaError(f"{key}.where.zmin", f"a 3D bound; with mechanics.formulation = {f!r} the box "
                                  "selects by x and y only: remove zmin/zmax/rmin/rmax")
            for c, comp in enumerate(fx.components):
                if comp > 1:
                    raise SchemaError(f"{key}.components[{c}]", f"got {comp}; with mechanics.formulation = {f!r} "
                                      "allowed: 0 (x or r), 1 (y or z)")
    for i, w in enumerate(case.walls):
        for key in ("point", "normal"):
            if len(getattr(w, key)) != 2:
                raise SchemaError(f"walls[{i}].{key}", f"got 3 components, a 3D vector; with "
                                  f"mechanics.formulation = {f!r} give [x, y]")
    for i, p in enumerate(case.probes):
        if len(p.point) != 2:
            raise SchemaError(f"probes[{i}].point", f"got 3 components, a 3D point; with "
                              f"mechanics.formulation = {f!r} give [x, y] (m)")
