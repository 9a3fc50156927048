"""Case-file tables of the parts: geometry primitives, bodies (deformable or rigid, with end stops),
contact pairs and rigid walls (SI units, validated; see :mod:`.model` for the whole case)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from .names import check_file_name
from .schema import SchemaError, spec
from .solid3d import SolidBox, SolidCylinder

Vec2 = tuple[float, float]
#: a vector of a 2D case (x, y) or of a 3D case (x, y, z); :mod:`.solid3d` checks which
Vec = tuple[float, float] | tuple[float, float, float]


# --------------------------------------------------------------------------- geometry primitives
@dataclass(frozen=True, kw_only=True)
class Box:
    """Axis-aligned box selecting boundary nodes/facets whose points lie inside it (inclusive)."""

    xmin: float = spec(-math.inf, unit="m", doc="lower x (or r) bound")
    xmax: float = spec(math.inf, unit="m", doc="upper x (or r) bound")
    ymin: float = spec(-math.inf, unit="m", doc="lower y (or z) bound")
    ymax: float = spec(math.inf, unit="m", doc="upper y (or z) bound")
    zmin: float = spec(-math.inf, unit="m", doc="lower z bound (3D cases)")
    zmax: float = spec(math.inf, unit="m", doc="upper z bound (3D cases)")
    rmin: float = spec(0.0, unit="m", ge=0.0, doc="3D cases: lower bound of the distance sqrt(x² + y²) from the "
                                                  "z-axis (a cylindrical shell selects a sector's rim)")
    rmax: float = spec(math.inf, unit="m", gt=0.0, doc="3D cases: upper bound of the distance from the z-axis")

    def validate(self, path: str) -> None:
        if not self.xmin <= self.xmax:
            raise SchemaError(f"{path}.xmax", f"got {self.xmax:g}; must be >= xmin = {self.xmin:g} (m)")
        if not self.ymin <= self.ymax:
            raise SchemaError(f"{path}.ymax", f"got {self.ymax:g}; must be >= ymin = {self.ymin:g} (m)")
        if not self.zmin <= self.zmax:
            raise SchemaError(f"{path}.zmax", f"got {self.zmax:g}; must be >= zmin = {self.zmin:g} (m)")
        if not self.rmin <= self.rmax:
            raise SchemaError(f"{path}.rmax", f"got {self.rmax:g}; must be >= rmin = {self.rmin:g} (m)")

    def has_z(self) -> bool:
        """True if a bound of 3D cases is set (z, or the distance from the z-axis)."""
        return math.isfinite(self.zmin) or math.isfinite(self.zmax) or self.rmin > 0.0 or math.isfinite(self.rmax)


@dataclass(frozen=True, kw_only=True)
class Rectangle:
    """Rectangle with its lower-left corner at ``origin``."""

    type: Literal["rectangle"] = spec(doc="shape kind")
    origin: Vec2 = spec((0.0, 0.0), unit="m", doc="lower-left corner (x, y) or (r, z)")
    width: float = spec(unit="m", gt=0.0, doc="extent along x (or r)")
    height: float = spec(unit="m", gt=0.0, doc="extent along y (or z)")


@dataclass(frozen=True, kw_only=True)
class Polygon:
    """Simple polygon given by its vertices in counter-clockwise order."""

    type: Literal["polygon"] = spec(doc="shape kind")
    points: tuple[Vec2, ...] = spec(unit="m", doc="vertices, counter-clockwise, >= 3")

    def validate(self, path: str) -> None:
        if len(self.points) < 3:
            raise SchemaError(f"{path}.points", f"got {len(self.points)} points; need at least 3")
        area = 0.5 * sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1)
                         in zip(self.points, self.points[1:] + self.points[:1]))
        if area <= 0.0:
            raise SchemaError(f"{path}.points", "vertices must be counter-clockwise with positive area")


Shape = Rectangle | Polygon | SolidBox | SolidCylinder



# --------------------------------------------------------------------------- bodies and contact
@dataclass(frozen=True, kw_only=True)
class FixedBoundary:
    """Zero displacement of the chosen components on boundary nodes inside ``where`` (or, in a 3D geometry
    file, on the nodes of a physical surface ``group``)."""

    where: Box | None = spec(None, doc="box selecting the boundary nodes (inclusive)")
    group: str | None = spec(None, doc="3D geometry files: a physical surface group whose nodes are held")
    components: tuple[int, ...] = spec((0, 1), unit="-", ge=0, le=2, doc="0 = x (r), 1 = y (z), 2 = z (3D)")

    def validate(self, path: str) -> None:
        if not self.components:
            raise SchemaError(f"{path}.components", "got an empty list; allowed: [0], [1] or [0, 1] ([0, 1, 2] in 3D)")
        if (self.where is None) == (self.group is None):
            raise SchemaError(f"{path}.where", "give exactly one of where (a box) or group (a physical surface "
                              "group of a 3D geometry file)")


@dataclass(frozen=True, kw_only=True)
class EndStopTable:
    """A limit of a rigid body's translation: a support it rests on, or the end of its travel."""

    component: int = spec(1, unit="-", ge=0, le=2, doc="translation component it limits: 0 = x (r), 1 = y (z); "
                           "2 = z in 3D")
    position: float = spec(unit="m", doc="the limit, as a value of that translation "
                           "component (0: the body's initial place)")
    side: Literal["min", "max"] = spec("min", doc="'min': the translation stays >= position (a support below); "
                                                  "'max': it stays <= position (a stop above)")
    restitution: float = spec(0.0, unit="-", ge=0.0, le=1.0, doc="rebound / impact speed (0: the body stays on it)")


