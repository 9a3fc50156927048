"""The case file model: typed, frozen dataclasses in SI units, validated from TOML.

Every key states its unit and allowed range through :func:`~pulseform.orchestrator.case.schema.spec`;
the case-file reference page (docs/reference/case-file.md) is generated from these declarations
(``python -m pulseform.orchestrator.case.reference``) and a test keeps the two in step.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Literal

from .analysis_names import ANALYSES, ANALYSIS_PAIRS
from .em_table import EM, CapacitorBank, DampedSineCurrent
from .em_model import (FlatCoilSheet, Geometry, OuterTube, PlanarCoilBlankDie,
                      SheetDie, SolenoidTube)
from .em_applied import check_applied_field
from .forming_limit import FormingLimitTable
from .magnetic import check_magnetic_em
from .materials import CowperSymondsTable, JohnsonCookTable, MaterialTable
from .em_sources import check_coils
from .guards import check_resources
from .names import check_file_name, check_folder_name, folder_name
from .parts import (Box, BodyTable, ContactPair, EndStopTable, FixedBoundary, Polygon, Rectangle, RigidWall, Shape,
                    Vec, Vec2, rigid_moves, validate_rigid)
from .rigid_steps import check_rigid_time_scale
from .schema import SchemaError, spec
from .springback import SpringbackTable
from .stages import StageTable, check_adaptive, check_implicit_reach, check_stages
from .solid3d import SolidBox, SolidCylinder, SymmetryPlane, validate_dimension

__all__ = ["Box", "Rectangle", "Polygon", "SolidBox", "SolidCylinder", "SymmetryPlane", "Shape", "CowperSymondsTable", "JohnsonCookTable", "FormingLimitTable", "MaterialTable", "FixedBoundary",
           "EndStopTable", "BodyTable", "ContactPair", "RigidWall", "PulseSin2", "PulseExp", "Load", "CaseInfo", "TimeControl",
           "MechanicsTable", "Coupling", "Probe", "Output", "Limits", "Case", "EM", "CapacitorBank", "DampedSineCurrent",
           "FlatCoilSheet", "Geometry", "SolenoidTube", "SheetDie", "OuterTube", "PlanarCoilBlankDie"]

# --------------------------------------------------------------------------- loads
@dataclass(frozen=True, kw_only=True)
class _PulseWindow:
    """What every pressure pulse has: where it acts and when."""

    body: str = spec(doc="loaded body")
    surface: Box = spec(doc="box selecting the loaded boundary facets")
    amplitude: float = spec(unit="Pa", gt=0.0, doc="peak pressure scale (P0 or p0)")
    t_start: float = spec(0.0, unit="s", ge=0.0, doc="pulse start")
    t_end: float = spec(unit="s", gt=0.0, doc="pulse end (pressure is zero afterwards)")
    trigger: Literal["time", "rest"] = spec(
        "time", doc="'rest': start (with the same window length) once the previous pulse has ended and "
                    "the loaded body's max speed is below rest_speed")
    rest_speed: float = spec(0.5, unit="m/s", gt=0.0, doc="speed below which the body counts as at rest")
    rest_damping: float = spec(0.0, unit="1/s", ge=0.0,
                               doc="mass damping α on every body while this 'rest' pulse waits (after the previous "
                                   "window): dynamic relaxation standing in for the time between discharges")

    def validate(self, path: str) -> None:
        _check_window(self.t_start, self.t_end, path)


@dataclass(frozen=True, kw_only=True)
class PulseSin2(_PulseWindow):
    """Pressure pulse, paper eq. (7): P = P0 e^(−βt) sin²(ωt), t measured from ``t_start``."""

    type: Literal["pulse_sin2"] = spec(doc="load kind")
    beta: float = spec(unit="1/s", ge=0.0, doc="decay rate β")
    omega: float = spec(unit="rad/s", gt=0.0, doc="angular frequency ω")


@dataclass(frozen=True, kw_only=True)
class PulseExp(_PulseWindow):
    """Pressure pulse, paper eq. (8): p = p0 e^(−t/T), t measured from ``t_start``."""

    type: Literal["pulse_exp"] = spec(doc="load kind")
    decay_time: float = spec(unit="s", gt=0.0, doc="T")


def _check_window(t_start: float, t_end: float, path: str) -> None:
    if t_end <= t_start:
        raise SchemaError(f"{path}.t_end", f"got {t_end:g}; must be > t_start = {t_start:g} (s)")


Load = PulseSin2 | PulseExp


# --------------------------------------------------------------------------- run control
@dataclass(frozen=True, kw_only=True)
class CaseInfo:
    """What the case is."""

    name: str = spec(doc="case name, in any language: 1 to 100 bytes (UTF-8) of letters of any script, digits, spaces, "
                         "'.', '_', '-', not starting with a space, '.' or '-' nor ending with a space or '.' (it "
                         "names the default results folder results/<name>; Unicode NFC-normalised)")
    kind: Literal["mechanics", "coupled"] = spec(
        "mechanics", doc="'mechanics': explicit solver with pressure loads; 'coupled': GetDP + explicit solver")
    description: str = spec("", doc="free text")

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", folder_name(self.name))  # one spelling, one folder

    def validate(self, path: str) -> None:
        check_folder_name(self.name, f"{path}.name", "results/<name>")


@dataclass(frozen=True, kw_only=True)
class TimeControl:
    """Time stepping of the explicit mechanics."""

    end: float = spec(unit="s", gt=0.0, doc="simulated end time")
    cfl: float = spec(0.5, unit="-", gt=0.0, le=1.0, doc="safety factor on the stable time step")
    dt_max: float | None = spec(None, unit="s", gt=0.0, doc="upper bound on the mechanical step")


@dataclass(frozen=True, kw_only=True)
class ImplicitTable:
    """The implicit integrator's step and Newton iterations (``mechanics.integrator = "implicit"``)."""

    dt: float | None = spec(None, unit="s", gt=0.0,
                            doc="the implicit mechanical step (required with integrator = 'implicit'; no stability "
                                "limit: accuracy decides, e.g. 1/40 of the shortest period of interest, period error "
                                "(2π/40)²/12 = 0.2 %)")
    scheme: Literal["trapezoidal", "hht", "static"] = spec(
        "trapezoidal", doc="'trapezoidal': Newmark average acceleration (no numerical damping); 'hht': HHT-α (damps "
                           "the modes the step does not resolve); 'static': equilibrium steps without inertia "
                           "(quasi-static loading; every body must be supported against rigid motion)")
    alpha: float = spec(-0.1, unit="-", ge=-1.0 / 3.0, le=0.0,
                        doc="HHT's α (scheme = 'hht' only): 0 is the trapezoidal rule, −1/3 the most damping "
                            "(spectral radius (1 + α)/(1 − α) at high frequency)")
    newton_tol: float = spec(1e-8, unit="-", gt=0.0, lt=1.0,
                             doc="Newton stops when the residual is below this fraction of the largest of the "
                                 "inertia, internal (reactions included) and external force norms")
    newton_max: int = spec(25, unit="-", ge=1, doc="most Newton iterations per step")
    max_cuts: int = spec(6, unit="-", ge=0, le=30,
                         doc="a step that does not converge is retried as two half steps, at most this many times "
                             "in a row; then the run stops in one line with the results so far")
    adaptive: bool = spec(False, doc="choose each step from a local error estimate (Zienkiewicz & Xie: dt²(β − 1/6)"
                                     "(a₁ − a₀)): dt is the first step, time.dt_max the largest (set it below the "
                                     "shortest load feature: a step longer than a pulse steps over it); not with "
                                     "scheme = 'static'; coupled runs: coupling.n = 1, not coupling.adaptive")
    error_tol: float = spec(1e-3, unit="-", gt=0.0, lt=1.0,
                            doc="adaptive: the accepted local error per step relative to the largest displacement "
                                "so far (a free vibration: (ω dt)³/12 per step)")
    error_atol: float = spec(1e-9, unit="m", ge=0.0,
                             doc="adaptive: the accepted local error per step added to error_tol times the "
                                 "displacement (root mean square over the nodes; keeps a start from rest from "
                                 "taking ever shorter steps)")
    dt_min: float | None = spec(None, unit="s", gt=0.0,
                                doc="adaptive: the shortest step (accepted whatever its error; default dt/1000)")


