"""Case-file keys of the coupled 3D racetrack case (``kind = "coupled"``, ``mechanics.formulation = "3d"``
with a ``[racetrack]`` table; issue 20, case (b)): a racetrack coil forms a rectangular sheet into the
groove of a deformable die, a quarter model (symmetry planes x = 0 and y = 0) meshed with tetrahedra.

``[racetrack]`` holds the geometry (the coil's turns, the sheet, the die and its groove, the air and the
shell), the mesh sizes, the EM step and what happens when the air mesh breaks (``on_mesh_break``); the
rest is in the usual tables: the bank in ``em.circuit`` (and ``em.coil_conductivity``, ``em.time_scheme``),
the two bodies in ``[[bodies]]`` (region ``"workpiece"``: the sheet, ``"die"``: the die; their
``[materials.*]`` give the mechanics and the electrical conductivity), the soft contact sheet (slave) -
die (master) in one ``[[contact]]`` pair (stiffness, h0, friction). The sheet's far edges
(x = ``sheet_half_x``, y = ``sheet_half_y``) are clamped, the die's top face held, both slide in the
symmetry planes (:mod:`pulseform.orchestrator.run.coupled_racetrack`). A racetrack case has no
``[geometry]`` and no ``[sector]``. Units: m, s.

The defaults are the design of ``orchestrator/run/racetrack_design.py`` (``RACETRACK``: docs/coupling.md,
"Case (b)"), so ``cases/emf_racetrack_groove`` reproduces ``studies/emf_racetrack_groove/reference``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .schema import SchemaError, spec
from .sector3d import MEMORY_BASE, MEMORY_PER_TET, ON_MESH_BREAK, TETS_PER_H3, available_memory


@dataclass(frozen=True, kw_only=True)
class Racetrack:
    """[racetrack] of a coupled 3D racetrack case (module docstring): geometry, mesh and EM step (m, s)."""

    turns: int = spec(3, unit="-", ge=1, le=50, doc="racetrack turns of the coil (in series)")
    half_straight: float = spec(15e-3, unit="m", gt=0.0, doc="half length of the turns' straight sides (along y)")
    bend_radius: float = spec(8e-3, unit="m", gt=0.0, doc="inner radius of the innermost turn's ends (its inner "
                              "face at |x| = bend_radius)")
    turn_width: float = spec(3e-3, unit="m", gt=0.0, doc="turn's width (x)")
    turn_height: float = spec(4e-3, unit="m", gt=0.0, doc="turn's height (z)")
    turn_gap: float = spec(1e-3, unit="m", gt=0.0, doc="gap between turns")
    coil_gap: float = spec(1e-3, unit="m", gt=0.0, doc="air gap between the coil's top and the sheet's lower face")
    sheet_thickness: float = spec(1e-3, unit="m", gt=0.0, doc="sheet thickness")
    sheet_half_x: float = spec(35e-3, unit="m", gt=0.0, doc="sheet half width (x); clamped at its far edge")
    sheet_half_y: float = spec(45e-3, unit="m", gt=0.0, doc="sheet half length (y); clamped at its far edge")
    die_gap: float = spec(2e-3, unit="m", gt=0.0, doc="air gap between the sheet's top and the die's lower face")
    die_height: float = spec(10e-3, unit="m", gt=0.0, doc="die height (z); its top face is held")
    die_half_x: float = spec(35e-3, unit="m", gt=0.0, doc="die half width (x)")
    die_half_y: float = spec(45e-3, unit="m", gt=0.0, doc="die half length (y)")
    groove_x0: float | None = spec(None, unit="m", gt=0.0, doc="inner |x| of the groove (unset: bend_radius - "
                                   "turn_gap, over the winding)")
    groove_x1: float | None = spec(None, unit="m", gt=0.0, doc="outer |x| of the groove (unset: the coil's outer "
                                   "half width + turn_gap)")
    groove_half_length: float = spec(10e-3, unit="m", gt=0.0, doc="groove half length (y): a groove of finite length")
    groove_depth: float = spec(4e-3, unit="m", gt=0.0, doc="groove depth from the die's lower face")
    air_radius: float = spec(0.12, unit="m", gt=0.0, doc="radius of the air sphere about the origin")
    shell_radius: float = spec(0.15, unit="m", gt=0.0, doc="outer radius of the shell (transformation to infinity)")
    mesh_size_coil: float = spec(3e-3, unit="m", gt=0.0, doc="element size in the turns")
    mesh_size_sheet: float = spec(2e-3, unit="m", gt=0.0, doc="in-plane element size of the sheet over the coil's "
                                  "footprint (growing by mesh_grading per metre beyond it)")
    sheet_layers: int = spec(3, unit="-", ge=1, le=64, doc="tetrahedron layers through the sheet's thickness")
    mesh_size_die: float = spec(4e-3, unit="m", gt=0.0, doc="element size in the die")
    mesh_size_air: float = spec(0.03, unit="m", gt=0.0, doc="element size at the air sphere")
    mesh_grading: float = spec(0.4, unit="-", ge=0.0, doc="growth of the element size per metre away from the "
                               "coil's footprint")
    em_step: float = spec(1e-6, unit="s", gt=0.0, doc="target EM step (one BDF2 getdp step each): n = round(em_step "
                          "/ stable mechanical step) mechanical steps per EM step")
    on_mesh_break: str = spec("remesh", doc="when the air mesh breaks: " + "; ".join(
        f"'{k}': {v}" for k, v in ON_MESH_BREAK.items()))
    break_quality: float = spec(1e-3, unit="-", gt=0.0, lt=1.0, doc="the air mesh counts as broken when its worst "
                                "tetrahedron's quality falls below this fraction of the fresh mesh's")
    em_order: int = spec(1, unit="-", ge=1, le=2, doc="edge elements of the EM: 1 (Whitney) or 2 (second order in the "
                         "coil and the conductors, the air first order; ~6 % / ~12 % more peak force / impulse than "
                         "order 1 on the design mesh and within ~3 % on a mesh twice as coarse: docs/em_geometries.md, "
                         "racetrack); order 2 cannot remesh (on_mesh_break 'freeze' or 'stop')")

    @property
    def coil_outer(self) -> float:
        """Distance (m) of the outermost turn's outer face from the centre line x = 0."""
        return self.bend_radius + self.turns * self.turn_width + (self.turns - 1) * self.turn_gap

    @property
    def groove_x(self) -> tuple[float, float]:
        """(inner, outer) |x| of the groove (m), the defaults resolved."""
        x0 = self.bend_radius - self.turn_gap if self.groove_x0 is None else self.groove_x0
        x1 = self.coil_outer + self.turn_gap if self.groove_x1 is None else self.groove_x1
        return x0, x1

    def validate(self, path: str) -> None:
        """One :class:`SchemaError` naming the first key whose value does not fit the others."""
        if self.on_mesh_break not in ON_MESH_BREAK:
            raise SchemaError(f"{path}.on_mesh_break", f"got {self.on_mesh_break!r}; allowed: "
                              + ", ".join(repr(k) for k in ON_MESH_BREAK))
        if self.em_order == 2 and self.on_mesh_break == "remesh":
            raise SchemaError(f"{path}.on_mesh_break", "got 'remesh' with em_order = 2: the remesh carries first-order "
                              "edge unknowns only; allowed with em_order = 2: 'freeze', 'stop'")
        x0, x1 = self.groove_x
        length = self.half_straight + self.coil_outer
        checks = (
            ("sheet_half_x", self.sheet_half_x > self.coil_outer,
             f"must exceed the coil's outer half width {self.coil_outer:g} (bend_radius + turns x turn_width + "
             "(turns - 1) x turn_gap): the coil would stick out under the sheet's clamped edge"),
            ("sheet_half_y", self.sheet_half_y > length,
             f"must exceed the coil's half length {length:g} (half_straight + its outer half width)"),
            ("groove_x0", x0 > 0.0, f"resolves to {x0:g}; must be > 0 (give groove_x0 or a larger bend_radius)"),
            ("groove_x1", x1 > x0, f"resolves to {x1:g}; must exceed groove_x0 = {x0:g}"),
            ("groove_x1", x1 < self.sheet_half_x,
             f"resolves to {x1:g}: the groove is wider than the sheet; must be < sheet_half_x = {self.sheet_half_x:g}"),
            ("groove_x1", x1 < self.die_half_x, f"resolves to {x1:g}; must be < die_half_x = {self.die_half_x:g}"),
            ("groove_half_length", self.groove_half_length < min(self.die_half_y, self.sheet_half_y),
             f"must be < die_half_y and sheet_half_y (= {min(self.die_half_y, self.sheet_half_y):g})"),
            ("groove_depth", self.groove_depth < self.die_height, f"must be < die_height = {self.die_height:g}"),
            ("shell_radius", self.shell_radius > self.air_radius, f"must exceed air_radius = {self.air_radius:g}"),
        )
        for key, ok, text in checks:
            if not ok:
                raise SchemaError(f"{path}.{key}", f"got {getattr(self, key)!r}; {text} (m)")
        corner = math.hypot(max(self.sheet_half_x, self.die_half_x), max(self.sheet_half_y, self.die_half_y))
        reach = math.hypot(corner, max(self.sheet_thickness + self.die_gap + self.die_height,
                                       self.coil_gap + self.turn_height))
        if reach >= self.air_radius:
            raise SchemaError(f"{path}.air_radius", f"got {self.air_radius:g}; must enclose the coil, the sheet and the "
                              f"die: > {reach:.4g} (m)")


