"""3D transient eddy currents with GetDP: the model, one getdp run per transient, its results.

``decks/em_case3d.pro`` + ``decks/Lib_PulsedForming3D.pro`` (edge elements, tree-cotree gauge in
the non-conducting region, a* in the massive conductors, stranded coils with a direction field,
prescribed currents or the capacitor bank, symmetry planes, shell); meshes from :mod:`.mesh3d`.

::

    model = EM3DModel(coils=[Coil3D(turns=5, waveform=DampedSine(20e3, 1e4, 1e5))],
                      conductors=[Conductor(3.5e7)], shell=(0.1, 0.125), sector_deg=mesh.sector_deg)
    res = solve_transient3d(model, mesh, t_end=30e-6, n_steps=60, work_dir=run_dir)
    res.conductor_force[:, 0, 2] * model.symmetry_factor   # F_z of the whole axisymmetric device (N)
"""
from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from .files import read_element_table, read_table
from .mesh import AIR, COIL_BASE, CONDUCTOR_BASE, CORE_BASE, OUTER, SHELL, coil_tag
from .applied_field import AppliedField, planes_of_faces
from .mesh3d import (CUT_BASE, ELEC_IN_BASE, ELEC_OUT_BASE, SKIN_BASE, SYM_A, SYM_H, Mesh3D, cut_orientation, cut_tag,
                     physical_surface_area, read_msh22_triangles, skin_tag)
from .bh_curve import MagneticRegions, model_magnetic, read_newton
from .conductivity import ConductivityLaw, has_laws, law_from_dict
from .model import Circuit, Conductor, CurrentTable, DampedSine, MagneticCore, table_lines
from .deck_numbers import body_numbers, waveform_numbers
from .runner import RunInfo, run_getdp

logger = logging.getLogger(__name__)

DECK3D = Path(__file__).resolve().parent / "decks" / "em_case3d.pro"
RESOLUTION3D = "EM_Transient3D"
#: direct solver of the 3D runs (PETSc options on getdp's command line): UMFPACK with METIS's nested dissection,
#: measured on GetDP's own 3D system (bench/solve_floor.py's matrix, 19,595 unknowns): factorisation 0.38 s and a
#: solve 5.3 ms vs MUMPS (PORD: Debian's MUMPS has neither METIS nor SCOTCH) 0.39 s and 7 ms. Serial only: a getdp
#: under ``mpirun`` takes MUMPS (MUMPS_PETSC_ARGS_3D; UMFPACK is sequential)
DEFAULT_PETSC_ARGS_3D = ("-ksp_type", "preonly", "-pc_type", "lu", "-pc_factor_mat_solver_type", "umfpack",
                         "-mat_umfpack_ordering", "METIS")
#: the parallel direct solver of a 3D getdp under ``mpirun``
MUMPS_PETSC_ARGS_3D = ("-ksp_type", "preonly", "-pc_type", "lu", "-pc_factor_mat_solver_type", "mumps")


#: ``Coil3D.direction`` -> the deck's ``Coil_DirType``
DIRECTIONS = {"azimuthal": 0, "deck": 1, "electrokinetic": 2, "cut": 3}


