"""3D EM mesh of a racetrack coil forming a rectangular sheet into a die groove (issue 20, case b).

A quarter model (symmetry planes x = 0 and y = 0) or a half model (the plane y = 0 only), meshed by
gmsh's OpenCASCADE kernel into tetrahedra (MSH 2.2 for GetDP), with the physical ids of :mod:`.mesh3d`:

- the coil (stranded, id 101): ``turns`` racetrack turns of section ``turn_width`` x ``turn_height``
  (x by z) spaced by ``turn_gap``; their straight sides run along y at x = +-(``bend_radius`` + ...)
  for |y| <= ``half_straight``, their ends are half rings about (0, +-``half_straight``); the innermost
  turn's inner face lies at |x| = ``bend_radius``. The coil's top is at z = -``coil_gap``;
- the sheet (massive conductor 1, id 201; skin 401): the box |x| <= ``sheet_half_x``,
  |y| <= ``sheet_half_y``, 0 <= z <= ``sheet_thickness``, meshed as its bottom face extruded in
  ``sheet_layers`` layers (prisms split into tetrahedra: a thin conductor needs elements of a fraction
  of the skin depth through its thickness, which free tetrahedra cannot afford);
- the die (massive conductor 2, id 202; skin 402; or air when ``die_conductor`` is False): the box
  |x| <= ``die_half_x``, |y| <= ``die_half_y`` from ``die_gap`` above the sheet, ``die_height`` high,
  minus the groove: |x| in [``groove_x0``, ``groove_x1``] (default: over the winding, one
  ``turn_gap`` wider on each side), |y| <= ``groove_half_length`` (shorter than the straight sides:
  a groove of finite length), ``groove_depth`` deep from the die's lower face;
- air (1) in a sphere of radius ``air_radius`` about the origin, and a spherical shell (2) to
  ``shell_radius`` (transformation to infinity);
- symmetry planes (14, n x a = 0: every current crosses them at right angles, B is tangential), the
  outer sphere (12), the coil's faces on the planes as electrodes (501 in on y = 0, x > 0; 601 out on
  x = 0, or on y = 0, x < 0 in the half model) of the electrokinetic direction pre-solve.

All interfaces are conforming (one ``fragment``). :func:`pulseform.orchestrator.mesh.shared3d.conductor_submesh3d` cuts the sheet's or the
die's tetrahedra out of the EM mesh as a mechanical mesh that shares its nodes (``em_nodes``).
Lengths in m.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from .mesh import AIR, OUTER, SHELL, coil_tag, conductor_tag, gmsh_session
from .mesh3d import ELEC_IN_BASE, ELEC_OUT_BASE, SYM_A, Mesh3D, generate_tets, name_groups, read_mesh3d, skin_tag

logger = logging.getLogger(__name__)

#: the EM conductor numbers of the sheet and the die (physical 200 + k)
SHEET, DIE = 1, 2


@dataclass(frozen=True)
class RacetrackGroove:
    """Geometry and mesh sizes (m) of the racetrack / sheet / grooved die model (module docstring).

    ``h_coil``: element size in the turns; ``h_sheet``: in-plane size of the sheet over the coil's
    footprint (growing by ``grading`` per metre beyond it), ``sheet_layers`` elements through its
    thickness; ``h_die`` in the die, ``h_air`` at the sphere. :meth:`scaled` refines them all at once.
    """

    turns: int = 3
    half_straight: float = 25e-3
    bend_radius: float = 8e-3
    turn_width: float = 3e-3
    turn_height: float = 4e-3
    turn_gap: float = 1e-3
    coil_gap: float = 1e-3
    sheet_thickness: float = 1e-3
    sheet_half_x: float = 35e-3
    sheet_half_y: float = 55e-3
    die_gap: float = 0.5e-3
    die_height: float = 10e-3
    die_half_x: float = 35e-3
    die_half_y: float = 55e-3
    groove_x0: float | None = None
    groove_x1: float | None = None
    groove_half_length: float = 15e-3
    groove_depth: float = 4e-3
    air_radius: float = 0.12
    shell_radius: float | None = 0.15
    h_coil: float = 3e-3
    h_sheet: float = 2.5e-3
    sheet_layers: int = 4
    h_die: float = 4e-3
    h_air: float = 0.03
    grading: float = 0.4

    # --- derived dimensions -------------------------------------------------------------------
    @property
    def coil_outer(self) -> float:
        """Distance (m) of the outermost turn's outer face from the centre line x = 0."""
        return self.bend_radius + self.turns * self.turn_width + (self.turns - 1) * self.turn_gap

    def turn_x(self, i: int) -> tuple[float, float]:
        """(inner, outer) distance (m) of turn ``i`` (0-based, innermost first) from the centre line."""
        x0 = self.bend_radius + i * (self.turn_width + self.turn_gap)
        return x0, x0 + self.turn_width

    @property
    def coil_z(self) -> tuple[float, float]:
        """(bottom, top) z of the turns (m)."""
        return -self.coil_gap - self.turn_height, -self.coil_gap

    @property
    def die_z(self) -> tuple[float, float]:
        """(lower face, top face) z of the die (m)."""
        z0 = self.sheet_thickness + self.die_gap
        return z0, z0 + self.die_height

    @property
    def groove_x(self) -> tuple[float, float]:
        """(inner, outer) |x| of the groove (m): by default over the winding, ``turn_gap`` wider each side."""
        x0 = self.bend_radius - self.turn_gap if self.groove_x0 is None else self.groove_x0
        x1 = self.coil_outer + self.turn_gap if self.groove_x1 is None else self.groove_x1
        return x0, x1

    def scaled(self, factor: float) -> "RacetrackGroove":
        """The same geometry with every element size times ``factor`` and the sheet's layers divided by it;
        ``h_air`` (at the sphere) is only ever refined: a coarser faceted sphere would put the shell's
        tetrahedra inside ``air_radius``, where the shell transformation is undefined."""
        return replace(self, h_coil=self.h_coil * factor, h_sheet=self.h_sheet * factor, h_die=self.h_die * factor,
                       h_air=self.h_air * min(factor, 1.0), sheet_layers=max(1, round(self.sheet_layers / factor)))

    def validate(self) -> None:
        """Raise ValueError naming the first inconsistent dimension."""
        for f in fields(self):
            v = getattr(self, f.name)
            if v is None or f.name in ("grading",):
                continue
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{f.name} must be a positive number, got {v!r}")
        gx0, gx1 = self.groove_x
        checks = [
            (self.grading >= 0, "grading must be >= 0"),
            (self.sheet_half_x > self.coil_outer, "sheet_half_x must exceed the coil's outer half width"),
            (self.sheet_half_y > self.half_straight + self.coil_outer, "sheet_half_y must exceed the coil's half length"),
            (0 < gx0 < gx1 < self.die_half_x, "need 0 < groove_x0 < groove_x1 < die_half_x"),
            (self.groove_half_length < self.die_half_y, "groove_half_length must be below die_half_y"),
            (self.groove_depth < self.die_height, "groove_depth must be below die_height"),
            (self.shell_radius is None or self.shell_radius > self.air_radius, "shell_radius must exceed air_radius"),
        ]
        corner = math.hypot(max(self.sheet_half_x, self.die_half_x), max(self.sheet_half_y, self.die_half_y))
        checks.append((math.hypot(corner, max(self.die_z[1], -self.coil_z[0])) < self.air_radius,
                       "air_radius must enclose the coil, the sheet and the die"))
        for ok, text in checks:
            if not ok:
                raise ValueError(text)


