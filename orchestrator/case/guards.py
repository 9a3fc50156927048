"""Resource guards: refuse a case whose meshes or step count would exhaust the machine, before any meshing.

Estimates (checked by ``Case.validate``, so ``pulseform check`` and every run see them):

- **cells**: per meshed region, its 2D area over its element size squared, times 2.31 (equilateral
  triangles of side h cover 0.433 h² each): the bodies' own shapes, and for built-in EM geometries the
  conductors, the coil turns and the air half-disk at its far-field size (a lower estimate: the graded
  air near the conductors adds more); a 3D body (tetrahedra): its volume over h³ times 8.49 (regular
  tetrahedra of edge h fill 0.118 h³ each). User decks are meshed by their own ``.geo``: gmsh's time limit
  guards those.
- **explicit steps**: ``time.end`` over the smallest estimated stable step of the undeformed meshes,
  ``cfl · 0.5 h / c_d`` with the dilatational wave speed ``c_d = sqrt((K + 4G/3) / ρ)`` (a well-shaped
  triangle of size h has an altitude of ~0.87 h; 0.5 h allows for real meshes), capped by ``time.dt_max``.
  h is the region's element size, or its thickness where that is smaller (a 1 µm sheet meshed "at
  0.5 mm" gets 1 µm elements).
- **EM steps** of a GetDP-coupled case: explicit steps / ``coupling.n`` (one getdp run each).
- a case whose bodies are all **rigid** has no stability limit: its step is an upper bound of the
  source's period over ``coupling.steps_per_period`` EM steps of ``coupling.n`` steps
  (:mod:`.rigid_steps`), capped by ``time.dt_max``.

The limits are the case's ``[limits]`` table (see :class:`~pulseform.orchestrator.case.model.Limits`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .rigid_steps import all_rigid, period_upper_bound
from .schema import SchemaError
from .skin import provisional_size

#: cells per (area / h²) of a mesh of equilateral triangles of side h
CELLS_PER_AREA_OVER_H2 = 4.0 / math.sqrt(3.0)
#: cells per (volume / h³) of a mesh of regular tetrahedra of edge h (3D cases)
CELLS_PER_VOLUME_OVER_H3 = 6.0 * math.sqrt(2.0)
#: stable-step length of an element of size h, as a fraction of h (see the module docstring)
STEP_LENGTH_FRACTION = 0.5


@dataclass(frozen=True)
class Region:
    """One meshed region: where its size is set (key path), its 2D area (m²) and element size (m); a
    3D region (tetrahedra) gives its volume (m³) instead."""

    key: str
    area: float
    size: float
    thinnest: float = math.inf  # the region's smallest extent (m): a sheet's thickness caps its elements
    volume: float | None = None

    @property
    def h(self) -> float:
        """Element size (m): the set size, or the region's thickness where that is smaller."""
        return min(self.size, self.thinnest)

    @property
    def cells(self) -> float:
        if self.volume is not None:
            return CELLS_PER_VOLUME_OVER_H3 * self.volume / self.h ** 3
        return CELLS_PER_AREA_OVER_H2 * self.area / self.h ** 2


def _shape_area(shape) -> float:
    if shape.type == "rectangle":
        return shape.width * shape.height
    pts = shape.points
    return 0.5 * abs(sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(pts, pts[1:] + pts[:1])))


