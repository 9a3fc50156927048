"""Case-file keys of a coupled 3D case (``kind = "coupled"``, ``mechanics.formulation = "3d"``, issue 20):
a thin sector of an axisymmetric ``flat_coil_sheet`` setup about the z-axis, meshed with tetrahedra.

The ``[geometry]`` table is the 2D one (coil turns, gap, sheet, air, shell; ``mesh_size_sheet`` is the
in-plane element size of the sheet over the coil and defaults from the skin depth as in 2D,
``mesh_size_coil`` and ``mesh_size_air`` the sizes in the turns and at the air sphere). ``[sector]``
adds what only the sector has: its angle, the tetrahedron layers through the sheet, the sheet's size
beyond the coil, the EM step, the clamp (a radial selection: the sheet is held for r >= ``clamp_rmin``) and
what happens when the moved air mesh breaks (``on_mesh_break``: by default the air is meshed again with the
EM state carried, as in the racetrack case; ``break_quality``).
The sector's two meridian faces are its symmetry planes (n × a = 0 for the field, sliding planes for the
sheet and the air motion): a coupled 3D case gives no ``[[symmetry]]``. Units: m, s, degrees for the angle.

``coupling.load = "pressure"`` with ``[[loads]]`` (the one key of ``[coupling]`` a sector takes) drives the
same sheet mesh (cut from the same EM mesh), clamp, sliding faces and loop with pressure pulses instead of
getdp (``pulseform compare``); a load's ``surface`` box is read in the sector's (r, z) coordinates,
r = sqrt(x² + y²) (``xmin``/``xmax``) and z (``ymin``/``ymax``), as in the axisymmetric case, so the
[[loads]] of the 2D case act unchanged on its sector.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .memory import MEMORY_BASE, MEMORY_PER_TET, available_memory
from .schema import SchemaError, spec

#: what a coupled 3D run does when the air's worst tetrahedron falls below its break quality times the fresh
#: mesh's (``sector.on_mesh_break``, ``racetrack.on_mesh_break``): a set that can grow (the run checks its value
#: against these keys)
ON_MESH_BREAK: dict[str, str] = {
    "remesh": "the air is meshed again around the bodies and the EM state carried edge by edge into the new mesh "
              "(orchestrator/em/remesh3d.py); a remesh that fails freezes (below)",
    "freeze": "the EM mesh stays at the last valid one (the EM no longer sees the bodies move; the history flags "
              "it, metrics.json says when and the impulse after it)",
    "stop": "the run ends there as failed, with one line naming the tetrahedron (the history and the fields "
            "of the output times before it kept)",
}
#: the sector angles allowed (degrees, open interval): at 180° the two meridian faces are one plane
ANGLE_RANGE_DEG = (0.0, 180.0)
#: the sheet's fine region reaches this far beyond the coil's outer radius (m); the sheet's size there
#: is ``geometry.mesh_size_sheet``, beyond it ``sector.mesh_size_sheet_outer``
FINE_MARGIN = 5e-3


@dataclass(frozen=True, kw_only=True)
class Sector:
    """[sector] of a coupled 3D case (module docstring): the modelled sector of the axisymmetric setup."""

    angle_deg: float = spec(2.5, unit="deg", gt=ANGLE_RANGE_DEG[0], lt=ANGLE_RANGE_DEG[1],
                            doc="sector angle about the z-axis in degrees (0 < angle < 180); forces, impulse and "
                                "energies of the device are the sector's times 360 / angle")
    sheet_layers: int | None = spec(None, unit="-", ge=1, le=64,
                                    doc="tetrahedron layers through the sheet's thickness (unset: thickness / "
                                        "geometry.mesh_size_sheet rounded up, at least 2)")
    mesh_size_sheet_outer: float | None = spec(None, unit="m", gt=0.0,
                                               doc="the sheet's element size beyond the coil's outer radius + 5 mm "
                                                   "(unset: 3 × geometry.mesh_size_sheet)")
    em_step: float = spec(0.45e-6, unit="s", gt=0.0,
                          doc="target EM step (one getdp run each): n = round(em_step / stable mechanical step) "
                              "mechanical steps per EM step")
    clamp_rmin: float | None = spec(None, unit="m", gt=0.0,
                                    doc="the sheet is held (all three components) where r >= clamp_rmin (unset: free)")
    on_mesh_break: str = spec("remesh", doc="when the air mesh breaks: " + "; ".join(
        f"'{k}': {v}" for k, v in ON_MESH_BREAK.items()))
    break_quality: float = spec(0.2, unit="-", gt=0.0, lt=1.0,
                                doc="the air mesh counts as broken when its worst tetrahedron's quality falls below "
                                    "this fraction of the fresh mesh's (then sector.on_mesh_break)")

    def validate(self, path: str) -> None:
        """One :class:`SchemaError` naming ``on_mesh_break`` when it is none of :data:`ON_MESH_BREAK`."""
        if self.on_mesh_break not in ON_MESH_BREAK:
            raise SchemaError(f"{path}.on_mesh_break", f"got {self.on_mesh_break!r}; allowed: "
                              + ", ".join(repr(k) for k in ON_MESH_BREAK))

    def layers(self, thickness: float, size: float) -> int:
        """Tetrahedron layers through a sheet of ``thickness`` (m) meshed at ``size`` (m)."""
        if self.sheet_layers is not None:
            return self.sheet_layers
        return max(2, math.ceil(thickness / size - 1e-9))

    def outer_size(self, size: float) -> float:
        """The sheet's element size beyond the coil (m), ``size`` the fine one (m)."""
        return self.mesh_size_sheet_outer if self.mesh_size_sheet_outer is not None else 3.0 * size