@dataclass(frozen=True, kw_only=True)
class MechanicsTable:
    """Mechanical model options."""

    formulation: Literal["plane_stress", "plane_strain", "axisymmetric", "3d"] = spec(
        "plane_strain", doc="kinematics: 2D (triangles), or '3d' (tetrahedra: mechanics cases, and coupled cases "
            "from a 3D geometry file, geometry.type = 'geometry_3d')")
    thickness: float = spec(1.0, unit="m", gt=0.0, doc="out-of-plane thickness (planar only)")
    bulk_viscosity: bool = spec(True, doc="linear + quadratic artificial bulk viscosity")
    bulk_viscosity_linear: float = spec(0.06, unit="-", ge=0.0, doc="linear coefficient")
    bulk_viscosity_quadratic: float = spec(1.2, unit="-", ge=0.0, doc="quadratic coefficient")
    mass_damping: float = spec(0.0, unit="1/s", ge=0.0,
                               doc="mass-proportional damping α: force −α m v on every node (dynamic relaxation)")
    mass_damping_until: float = spec(math.inf, unit="s", gt=0.0, doc="damping acts for t < this time")
    mass_damping_from: float = spec(0.0, unit="s", ge=0.0, doc="damping acts for t >= this time (final relaxation)")
    kinetic_damping_until: float = spec(
        0.0, unit="s", ge=0.0,
        doc="kinetic damping (dynamic relaxation) for t < this time: a body's velocities are set to zero "
            "whenever its kinetic energy has passed a peak (quasi-static loading; 0: off)")
    mass_scaling_dt: float | None = spec(
        None, unit="s", gt=0.0,
        doc="selective mass scaling for quasi-static explicit 3D runs of ten-node bodies (with kinetic or mass "
            "damping): every cell whose critical step is below this one gets the density that brings it there; "
            "the added mass is logged. The static state dynamic relaxation reaches does not depend on the mass; "
            "a pulse's dynamics would: mechanics-only cases only (docs/mechanics.md, Selective mass scaling)")
    gravity: Vec2 = spec((0.0, 0.0), unit="m/s^2", doc="acceleration of gravity on the rigid bodies, e.g. "
                         "[0, -9.81] (deformable bodies: not applied)")
    integrator: Literal["explicit", "implicit"] = spec(
        "explicit", doc="'explicit': central differences at the stable step (forming pulses, µs); 'implicit': "
                        "Newmark / HHT-α / static steps of mechanics.implicit.dt with Newton iterations (slow "
                        "motions, ms to s; contact (no friction or viscosity) and walls, rigid bodies (not in static steps); coupled runs: coupling.n = 1, and "
                        "coupling.iterate = true for steps near the parts' periods; docs/mechanics.md)")
    implicit: ImplicitTable = spec(ImplicitTable(), doc="[mechanics.implicit] table")
    threads: int = spec(1, unit="-", ge=1,
                        doc="threads of the element kernel in serial GetDP-coupled runs and in 3D runs (results do not "
                            "depend on it; worth it from ~10^4 cells in 2D, from 65 536 tetrahedra in a 3D body, on cores "
                            "no other process uses; 2D mechanics-only pulse runs keep one thread)")

    def validate(self, path: str) -> None:
        if self.mass_scaling_dt is not None and self.formulation != "3d":
            raise SchemaError(f"{path}.mass_scaling_dt", f"given with formulation = {self.formulation!r}; selective mass "
                              "scaling is done for ten-node bodies of 3D cases: formulation = '3d'")
        cores = os.cpu_count() or 1
        if self.threads > cores:
            raise SchemaError(f"{path}.threads", f"got {self.threads}; this machine has {cores} cores: 1 to {cores}")
        if self.integrator == "implicit":
            if self.implicit.dt is None:
                raise SchemaError(f"{path}.implicit.dt", "missing; integrator = 'implicit' needs its step (s), "
                                  "e.g. 1/40 of the shortest period of interest")
            if self.kinetic_damping_until > 0.0:
                raise SchemaError(f"{path}.kinetic_damping_until", "kinetic damping is the explicit integrator's; "
                                  "with integrator = 'implicit' use implicit.scheme = 'static' (or 'hht') instead")
            im = self.implicit
            if im.adaptive and im.scheme == "static":
                raise SchemaError(f"{path}.implicit.adaptive", "adaptive steps need scheme = 'trapezoidal' or 'hht' "
                                  "(static steps have no time-integration error to estimate)")
            if im.adaptive and im.dt_min is not None and im.dt_min > im.dt:
                raise SchemaError(f"{path}.implicit.dt_min", f"got {im.dt_min!r} s; the shortest adaptive step must "
                                  f"not exceed the first, implicit.dt = {im.dt!r} s")