@dataclass
class Coil3D:
    """A stranded coil (physical region 100+k): ``turns`` in series, uniform current density.

    ``direction``: ``"azimuthal"`` (about the z-parallel axis through ``axis`` = (x, y), m: ring or
    circular coils; a positive current flows along +e_phi), ``"electrokinetic"`` (-grad v / |grad v|
    of a pre-solve in the coil, v = 1 on its electrode 500+k, 0 on 600+k: the current enters at 500+k)
    , ``"cut"`` (a CLOSED coil: -grad v / |grad v| of a pre-solve in which v jumps by 1 across the cut
    surface 700+k, a surface spanning the coil's whole cross-section, conforming with its tetrahedra)
    or ``"deck"`` (the case deck defines ``CoilDir[Coil~{k}]``). ``section``: conductor cross-section
    of all turns (m^2); None: from the mesh -- azimuthal: sum over the coil's tetrahedra of
    V / (r alpha) (the ring's meridian section, alpha the sector angle); electrokinetic: the area of
    the electrode where the current enters (``Mesh3D.electrode_area``); cut: the area of the cut
    (:func:`~.mesh3d.physical_surface_area` of 700+k). ``cut_normal`` (direction ``"cut"`` only): the
    current (times ``sign``) crosses the cut along this vector (x, y, z), e.g. (0, 1, 0) for a ring about
    +z cut by the half-plane y = 0, x > 0 and a current along +e_phi; None: along the normal
    (x1 - x0) x (x2 - x0) of the cut's triangles as written in the mesh file (:func:`~.mesh3d.cut_orientation`).
    ``waveform`` without a circuit (A); ``sign`` +1 or -1;
    ``name`` names its history columns when a model has several coils.
    ``conductivity_law``, ``initial_temperature`` (K), ``density`` (kg/m³), ``heat_capacity`` (J/(kg·K)): σ(T) of a
    lumped coil, as :class:`~.model.Coil`'s (:mod:`.conductivity`; m c_p and the Joule heat of the modelled sector,
    so the same temperature as the whole coil's).
    """

    turns: int
    sigma: float = 5.8e7
    waveform: DampedSine | CurrentTable | None = None
    sign: int = 1
    direction: str = "azimuthal"
    axis: tuple[float, float] = (0.0, 0.0)
    section: float | None = None
    name: str = ""
    cut_normal: tuple[float, float, float] | None = None
    density: float = 8960.0
    heat_capacity: float = 385.0
    conductivity_law: ConductivityLaw | None = None
    initial_temperature: float = 293.15

    def __post_init__(self) -> None:
        self.conductivity_law = law_from_dict(self.conductivity_law)
        if self.sign not in (1, -1):
            raise ValueError(f"a coil's sign is +1 or -1, got {self.sign!r}")
        if self.direction not in DIRECTIONS:
            raise ValueError(f"coil direction is one of {sorted(DIRECTIONS)}, got {self.direction!r}")
        if self.direction == "deck" and self.section is None:
            raise ValueError("a coil whose direction comes from the deck needs its section (m^2)")
        if self.cut_normal is not None and self.direction != "cut":
            raise ValueError("cut_normal orients the cut of a coil with direction='cut' only")