def racetrack_groove_mesh(path: str | Path, g: RacetrackGroove = RacetrackGroove(), *, half: bool = False,
                          conductors: bool = True, die_conductor: bool = True) -> Mesh3D:
    """Mesh the model ``g`` (quarter; ``half``: the half y >= 0) and write it to ``path`` (MSH 2.2).

    ``conductors`` False meshes the same geometry with the sheet and the die as air (the coil's field
    alone); ``die_conductor`` False: the die is air, the sheet is the only conductor.
    Returns the :class:`~.mesh3d.Mesh3D` (``sector_deg`` 90 or 180, ``electrode_area`` of the coil).
    """
    g.validate()
    path = Path(path).resolve()
    sector = 180.0 if half else 90.0
    alpha = math.radians(sector)
    with gmsh_session("pulseform_racetrack") as gmsh:
        occ, model = gmsh.model.occ, gmsh.model

        def mirrored(tags: list[int]) -> list[int]:
            """In the half model, each volume fused with its mirror image about x = 0."""
            if not half:
                return tags
            out = []
            for t in tags:
                copy = occ.copy([(3, t)])
                occ.mirror(copy, 1, 0, 0, 0)
                fused = occ.fuse([(3, t)], copy)[0]
                out += [v for d, v in fused if d == 3]
            return out

        z0c, z1c = g.coil_z
        turns = []
        for i in range(g.turns):
            x0, x1 = g.turn_x(i)
            bar = occ.addBox(x0, 0, z0c, x1 - x0, g.half_straight, z1c - z0c)
            arc = occ.addCylinder(0, g.half_straight, z0c, 0, 0, z1c - z0c, x1, angle=math.pi / 2)
            hole = occ.addCylinder(0, g.half_straight, z0c, 0, 0, z1c - z0c, x0, angle=math.pi / 2)
            arc = occ.cut([(3, arc)], [(3, hole)])[0][0][1]
            turns.append(occ.fuse([(3, bar)], [(3, arc)])[0][0][1])
        turns = mirrored(turns)
        # the sheet: its lower face extruded in layers (structured through the thickness)
        xs = -g.sheet_half_x if half else 0.0
        face = occ.addRectangle(xs, 0, 0, g.sheet_half_x - xs, g.sheet_half_y)
        ext = occ.extrude([(2, face)], 0, 0, g.sheet_thickness, numElements=[g.sheet_layers], recombine=False)
        sheet = [t for d, t in ext if d == 3]
        # the die with its groove
        zd0, zd1 = g.die_z
        gx0, gx1 = g.groove_x
        die = occ.addBox(0, 0, zd0, g.die_half_x, g.die_half_y, zd1 - zd0)
        groove = occ.addBox(gx0, -g.die_half_y, zd0 - g.die_gap / 2, gx1 - gx0, g.die_half_y + g.groove_half_length,
                            g.groove_depth + g.die_gap / 2)
        die = [t for d, t in occ.cut([(3, die)], [(3, groove)])[0] if d == 3]
        die = mirrored(die)
        def part_sphere(r: float) -> int:
            """The sphere of radius r cut to y >= 0 (and x >= 0 in the quarter model): one flat face per
            plane (a sector sphere of angle pi has two half faces on y = 0 meeting on the z-axis, which
            would split the sheet's side face and break its extrusion)."""
            box = occ.addBox(-r if half else 0.0, 0, -r, 2 * r if half else r, r, 2 * r)
            return occ.intersect([(3, occ.addSphere(0, 0, 0, r))], [(3, box)])[0][0][1]

        objects = [(3, part_sphere(g.air_radius))]
        if g.shell_radius:
            objects.append((3, part_sphere(g.shell_radius)))
        groups = [turns, sheet, die]
        out, out_map = occ.fragment(objects, [(3, v) for grp in groups for v in grp])
        occ.synchronize()
        n_obj = len(objects)
        shell = ({t for d, t in out_map[1]} - {t for d, t in out_map[0]}) if g.shell_radius else set()
        parts, k = [], n_obj
        for grp in groups:
            parts.append(sorted({t for m in out_map[k:k + len(grp)] for d, t in m}))
            k += len(grp)
        coil_v, sheet_v, die_v = parts
        used = set(coil_v) | set(sheet_v) | set(die_v) | shell
        air_v = [t for d, t in out if d == 3 and t not in used]
        cond = []
        if conductors:
            cond.append(sheet_v)
            if die_conductor:
                cond.append(die_v)
        air_all = air_v + [t for grp in (sheet_v, die_v) if not any(grp is c for c in cond) for t in grp]
        model.addPhysicalGroup(3, sorted(air_all), AIR)
        if shell:
            model.addPhysicalGroup(3, sorted(shell), SHELL)
        model.addPhysicalGroup(3, coil_v, coil_tag(1))
        for k, vols in enumerate(cond, start=1):
            model.addPhysicalGroup(3, vols, conductor_tag(k))
            skin = model.getBoundary([(3, t) for t in vols], combined=True, oriented=False)
            model.addPhysicalGroup(2, [abs(t) for d, t in skin], skin_tag(k))
        _boundaries(gmsh, out, coil_v, alpha, g.shell_radius or g.air_radius)
        electrode_area = {1: float(sum(occ.getMass(2, t) for t in model.getEntitiesForPhysicalGroup(2, ELEC_IN_BASE + 1)))}
        _sizes(gmsh, g, half, air_v + sorted(shell), coil_v, sheet_v, die_v)
        name_groups(gmsh, ["sheet", "die"][:len(cond)])
        generate_tets(gmsh, path)
    mesh = read_mesh3d(path, sector, electrode_area)
    logger.info("racetrack mesh %s (%s): %d tetrahedra, %d nodes", path.name, "half" if half else "quarter",
                mesh.n_tets, mesh.n_nodes)
    return mesh