#: default EM steps per period of an all-rigid run's source (docs/mechanics.md: the jumping ring's first peak
#: +6.0 / +1.4 / +0.57 / +0.27 % at 20 / 40 / 80 / 160 steps against 320; wall 8 / 15 / 24 / 51 / 115 s for 0.3 s)
STEPS_PER_PERIOD = 80


@dataclass(frozen=True, kw_only=True)
class Coupling:
    """Staggered EM–mechanics coupling (used by coupled cases)."""

    n: int = spec(10, unit="-", ge=1, doc="mechanical steps per EM step (subcycling)")
    em_substeps: int = spec(1, unit="-", ge=1,
                            doc="implicit-Euler sub-steps inside each EM step (one getdp run; mean force is held)")
    load: Literal["getdp", "pressure"] = spec(
        "getdp", doc="coupled cases: GetDP eddy-current forces, or the [[loads]] pressure pulses on the "
                     "same workpiece mesh through the same loop (for comparisons)")
    adaptive: bool = spec(False, doc="adapt n from the change of the force resultant between EM steps")
    n_min: int = spec(1, unit="-", ge=1, doc="smallest n when adaptive")
    n_max: int = spec(1000, unit="-", ge=1, doc="largest n when adaptive")
    adapt_tol: float = spec(0.05, unit="-", gt=0.0, doc="relative resultant change that halves n (a quarter doubles it)")
    iterate: bool = spec(False, doc="repeat each EM step on its end geometry until force and motion settle")
    iterate_tol: float = spec(1e-3, unit="-", gt=0.0, doc="relative change that ends the iterations")
    iterate_max: int = spec(10, unit="-", ge=1, doc="most iterations per EM step")
    steps_per_period: int = spec(STEPS_PER_PERIOD, unit="-", ge=4, doc="EM steps per period of the source when "
                                 "every body is rigid (no stability limit): period 2π/ω of a prescribed current, "
                                 "2π√((L_coil + L_ext) C) of a bank (L_coil from the turns' geometry); the "
                                 "mechanical step is that EM step / n, capped by time.dt_max. 80 puts the jumping "
                                 "ring's first peak 0.6 % above that of 320 steps (40: 1.4 %, 20: 6 %)")

    def validate(self, path: str) -> None:
        if not self.n_min <= self.n <= self.n_max:
            raise SchemaError(f"{path}.n", f"got {self.n}; must lie in [n_min, n_max] = [{self.n_min}, {self.n_max}]")