@dataclass
class EM3DModel(MagneticRegions):
    """Static description of a 3D EM problem.

    ``sector_deg``: angle of the modelled sector about the z-axis (degrees; 360 for a whole model);
    ``symmetry_factor`` (default 360 / sector_deg) = full device / modelled part: it scales the coil
    voltage in the circuit. ``shell = (R_int, R_ext)`` (m) enables the spherical shell transformation
    on region 2, centred at ``shell_centre``. ``probes``: points (x, y, z) (m) where B is reported.
    ``order``: 1 (Whitney edge elements) or 2 (the deck's ``Order_a = 2``: hierarchical second-order edge
    elements: B complete of degree 1 and E complete of degree 1 in the conductors). With order 2,
    ``order2_air`` False leaves the air and the shell first order (the face functions only on the coils'
    and conductors' faces) and ``order2_conductors`` (1-based numbers; None: all) chooses the
    conductors made second order, the others staying first order.
    ``applied_field``: a uniform applied field (:class:`~.applied_field.AppliedField` with a 3-component
    direction), alone or beside coils, by the reduced-field split (:mod:`.applied_field`): B, j, forces,
    Joule power and probes are total, the magnetic energy is the reaction field's. It must be tangential
    to the symmetry planes with n x a = 0 (physical 14: a sector's meridian planes admit only B_z) and
    normal to those with n x h = 0 (physical 15); the run refuses other directions (``ValueError``).
    ``cores`` (non-conducting magnetic regions 800+k), the conductors' ``mu_r`` / ``bh_curve`` and Newton's
    settings: as :class:`~.model.EMModel`'s.
    """

    coils: list[Coil3D] = field(default_factory=list)
    conductors: list[Conductor] = field(default_factory=list)
    circuit: Circuit | None = None
    shell: tuple[float, float] | None = None
    shell_centre: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sector_deg: float = 360.0
    symmetry_factor: float | None = None
    probes: list[tuple[float, float, float]] = field(default_factory=list)
    order: int = 1
    order2_air: bool = True
    order2_conductors: tuple[int, ...] | None = None
    applied_field: AppliedField | None = None
    cores: list[MagneticCore] = field(default_factory=list)
    newton_tolerance: float = 1e-8
    newton_max_iterations: int = 30

    def __post_init__(self) -> None:
        if isinstance(self.applied_field, dict):
            self.applied_field = AppliedField(**self.applied_field)
        if self.applied_field is not None:
            self.applied_field.unit_vector(3)   # 3 components, or a ValueError
        if self.order not in (1, 2):
            raise ValueError(f"the 3D EM order is 1 or 2, got {self.order!r}")
        if self.order2_conductors is not None and not set(self.order2_conductors) <= set(range(1, len(self.conductors) + 1)):
            raise ValueError(f"order2_conductors are conductor numbers 1..{len(self.conductors)}, "
                             f"got {self.order2_conductors!r}")
        if self.symmetry_factor is None:
            self.symmetry_factor = 360.0 / float(self.sector_deg)
        for c in self.coils:
            if self.circuit is not None and c.waveform is not None:
                raise ValueError("with a circuit the coil current is computed: give no waveform")
            if self.circuit is None and c.waveform is None:
                raise ValueError("without a circuit every coil needs a waveform")
        self.check_magnetic()

    @property
    def has_conductivity_laws(self) -> bool:
        """True when a coil or a conductor has a σ(T) law (:mod:`.conductivity`)."""
        return has_laws(self)


@dataclass
class EM3DResult:
    """Histories of one 3D transient run (modelled part unless stated; SI units).

    ``times`` (n,) s; ``coil_current``, ``coil_voltage`` (n, n_coils) A, V (the whole coil; the drop along the current);
    ``coil_power`` (n, n_coils) W; ``coil_force``, ``conductor_force`` (n, n_*, 3) N;
    ``conductor_power`` (n, n_cond) W; ``magnetic_energy`` (n,) J; ``capacitor_voltage``,
    ``circuit_current`` (n,) or None; ``probe_b`` (n, n_probes, 3) T; ``elements`` rows of
    ``mesh.tets`` in the conductors; ``force_density`` (n_out, n_el, 3) N/m^3 and ``joule_density``
    (n_out, n_el) W/m^3 as element averages (element integral / volume); ``flux_density``
    (n_out, n_el, 3) T at the centroids; ``b_cells`` (n_tets, 3) T, B of every tetrahedron (rows of
    ``mesh.tets``) after the last step (``field_output=True``); ``coil_dir`` (n_tets, 3), the unit current
    direction of every coil tetrahedron (NaN elsewhere; ``direction_output=True``); ``res_path`` getdp's solution file
    (``restart_res`` of a following run); ``n_dofs``; ``wall_pre``, ``wall_loop`` s (getdp's own
    timers: pre-processing, the time loop), ``wall_per_step`` and ``cpu_per_step`` s (CPU time of the
    time loop per step: what a loaded machine does not inflate).
    """

    times: np.ndarray
    coil_current: np.ndarray
    coil_voltage: np.ndarray
    coil_power: np.ndarray
    coil_force: np.ndarray
    conductor_force: np.ndarray
    conductor_power: np.ndarray
    magnetic_energy: np.ndarray
    probe_b: np.ndarray
    capacitor_voltage: np.ndarray | None = None
    circuit_current: np.ndarray | None = None
    elements: np.ndarray | None = None
    element_tags: np.ndarray | None = None
    force_density: np.ndarray | None = None
    force_density_mean: np.ndarray | None = None  # (n_el, 3) N/m^3 held over a step (:mod:`.stepper3d`)
    joule_density: np.ndarray | None = None
    flux_density: np.ndarray | None = None
    b_cells: np.ndarray | None = None
    coil_dir: np.ndarray | None = None
    res_path: Path | None = None
    n_dofs: int = 0
    wall_pre: float = math.nan
    wall_loop: float = math.nan
    wall_per_step: float = math.nan
    cpu_per_step: float = math.nan
    run: RunInfo | None = None
    newton_iterations: list[int] | None = None   # with a B–H curve: linear solves per step (.bh_curve.read_newton)