#: keys whose presence says the case means a 2D coupled model: (table, key or None for the whole table, why)
_RAW_2D_KEYS = (
    ("coupling", None, "the 2D loop's options; the 3D sector sets its EM step by sector.em_step"),
    ("em", "getdp_process", "the persistent getdp is 2D-only; the 3D sector runs a getdp process per EM step"),
    ("em", "remesh_quality", "the 2D air remesh; a 3D sector's is sector.break_quality"),
    ("em", "keep_runs", "the 3D sector keeps the last two getdp run folders"),
)


#: keys of those tables a coupled 3D case does take: the load (``coupling.load = "pressure"`` with
#: [[loads]]: the sector driven by pressure pulses instead of getdp, module docstring)
_RAW_3D_KEYS = (("coupling", "load"),)


def check_raw_coupled_3d(data: dict[str, Any]) -> None:
    """In the raw case mapping of a coupled 3D case: refuse 2D-only keys whose defaults would be silently
    ignored (:data:`_RAW_2D_KEYS`); in a 2D case refuse ``[sector]``."""
    mech = data.get("mechanics")
    info = data.get("case")
    sector = data.get("sector")
    if isinstance(sector, dict) and "stop_quality" in sector:
        raise SchemaError("sector.stop_quality", "renamed sector.break_quality (the air mesh counts as broken below "
                          "it; what then happens: sector.on_mesh_break = 'remesh', 'freeze' or 'stop')")
    three_d = isinstance(mech, dict) and mech.get("formulation") == "3d"
    coupled = isinstance(info, dict) and info.get("kind") == "coupled"
    if "sector" in data and not (three_d and coupled):
        f = mech.get("formulation", "plane_strain") if isinstance(mech, dict) else "plane_strain"
        raise SchemaError("sector", "a key of coupled 3D cases (case.kind = 'coupled', mechanics.formulation = "
                          f"'3d'); this case has kind = {info.get('kind', 'mechanics') if isinstance(info, dict) else 'mechanics'!r}, "
                          f"formulation = {f!r}: remove [sector]")
    if not (three_d and coupled):
        return
    for table, key, why in _RAW_2D_KEYS:
        t = data.get(table)
        if not isinstance(t, dict):
            continue
        other = [k for k in t if (table, k) not in _RAW_3D_KEYS]
        if key is None and other:
            raise SchemaError(f"{table}.{other[0]}", f"a 2D-only key ({why}); a coupled 3D case has no "
                              f"[{table}] table but coupling.load: remove it")
        if key is not None and key in t:
            raise SchemaError(f"{table}.{key}", f"a 2D-only key ({why}): remove it")