@dataclass(frozen=True, kw_only=True)
class Probe:
    """A point whose history goes into history.csv."""

    name: str = spec(doc="column prefix in history.csv and plots/<name>_<quantity>.png: 1 to 100 letters, digits, ._-")
    body: str = spec(doc="body the point belongs to")
    point: Vec = spec(unit="m", doc="initial (material) position ([x, y, z] in 3D)")
    quantity: Literal["contact_pressure", "wall_pressure", "von_mises", "velocity", "displacement"] = spec(
        doc="recorded quantity (Pa, Pa, Pa, m/s, m); wall_pressure: reaction per area of the first wall")


@dataclass(frozen=True, kw_only=True)
class Output:
    """What is written to the results folder."""

    field_interval: float | None = spec(None, unit="s", gt=0.0,
                                        doc="XDMF field output interval (default: end / 20, made a whole number of EM steps where the "
                                            "case sets the EM step: every body rigid, or time.dt_max below the stable step)")
    history_every: int = spec(1, unit="-", ge=1, doc="history.csv row every N EM steps (mechanics cases: mechanical steps), plus one at each output time")
    plots: bool = spec(True, doc="write plots/*.png")


@dataclass(frozen=True, kw_only=True)
class Limits:
    """Guards against runs that would exhaust the machine (orchestrator/case/guards.py says how they are estimated)."""

    max_cells: float = spec(2e6, unit="-", gt=0.0, magnitude=(1.0, 1e12),
                            doc="most mesh cells (estimated from areas / mesh size² before any meshing)")
    max_steps: float = spec(5e7, unit="-", gt=0.0, magnitude=(1.0, 1e12),
                            doc="most explicit steps (estimated: time.end / stable step of the undeformed mesh)")
    max_em_steps: float = spec(5e4, unit="-", gt=0.0, magnitude=(1.0, 1e12),
                               doc="most EM steps of a GetDP-coupled case (getdp runs; estimated: explicit steps / "
                                   "coupling.n)")
    gmsh_time_limit_s: float = spec(600.0, unit="s", gt=0.0, magnitude=(1e-3, 1e6),
                                    doc="wall-time limit of one gmsh run (built-in geometry, remesh, user .geo)")
    getdp_time_limit_s: float = spec(600.0, unit="s", gt=0.0, magnitude=(1e-3, 1e6),
                                     doc="wall-time limit of one getdp run (one EM step)")