def coil_section_from_mesh(mesh: Mesh3D, k: int, axis: tuple[float, float] = (0.0, 0.0)) -> float:
    """Meridian cross-section (m^2) of azimuthal coil ``k`` in ``mesh``: sum of V_e / (r_e alpha),
    r_e the centroid's distance to the axis, alpha the sector angle (exact for a ring up to the
    centroid rule: the integral of 1/r over a sector of a ring is alpha times its section)."""
    rows = np.flatnonzero(mesh.tet_tags == coil_tag(k))
    if rows.size == 0:
        raise ValueError(f"coil {k}: region {coil_tag(k)} is empty in the mesh")
    c = mesh.centroids(rows)
    r = np.hypot(c[:, 0] - axis[0], c[:, 1] - axis[1])
    return float(np.sum(mesh.volumes(rows) / r) / math.radians(mesh.sector_deg))


def model_numbers(model: EM3DModel, mesh: Mesh3D) -> tuple[dict[str, float], list[str]]:
    """The ``-setnumber`` inputs of the 3D deck for ``model`` on ``mesh`` (the physical ids of
    :mod:`.mesh3d` too: defined once in Python), and the lines of tables (current tables) for the
    run's wrapper deck."""
    if abs(model.sector_deg - mesh.sector_deg) > 1e-9:
        raise ValueError(f"model sector {model.sector_deg} deg but mesh sector {mesh.sector_deg} deg")
    nb: dict[str, float] = {"Phys_Air": AIR, "Phys_Shell": SHELL, "Phys_Outer": OUTER, "Phys_SymA": SYM_A,
                            "Phys_Coil_Base": COIL_BASE, "Phys_Cond_Base": CONDUCTOR_BASE, "Phys_Skin_Base": SKIN_BASE,
                            "Phys_ElecIn_Base": ELEC_IN_BASE, "Phys_ElecOut_Base": ELEC_OUT_BASE, "Phys_Cut_Base": CUT_BASE,
                            "Phys_Core_Base": CORE_BASE,
                            "NbCoils": len(model.coils), "NbConductors": len(model.conductors),
                            "Flag_Circuit": int(model.circuit is not None), "NbProbes": len(model.probes),
                            "SymmetryFactor": float(model.symmetry_factor)}
    if model.order != 1:   # order 1 passes nothing: the deck's default, runs unchanged
        nb["Order_a"] = model.order
        if not model.order2_air:
            nb["Air_Order"] = 1
        for k in range(1, len(model.conductors) + 1):
            if model.order2_conductors is not None and k not in model.order2_conductors:
                nb[f"Cond_Order_{k}"] = 1
    for i, (x, y, z) in enumerate(model.probes, start=1):
        nb[f"Probe_X_{i}"], nb[f"Probe_Y_{i}"], nb[f"Probe_Z_{i}"] = x, y, z
    if model.shell is not None:
        nb.update(Flag_Shell=1, Val_Rint=model.shell[0], Val_Rext=model.shell[1], Val_Cx=model.shell_centre[0],
                  Val_Cy=model.shell_centre[1], Val_Cz=model.shell_centre[2])
    for k, c in enumerate(model.coils, start=1):
        section = c.section
        if section is None and c.direction == "electrokinetic":
            if not mesh.electrode_area or not mesh.electrode_area.get(k):
                raise ValueError(f"coil {k}: electrokinetic direction but the mesh has no electrode {k}")
            section = mesh.electrode_area[k]
        elif section is None and c.direction == "cut":
            section = physical_surface_area(mesh.path, cut_tag(k))
        elif section is None:
            section = coil_section_from_mesh(mesh, k, c.axis)
        nb.update({f"Coil_Ns_{k}": c.turns, f"Coil_Sc_{k}": section, f"Coil_sigma_{k}": c.sigma,
                   f"Coil_Sign_{k}": c.sign, f"Coil_DirType_{k}": DIRECTIONS[c.direction],
                   f"Coil_Cx_{k}": c.axis[0], f"Coil_Cy_{k}": c.axis[1]})
        if c.direction == "cut":   # checks the cut (triangles, orientation) and orients it
            nb[f"Coil_CutSign_{k}"] = cut_orientation(mesh.path, cut_tag(k), c.cut_normal)
        nb.update(waveform_numbers(k, c.waveform))
    nb.update(body_numbers(model, mesh.tet_tags))
    if model.circuit is not None:
        nb.update(C_bank=model.circuit.C, R_ext=model.circuit.R_ext, L_ext=model.circuit.L_ext,
                  Init_Vc=model.circuit.V0, Init_I=0.0)
    if model.applied_field is not None:   # Field_F1 / Field_F2 (the state's) are the caller's
        nb.update(model.applied_field.numbers_3d(*symmetry_planes(mesh)))
    mag_numbers, mag_lines = model_magnetic(model)
    nb.update(mag_numbers)
    return nb, table_lines(model.coils, model.applied_field) + mag_lines