@dataclass(frozen=True, kw_only=True)
class BodyTable:
    """A body: deformable (P1 triangles, explicit elastic-plastic dynamics) or, in coupled cases, rigid."""

    name: str = spec(doc="unique body name")
    material: str = spec(doc="key of a [materials.<name>] table")
    shape: Shape | None = spec(None, doc="own geometry (rectangle or polygon; box or cylinder in 3D); or "
                                                "give region")
    region: str | None = spec(
        None, doc="the [geometry] conductor region this body is (its EM and mechanical meshes share nodes): "
                  "'workpiece', 'die', 'outer_tube' of the built-in geometries, a physical volume group of a 3D "
                  "geometry file")
    mesh_size: float | None = spec(None, unit="m", gt=0.0, doc="target element size (with shape)")
    element: Literal["tet4", "tet10", "tri6"] = spec(
        "tet4", doc="the body's element: 'tet4' linear cells (tetrahedra in 3D, triangles in 2D); 'tet10' (3D) "
                    "ten-node tetrahedra, 'tri6' (2D) six-node triangles (a node mid-edge), which bend without "
                    "locking (thin parts; one process; 'tet10': mechanics-only and coupled 3D cases, walls and soft "
                    "contact; 'tri6': mechanics-only and coupled 2D cases, walls and contact too; the forming-limit "
                    "check reads a quadratic cell's corners)")
    initial_velocity: Vec = spec((0.0, 0.0), unit="m/s", doc="uniform initial velocity ([vx, vy, vz] in 3D)")
    fixed: tuple[FixedBoundary, ...] = spec((), doc="clamped boundary parts")
    rigid: bool = spec(False, doc="a rigid body (coupled cases, with region): it translates without deforming "
                                  "under the resultant of its Lorentz forces and gravity; no stability limit")
    mass: float | None = spec(None, unit="kg", gt=0.0, doc="rigid body's mass (default: material density × "
                              "the region's volume, the full 2πr ring in axisymmetry, × mechanics.thickness in "
                              "plane models)")
    moves: tuple[int, ...] | None = spec(None, unit="-", ge=0, le=2, doc="rigid body's free translation "
                                         "components: [1] axial (the only one in axisymmetry, its default), "
                                         "[0], [1] or [0, 1] in plane models (default [0, 1])")
    offset: Vec = spec((0.0, 0.0), unit="m", doc="rigid body's initial translation from its place in the geometry "
                       "([x, y, z] in 3D)")
    gravity: Vec | None = spec(None, unit="m/s^2", doc="rigid body's gravity (default: mechanics.gravity; [gx, gy, gz] "
                               "in 3D, default none)")
    stops: tuple[EndStopTable, ...] = spec((), doc="[[bodies.stops]] rigid body's end stops (supports, limits "
                                                   "of travel)")

    def validate(self, path: str) -> None:
        check_file_name(self.name, f"{path}.name", "fields/<case>_<name>.xdmf")
        if (self.shape is None) == (self.region is None):
            raise SchemaError(f"{path}.shape", "give exactly one of shape (own geometry) or region "
                              "(a [geometry] region such as 'workpiece')")
        if self.shape is not None and self.mesh_size is None:
            raise SchemaError(f"{path}.mesh_size", "missing required key (a number > 0, in m) for a body with shape")
        if self.rigid:
            if self.region is None:
                raise SchemaError(f"{path}.rigid", "a rigid body is a conductor of a coupled case: give region "
                                  "(e.g. 'workpiece') instead of shape")
            if self.fixed:
                raise SchemaError(f"{path}.fixed", "a rigid body has no clamped parts: limit its motion with moves "
                                  "or [[bodies.stops]]")
            if self.moves is not None and not self.moves:
                raise SchemaError(f"{path}.moves", "got an empty list; allowed: [0], [1] or [0, 1]")
            for j, s in enumerate(self.stops):
                start = self.offset[s.component] if s.component < len(self.offset) else 0.0
                if s.side == "min" and start < s.position or s.side == "max" and start > s.position:
                    raise SchemaError(f"{path}.stops[{j}].position", f"got {s.position:g}; the initial offset "
                                      f"{start:g} m lies beyond this stop (side = {s.side!r})")
        else:
            for key, default in (("mass", None), ("moves", None), ("offset", (0.0, 0.0)), ("gravity", None),
                                 ("stops", ())):
                if getattr(self, key) != default:
                    raise SchemaError(f"{path}.{key}", "applies to rigid bodies only: set rigid = true or remove it")