#: tables and keys a racetrack case does not take: (table, key or None for the whole table, why)
_REFUSED = (("geometry", None, "the racetrack's geometry is [racetrack]"),
            ("sector", None, "[sector] is the sector of a flat_coil_sheet case; the racetrack is a quarter model"),
            ("symmetry", None, "the racetrack's planes x = 0 and y = 0 are its symmetry planes"),
            ("walls", None, "not in the racetrack case"), ("loads", None, "the racetrack is driven by getdp"))


def check_raw_racetrack(data: dict[str, Any]) -> None:
    """In the raw case mapping: ``[racetrack]`` only in a coupled 3D case, and no table of :data:`_REFUSED`
    beside it."""
    if "racetrack" not in data:
        return
    mech, info = data.get("mechanics"), data.get("case")
    kind = info.get("kind", "mechanics") if isinstance(info, dict) else "mechanics"
    form = mech.get("formulation", "plane_strain") if isinstance(mech, dict) else "plane_strain"
    if kind != "coupled" or form != "3d":
        raise SchemaError("racetrack", "a key of coupled 3D cases (case.kind = 'coupled', mechanics.formulation = "
                          f"'3d'); this case has kind = {kind!r}, formulation = {form!r}: remove [racetrack]")
    for table, _, why in _REFUSED:
        if table in data:
            raise SchemaError(table, f"not in a racetrack case ({why}): remove it")