def symmetry_planes(mesh: Mesh3D) -> tuple[list, list]:
    """The symmetry planes of ``mesh`` (read from its file): those with n x a = 0 (physical 14) and
    those with n x h = 0 (physical 15), each as (unit normal, offset n . p) (m)."""
    tri, tags = read_msh22_triangles(mesh.path, (SYM_A, SYM_H))
    return (planes_of_faces(mesh.points, tri[tags == SYM_A]), planes_of_faces(mesh.points, tri[tags == SYM_H]))


def applied_state_values(model: EM3DModel, t: float, steps: int, dt_prev: float) -> tuple[float, float]:
    """The applied field's unit time function (``Field_F1``, ``Field_F2``) of the states x_n at ``t`` (s) and
    x_{n-1} at ``t - dt_prev``, after ``steps`` steps from rest (the state at rest has 0: no field)."""
    f = model.applied_field
    if f is None:
        return 0.0, 0.0
    f1 = float(f.unit_f(t)) if steps >= 1 else 0.0
    f2 = float(f.unit_f(t - dt_prev)) if steps >= 2 else 0.0
    return f1, f2


_WALL = re.compile(r"^Info\s*:\s*\(Wall = ([0-9.eE+-]+)s, CPU = ([0-9.eE+-]+)s", re.M)
_DOFS = re.compile(r"System \d+/\d+: (\d+) Dofs")
_SYSTEMS = re.compile(r"^Info\s*:\s*System '(\w+)' :", re.M)


def _timers(log_text: str) -> tuple[int, float, float, float]:
    """(dofs of the magnetic system A -- the last one listed when the systems' names are not found; wall
    after pre-processing; wall at the end of the time loop; CPU time of the time loop) from a ``-v 5``
    log (s)."""
    marks = [(float(m.group(1)), float(m.group(2))) for m in _WALL.finditer(log_text)]
    found = _DOFS.findall(log_text)
    names = _SYSTEMS.findall(log_text)
    if found and len(names) == len(found) and "A" in names:   # the systems are listed in their order
        dofs = int(found[names.index("A")])
    else:
        dofs = int(found[-1]) if found else 0
    if len(marks) < 2:
        return dofs, math.nan, math.nan, math.nan
    return dofs, marks[0][0], marks[-1][0], marks[-1][1] - marks[0][1]