@dataclass(frozen=True, kw_only=True)
class ContactPair:
    """Soft contact, paper eq. (5): p = k (1/h − 1/h0) for h < h0, slave nodes on master segments."""

    slave: str = spec(doc="body whose boundary nodes are checked")
    master: str = spec(doc="body whose boundary segments repel")
    stiffness: float = spec(unit="Pa·m", gt=0.0, doc="k per unit area")
    h0: float = spec(unit="m", gt=0.0, doc="width of the force layer")
    friction: float = spec(0.0, unit="-", ge=0.0, doc="Coulomb coefficient μ")
    viscosity: float = spec(0.0, unit="Pa·s²/m²", ge=0.0,
                            doc="paper's ν in ν|v|², on the pair's relative normal velocity")
    two_pass: bool = spec(False, doc="also check master nodes against slave segments")

    def validate(self, path: str) -> None:
        if self.slave == self.master:
            raise SchemaError(f"{path}.master", f"got {self.master!r}; must differ from slave")


@dataclass(frozen=True, kw_only=True)
class RigidWall:
    """Rigid half-space: a node with (x − point)·normal < 0 is put back on the wall with v = 0."""

    point: Vec = spec(unit="m", doc="a point on the wall ([x, y, z] in 3D)")
    normal: Vec = spec(unit="-", doc="normal pointing into the allowed side")
    bodies: tuple[str, ...] = spec((), doc="bodies it acts on (empty = all)")
    sliding: bool = spec(False, doc="frictionless: remove only the normal velocity (false: the paper's "
                                    "rule v = 0, which also sticks the face tangentially)")

    def validate(self, path: str) -> None:
        if math.hypot(*self.normal) == 0.0:
            raise SchemaError(f"{path}.normal", f"got {list(self.normal)}; must be a non-zero vector")


def rigid_moves(b: BodyTable, formulation: str, symmetry=()) -> tuple[int, ...]:
    """The free translation components of rigid body ``b``: its ``moves``, or the default of the
    formulation ([1] in axisymmetry, [0, 1] in plane models; in 3D the components parallel to every
    ``symmetry`` plane acting on it: a translation that keeps the modelled part symmetric)."""
    if b.moves is not None:
        return tuple(sorted(set(b.moves)))
    if formulation == "3d":
        return allowed_moves_3d(b, symmetry)
    return (1,) if formulation == "axisymmetric" else (0, 1)


def allowed_moves_3d(b: BodyTable, symmetry) -> tuple[int, ...]:
    """The translation components (0, 1, 2) of a 3D body that lie in every symmetry plane acting on it."""
    planes = [s for s in symmetry if not s.bodies or b.name in s.bodies]
    return tuple(i for i in range(3) if all(abs(s.normal[i]) <= 1e-12 * math.hypot(*s.normal) for s in planes))


def validate_rigid(case) -> None:
    """Rigid bodies: GetDP-coupled, translations the formulation allows, stops on free components, and
    no contact, walls, loads or probes on them (their motion is in history.csv)."""
    rigid = [b.name for b in case.bodies if b.rigid]
    if not rigid:
        return
    i = next(i for i, b in enumerate(case.bodies) if b.rigid)
    if case.case.kind != "coupled" or case.coupling.load != "getdp":
        raise SchemaError(f"bodies[{i}].rigid", "rigid bodies move under GetDP's forces: case.kind = 'coupled' "
                          "with coupling.load = 'getdp'")
    for i, b in enumerate(case.bodies):
        if not b.rigid:
            continue
        moves = rigid_moves(b, case.mechanics.formulation)
        if case.mechanics.formulation == "axisymmetric" and moves != (1,):
            raise SchemaError(f"bodies[{i}].moves", f"got {list(moves)}; an axisymmetric rigid body translates "
                              "along the axis only: [1]")
        for j, s in enumerate(b.stops):
            if s.component not in moves:
                raise SchemaError(f"bodies[{i}].stops[{j}].component", f"got {s.component}; the body moves "
                                  f"along {list(moves)} only")
    for key, items, attrs in (("contact", case.contact, ("slave", "master")), ("walls", case.walls, ("bodies",)),
                              ("loads", case.loads, ("body",)), ("probes", case.probes, ("body",))):
        for k, item in enumerate(items):
            for attr in attrs:
                value = getattr(item, attr)
                for name in (value if isinstance(value, tuple) else (value,)):
                    if name in rigid:
                        raise SchemaError(f"{key}[{k}].{attr}", f"got {name!r}, a rigid body; {key} act on "
                                          "deformable bodies only (a rigid body's position, velocity, "
                                          "acceleration and force are in history.csv)")
    for k, w in enumerate(case.walls):
        if not w.bodies:
            raise SchemaError(f"walls[{k}].bodies", "got [] (all bodies); with rigid bodies list the deformable "
                              "bodies the wall acts on")