def validate_racetrack(case) -> None:
    """A coupled 3D racetrack case (module docstring): one :class:`SchemaError` naming the key that does
    not fit (the [racetrack] table itself checks in :meth:`Racetrack.validate`)."""
    em = case.em
    if em is None:
        raise SchemaError("em", "missing required table [em] for case.kind = 'coupled': give em.circuit (the bank)")
    if em.circuit is None or em.current is not None or em.sources or em.coils:
        raise SchemaError("em.circuit", "the racetrack's coil discharges a capacitor bank: give em.circuit "
                          "(capacitance, voltage, resistance, inductance) and no em.current, em.sources or em.coils")
    if case.coupling.load != "getdp":
        raise SchemaError("coupling.load", f"got {case.coupling.load!r}; the racetrack case runs on getdp: 'getdp'")
    regions = [b.region for b in case.bodies]
    if sorted(r or "" for r in regions) != ["die", "workpiece"]:
        raise SchemaError("bodies", f"got regions {regions}; the racetrack case has two bodies: the sheet "
                          "(region = 'workpiece') and the die (region = 'die')")
    for i, b in enumerate(case.bodies):
        for key, bad in (("rigid", b.rigid), ("fixed", bool(b.fixed)), ("initial_velocity", any(b.initial_velocity)),
                         ("shape", b.shape is not None)):
            if bad:
                raise SchemaError(f"bodies[{i}].{key}", "not in the racetrack case (its bodies are cut from the EM "
                                  "mesh, deformable, at rest, held by the clamp and the die's top): remove it")
    for i, b in enumerate(case.bodies):
        want = "sheet" if b.region == "workpiece" else "die"
        if b.name != want:
            raise SchemaError(f"bodies[{i}].name", f"got {b.name!r}; the racetrack's body of region {b.region!r} is "
                              f"named {want!r} (its history columns and pictures use the name)")
    sheet, die = "sheet", "die"
    if len(case.contact) != 1:
        raise SchemaError("contact", f"got {len(case.contact)} pairs; the racetrack case takes one [[contact]] pair: "
                          f"slave = {sheet!r}, master = {die!r} (stiffness, h0, friction)")
    c = case.contact[0]
    if (c.slave, c.master) != (sheet, die):
        raise SchemaError("contact[0].slave", f"got slave {c.slave!r}, master {c.master!r}; the racetrack's pair is "
                          f"slave = {sheet!r} (the sheet), master = {die!r} (the die)")
    if c.viscosity:
        raise SchemaError("contact[0].viscosity", "not in the racetrack case: remove it")
    mo = case.mechanics
    for key, default in (("bulk_viscosity", True), ("bulk_viscosity_linear", 0.06), ("bulk_viscosity_quadratic", 1.2)):
        if getattr(mo, key) != default:
            raise SchemaError(f"mechanics.{key}", f"got {getattr(mo, key)!r}; the racetrack case runs with the "
                              f"default bulk viscosity ({default!r}): remove it")
    for i, b in enumerate(case.bodies):
        if b.material not in case.materials:
            raise SchemaError(f"bodies[{i}].material", f"got {b.material!r}; allowed: "
                              + (", ".join(repr(n) for n in case.materials) or "(none defined)"))
        if case.materials[b.material].electrical_conductivity <= 0.0:
            raise SchemaError(f"materials.{b.material}.electrical_conductivity", "got 0; the racetrack's sheet and "
                              "die are EM conductors: give their conductivity (S/m)")
    if case.time.dt_max is not None:
        raise SchemaError("time.dt_max", "not in the racetrack case (its step is the stable step): remove it")