def ball_average(mesh: Mesh3D, values: np.ndarray, centre: Sequence[float], radius: float) -> tuple[np.ndarray, int]:
    """Volume-weighted mean of per-tetrahedron ``values`` over the tetrahedra whose centroid lies within
    ``radius`` (m) of ``centre`` (m), and their number.  In a current-free ball an axisymmetric
    harmonic field's mean over the ball (or over a sector of it) is its value at the centre."""
    c = mesh.centroids()
    sel = np.linalg.norm(c - np.asarray(centre, float)[None, :], axis=1) <= radius
    if not np.any(sel):
        raise ValueError("no tetrahedron in the ball")
    v = mesh.volumes(np.flatnonzero(sel))
    return (values[sel] * v[:, None]).sum(0) / v.sum(), int(sel.sum())


def solve_transient3d(model: EM3DModel, mesh: Mesh3D, t_end: float, n_steps: int, work_dir: str | Path, *,
                      t0: float = 0.0, element_output: str = "all", field_output: bool = False,
                      direction_output: bool = False,
                      restart_res: str | Path | None = None, circuit_state: tuple[float, float] | None = None,
                      time_scheme: str = "euler", extra_numbers: dict[str, float] | None = None,
                      applied_start: float | None = None, extra_lines: Sequence[str] = (), executable: str = "getdp",
                      petsc_args: Sequence[str] = DEFAULT_PETSC_ARGS_3D, timeout: float | None = None) -> EM3DResult:
    """Run the 3D deck from ``t0`` to ``t_end`` (s) in ``n_steps`` implicit Euler steps.

    The fields start from zero at ``t0``, or with ``restart_res`` (the ``res_path`` of a previous run
    that ended at ``t0`` on a mesh of the same connectivity, nodes possibly moved) from its last state:
    ``getdp -restart -res``. ``circuit_state`` = (capacitor voltage V, current A) at ``t0`` (default:
    ``Circuit.V0`` and no current), e.g. the previous result's last ``capacitor_voltage`` and
    ``circuit_current``.

    ``element_output``: ``"all"`` (per-tetrahedron tables every step), ``"last"`` or ``"none"``;
    ``field_output``: also B on every tetrahedron after the last step (``b_cells``);
    ``direction_output``: the coils' unit current direction per tetrahedron (``coil_dir``).
    ``extra_numbers``: more ``-setnumber`` inputs of the deck (e.g. ``Flag_SaveInit``); ``extra_lines``: more lines
    of the run's wrapper deck (e.g. σ per element, :func:`.conductivity.step_inputs`).
    ``time_scheme``: ``"euler"`` (implicit Euler) or ``"bdf2"`` (second order, equal steps, the first one
    implicit Euler; from zero fields only: no ``restart_res``).
    ``applied_start``: with an applied field, its unit time function of the start state (``Field_F1``;
    default: 0 from rest, f(t0) with ``restart_res``; a BDF2 x~ passes its combination c1 f_n - c2 f_{n-1}).
    One getdp process in ``work_dir`` (created; its log ``getdp.log``); ``timeout`` in s.
    Raises :class:`~.runner.GetDPError` when getdp fails.
    """
    if n_steps < 1 or not t_end > t0:
        raise ValueError("need n_steps >= 1 and t_end > t0")
    flag_elem = {"all": 1, "last": 2, "none": 0}[element_output]
    run_dir = Path(work_dir).resolve()
    out_dir = run_dir / "out"
    out_dir.mkdir(parents=True, exist_ok=True)
    for old in out_dir.glob("*.txt"):   # getdp appends (File >)
        old.unlink()
    numbers, lines = model_numbers(model, mesh)
    numbers.update(TimeInit=float(t0), TimeFinal=float(t_end), NbSteps=int(n_steps), Flag_ElemOut=flag_elem,
                   Flag_FieldOut=int(field_output), **(extra_numbers or {}))
    if direction_output:
        numbers["Flag_DirOut"] = 1
    if time_scheme not in ("euler", "bdf2"):
        raise ValueError(f"time_scheme is 'euler' or 'bdf2', got {time_scheme!r}")
    if model.applied_field is not None:
        if numbers.get("TimeTheta", 1.0) != 1.0:
            raise ValueError("an applied field needs TimeTheta = 1 (its source is the implicit-Euler / BDF2 "
                             "difference of the step)")
        if applied_start is None:
            applied_start = float(model.applied_field.unit_f(float(t0))) if restart_res is not None else 0.0
        numbers["Field_F1"] = float(applied_start)
    if time_scheme == "bdf2" and (restart_res is not None or circuit_state is not None):
        raise ValueError("bdf2 starts from zero fields: its restart (two history states) is not done")
    restart: list[str] = []
    if restart_res is not None:
        restart = ["-restart", "-res", str(Path(restart_res).resolve())]
    if circuit_state is not None:
        if model.circuit is None:
            raise ValueError("circuit_state given but the model has no circuit")
        numbers.update(Init_Vc=float(circuit_state[0]), Init_I=float(circuit_state[1]))
    wrapper = run_dir / "run3d.pro"
    wrapper.write_text("\n".join(lines + list(extra_lines) + [f'Include "{DECK3D}";', ""]))
    resolution = RESOLUTION3D if time_scheme == "euler" else RESOLUTION3D + "_BDF2"
    info = run_getdp(wrapper, mesh.path, run_dir, resolution=resolution, numbers=numbers,
                     strings={"OutDir": str(out_dir) + "/"}, extra_args=restart + list(petsc_args),
                     executable=executable, timeout=timeout, verbosity=5)
    res = read_results3d(model, mesh, out_dir, int(n_steps), flag_elem)
    if model.is_nonlinear:   # a step above Newton's tolerance stops here (NewtonFailed)
        res.newton_iterations = read_newton(out_dir, model.newton_tolerance, 0.0, model.newton_max_iterations,
                                            log_path=info.log_path)
    if field_output:
        ids, b = read_element_table(out_dir / "field_b.txt", 3, 1)
        res.b_cells = np.full((mesh.n_tets, 3), np.nan)
        res.b_cells[mesh.rows_of_ids(ids)] = b[0]
    if direction_output:
        ids, d = read_element_table(out_dir / "coil_dir.txt", 3, 1)
        res.coil_dir = np.full((mesh.n_tets, 3), np.nan)
        res.coil_dir[mesh.rows_of_ids(ids)] = d[0]
    res.run = info
    res.res_path = run_dir / "em.res"
    res.n_dofs, res.wall_pre, wall_end, cpu_loop = _timers(info.log_path.read_text(errors="replace"))
    res.wall_loop = wall_end - res.wall_pre
    res.wall_per_step = res.wall_loop / n_steps
    res.cpu_per_step = cpu_loop / n_steps
    logger.info("3D EM run %s: %d tets, %d dofs, %d steps, %.2f s wall / %.2f s CPU per step (pre-processing "
                "%.2f s)", run_dir.name, mesh.n_tets, res.n_dofs, n_steps, res.wall_per_step, res.cpu_per_step,
                res.wall_pre)
    return res


