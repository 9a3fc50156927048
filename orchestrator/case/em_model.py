"""Case-file model of the coupled cases: EM geometries and sources (SI units, validated)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from operator import attrgetter
from typing import ClassVar, Literal

from .deck_files import remesh_air_error
from .em_cores import Box4, CoaxialCore, check_box, check_cores, check_placed
from .geometry3d import GeometryFile3D
from .schema import SchemaError, spec

def _check_open_boundary(path: str, extent: float, air: float, shell: float, what: str) -> None:
    """The air half-disk must hold the setup with margin (1.5 × its extent); the shell lies outside it."""
    if air <= 1.5 * extent:
        raise SchemaError(f"{path}.air_radius", f"got {air:g}; must be > 1.5 × the {what} extent = "
                          f"{1.5 * extent:g} (m)")
    if shell <= air:
        raise SchemaError(f"{path}.shell_radius", f"got {shell:g}; must be > air_radius = {air:g} (m)")


def _polygon_area(points) -> float:
    """Signed area (m²) of a polygon; > 0 when counter-clockwise."""
    return 0.5 * sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(points, list(points[1:]) + list(points[:1])))


class _ConductorRoles:
    """The EM conductor roles of a geometry: the workpiece, and a second conductor when the geometry
    has one (``_second``: its role and the attribute path that holds it, None when absent)."""

    planar: ClassVar[bool] = False
    _second: ClassVar[tuple[str, str] | None] = None

    def conductor_roles(self) -> tuple[str, ...]:
        """EM conductor regions, in conductor order (201, 202)."""
        if self._second is not None and attrgetter(self._second[1])(self) is not None:
            return ("workpiece", self._second[0])
        return ("workpiece",)


@dataclass(frozen=True, kw_only=True)
class SheetDie:
    """A conducting die above the sheet: a block with a cylindrical cavity on the axis.

    The die's lower face lies ``gap`` above the sheet's upper face; the block spans
    0 <= r <= ``outer_radius`` and ``height`` upwards, the cavity 0 <= r <= ``cavity_radius``
    and ``cavity_depth`` into it; the cavity edge is rounded with ``entry_radius``.
    The die is EM region ``die`` (massive conductor 2) and may be a mechanical body.
    """

    cavity_radius: float = spec(unit="m", gt=0.0, doc="radius of the cavity the sheet bulges into")
    cavity_depth: float = spec(unit="m", gt=0.0, doc="depth of the cavity (closed by the die's top)")
    outer_radius: float = spec(unit="m", gt=0.0, doc="outer radius of the die block")
    height: float = spec(unit="m", gt=0.0, doc="height of the die block")
    gap: float = spec(unit="m", gt=0.0, doc="axial gap between the sheet's upper face and the die (> 0: the two "
                                          "bodies must not share nodes)")
    entry_radius: float = spec(0.0, unit="m", ge=0.0, doc="fillet radius of the cavity edge")
    mesh_size: float = spec(unit="m", gt=0.0, doc="element size in the die")

    def validate(self, path: str) -> None:
        if self.cavity_depth >= self.height:
            raise SchemaError(f"{path}.cavity_depth", f"got {self.cavity_depth:g}; must be < height = "
                              f"{self.height:g} (m)")
        if self.cavity_radius + self.entry_radius >= self.outer_radius:
            raise SchemaError(f"{path}.outer_radius", f"got {self.outer_radius:g}; must be > cavity_radius + "
                              f"entry_radius = {self.cavity_radius + self.entry_radius:g} (m)")
        if self.entry_radius >= self.cavity_depth:
            raise SchemaError(f"{path}.entry_radius", f"got {self.entry_radius:g}; must be < cavity_depth = "
                              f"{self.cavity_depth:g} (m)")


@dataclass(frozen=True, kw_only=True)
class OuterTube:
    """A second, coaxial tube around the first (tube-into-tube press fit), centred on z = 0.

    EM region ``outer_tube`` (massive conductor 2); may be a mechanical body.
    """

    inner_radius: float = spec(unit="m", gt=0.0, doc="inner radius")
    thickness: float = spec(unit="m", gt=0.0, doc="wall thickness")
    length: float = spec(unit="m", gt=0.0, doc="length")
    mesh_size: float | None = spec(None, unit="m", gt=0.0, doc="element size in the outer tube (unset: skin depth)")


@dataclass(frozen=True, kw_only=True)
class FlatCoilSheet(_ConductorRoles):
    """Axisymmetric flat spiral coil (coaxial rectangular turns in series) under a sheet.

    The coil's top face is at z = 0, the sheet's lower face at z = ``coil_gap``; the sheet spans
    0 <= r <= ``sheet_radius``. Air fills a half-disk of radius ``air_radius``; a shell out to
    ``shell_radius`` maps the open boundary to infinity.
    """

    type: Literal["flat_coil_sheet"] = spec(doc="geometry kind")
    turns: int = spec(unit="-", ge=1, doc="number of turns")
    coil_inner_radius: float = spec(unit="m", gt=0.0, doc="inner radius of the first turn")
    turn_width: float = spec(unit="m", gt=0.0, doc="radial width of a turn")
    turn_height: float = spec(unit="m", gt=0.0, doc="axial height of a turn")
    turn_gap: float = spec(unit="m", ge=0.0, doc="radial insulation gap between turns")
    coil_gap: float = spec(unit="m", gt=0.0, doc="axial gap between coil and sheet")
    sheet_radius: float = spec(unit="m", gt=0.0, doc="sheet radius")
    sheet_thickness: float = spec(unit="m", gt=0.0, doc="sheet thickness")
    air_radius: float = spec(unit="m", gt=0.0, doc="radius of the meshed air half-disk")
    shell_radius: float = spec(unit="m", gt=0.0, doc="outer radius of the shell to infinity")
    mesh_size_sheet: float | None = spec(
        None, unit="m", gt=0.0, doc="element size in the sheet (unset: from the skin depth)")
    mesh_size_coil: float = spec(unit="m", gt=0.0, doc="element size in and near the coil")
    mesh_size_air: float = spec(unit="m", gt=0.0, doc="element size far away in the air")
    die: SheetDie | None = spec(None, doc="[geometry.die] optional conducting die above the sheet")

    _second: ClassVar[tuple[str, str]] = ("die", "die")

    def validate(self, path: str) -> None:
        coil_r = self.coil_inner_radius + self.turns * self.turn_width + (self.turns - 1) * self.turn_gap
        top = self.coil_gap + self.sheet_thickness
        extent = max(coil_r, self.sheet_radius, top, self.turn_height)
        if self.die is not None:
            extent = max(extent, self.die.outer_radius, top + self.die.gap + self.die.height)
        _check_open_boundary(path, extent, self.air_radius, self.shell_radius, "coil/sheet/die")


@dataclass(frozen=True, kw_only=True)
class SolenoidTube(_ConductorRoles):
    """Axisymmetric solenoid (turns stacked along z) inside a tube, for tube expansion.

    Turns occupy r in [coil_inner_radius, coil_inner_radius + turn_width], centred on z = 0;
    the tube spans r in [tube_inner_radius, tube_inner_radius + tube_thickness],
    |z| <= tube_length / 2.
    """

    type: Literal["solenoid_tube"] = spec(doc="geometry kind")
    turns: int = spec(unit="-", ge=1, doc="number of turns")
    coil_inner_radius: float = spec(unit="m", gt=0.0, doc="inner radius of the turns")
    turn_width: float = spec(unit="m", gt=0.0, doc="radial width of a turn")
    turn_height: float = spec(unit="m", gt=0.0, doc="axial height of a turn")
    turn_gap: float = spec(unit="m", ge=0.0, doc="axial insulation gap between turns")
    tube_inner_radius: float = spec(unit="m", gt=0.0, doc="tube inner radius")
    tube_thickness: float = spec(unit="m", gt=0.0, doc="tube wall thickness")
    tube_length: float = spec(unit="m", gt=0.0, doc="tube length")
    air_radius: float = spec(unit="m", gt=0.0, doc="radius of the meshed air half-disk")
    shell_radius: float = spec(unit="m", gt=0.0, doc="outer radius of the shell to infinity")
    mesh_size_tube: float | None = spec(
        None, unit="m", gt=0.0, doc="element size in the tube (unset: from the skin depth)")
    mesh_size_coil: float = spec(unit="m", gt=0.0, doc="element size in and near the coil")
    mesh_size_air: float = spec(unit="m", gt=0.0, doc="element size far away in the air")
    outer_tube: OuterTube | None = spec(None, doc="[geometry.outer_tube] optional second tube (press fit)")

    _second: ClassVar[tuple[str, str]] = ("outer_tube", "outer_tube")

    def validate(self, path: str) -> None:
        if self.coil_inner_radius + self.turn_width >= self.tube_inner_radius:
            raise SchemaError(f"{path}.tube_inner_radius", f"got {self.tube_inner_radius:g}; must be > "
                              f"coil outer radius = {self.coil_inner_radius + self.turn_width:g} (m)")
        extent = max(self.tube_inner_radius + self.tube_thickness, self.tube_length / 2,
                     self.turns * (self.turn_height + self.turn_gap) / 2)
        o = self.outer_tube
        if o is not None:
            if o.inner_radius <= self.tube_inner_radius + self.tube_thickness:
                raise SchemaError(f"{path}.outer_tube.inner_radius", f"got {o.inner_radius:g}; must be > the inner "
                                  f"tube's outer radius = {self.tube_inner_radius + self.tube_thickness:g} (m)")
            extent = max(extent, o.inner_radius + o.thickness, o.length / 2)
        _check_open_boundary(path, extent, self.air_radius, self.shell_radius, "coil/tube")


@dataclass(frozen=True, kw_only=True)
class PlanarCoilBlankDie(_ConductorRoles):
    """Plane-strain half model (x >= 0, symmetry plane x = 0): a blank over a die, a flat coil above.

    The blank spans 0 <= x <= ``blank_half_width``, 0 <= y <= ``blank_thickness``; the coil's
    rectangular turns lie ``coil_gap`` above the blank, the first from x = ``coil_inner_x``.
    Currents are mirrored with opposite sign about x = 0 (a = 0 there), as in the cut through a
    flat spiral coil. The die is a polygon below the blank (counter-clockwise vertices, m), EM
    region ``die``. Fields and forces are per metre of depth (z); the mechanics' ``thickness``
    scales them.
    """

    type: Literal["planar_coil_blank_die"] = spec(doc="geometry kind")
    turns: int = spec(unit="-", ge=1, doc="number of turns in the half model")
    coil_inner_x: float = spec(unit="m", ge=0.0, doc="x of the first turn's inner edge")
    turn_width: float = spec(unit="m", gt=0.0, doc="width (x) of a turn")
    turn_height: float = spec(unit="m", gt=0.0, doc="height (y) of a turn")
    turn_gap: float = spec(unit="m", ge=0.0, doc="insulation gap between turns (x)")
    coil_gap: float = spec(unit="m", gt=0.0, doc="gap between the blank's upper face and the coil")
    blank_half_width: float = spec(unit="m", gt=0.0, doc="half width of the blank")
    blank_thickness: float = spec(unit="m", gt=0.0, doc="blank thickness")
    die: tuple[tuple[float, float], ...] | None = spec(
        None, unit="m", doc="die polygon: vertices (x, y), counter-clockwise, below the blank (y < 0)")
    air_radius: float = spec(unit="m", gt=0.0, doc="radius of the meshed air half-disk")
    shell_radius: float = spec(unit="m", gt=0.0, doc="outer radius of the shell to infinity")
    mesh_size_blank: float | None = spec(
        None, unit="m", gt=0.0, doc="element size in the blank (unset: from the skin depth)")
    mesh_size_die: float = spec(1e-3, unit="m", gt=0.0, doc="element size in the die")
    mesh_size_coil: float = spec(unit="m", gt=0.0, doc="element size in and near the coil")
    mesh_size_air: float = spec(unit="m", gt=0.0, doc="element size far away in the air")

    planar: ClassVar[bool] = True
    _second: ClassVar[tuple[str, str]] = ("die", "die")

    def validate(self, path: str) -> None:
        top = self.blank_thickness + self.coil_gap + self.turn_height
        coil_x = self.coil_inner_x + self.turns * self.turn_width + (self.turns - 1) * self.turn_gap
        extent = max(self.blank_half_width, coil_x, top)
        if self.die is not None:
            if len(self.die) < 3 or _polygon_area(self.die) <= 0.0:
                raise SchemaError(f"{path}.die", "need >= 3 vertices, counter-clockwise with positive area")
            if max(y for _, y in self.die) >= 0.0 or min(x for x, _ in self.die) < 0.0:
                raise SchemaError(f"{path}.die", "the die must lie below the blank (y < 0) in x >= 0")
            extent = max(extent, max(abs(x) for x, _ in self.die), max(abs(y) for _, y in self.die))
        _check_open_boundary(path, extent, self.air_radius, self.shell_radius, "coil/blank/die")


@dataclass(frozen=True, kw_only=True)
class CoaxialCoil:
    """One coil of ``coaxial_coils``: its turns in series, spread uniformly over its winding cross-sections."""

    name: str = spec(doc="the coil's name ([[em.coils]] connects it to a source; history columns <name>_current_A, "
                         "... with several coils)")
    turns: int = spec(unit="-", ge=1, doc="turns in series over all its windings (uniform current density in them)")
    windings: tuple[Box4, ...] = spec(unit="m", doc="winding cross-sections [r0, z0, r1, z1], r >= 0 (one or more)")


@dataclass(frozen=True, kw_only=True)
class CoaxialWorkpiece:
    """The conducting workpiece of ``coaxial_coils``: a plate/disk (r0 = 0) or a ring, as its (r, z) rectangle."""

    r0: float = spec(unit="m", ge=0.0, doc="inner radius (0: a plate or disk)")
    z0: float = spec(unit="m", doc="lower face")
    r1: float = spec(unit="m", gt=0.0, doc="outer radius")
    z1: float = spec(unit="m", doc="upper face")
    mesh_size: float | None = spec(None, unit="m", gt=0.0, doc="element size in the workpiece (unset: skin depth)")

    def validate(self, path: str) -> None:
        check_box((self.r0, self.z0, self.r1, self.z1), path)

    @property
    def box(self) -> Box4:
        """[r0, z0, r1, z1] (m)."""
        return (self.r0, self.z0, self.r1, self.z1)


@dataclass(frozen=True, kw_only=True)
class CoaxialCoils(_ConductorRoles):
    """Axisymmetric: any number of coaxial coils, each of rectangular windings, and one conducting workpiece
    (a plate or a ring; EM region ``workpiece``, conductor 1). Each coil is driven by the source that
    ``[[em.coils]]`` gives it. Air fills a half-disk of radius ``air_radius``; a shell out to
    ``shell_radius`` maps the open boundary to infinity.

    ``planar = true``: the plane equivalent, a half model x >= 0 with the symmetry plane x = 0 (a = 0
    there: each winding's mirror image carries the opposite current, the cut through flat coils),
    (r, z) read as (x, y); fields and forces per metre of depth, scaled by ``mechanics.thickness``;
    prescribed sources only (a bank would need the coils' length).
    """

    type: Literal["coaxial_coils"] = spec(doc="geometry kind")
    planar: bool = spec(False, doc="the plane half model x >= 0 (symmetry plane x = 0, per metre of depth; "
                                   "windings and workpiece as [x0, y0, x1, y1]) instead of an axisymmetric one")
    coils: tuple[CoaxialCoil, ...] = spec(doc="[[geometry.coils]] the coils (coil k is physical 100 + k, in this order)")
    workpiece: CoaxialWorkpiece = spec(doc="[geometry.workpiece] the conducting workpiece")
    cores: tuple[CoaxialCore, ...] = spec((), doc="[[geometry.cores]] non-conducting magnetic cores (laminated "
                                                  "or powder iron; core k is physical 800 + k, one per box)")
    air_radius: float = spec(unit="m", gt=0.0, doc="radius of the meshed air half-disk")
    shell_radius: float = spec(unit="m", gt=0.0, doc="outer radius of the shell to infinity")
    mesh_size_coil: float = spec(unit="m", gt=0.0, doc="element size in and near the coils")
    mesh_size_air: float = spec(unit="m", gt=0.0, doc="element size far away in the air")

    def validate(self, path: str) -> None:
        if not self.coils:
            raise SchemaError(f"{path}.coils", "got an empty list; give at least one [[geometry.coils]] entry")
        work = self.workpiece.box
        placed = check_placed(path, "coils", self.coils, "windings", [], work)
        placed += check_cores(path, self.cores, placed, work)
        corners = [abs(x) for _, b in placed for x in b] + [abs(x) for x in work]
        _check_open_boundary(path, max(corners), self.air_radius, self.shell_radius, "coils/workpiece/cores")


@dataclass(frozen=True, kw_only=True)
class DeckRegions:
    """Physical-group names of the user's mesh for each role (renumbered to the runner's ids)."""

    air: str = spec(doc="air (physical surface)")
    coil: str | None = spec(None, doc="the one stranded coil (physical surface; with geometry.turns), or [[geometry.coils]]")
    workpiece: str = spec(doc="the workpiece, a massive conductor (physical surface)")
    die: str | None = spec(None, doc="a die, massive conductor 2 (physical surface); needs a body with region = 'die'")
    axis: str = spec(doc="the symmetry axis r = 0, a = 0 (physical curve)")
    outer: str = spec(doc="the outer boundary, a = 0 (physical curve)")
    shell: str | None = spec(None, doc="shell transformation to infinity (physical surface)")

    def groups(self) -> dict[str, str]:
        """Role (``regions.<role>``) -> physical-group name, for the roles that are given."""
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None}


@dataclass(frozen=True, kw_only=True)
class DeckCoil:
    """One coil role of a user deck: a named physical surface, its turns in series (stranded: uniform current density)."""

    name: str = spec(doc="the coil's name ([[em.coils]] connects it to a source; history columns <name>_current_A, "
                         "... with several coils)")
    group: str = spec(doc="the coil's physical-group name in the mesh (a physical surface)")
    turns: int = spec(unit="-", ge=1, doc="turns in series over the group's cross-section")


@dataclass(frozen=True, kw_only=True)
class DeckTemplate:
    """What pulseform drives in a deck written on GetDP's template ``Lib_Magnetodynamics2D_av_Cir.pro``
    (``geometry.library = "getdp_template"``): the user's formulation and the system pulseform's own
    Resolution solves (docs/workflow.md, "Decks on GetDP's template")."""

    formulation: str = spec("Magnetodynamics2D_av", doc="the deck's Formulation (the template's "
                                                        "quantities a, ur, ir, Is, Us, Iz, Uz)")
    system: str = spec("A", doc="the system of the deck's Resolution on that formulation")


@dataclass(frozen=True, kw_only=True)
class UserDeck(_ConductorRoles):
    """A user's own EM deck: a Gmsh .geo (meshed by the runner) or .msh and a GetDP .pro (docs/workflow.md): axisymmetric
    or planar; one coil (``regions.coil``, ``turns``) or several (``[[geometry.coils]]``: coil k is physical 100 + k); the
    workpiece, optionally a die; ``remesh_air``: the air groups meshed again when the moved mesh degrades."""

    type: Literal["user_deck"] = spec(doc="geometry kind")
    mesh: str = spec(doc=".geo (meshed with gmsh, MSH 2.2) or .msh, relative to the case folder")
    pro: str = spec(doc="GetDP .pro deck, relative to the case folder")
    allow_outside: bool = spec(False, doc="allow mesh/pro paths outside the case folder")
    allow_system_calls: bool = spec(False, doc="run decks that run programs (SystemCall, System, NonBlockingSystemCall, "
                                    "OnelabRun, Merge of a .py in the .geo; SystemCommand, Python in the .pro; also in "
                                    "their Includes); a deck is code: allow only decks you trust")
    regions: DeckRegions = spec(doc="physical-group names of the roles")
    planar: bool = spec(False, doc="a plane deck (Flag_Axi = 0): the mesh's (x, y) a plane section, the axis role a symmetry "
                                   "plane (a = 0), per metre of depth scaled by mechanics.thickness; prescribed sources only")
    turns: int | None = spec(None, unit="-", ge=1, doc="number of turns of the coil region regions.coil (one coil; "
                                                 "[[geometry.coils]] give their own; a 'getdp_template' deck's own "
                                                 "when not given)")
    coils: tuple[DeckCoil, ...] = spec((), doc="[[geometry.coils]] several coil roles instead of regions.coil: coil k "
                                          "is renumbered to physical 100 + k and is Coil_k of the deck, in this order")
    shell_inner_radius: float | None = spec(None, unit="m", gt=0.0, doc="shell transformation: inner radius")
    shell_outer_radius: float | None = spec(None, unit="m", gt=0.0, doc="shell transformation: outer radius")
    parameters: dict[str, float] | None = spec(None, doc="numbers passed with -setnumber to gmsh (.geo) and getdp: "
                                                   "identifiers, finite, none of the names the runner sets")
    library: Literal["pulseform", "getdp_template"] = spec(
        "pulseform", doc="what the .pro is written on: 'pulseform' (Include PulseformLib, the deck contract) or "
                         "'getdp_template' (Include Lib_Magnetodynamics2D_av_Cir.pro, unchanged: pulseform adds its "
                         "own PostProcessing and Resolution; its own physical ids are kept)")
    template: DeckTemplate | None = spec(None, doc="[geometry.template] the formulation and system of a "
                                                   "'getdp_template' deck (defaults Magnetodynamics2D_av, A)")
    remesh_air: tuple[str, ...] = spec((), doc="physical surfaces (the groups of regions.air / regions.shell) meshed again "
                                               "when the moved mesh degrades; empty: never remeshed (the run stops)")

    _second: ClassVar[tuple[str, str]] = ("die", "regions.die")

    def validate(self, path: str) -> None:
        if not self.mesh.endswith((".geo", ".msh")):
            raise SchemaError(f"{path}.mesh", f"got {self.mesh!r}; must be a .geo or .msh file")
        if not self.pro.endswith(".pro"):
            raise SchemaError(f"{path}.pro", f"got {self.pro!r}; must be a .pro file")
        if (self.shell_inner_radius is None) != (self.shell_outer_radius is None) or \
                (self.regions.shell is None) != (self.shell_inner_radius is None):
            raise SchemaError(f"{path}.shell_inner_radius", "give regions.shell, shell_inner_radius and "
                              "shell_outer_radius together (or none of them)")
        if self.shell_inner_radius is not None and self.shell_outer_radius <= self.shell_inner_radius:
            raise SchemaError(f"{path}.shell_outer_radius", f"got {self.shell_outer_radius:g}; must be > "
                              f"shell_inner_radius = {self.shell_inner_radius:g} (m)")
        self._validate_coils(path)
        if self.template is not None and self.library != "getdp_template":
            raise SchemaError(f"{path}.template", "[geometry.template] is for library = 'getdp_template' (a deck on "
                              "GetDP's template); remove it or set geometry.library")
        if (why := remesh_air_error(self)) is not None:
            raise SchemaError(f"{path}.remesh_air", why)

    def template_spec(self) -> DeckTemplate:
        """The ``[geometry.template]`` table, or its defaults."""
        return self.template if self.template is not None else DeckTemplate()

    def _validate_coils(self, path: str) -> None:
        """One coil (``regions.coil`` with ``turns``) or ``[[geometry.coils]]``, never both; unique coil names;
        no physical group in two roles."""
        if self.coils:
            if self.regions.coil is not None:
                raise SchemaError(f"{path}.regions.coil", "give either regions.coil (one coil, with turns) or "
                                  "[[geometry.coils]] (each with its group and turns), not both")
            if self.turns is not None:
                raise SchemaError(f"{path}.turns", "with [[geometry.coils]] each coil gives its own turns; remove "
                                  "geometry.turns")
        elif self.regions.coil is None:
            raise SchemaError(f"{path}.regions.coil", "missing: give the coil's physical-group name (and turns), or "
                              "[[geometry.coils]] entries (name, group, turns) for several coils")
        elif self.turns is None and self.library != "getdp_template":  # a template deck has its own
            raise SchemaError(f"{path}.turns", "missing: the number of turns of the coil regions.coil (an integer "
                              ">= 1)")
        seen: dict[str, str] = {}
        for role, group in self.regions.groups().items():
            if group in seen:
                raise SchemaError(f"{path}.regions.{role}", f"got {group!r}, which is already {seen[group]}; a "
                                  "physical group has one role")
            seen[group] = f"{path}.regions.{role}"
        names: list[str] = []
        for i, c in enumerate(self.coils):
            if c.name in names:
                raise SchemaError(f"{path}.coils[{i}].name", f"got {c.name!r}; coil names must be unique")
            names.append(c.name)
            if c.group in seen:
                raise SchemaError(f"{path}.coils[{i}].group", f"got {c.group!r}, which is already {seen[c.group]}; "
                                  "a physical group has one role")
            seen[c.group] = f"{path}.coils[{i}].group"

    def coil_groups(self) -> list[tuple[str, str, str, int]]:
        """(key, name, physical-group name, turns) of every coil in coil order (coil k becomes physical
        100 + k); ``key`` is the case-file key of its group, ``name`` None for the one coil of ``regions.coil``."""
        if self.coils:
            return [(f"geometry.coils[{i}].group", c.name, c.group, c.turns) for i, c in enumerate(self.coils)]
        return [("geometry.regions.coil", None, self.regions.coil, self.turns)]


Geometry = FlatCoilSheet | SolenoidTube | PlanarCoilBlankDie | CoaxialCoils | UserDeck | GeometryFile3D