@dataclass(frozen=True, kw_only=True)
class Case:
    """A whole case file."""

    case: CaseInfo = spec(doc="[case] table")
    time: TimeControl = spec(doc="[time] table")
    materials: dict[str, MaterialTable] = spec(doc="[materials.<name>] tables")
    bodies: tuple[BodyTable, ...] = spec(doc="[[bodies]] list")
    mechanics: MechanicsTable = spec(MechanicsTable(), doc="[mechanics] table")
    contact: tuple[ContactPair, ...] = spec((), doc="[[contact]] pairs")
    walls: tuple[RigidWall, ...] = spec((), doc="[[walls]] rigid half-spaces")
    symmetry: tuple[SymmetryPlane, ...] = spec((), doc="[[symmetry]] planes of a 3D model (a quarter, a sector)")
    loads: tuple[Load, ...] = spec((), doc="[[loads]] surface pressure pulses")
    coupling: Coupling = spec(Coupling(), doc="[coupling] table")
    geometry: Geometry | None = spec(None, doc="[geometry] EM setup (coupled cases)")
    em: EM | None = spec(None, doc="[em] table (coupled cases)")
    probes: tuple[Probe, ...] = spec((), doc="[[probes]] point histories")
    output: Output = spec(Output(), doc="[output] table")
    analysis: tuple[str, ...] = spec((), doc="case-specific analyses (extra history columns, metrics, plots)")
    springback: SpringbackTable | None = spec(None, doc="[springback] after the run (fields/springback/<name>_<body>, "
                                              "<body>_springback_* metrics; docs/mechanics.md)")
    stages: tuple[StageTable, ...] = spec((), doc="[[stages]] a chained run: quasi-static preform, pulses, springbacks "
                                          "on one time axis, one history (docs/guide/case-files.md)")
    limits: Limits = spec(Limits(), doc="[limits] resource guards")

    def validate(self, path: str) -> None:
        validate_dimension(self)
        if not self.materials:
            raise SchemaError("materials", "no material defined; add a [materials.<name>] table")
        if not self.bodies:
            raise SchemaError("bodies", "no body defined; add at least one [[bodies]] table")
        names: list[str] = []
        for i, b in enumerate(self.bodies):
            if b.name in names:
                raise SchemaError(f"bodies[{i}].name", f"got {b.name!r}; body names must be unique")
            names.append(b.name)
            if b.material not in self.materials:
                raise SchemaError(f"bodies[{i}].material",
                                  f"got {b.material!r}; allowed: {_choices(self.materials)}")
        for i, c in enumerate(self.contact):
            for role in ("slave", "master"):
                if getattr(c, role) not in names:
                    raise SchemaError(f"contact[{i}].{role}",
                                      f"got {getattr(c, role)!r}; allowed: {_choices(names)}")
        for i, w in enumerate(self.walls):
            for j, b in enumerate(w.bodies):
                if b not in names:
                    raise SchemaError(f"walls[{i}].bodies[{j}]", f"got {b!r}; allowed: {_choices(names)}")
        for i, ld in enumerate(self.loads):
            if ld.body not in names:
                raise SchemaError(f"loads[{i}].body", f"got {ld.body!r}; allowed: {_choices(names)}")
        self._validate_coupled()
        self._validate_integrator()
        check_stages(self)
        if self.springback is not None:
            for i, n in enumerate(self.springback.bodies):
                if n not in names or self.body(n).rigid:
                    raise SchemaError(f"springback.bodies[{i}]", f"got {n!r}; allowed: "
                                      f"{_choices([b.name for b in self.bodies if not b.rigid])}")
        for i, name in enumerate(self.analysis):
            if name not in ANALYSES:
                raise SchemaError(f"analysis[{i}]", f"got {name!r}; allowed: {_choices(sorted(ANALYSES))}")
            slave, master = ANALYSIS_PAIRS[name]
            if not any(c.slave == slave and c.master == master for c in self.contact) or \
                    any(b.rigid for b in self.bodies if b.name in (slave, master)):
                raise SchemaError(f"analysis[{i}]", f"got {name!r}; it reads the deformable bodies {slave!r} and "
                                  f"{master!r} and their [[contact]] pair (slave {slave!r}, master {master!r}): "
                                  "give them, or remove the analysis")
        for i, ld in enumerate(self.loads):
            if ld.trigger == "rest" and i == 0:
                raise SchemaError(f"loads[{i}].trigger", "the first pulse cannot wait for rest; use 'time'")
        probe_names: list[str] = []
        for i, p in enumerate(self.probes):
            if p.body not in names:
                raise SchemaError(f"probes[{i}].body", f"got {p.body!r}; allowed: {_choices(names)}")
            check_file_name(p.name, f"probes[{i}].name", "history.csv columns and plots/<name>_<quantity>.png")
            if p.name in probe_names:
                raise SchemaError(f"probes[{i}].name", f"got {p.name!r}; probe names must be unique")
            probe_names.append(p.name)
        if self.mechanics.formulation == "axisymmetric":
            for i, b in enumerate(self.bodies):
                if b.shape is None:
                    continue
                xmin = _shape_xmin(b.shape)
                if xmin < 0.0:
                    raise SchemaError(f"bodies[{i}].shape",
                                      f"reaches r = {xmin:g} m; axisymmetric bodies need r >= 0")
        if self.output.field_interval is not None and self.output.field_interval > self.time.end:
            raise SchemaError("output.field_interval",
                              f"got {self.output.field_interval:g}; must be <= time.end = {self.time.end:g} (s)")
        check_resources(self)

    def _validate_coupled(self) -> None:
        regions = [b.region for b in self.bodies if b.region is not None]
        file3d = getattr(self.geometry, "type", None) == "geometry_3d"  # .geometry3d (validate_dimension)
        if self.case.kind == "coupled" and self.em is not None:
            _check_temperature_em(self)
            check_magnetic_em(self)
        if self.case.kind == "coupled" and not file3d:
            for key in ("geometry", "em"):
                if getattr(self, key) is None:
                    raise SchemaError(key, f"missing required table [{key}] for case.kind = 'coupled'")
            if "workpiece" not in regions:
                raise SchemaError("bodies", "a coupled case needs a body with region = 'workpiece'")
            roles = self.geometry.conductor_roles()
            for i, b in enumerate(self.bodies):
                if b.region is not None and b.region not in roles:
                    raise SchemaError(f"bodies[{i}].region", f"got {b.region!r}; the {self.geometry.type} geometry "
                                      f"has the conductor regions {_choices(roles)}")
            for role in roles:
                if role not in regions:
                    raise SchemaError("bodies", f"the geometry's conductor region {role!r} needs a body with "
                                      f"region = {role!r} (its material gives the conductivity)")
            if self.coupling.load == "pressure" and not self.loads:
                raise SchemaError("loads", "coupling.load = 'pressure' needs at least one [[loads]] pulse")
            if self.coupling.load == "getdp" and self.loads:
                raise SchemaError("loads", "pressure [[loads]] are used only with coupling.load = 'pressure'; "
                                  "remove them or set coupling.load = 'pressure'")
            if self.coupling.load == "getdp":
                _refuse_damping(self.mechanics)
            if self.geometry.planar and self.mechanics.formulation == "axisymmetric":
                raise SchemaError("mechanics.formulation", f"got 'axisymmetric'; the {self.geometry.type} "
                                  "geometry is planar: use 'plane_strain' or 'plane_stress'")
            if not self.geometry.planar and self.mechanics.formulation not in ("axisymmetric", "3d"):
                raise SchemaError("mechanics.formulation", f"got {self.mechanics.formulation!r}; the "
                                  f"{self.geometry.type} geometry is axisymmetric: use 'axisymmetric'")
            if self.em.time_scheme == "bdf2" and self.coupling.em_substeps != 1:
                raise SchemaError("coupling.em_substeps", f"got {self.coupling.em_substeps}; em.time_scheme = "
                                  "'bdf2' takes one step per getdp run: use 1 (and a smaller coupling.n)")
            template = getattr(self.geometry, "library", None) == "getdp_template"
            if not any((self.em.circuit, self.em.current, self.em.sources)):
                if not template:
                    raise SchemaError("em.circuit", "the geometry's coil needs a source: give em.circuit (a capacitor "
                                      "bank), em.current or [[em.sources]] with [[em.coils]]")
                if self.geometry.coils:  # the deck's own source: one coil (orchestrator/em/deck_sources.py)
                    raise SchemaError("em.sources", "the coils of [[geometry.coils]] need their sources in the case: "
                                      "give [[em.sources]] with [[em.coils]] (a template deck's own bank or current "
                                      "is read for the one coil of geometry.regions.coil)")
            check_coils(self)
            check_applied_field(self)
            if getattr(self.geometry, "library", None) == "getdp_template" and self.em.getdp_process == "persistent":
                raise SchemaError("em.getdp_process", "got 'persistent'; a deck on GetDP's template runs a getdp "
                                  "process per EM step (its state carried by -restart): set em.getdp_process = "
                                  "'per_step' or 'auto'")
            if self.geometry.planar and self.em.circuit is not None:
                raise SchemaError("em.circuit", "planar geometries are per metre of depth: give a prescribed "
                                  "em.current (a capacitor bank would need the coil's length)")
        elif regions and self.case.kind != "coupled":
            i = next(i for i, b in enumerate(self.bodies) if b.region is not None)
            raise SchemaError(f"bodies[{i}].region", "regions exist only in coupled cases; give a shape")
        validate_rigid(self)
        check_rigid_time_scale(self)
        if len(set(regions)) != len(regions):
            raise SchemaError("bodies", "each geometry region may be used by one body only")

    def _validate_integrator(self) -> None:
        """The implicit integrator's present reach (:func:`.stages.check_implicit_reach`)."""
        if self.mechanics.integrator == "implicit":
            check_implicit_reach(self)
            check_adaptive(self)

    def rigid_moves(self, b: BodyTable) -> tuple[int, ...]:
        """The free translation components of rigid body ``b`` (see :func:`.parts.rigid_moves`)."""
        return rigid_moves(b, self.mechanics.formulation, self.symmetry)

    def body(self, name: str) -> BodyTable:
        """The body called ``name``."""
        return next(b for b in self.bodies if b.name == name)