def _boundaries(gmsh, out, coil_v: list[int], alpha: float, r_out: float) -> None:
    """Physical groups of the symmetry planes (14), the outer sphere (12) and the coil's electrodes
    (501 in: on y = 0 with x > 0; 601 out: on the plane phi = alpha on its side of the axis)."""
    occ, model = gmsh.model.occ, gmsh.model
    n0 = np.array([0.0, 1.0, 0.0])
    n1 = np.array([-math.sin(alpha), math.cos(alpha), 0.0])
    e0, e1 = np.array([1.0, 0.0, 0.0]), np.array([math.cos(alpha), math.sin(alpha), 0.0])
    sym, outer = [], []
    for d, t in model.getBoundary([(3, v) for v in {t for d, t in out if d == 3}], combined=True, oriented=False):
        c = np.array(occ.getCenterOfMass(2, abs(t)))
        lo, hi = model.getParametrizationBounds(2, abs(t))
        nrm = np.array(model.getNormal(abs(t), [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])]))
        on_plane = any(abs(c @ n) < 1e-6 * r_out and abs(nrm @ n) > 1 - 1e-9 for n in (n0, n1))
        (sym if on_plane else outer).append(abs(t))
    model.addPhysicalGroup(2, sym, SYM_A)
    model.addPhysicalGroup(2, outer, OUTER)
    faces_in, faces_out = set(), set()
    for d, t in model.getBoundary([(3, v) for v in coil_v], combined=True, oriented=False):
        c = np.array(occ.getCenterOfMass(2, abs(t)))
        if abs(c @ n0) < 1e-6 * r_out and c @ e0 > 0:
            faces_in.add(abs(t))
        elif abs(c @ n1) < 1e-6 * r_out and c @ e1 > 0:
            faces_out.add(abs(t))
    if not faces_in or not faces_out:
        raise RuntimeError("racetrack mesh: the coil's electrode faces were not found on the symmetry planes")
    model.addPhysicalGroup(2, sorted(faces_in), ELEC_IN_BASE + 1)
    model.addPhysicalGroup(2, sorted(faces_out), ELEC_OUT_BASE + 1)


