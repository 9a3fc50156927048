"""Case-file keys of a coupled 3D case built from the user's own geometry (``[geometry] type = "geometry_3d"``,
issue 29): one coupled 3D path for any Gmsh or CAD model.

The geometry is a file of the case folder: a Gmsh ``.geo``, a CAD file gmsh's OpenCASCADE reads
(``.step``/``.stp``, ``.brep``, ``.iges``/``.igs``), a ready mesh ``.msh``, or a Python gmsh script ``.py``
(a builder: it is code and runs only with ``allow_system_calls = true``). The runner meshes it (tetrahedra,
at ``mesh_sizes`` per physical group or the file's own sizes) and reads its **named physical groups**; the
role map names them:

* ``air`` (volume) and optionally ``shell`` (volume: the spherical transformation to infinity about
  ``shell_centre``, its radii read from the mesh);
* ``[[geometry.coils]]``: each coil's volume, turns and current path: two ``terminals`` (surfaces: in, out)
  of an open coil (an electrokinetic pre-solve gives the direction), a ``cut`` surface of a closed loop, or
  ``axis`` (azimuthal about a z-parallel axis through [x, y]: ring coils);
* conductors: every ``[[bodies]]`` entry's ``region`` is a volume group (a deformable or a rigid body), and
  ``[[geometry.conductors]]`` are fixed conductors (a field shaper, a held die: EM only, they do not move);
* ``[[symmetry]]`` planes (their EM condition ``field`` and the mechanical roller) are found on the mesh's
  boundary by geometry; supports are ``[[bodies.fixed]]`` (a box with z bounds, or a surface ``group``).

The coils are driven by ``em.circuit`` / ``em.current`` (every coil in series) or by ``[[em.sources]]`` with
``[[em.coils]]`` naming the coils of this table. Units: m, s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from .schema import SchemaError, spec

#: suffixes of the geometry files gmsh reads (CAD through OpenCASCADE), a mesh, a Python gmsh builder
GEO_SUFFIXES = (".geo",)
CAD_SUFFIXES = (".step", ".stp", ".brep", ".iges", ".igs")
MESH_SUFFIXES = (".msh",)
SCRIPT_SUFFIXES = (".py",)
ALL_SUFFIXES = GEO_SUFFIXES + CAD_SUFFIXES + MESH_SUFFIXES + SCRIPT_SUFFIXES
#: what happens when the moved air mesh breaks
ON_MESH_BREAK_3D = ("remesh", "freeze", "stop")

Vec3 = tuple[float, float, float]


@dataclass(frozen=True, kw_only=True)
class CoilGroup3D:
    """A stranded coil of a 3D geometry file: a volume group, its turns (uniform current density over
    the cross-section of all turns) and how its current flows (exactly one of terminals, cut, axis)."""

    name: str = spec(doc="the coil's name ([[em.coils]] connects it to a source; history columns "
                         "<name>_current_A with several coils)")
    group: str = spec(doc="the coil's physical volume group")
    turns: int = spec(unit="-", ge=1, le=10000, doc="turns in series over the group's cross-section")
    terminals: tuple[str, str] | None = spec(None, doc="[in, out] physical surface groups of an open coil: where "
                                             "the current enters and leaves (an electrokinetic pre-solve in the "
                                             "coil gives its direction; the section is the 'in' terminal's area)")
    cut: str | None = spec(None, doc="physical surface group cutting a closed loop across its section (the "
                           "potential jumps by one there; the section is the cut's area)")
    cut_direction: tuple[float, float, float] | None = spec(
        None, unit="-", doc="with cut: the direction [x, y, z] in which the current crosses the cut (default: the "
                            "normal of the cut's triangles as the mesh file orients them)")
    axis: tuple[float, float] | None = spec(None, unit="m", doc="[x, y] of a z-parallel axis: the current runs "
                                            "azimuthally about it (ring coils; the section from the mesh)")
    section: float | None = spec(None, unit="m^2", gt=0.0,
                                 doc="cross-section of all turns (default: from the terminal, the cut or the mesh)")

    def validate(self, path: str) -> None:
        given = [k for k in ("terminals", "cut", "axis") if getattr(self, k) is not None]
        if len(given) != 1:
            raise SchemaError(f"{path}.terminals", "give exactly one current path: terminals = [in, out] (an open "
                              "coil), cut (a closed loop) or axis = [x, y] (azimuthal)"
                              + (f"; got {', '.join(given)}" if given else ""))
        if self.cut_direction is not None and (self.cut is None or not any(self.cut_direction)):
            raise SchemaError(f"{path}.cut_direction", "a non-zero vector [x, y, z], given with cut")
        if self.terminals is not None and self.terminals[0] == self.terminals[1]:
            raise SchemaError(f"{path}.terminals", f"got the same group {self.terminals[0]!r} twice; the current "
                              "enters and leaves through two different surfaces")

    @property
    def direction(self) -> str:
        """The EM deck's coil direction kind: "electrokinetic", "cut" or "azimuthal"."""
        return "electrokinetic" if self.terminals is not None else ("cut" if self.cut is not None else "azimuthal")