def validate_coupled_3d(case) -> None:
    """A coupled 3D case (module docstring): one :class:`SchemaError` naming the key that does not fit."""
    g, em = case.geometry, case.em
    if g is None or em is None:
        raise SchemaError("geometry" if g is None else "em", "missing required table for case.kind = 'coupled'")
    if g.type != "flat_coil_sheet":
        raise SchemaError("geometry.type", f"got {g.type!r}; a coupled 3D case (mechanics.formulation = '3d') is a "
                          "sector of 'flat_coil_sheet' for now")
    if g.die is not None:
        raise SchemaError("geometry.die", "the 3D sector has no die yet: remove [geometry.die]")
    if em.sources or em.coils:
        raise SchemaError("em.sources", "the 3D sector's coil is the geometry's turns in series: give em.circuit "
                          "(a capacitor bank) or em.current")
    s = case.sector or Sector()
    if s.clamp_rmin is not None and s.clamp_rmin >= g.sheet_radius:
        raise SchemaError("sector.clamp_rmin", f"got {s.clamp_rmin:g}; must be < geometry.sheet_radius = "
                          f"{g.sheet_radius:g} (m), else it holds no node of the sheet")
    for key in ("symmetry", "walls", "contact") + (() if case.coupling.load == "pressure" else ("loads",)):
        if getattr(case, key):
            what = {"symmetry": "the sector's two meridian faces are its symmetry planes",
                    "loads": "pressure pulses drive the sector only with coupling.load = 'pressure'"}.get(
                        key, "not in the coupled 3D sector yet")
            raise SchemaError(key, f"[[{key}]] in a coupled 3D case: {what}; remove it")
    for i, b in enumerate(case.bodies):
        if b.region != "workpiece":
            raise SchemaError(f"bodies[{i}].region", f"got {b.region!r}; the coupled 3D sector has one body, the "
                              "sheet: region = 'workpiece'")
        if b.rigid:
            raise SchemaError(f"bodies[{i}].rigid", "the sheet of the 3D sector is deformable: remove rigid")
        if b.fixed:
            raise SchemaError(f"bodies[{i}].fixed", "a 2D-only key (its box selects by r and z); in a coupled 3D "
                              "case clamp the sheet with sector.clamp_rmin (m)")
        if any(b.initial_velocity):
            raise SchemaError(f"bodies[{i}].initial_velocity", "the sheet of the 3D sector starts at rest: remove it")


# --------------------------------------------------------------------------- resources
#: triangles per (area / h²) of the sheet's sector face (equilateral triangles of side h)
_TRI_PER_AREA = 4.0 / math.sqrt(3.0)
#: the whole EM mesh (sheet, coil, air) over the sheet's tetrahedra, at least: 2.8 (demo sector), 3.3
#: (5°, 0.5 mm, 4 layers) and 6.3 (coarse 5°) in the meshes measured (docs/coupling.md)
MESH_OVER_SHEET = 2.5
#: tetrahedra per h^3 of volume at element size h, taken low: a regular tetrahedron of edge h holds
#: h^3 / 8.49, and gmsh's elements scatter about the size (a lower estimate)
TETS_PER_H3 = 8.49 / 2.0