def _geometry_regions(case) -> list[Region]:
    """Meshed regions of a built-in EM geometry (conductors, coil, air); none for a user deck. A conductor
    size the case leaves unset is estimated from the skin depth (:func:`.skin.provisional_size`)."""
    g = case.geometry

    def size(key: str, value: float | None) -> float:
        return value if value is not None else provisional_size(case, key)

    air = 0.5 * math.pi * g.air_radius ** 2 if hasattr(g, "air_radius") else 0.0
    turn = g.turn_width * g.turn_height if hasattr(g, "turn_width") else 0.0
    if g.type == "flat_coil_sheet":
        out = [Region("geometry.mesh_size_sheet", g.sheet_radius * g.sheet_thickness,
                      size("geometry.mesh_size_sheet", g.mesh_size_sheet),
                      g.sheet_thickness)]
        if g.die is not None:
            d = g.die
            out.append(Region("geometry.die.mesh_size", d.outer_radius * d.height, d.mesh_size))
    elif g.type == "solenoid_tube":
        out = [Region("geometry.mesh_size_tube", g.tube_thickness * g.tube_length,
                      size("geometry.mesh_size_tube", g.mesh_size_tube),
                      g.tube_thickness)]
        if g.outer_tube is not None:
            o = g.outer_tube
            out.append(Region("geometry.outer_tube.mesh_size", o.thickness * o.length,
                              size("geometry.outer_tube.mesh_size", o.mesh_size), o.thickness))
    elif g.type == "coaxial_coils":
        w = g.workpiece
        windings = [b for c in g.coils for b in c.windings]
        return [Region("geometry.workpiece.mesh_size", (w.r1 - w.r0) * (w.z1 - w.z0),
                       size("geometry.workpiece.mesh_size", w.mesh_size),
                       min(w.r1 - w.r0, w.z1 - w.z0)),
                Region("geometry.mesh_size_coil", sum((b[2] - b[0]) * (b[3] - b[1]) for b in windings),
                       g.mesh_size_coil, min(min(b[2] - b[0], b[3] - b[1]) for b in windings)),
                Region("geometry.mesh_size_air", air, g.mesh_size_air)]
    elif g.type == "planar_coil_blank_die":
        out = [Region("geometry.mesh_size_blank", g.blank_half_width * g.blank_thickness,
                      size("geometry.mesh_size_blank", g.mesh_size_blank),
                      g.blank_thickness)]
        if g.die is not None:
            pts = list(g.die)
            area = 0.5 * abs(sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(pts, pts[1:] + pts[:1])))
            out.append(Region("geometry.mesh_size_die", area, g.mesh_size_die))
    else:
        return []
    out.append(Region("geometry.mesh_size_coil", g.turns * turn, g.mesh_size_coil, min(g.turn_width, g.turn_height)))
    out.append(Region("geometry.mesh_size_air", air, g.mesh_size_air))
    return out


def _body_regions(case) -> list[Region]:
    """Each body's meshed region, in the order of ``case.bodies`` (None where unknown before meshing)."""
    g = case.geometry
    geo = {r.key: r for r in _geometry_regions(case)} if g is not None else {}
    key = {"workpiece": {"flat_coil_sheet": "mesh_size_sheet", "solenoid_tube": "mesh_size_tube",
                         "planar_coil_blank_die": "mesh_size_blank", "coaxial_coils": "workpiece.mesh_size"},
           "die": {"flat_coil_sheet": "die.mesh_size", "planar_coil_blank_die": "mesh_size_die"},
           "outer_tube": {"solenoid_tube": "outer_tube.mesh_size"}}
    out = []
    for i, b in enumerate(case.bodies):
        if b.shape is not None and b.mesh_size is not None and hasattr(b.shape, "volume"):  # 3D solids
            out.append(Region(f"bodies[{i}].mesh_size", 0.0, b.mesh_size, b.shape.thinnest(), b.shape.volume()))
        elif b.shape is not None and b.mesh_size is not None:
            thin = min(b.shape.width, b.shape.height) if b.shape.type == "rectangle" else math.inf
            out.append(Region(f"bodies[{i}].mesh_size", _shape_area(b.shape), b.mesh_size, thin))
        else:
            out.append(geo.get("geometry." + key.get(b.region or "", {}).get(g.type if g else "", ""), None))
    return out


def estimated_cells(case) -> tuple[float, Region | None]:
    """(estimated cells of all meshes, the region contributing most)."""
    regions = [r for r, b in zip(_body_regions(case), case.bodies) if r is not None and b.shape is not None]
    if case.geometry is not None:
        regions += _geometry_regions(case)
    if not regions:
        return 0.0, None
    return sum(r.cells for r in regions), max(regions, key=lambda r: r.cells)