@dataclass(frozen=True, kw_only=True)
class FixedConductor3D:
    """A conductor that does not move (a field shaper, a held die): EM only, induced currents."""

    name: str = spec(doc="its name (history columns <name>_joule_power_W, ...)")
    group: str = spec(doc="its physical volume group")
    material: str = spec(doc="key of a [materials.<name>] table (its electrical_conductivity)")


@dataclass(frozen=True, kw_only=True)
class GeometryFile3D:
    """[geometry] of a coupled 3D case from the user's own geometry file (module docstring)."""

    type: Literal["geometry_3d"] = spec(doc="geometry kind")
    file: str = spec(doc="relative to the case folder: .geo, .step/.stp, .brep, .iges/.igs (meshed by gmsh), .msh "
                         "(read as it is) or .py (a gmsh builder script: code, needs allow_system_calls)")
    parameters: dict[str, float] | None = spec(None, doc="numbers passed to the .geo (-setnumber) or to the .py "
                                                  "builder (name=value arguments)")
    mesh_sizes: dict[str, float] | None = spec(None, unit="m", gt=0.0, doc="element size per physical volume group "
                                                  "(its points); unset: the file's own sizes")
    mesh_size_factor: float = spec(1.0, unit="-", gt=0.0, le=100.0, doc="every element size times this (gmsh's "
                                   "Mesh.MeshSizeFactor; a .py builder gets mesh_size_factor=<value>: "
                                   "pulseform converge refines it)")
    allow_outside: bool = spec(False, doc="allow a file outside the case folder")
    allow_system_calls: bool = spec(False, doc="run a .py builder, or a .geo that runs programs (SystemCall, ...): "
                                    "allow only files you trust")
    air: str = spec(doc="the air: physical volume group")
    shell: str | None = spec(None, doc="shell of the transformation to infinity: a physical volume group between two "
                             "spheres about shell_centre (radii read from the mesh)")
    shell_centre: Vec3 = spec((0.0, 0.0, 0.0), unit="m", doc="centre of the shell's spheres")
    shell_radii: tuple[float, float] | None = spec(None, unit="m", gt=0.0, doc="[inner, outer] radius of the shell "
                                                   "(default from the mesh: the outer its largest node radius, the "
                                                   "inner below its faceted inner face)")
    coils: tuple[CoilGroup3D, ...] = spec((), doc="[[geometry.coils]] the coils (none: an applied field alone)")
    conductors: tuple[FixedConductor3D, ...] = spec((), doc="[[geometry.conductors]] fixed conductors (no body)")
    symmetry_factor: float | None = spec(None, unit="-", ge=1.0, le=1e6, doc="whole device / modelled part "
                                         "(device figures, the bank's voltage over the part); default from the "
                                         "[[symmetry]] planes: 1, 2, 4 or 8 for 0-3 mutually perpendicular planes, "
                                         "360 deg / the wedge's angle (read from the mesh) for two others")
    em_step: float | None = spec(None, unit="s", gt=0.0, doc="target EM step: n = round(em_step / stable "
                                 "mechanical step) (unset: coupling.n)")
    em_order: int = spec(1, unit="-", ge=1, le=2, doc="edge elements: 1 (Whitney) or 2 (second order in the coils and "
                         "conductors, the air first order; cannot remesh)")
    on_mesh_break: Literal["remesh", "freeze", "stop"] = spec(
        "remesh", doc="when the moved air mesh breaks: 'remesh' (mesh the air again, EM state carried), 'freeze' "
                      "(keep the last valid EM mesh), 'stop' (end the run, outputs kept)")
    break_quality: float = spec(1e-3, unit="-", gt=0.0, lt=1.0, doc="the air mesh counts as broken when its worst "
                                "tetrahedron's quality falls below this fraction of the fresh mesh's")

    def validate(self, path: str) -> None:
        if not self.file.lower().endswith(ALL_SUFFIXES):
            raise SchemaError(f"{path}.file", f"got {self.file!r}; allowed suffixes: {', '.join(ALL_SUFFIXES)}")
        if self.shell_radii is not None and (self.shell is None or self.shell_radii[1] <= self.shell_radii[0]):
            raise SchemaError(f"{path}.shell_radii", "give an increasing [inner, outer] pair (m), with geometry.shell")
        if self.em_order == 2 and self.on_mesh_break == "remesh":
            raise SchemaError(f"{path}.em_order", "got 2; second-order edge elements cannot remesh (the carry maps "
                              "Whitney edge unknowns only): set geometry.on_mesh_break = 'freeze' or 'stop'")
        seen: dict[str, str] = {self.air: f"{path}.air"}
        if self.shell is not None:
            _one_role(seen, self.shell, f"{path}.shell")
        names: list[str] = []
        for i, c in enumerate(self.coils):
            if c.name in names:
                raise SchemaError(f"{path}.coils[{i}].name", f"got {c.name!r}; coil names must be unique")
            names.append(c.name)
            _one_role(seen, c.group, f"{path}.coils[{i}].group")
            for j, t in enumerate(c.terminals or ()):
                _one_role(seen, t, f"{path}.coils[{i}].terminals[{j}]")
            if c.cut is not None:
                _one_role(seen, c.cut, f"{path}.coils[{i}].cut")
        for i, c in enumerate(self.conductors):
            if c.name in names:
                raise SchemaError(f"{path}.conductors[{i}].name", f"got {c.name!r}; names must be unique")
            names.append(c.name)
            _one_role(seen, c.group, f"{path}.conductors[{i}].group")
        for group in (self.mesh_sizes or {}):
            if not group:
                raise SchemaError(f"{path}.mesh_sizes", "an empty group name")

    def role_groups(self) -> dict[str, str]:
        """Physical-group name -> case-file key of every group the [geometry] table names (not the bodies')."""
        out = {self.air: "geometry.air"}
        if self.shell is not None:
            out[self.shell] = "geometry.shell"
        for i, c in enumerate(self.coils):
            out[c.group] = f"geometry.coils[{i}].group"
            for j, t in enumerate(c.terminals or ()):
                out[t] = f"geometry.coils[{i}].terminals[{j}]"
            if c.cut is not None:
                out[c.cut] = f"geometry.coils[{i}].cut"
        for i, c in enumerate(self.conductors):
            out[c.group] = f"geometry.conductors[{i}].group"
        return out

    def conductor_roles(self) -> tuple[str, ...]:
        """The fixed conductors' groups (the bodies' regions are their own conductor groups)."""
        return tuple(c.group for c in self.conductors)

    @property
    def planar(self) -> bool:
        """A 3D geometry is never a plane section."""
        return False