def _strip_triangles(alpha: float, r0: float, r1: float, h: float) -> float:
    """Triangles of a sector face 0 <= phi <= alpha (rad), r0 <= r <= r1 (m), at size h (m): the area's
    triangles where the arc r alpha is wider than about h, else two triangles per h of length (a strip
    one element wide: the elements stretch across it)."""
    if r1 <= r0:
        return 0.0
    rc = min(max(2.0 * h / (_TRI_PER_AREA * alpha), r0), r1)
    return 2.0 * (rc - r0) / h + _TRI_PER_AREA * alpha * (r1 ** 2 - rc ** 2) / (2.0 * h ** 2)


def estimated_sector_tets(case) -> tuple[float, float]:
    """(EM tetrahedra, the sheet's tetrahedra) of a coupled 3D case's sector mesh, estimated before any
    meshing (lower estimates): the sheet's face triangles (:func:`_strip_triangles`, at
    ``geometry.mesh_size_sheet`` over the coil + 5 mm, the outer size beyond) × layers × 3 tetrahedra per
    prism, the whole mesh :data:`MESH_OVER_SHEET` times that. An unset sheet size is taken as half the
    sheet's thickness (no smaller than its skin-depth default: a lower estimate)."""
    g = case.geometry
    s = case.sector or Sector()
    h = g.mesh_size_sheet if g.mesh_size_sheet is not None else g.sheet_thickness / 2.0
    alpha = math.radians(s.angle_deg)
    r_coil = g.coil_inner_radius + g.turns * g.turn_width + (g.turns - 1) * g.turn_gap
    r_box = min(r_coil + FINE_MARGIN, g.sheet_radius)
    tri = _strip_triangles(alpha, 0.0, r_box, h) + _strip_triangles(alpha, r_box, g.sheet_radius, s.outer_size(h))
    sheet = 3.0 * s.layers(g.sheet_thickness, h) * tri
    # no element larger than its region's size: at least volume / (a regular tetrahedron's h^3 / 8.49), taken
    # at half that (gmsh's sizes scatter) -- the turns at mesh_size_coil, the air and shell at mesh_size_air
    r_turn = [g.coil_inner_radius + i * (g.turn_width + g.turn_gap) + g.turn_width / 2 for i in range(g.turns)]
    coil = sum(alpha * r * g.turn_width * g.turn_height for r in r_turn)
    air = alpha / 3.0 * g.shell_radius ** 3 * 2.0   # the sector of the sphere of the shell's radius
    by_volume = TETS_PER_H3 * (coil / g.mesh_size_coil ** 3 + air / g.mesh_size_air ** 3)
    return max(MESH_OVER_SHEET * sheet, sheet + by_volume), sheet


def check_sector_resources(case, available: float | None = None) -> None:
    """Refuse a coupled 3D case whose sector mesh would exceed ``limits.max_cells`` or, at
    :data:`MEMORY_PER_TET`, the machine's available memory (``available`` bytes; default:
    :func:`available_memory`)."""
    tets, sheet = estimated_sector_tets(case)
    s, g = case.sector or Sector(), case.geometry
    layers = s.layers(g.sheet_thickness, g.mesh_size_sheet or g.sheet_thickness / 2.0)
    what = (f"the 3D sector's mesh would have ~{tets:.3g} tetrahedra (the sheet ~{sheet:.3g}: sector.angle_deg = "
            f"{s.angle_deg:g}, {layers} layers)")
    size = g.mesh_size_sheet
    got = f"got {size:g} m: " if size is not None else ""
    if tets > case.limits.max_cells:
        raise SchemaError("geometry.mesh_size_sheet", f"{got}{what}, above limits.max_cells = "
                          f"{case.limits.max_cells:.3g}; coarsen it, narrow the sector or raise limits.max_cells")
    avail = available_memory() if available is None else available
    need = MEMORY_BASE + MEMORY_PER_TET * tets
    if avail is not None and need > avail:
        raise SchemaError("geometry.mesh_size_sheet", f"{got}{what}, needing ~{need / 1e9:.3g} GB of memory, above "
                          f"the {avail / 1e9:.3g} GB available on this machine; coarsen it or narrow the sector")