def _refuse_damping(mo: MechanicsTable) -> None:
    """Damping acts through the pressure-pulse load provider; a GetDP-coupled run has none."""
    for key in ("mass_damping", "kinetic_damping_until"):
        if getattr(mo, key) > 0.0:
            raise SchemaError(f"mechanics.{key}", "damping acts with pressure loads only (case.kind = 'mechanics' "
                              "or coupling.load = 'pressure'); a GetDP-coupled run would ignore it: remove it")


def _shape_xmin(shape: Shape) -> float:
    if isinstance(shape, Rectangle):
        return shape.origin[0]
    return min(p[0] for p in shape.points)


def _choices(names) -> str:
    return ", ".join(repr(n) for n in names) if names else "(none defined)"


def _check_temperature_em(case: "Case") -> None:
    """A conductivity that follows temperature and repeated shots: on the built-in deck, shots with deformable bodies
    only (one line naming the key otherwise)."""
    em = case.em
    curves = [f"materials.{b.material}.conductivity_curve" for b in case.bodies
              if case.materials[b.material].conductivity_curve is not None]
    if em.coil_conductivity_curve is not None:
        curves.append("em.coil_conductivity_curve")
    keys = curves + (["em.shots"] if em.shots is not None else [])
    if not keys:
        return
    if case.geometry.type == "user_deck":
        raise SchemaError(keys[0], "needs the built-in GetDP deck (a user_deck geometry has its own conductivities)")
    if em.shots is not None and any(b.rigid for b in case.bodies):
        raise SchemaError("em.shots", "repeated shots carry deformable bodies only: a rigid body's motion would "
                                      "restart; make the bodies deformable or drop em.shots")