def _one_role(seen: dict[str, str], group: str, key: str) -> None:
    """A physical group has one role: raise naming both keys otherwise."""
    if group in seen:
        raise SchemaError(key, f"got {group!r}, which is already {seen[group]}; a physical group has one role")
    seen[group] = key


def validate_geometry_3d(case) -> None:
    """Cross-checks of a coupled 3D geometry-file case that need the whole case (the file's groups are
    checked when it is meshed): bodies' regions, materials, sources and coils, keys that do not apply."""
    g, em = case.geometry, case.em
    if em is None:
        raise SchemaError("em", "missing required table [em] for case.kind = 'coupled'")
    groups = g.role_groups()
    regions = []
    for i, b in enumerate(case.bodies):
        key = f"bodies[{i}]"
        if b.region is None:
            raise SchemaError(f"{key}.region", "missing: a body of a 3D geometry file is one of its physical volume "
                              "groups (region = '<group name>')")
        if b.region in groups:
            raise SchemaError(f"{key}.region", f"got {b.region!r}, which is already {groups[b.region]}; a physical "
                              "group has one role")
        if b.region in regions:
            raise SchemaError(f"{key}.region", f"got {b.region!r}; each group may be used by one body only")
        regions.append(b.region)
        if b.rigid:
            _check_rigid_3d(case, i, b)
        if b.material in case.materials and case.materials[b.material].electrical_conductivity <= 0.0 \
                and case.materials[b.material].conductivity_curve is None:
            raise SchemaError(f"materials.{b.material}.electrical_conductivity", "got 0; a body of a 3D geometry "
                              "file is a conductor: give its conductivity (S/m) or its conductivity_curve")
        for j, f in enumerate(b.fixed):
            if f.where is None and f.group is None:
                raise SchemaError(f"{key}.fixed[{j}]", "give where (a box) or group (a physical surface group)")
    for i, c in enumerate(g.conductors):
        if c.material not in case.materials:
            raise SchemaError(f"geometry.conductors[{i}].material", f"got {c.material!r}; allowed: "
                              + ", ".join(repr(m) for m in case.materials))
        if case.materials[c.material].electrical_conductivity <= 0.0:
            raise SchemaError(f"materials.{c.material}.electrical_conductivity", "got 0; a fixed conductor needs its "
                              "conductivity (S/m)")
    from .em_applied import check_applied_field

    if not g.coils and em.applied_field is None:
        raise SchemaError("geometry.coils", "no coil: give at least one [[geometry.coils]] entry (or an "
                          "[em.applied_field] alone)")
    if g.coils and not any((em.circuit, em.current, em.sources)):
        raise SchemaError("em.circuit", "the coils need a source: give em.circuit (a capacitor bank), em.current or "
                          "[[em.sources]] with [[em.coils]]")
    check_applied_field(case)
    coil_names = [c.name for c in g.coils]
    for i, c in enumerate(em.coils):
        if c.name not in coil_names:
            raise SchemaError(f"em.coils[{i}].name", f"got {c.name!r}; the coils of [[geometry.coils]]: "
                              + ", ".join(repr(n) for n in coil_names))
    if em.sources:
        wired = {c.name for c in em.coils}
        for i, c in enumerate(g.coils):
            if c.name not in wired:
                raise SchemaError(f"geometry.coils[{i}].name", f"coil {c.name!r} is on no source: connect it in "
                                  "[[em.coils]]")
        if any(getattr(s, "type", "") == "bank" for s in em.sources) and len(em.sources) > 1:
            raise SchemaError("em.sources", "a 3D case has one circuit: one bank with every coil in series on it, "
                              "or prescribed sources only")
    for key in ("walls", "analysis", "probes"):
        if getattr(case, key):
            raise SchemaError(key, f"[[{key}]] is not in the 3D geometry path yet: remove it")
    _check_pressure_3d(case)
    if case.em.time_scheme != "bdf2":
        raise SchemaError("em.time_scheme", f"got {case.em.time_scheme!r}; the 3D path steps with 'bdf2'")
    if case.coupling.em_substeps != 1:
        raise SchemaError("coupling.em_substeps", f"got {case.coupling.em_substeps}; the 3D path takes one BDF2 "
                          "step per EM step: 1")