def estimated_steps(case) -> tuple[float, str]:
    """(estimated explicit steps to time.end, the key path of the size that sets the step)."""
    worst, key = math.inf, ""
    implicit = case.mechanics.integrator == "implicit" and case.mechanics.implicit.dt is not None
    if implicit:  # no stability limit: the case's step
        worst, key = case.mechanics.implicit.dt, "mechanics.implicit.dt"
    for region, b in zip(_body_regions(case), case.bodies):
        if region is None or b.rigid or implicit:  # a rigid body has no stability limit
            continue
        m = case.materials[b.material]
        c_d = math.sqrt((m.bulk_modulus + 4.0 * m.shear_modulus / 3.0) / m.density)
        dt = case.time.cfl * STEP_LENGTH_FRACTION * region.h / c_d
        if dt < worst:
            worst, key = dt, region.key + (" (capped by the part's thickness)" if region.thinnest < region.size else "")
    if all_rigid(case) and case.case.kind == "coupled":  # no stability limit: a period of the source
        period = period_upper_bound(case)
        if period is not None:
            worst, key = period / (case.coupling.steps_per_period * case.coupling.n), "coupling.steps_per_period"
    if case.time.dt_max is not None:
        if case.time.dt_max < worst:
            key = "time.dt_max"
        worst = min(worst, case.time.dt_max)
    if not math.isfinite(worst):
        return 0.0, ""
    return case.time.end / worst, key


def _em_steps(case, steps: float) -> float:
    """GetDP runs of a coupled case with ``steps`` explicit steps (0 for other cases)."""
    if case.case.kind != "coupled" or case.coupling.load != "getdp":
        return 0.0
    if getattr(case.geometry, "type", None) == "geometry_3d":  # one getdp step per geometry.em_step, or per n
        return case.time.end / case.geometry.em_step if case.geometry.em_step else steps / case.coupling.n
    return steps / case.coupling.n


def check_resources(case) -> None:
    """Raise :class:`SchemaError` if the estimated cells or explicit steps exceed ``case.limits``."""
    lim = case.limits
    if getattr(case.geometry, "type", None) == "geometry_3d":
        return  # the file's mesh is known only once meshed: its cells, memory and steps are checked then
    cells, region = estimated_cells(case)
    if region is not None and cells > lim.max_cells:
        raise SchemaError(region.key, f"got {region.size:g} m: the meshes would have ~{cells:.3g} cells "
                          f"(this region ~{region.cells:.3g}), above limits.max_cells = {lim.max_cells:.3g}; "
                          "use a coarser size or raise limits.max_cells")
    steps, key = estimated_steps(case)
    if steps > lim.max_steps:
        raise SchemaError("time.end", f"got {case.time.end:g} s: ~{steps:.3g} explicit steps (stable step set by "
                          f"{key}), above limits.max_steps = {lim.max_steps:.3g}; shorten time.end, coarsen the "
                          "mesh or raise limits.max_steps")
    em = _em_steps(case, steps)
    if em > lim.max_em_steps:
        raise SchemaError("time.end", f"got {case.time.end:g} s: ~{em:.3g} EM steps (getdp runs; stable step set by "
                          f"{key}, coupling.n = {case.coupling.n}), above limits.max_em_steps = "
                          f"{lim.max_em_steps:.3g}; shorten time.end, coarsen the mesh, raise coupling.n or raise "
                          "limits.max_em_steps")


class LimitExceeded(ValueError):
    """A case exceeds ``[limits]`` once its meshes exist (e.g. a user deck's mesh): bad input, one line."""


def check_steps_of_meshes(case, stable_step: float) -> None:
    """After meshing: explicit steps and getdp runs at the meshes' actual stable step (s) against
    ``limits.max_steps`` and ``limits.max_em_steps``."""
    dt = stable_step if case.time.dt_max is None else min(stable_step, case.time.dt_max)
    steps = case.time.end / dt
    if steps > case.limits.max_steps:
        raise LimitExceeded(f"time.end: got {case.time.end:g} s: {steps:.3g} explicit steps at the meshes' stable step "
                            f"{dt:.3g} s, above limits.max_steps = {case.limits.max_steps:.3g}; shorten time.end, "
                            "coarsen the mesh or raise limits.max_steps")
    em = _em_steps(case, steps)
    if em > case.limits.max_em_steps:
        raise LimitExceeded(f"time.end: got {case.time.end:g} s: {em:.3g} EM steps (getdp runs) at the meshes' stable "
                            f"step {dt:.3g} s and coupling.n = {case.coupling.n}, above limits.max_em_steps = "
                            f"{case.limits.max_em_steps:.3g}; shorten time.end, coarsen the mesh or raise the limit")