# --------------------------------------------------------------------------- resources
#: triangles per (area / h²) of a face meshed with equilateral triangles of side h
_TRI_PER_AREA = 4.0 / math.sqrt(3.0)
#: the whole EM mesh over the conductors' tetrahedra (sheet + die), at least: 2.2 at the design mesh
#: (26275 / (8910 + 2983)); taken lower (a lower estimate, as the sector's)
MESH_OVER_CONDUCTORS = 2.0


def estimated_racetrack_tets(rt: Racetrack) -> tuple[float, float]:
    """(EM tetrahedra, the sheet's tetrahedra) of the quarter model's mesh, estimated before any meshing
    (lower estimates): the sheet's quarter face at ``mesh_size_sheet`` (its size only grows away from the
    coil) × layers × 3 tetrahedra per prism; the die, the coil and the air by volume at their sizes
    (:data:`~.sector3d.TETS_PER_H3`); the whole mesh at least :data:`MESH_OVER_CONDUCTORS` times the
    conductors'."""
    h = rt.mesh_size_sheet
    sheet = 3.0 * rt.sheet_layers * _TRI_PER_AREA * rt.sheet_half_x * rt.sheet_half_y / h ** 2
    x0, x1 = rt.groove_x
    die_v = rt.die_half_x * rt.die_half_y * rt.die_height - (x1 - x0) * rt.groove_half_length * rt.groove_depth
    die = TETS_PER_H3 * die_v / rt.mesh_size_die ** 3
    coil_v = rt.turns * rt.turn_width * rt.turn_height * (rt.half_straight + math.pi / 2 * (rt.coil_outer - rt.turn_width))
    air_v = math.pi / 3.0 * rt.shell_radius ** 3   # a quarter of the sphere of the shell's radius
    by_volume = TETS_PER_H3 * (coil_v / rt.mesh_size_coil ** 3 + air_v / rt.mesh_size_air ** 3)
    return max(MESH_OVER_CONDUCTORS * (sheet + die), sheet + die + by_volume), sheet


def check_racetrack_resources(case, available: float | None = None) -> None:
    """Refuse a racetrack case whose mesh would exceed ``limits.max_cells`` or, at
    :data:`~.sector3d.MEMORY_PER_TET`, the machine's available memory (``available`` bytes; default:
    :func:`~.sector3d.available_memory`), before any meshing."""
    rt = case.racetrack
    tets, sheet = estimated_racetrack_tets(rt)
    what = (f"got {rt.mesh_size_sheet:g} m: the racetrack's mesh would have ~{tets:.3g} tetrahedra (the sheet ~{sheet:.3g}, "
            f"{rt.sheet_layers} layers)")
    if tets > case.limits.max_cells:
        raise SchemaError("racetrack.mesh_size_sheet", f"{what}, above limits.max_cells = {case.limits.max_cells:.3g}; "
                          "coarsen it (or the other racetrack.mesh_size_*) or raise limits.max_cells")
    avail = available_memory() if available is None else available
    need = MEMORY_BASE + MEMORY_PER_TET * tets
    if avail is not None and need > avail:
        raise SchemaError("racetrack.mesh_size_sheet", f"{what}, needing ~{need / 1e9:.3g} GB of memory, above the "
                          f"{avail / 1e9:.3g} GB available on this machine; coarsen it")