def _check_pressure_3d(case) -> None:
    """``coupling.load = "pressure"`` (the model driven by the ``[[loads]]`` pulses instead of getdp: the
    pressure run of ``pulseform compare``) needs loads, on deformable bodies; loads need it; damping acts only
    with it."""
    if case.coupling.load == "pressure":
        if not case.loads:
            raise SchemaError("loads", "coupling.load = 'pressure' needs at least one [[loads]] pulse")
        rigid = {b.name for b in case.bodies if b.rigid}
        for i, ld in enumerate(case.loads):
            if ld.body in rigid:
                raise SchemaError(f"loads[{i}].body", f"got {ld.body!r}, a rigid body; pressure pulses load "
                                  "deformable bodies")
        return
    if case.loads:
        raise SchemaError("loads", "pressure [[loads]] are used only with coupling.load = 'pressure'; remove them "
                          "or set coupling.load = 'pressure'")
    for key in ("mass_damping", "kinetic_damping_until"):
        if getattr(case.mechanics, key) > 0.0:
            raise SchemaError(f"mechanics.{key}", "damping acts with pressure loads only (coupling.load = "
                              "'pressure'); a GetDP-coupled run would ignore it: remove it")


def is_geometry_3d(data: dict) -> bool:
    """True for the raw mapping of a case whose ``[geometry]`` is a 3D geometry file."""
    g = data.get("geometry")
    return isinstance(g, dict) and g.get("type") == "geometry_3d"