def _sizes(gmsh, g: RacetrackGroove, half: bool, air_v, coil_v, sheet_v, die_v) -> None:
    """Point sizes per part, and h_sheet + grading x (distance to the box over the coil's footprint from
    the coil's top to the die's lower face) as the background size."""
    model = gmsh.model
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", g.h_air)
    for tags, h in ((air_v, g.h_air), (die_v, g.h_die), (coil_v, g.h_coil), (sheet_v, g.h_sheet)):
        pts = model.getBoundary([(3, t) for t in tags], combined=False, oriented=False, recursive=True)
        model.mesh.setSize([p for p in pts if p[0] == 0], h)
    xm = g.coil_outer + g.turn_gap
    x_lo = -xm if half else 0.0
    ym, zlo, zhi = g.half_straight + xm, -g.coil_gap, g.die_z[0]
    d = [f"Max(Max({lo} - {v}, {v} - {hi}), 0)" for v, lo, hi in (("x", x_lo, xm), ("y", 0.0, ym), ("z", zlo, zhi))]
    near = model.mesh.field.add("MathEval")
    model.mesh.field.setString(near, "F", f"{g.h_sheet} + {g.grading} * Sqrt(({d[0]})^2 + ({d[1]})^2 + ({d[2]})^2)")
    model.mesh.field.setAsBackgroundMesh(near)


__all__ = ["RacetrackGroove", "racetrack_groove_mesh", "SHEET", "DIE"]