def read_results3d(model: EM3DModel, mesh: Mesh3D, out_dir: Path, n_steps: int, flag_elem: int,
                   element_fields: bool = True) -> EM3DResult:
    """Read the tables of a finished 3D run in ``out_dir`` (see the deck's PostOperation);
    ``element_fields=False``: of the per-element tables only the force (``EM_ElemF3D``; Joule power and b
    per element come later, :func:`read_conductor_fields3d`)."""
    def glob(name: str, ncol: int) -> np.ndarray:
        t = read_table(out_dir / name)
        t = t.reshape(-1, t.shape[-1]) if t.ndim > 1 else t.reshape(1, -1)
        if t.shape[0] != n_steps:
            raise RuntimeError(f"{name}: {t.shape[0]} rows for {n_steps} steps")
        return t[:, -ncol:]

    nc, nk = len(model.coils), len(model.conductors)
    times = glob("W.txt", 2)[:, 0]
    res = EM3DResult(
        times=times,
        magnetic_energy=glob("W.txt", 1)[:, 0],
        coil_current=np.stack([glob(f"coil_I_{k}.txt", 1)[:, 0] for k in range(1, nc + 1)], 1) if nc else np.zeros((n_steps, 0)),
        # GetDP's Us is the generator-convention voltage: the drop along the current is -Us (as in 2D)
        coil_voltage=-np.stack([glob(f"coil_U_{k}.txt", 1)[:, 0] for k in range(1, nc + 1)], 1) if nc else np.zeros((n_steps, 0)),
        coil_power=np.stack([glob(f"coil_P_{k}.txt", 1)[:, 0] for k in range(1, nc + 1)], 1) if nc else np.zeros((n_steps, 0)),
        coil_force=np.stack([glob(f"coil_F_{k}.txt", 3) for k in range(1, nc + 1)], 1) if nc else np.zeros((n_steps, 0, 3)),
        conductor_force=np.stack([glob(f"cond_F_{k}.txt", 3) for k in range(1, nk + 1)], 1) if nk else np.zeros((n_steps, 0, 3)),
        conductor_power=np.stack([glob(f"cond_P_{k}.txt", 1)[:, 0] for k in range(1, nk + 1)], 1) if nk else np.zeros((n_steps, 0)),
        probe_b=np.stack([glob(f"probe_b_{i}.txt", 3) for i in range(1, len(model.probes) + 1)], 1)
        if model.probes else np.zeros((n_steps, 0, 3)),
    )
    if model.circuit is not None:
        res.capacitor_voltage = glob("cir_U.txt", 1)[:, 0]
        res.circuit_current = glob("cir_I.txt", 1)[:, 0]
    if nk and flag_elem:
        n_blocks = n_steps if flag_elem == 1 else 1
        ids, force = read_element_table(out_dir / "elem_F.txt", 3, n_blocks)
        rows = mesh.rows_of_ids(ids)
        vol = mesh.volumes(rows)
        res.elements, res.element_tags = rows, mesh.tet_tags[rows]
        res.force_density = force / vol[None, :, None]
        if element_fields:
            res.joule_density, res.flux_density = read_conductor_fields3d(mesh, out_dir, ids, n_blocks)
    return res