#: keys of other tables that a 3D geometry file does not use, and what it uses instead
RAW_REFUSED = (("em", "remesh_quality", "the 2D air remesh's threshold; a 3D geometry file's is geometry.break_quality"),)


def check_raw_geometry_3d(data: dict) -> None:
    """In the raw case mapping of a 3D geometry-file case: refuse keys of other paths whose defaults it would
    ignore (:data:`RAW_REFUSED`): one :class:`SchemaError` naming the key."""
    if not is_geometry_3d(data):
        return
    for table, key, why in RAW_REFUSED:
        t = data.get(table)
        if isinstance(t, dict) and key in t:
            raise SchemaError(f"{table}.{key}", f"{why}: remove it")


def resolve_geometry_file(data: dict, file, source: str) -> None:
    """Make ``geometry.file`` of a 3D geometry-file case absolute (relative to the case file's folder) and
    check it before any gmsh run: it exists, lies inside the case folder unless ``allow_outside``, its
    ``parameters`` are identifiers with finite values, a ``.py`` builder or a ``.geo`` that runs programs
    only with ``allow_system_calls``. Raises :class:`~.errors.CaseError` (one line naming file and key)."""
    from pathlib import Path

    from .deck_files import check_parameters, find_program_call
    from .errors import CaseError

    if not is_geometry_3d(data):
        return
    g = data["geometry"]
    value = g.get("file")
    if not isinstance(value, str) or not value:
        return  # the schema reports the missing / mistyped key
    folder = Path(file).resolve().parent
    p = Path(value)
    p = (p if p.is_absolute() else folder / p).resolve()
    if g.get("allow_outside") is not True and not p.is_relative_to(folder):
        raise CaseError(source, "geometry.file", f"got {value!r}, which resolves outside the case folder {folder}; "
                        "move it into the folder or set geometry.allow_outside = true")
    if not p.is_file():
        raise CaseError(source, "geometry.file", f"got {value!r}: file not found ({p})")
    g["file"] = str(p)
    check_parameters(g.get("parameters"), source)
    if g.get("allow_system_calls") is True:
        return
    if p.suffix.lower() in SCRIPT_SUFFIXES:
        raise CaseError(source, "geometry.file", f"got {value!r}, a Python gmsh builder: it is code and runs only with "
                        "geometry.allow_system_calls = true (allow only files you trust)")
    if p.suffix.lower() in GEO_SUFFIXES:
        found = find_program_call(p, "geo")
        if found is not None:
            where, what = found
            raise CaseError(source, "geometry.file", f"{where}: {what}; refused unless geometry.allow_system_calls = "
                            "true (a .geo is code)")


def _check_rigid_3d(case, i: int, b) -> None:
    """A rigid body of a 3D geometry file: 3-component vectors, translations that keep the model symmetric."""
    from .parts import allowed_moves_3d

    key = f"bodies[{i}]"
    for name in ("offset", "gravity", "initial_velocity"):
        v = getattr(b, name)
        if v is not None and any(v) and len(v) != 3:
            raise SchemaError(f"{key}.{name}", f"got {len(v)} components; a 3D case needs [x, y, z]")
    allowed = allowed_moves_3d(b, case.symmetry)
    for c in case.rigid_moves(b):
        if c not in allowed:
            raise SchemaError(f"{key}.moves", f"got {list(case.rigid_moves(b))}; a translation along {'xyz'[c]} "
                              f"crosses a [[symmetry]] plane of the body: allowed {list(allowed)}")
    if not allowed:
        raise SchemaError(f"{key}.rigid", "the body's [[symmetry]] planes leave it no translation: make it "
                          "deformable or a fixed conductor")