def read_conductor_fields3d(mesh: Mesh3D, out_dir: Path, ids: np.ndarray,
                            n_blocks: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(Joule power density (n_blocks, n_el) W/m^3 as element averages, b (n_blocks, n_el, 3) T at the
    centroids) of the conductor elements ``ids`` (gmsh element ids, the order of ``elem_F.txt``) from
    ``elem_P.txt`` and ``elem_b.txt`` in ``out_dir`` (PostOperation ``EM_ElemPB3D``)."""
    ids_p, power = read_element_table(out_dir / "elem_P.txt", 1, n_blocks)
    ids_b, b = read_element_table(out_dir / "elem_b.txt", 3, n_blocks)
    if not (np.array_equal(ids, ids_p) and np.array_equal(ids, ids_b)):
        raise RuntimeError("element tables list different elements")
    vol = mesh.volumes(mesh.rows_of_ids(ids))
    return power[:, :, 0] / vol[None, :], b


__all__ = ["Coil3D", "EM3DModel", "EM3DResult", "solve_transient3d", "read_results3d", "read_conductor_fields3d",
           "model_numbers",
           "coil_section_from_mesh", "ball_average", "DEFAULT_PETSC_ARGS_3D", "MUMPS_PETSC_ARGS_3D", "skin_tag", "AppliedField",
           "symmetry_planes", "applied_state_values"]
