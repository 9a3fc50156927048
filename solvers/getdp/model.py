"""The EM participant's data: model description, serialisable state, results of one EM step."""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from .bh_curve import BHCurve, MagneticRegions, check_relative_permeability
from .conductivity import ConductivityLaw, has_laws, law_from_dict
from .mesh import EMMesh
from .runner import RunInfo

if TYPE_CHECKING:
    from .applied_field import AppliedField


# ----------------------------------------------------------------------------- model
@dataclass
class DampedSine:
    """I(t) = I0 exp(-beta (t - t_on)) sin(omega (t - t_on) + phase) (A) from ``t_on`` (s) on, 0 before;
    ``beta`` 1/s, ``omega`` rad/s, ``phase`` rad. A direct current I0 is omega = 0, phase = pi/2;
    ``phase = t_on = 0`` is the pulse I0 exp(-beta t) sin(omega t)."""

    I0: float
    beta: float
    omega: float
    phase: float = 0.0
    t_on: float = 0.0

    def __call__(self, t):
        """I(t) (A) at times ``t`` (s), as the deck computes it."""
        t = np.asarray(t, float)
        s = t - self.t_on
        return np.where(t >= self.t_on, self.I0 * np.exp(-self.beta * s) * np.sin(self.omega * s + self.phase), 0.0)


@dataclass
class CurrentTable:
    """I(t) linearly interpolated in (times, values) (s, A)."""

    times: Sequence[float]
    values: Sequence[float]

    def __post_init__(self):
        t = np.asarray(self.times, float)
        v = np.asarray(self.values, float)
        if t.ndim != 1 or t.shape != v.shape or len(t) < 2 or np.any(np.diff(t) <= 0):
            raise ValueError("CurrentTable needs >= 2 strictly increasing times and as many values")
        self.times, self.values = t.tolist(), v.tolist()

    def __call__(self, t):
        """I(t) (A) at times ``t`` (s), as the runner's deck computes it (the end values held beyond the table)."""
        return np.interp(np.asarray(t, float), self.times, self.values)


@dataclass
class Coil:
    """A stranded coil: all its turns form physical region 100+k (uniform current density).

    ``waveform`` is used without a circuit; with a circuit it must be None.
    ``density`` and ``heat_capacity`` (copper defaults) give the adiabatic temperature rise.
    ``sign``: the coil's orientation, +1 or -1 (wound the other way): its current is ``sign`` times
    its waveform, or ``sign`` times the circuit's current (the deck connects it the other way round).
    ``name``: what the coil is called (history columns), free text.
    ``conductivity_law``: σ(T) (:mod:`.conductivity`; None: ``sigma`` at every temperature); the coil is one
    lumped body at ``initial_temperature`` (K) plus its adiabatic rise (Joule heat / (m c_p)), and its σ — so its
    resistance — follows that temperature EM step by step (evaluated at the step's start).
    """

    turns: int
    sigma: float = 5.8e7
    waveform: DampedSine | CurrentTable | None = None
    density: float = 8960.0
    heat_capacity: float = 385.0
    sign: int = 1
    name: str = ""
    conductivity_law: ConductivityLaw | None = None
    initial_temperature: float = 293.15

    def __post_init__(self):
        self.conductivity_law = law_from_dict(self.conductivity_law)
        if isinstance(self.waveform, dict):
            self.waveform = (CurrentTable if "times" in self.waveform else DampedSine)(**self.waveform)
        if self.sign not in (1, -1):
            raise ValueError(f"a coil's sign is +1 or -1, got {self.sign!r}")


@dataclass
class Conductor:
    """A massive conductor (physical region 200+k) with eddy currents.

    ``conductivity_law``: σ(T) per element (:mod:`.conductivity`), from the element temperatures given with
    :meth:`~.solver.GetDPSolver.set_element_temperatures` (K; an element without one is at
    ``initial_temperature``); None: ``sigma`` everywhere.
    ``mu_r``: relative permeability; ``bh_curve``: a B–H curve in its place (:class:`~.bh_curve.BHCurve`;
    nonlinear: Newton's iterations in every EM step)."""

    sigma: float
    name: str = ""
    conductivity_law: ConductivityLaw | None = None
    initial_temperature: float = 293.15
    mu_r: float = 1.0
    bh_curve: BHCurve | None = None

    def __post_init__(self):
        self.conductivity_law = law_from_dict(self.conductivity_law)
        self.mu_r, self.bh_curve = _permeability(self.mu_r, self.bh_curve)


def _permeability(mu_r, bh_curve) -> tuple[float, BHCurve | None]:
    """A region's checked (μ_r, B–H curve): one of them (μ_r = 1 with a curve)."""
    mu_r, curve = check_relative_permeability(mu_r), BHCurve.from_any(bh_curve)
    if curve is not None and mu_r != 1.0:
        raise ValueError("give a relative permeability or a B-H curve, not both")
    return mu_r, curve


@dataclass
class MagneticCore:
    """A non-conducting magnetic region (physical region 800+k, :func:`~.mesh.core_tag`): a constant relative
    permeability ``mu_r`` or a B–H curve ``bh_curve`` (:class:`~.bh_curve.BHCurve`); no eddy current, no
    Lorentz force."""

    mu_r: float = 1.0
    bh_curve: BHCurve | None = None
    name: str = ""

    def __post_init__(self):
        self.mu_r, self.bh_curve = _permeability(self.mu_r, self.bh_curve)


@dataclass
class Circuit:
    """Capacitor bank C charged to V0, in series with R_ext, L_ext and all coils."""

    C: float
    V0: float
    R_ext: float = 0.0
    L_ext: float = 0.0


@dataclass
class EMModel(MagneticRegions):
    """Static description of the EM problem (everything except the mesh and the state).

    ``shell = (R_int, R_ext)`` enables the shell transformation to infinity on region 2,
    centred at ``shell_centre``.  ``h0_step`` imposes a tangential field step H0 (A/m)
    on boundary 13 (used by the diffusion verification).  ``probes``: points (x, y) where
    B is reported every sub-step (avoid x = 0 exactly in axisymmetry: NaN on the axis).
    ``applied_field``: a uniform applied field (:class:`~.applied_field.AppliedField`, 2 components:
    (x, y), in axisymmetry (r, z) with only z allowed), with or without coils; the decks' reduced-field
    split (see :mod:`.applied_field`): B, j, forces and Joule power are total, the magnetic energy and
    the nodal unknown (``a_nodes``, the state) are those of the reaction field.
    ``cores``: non-conducting magnetic regions (:class:`MagneticCore`). With a B–H curve in a conductor or a
    core, every time step is solved by Newton's method: at most ``newton_max_iterations`` iterations until the
    residual norm is ``newton_tolerance`` times the right-hand side's norm
    (:func:`~.bh_curve.read_newton` stops the run otherwise).
    """

    axisymmetric: bool
    coils: list[Coil] = field(default_factory=list)
    conductors: list[Conductor] = field(default_factory=list)
    circuit: Circuit | None = None
    shell: tuple[float, float] | None = None
    shell_centre: tuple[float, float] = (0.0, 0.0)
    h0_step: float = 0.0
    probes: list = field(default_factory=list)
    applied_field: AppliedField | None = None
    cores: list[MagneticCore] = field(default_factory=list)
    newton_tolerance: float = 1e-8
    newton_max_iterations: int = 30

    def __post_init__(self):
        from .applied_field import AppliedField

        if isinstance(self.applied_field, dict):
            self.applied_field = AppliedField(**self.applied_field)
        if self.applied_field is not None:
            self.applied_field.unit_vector(2)   # 2 components, or a ValueError
            if self.h0_step:
                raise ValueError("an applied field and h0_step (the tangential field on boundary 13) are two ways "
                                 "to impose an external field: give one")
        self.coils = [c if isinstance(c, Coil) else Coil(**c) for c in self.coils]
        self.conductors = [c if isinstance(c, Conductor) else Conductor(**c) for c in self.conductors]
        if isinstance(self.circuit, dict):
            self.circuit = Circuit(**self.circuit)
        if self.shell is not None:
            self.shell = tuple(float(x) for x in self.shell)
        self.shell_centre = tuple(float(x) for x in self.shell_centre)
        self.probes = [tuple(float(x) for x in p) for p in self.probes]
        for c in self.coils:
            if self.circuit is not None and c.waveform is not None:
                raise ValueError("with a circuit the coil current is computed: give no waveform")
            if self.circuit is None and c.waveform is None:
                raise ValueError("without a circuit every coil needs a waveform")
        if self.circuit is not None and not self.coils:
            raise ValueError("a circuit needs at least one coil")
        self.check_magnetic()

    @property
    def has_conductivity_laws(self) -> bool:
        """True when a coil or a conductor has a σ(T) law (:mod:`.conductivity`)."""
        return has_laws(self)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "EMModel":
        return cls(**d)


# ----------------------------------------------------------------------------- state
@dataclass
class EMState:
    """Everything needed to continue after time ``t`` (JSON-serialisable with to_dict()).

    ``res_path``/``mesh_signature``: the previous run's .res and the connectivity it was
    computed on (restart path).  ``a_*``: the nodal unknown (r a_phi in axisymmetry,
    a_z in planar) on the conductor and coil nodes, at material coordinates
    ``a_points`` on triangles ``a_triangles`` (general path through an Init constraint).
    BDF2 history (``time_scheme="bdf2"``, see :mod:`.bdf2`): ``dt_prev`` (s) the last step,
    ``a_prev_values`` the nodal unknown at its start (on ``a_points``), the circuit state then
    (``capacitor_voltage_prev`` V, ``current_prev`` A), and the values at ``t`` that open the
    next step's trapezoid means: ``coil_power`` (W per coil), ``force_density`` (N/m^3 per
    conductor element) at element centroids ``force_points`` (material coordinates).
    ``applied_f``, ``applied_f_prev``: with an applied field, its unit time function of the states at
    ``t`` and at ``t - dt_prev`` (0 for the state at rest). ``factorisations``, ``corrections``: the
    persistent getdp's solves so far. ``coil_sigma``: with a coil σ(T), each coil's σ (S/m) of the last step.
    """

    t: float = 0.0
    step_index: int = 0
    capacitor_voltage: float = 0.0
    current: float = 0.0
    coil_heat: list[float] = field(default_factory=list)
    res_path: str | None = None
    mesh_signature: str | None = None
    a_points: list | None = None
    a_triangles: list | None = None
    a_values: list | None = None
    pre_path: str | None = None
    # BDF2 history (time_scheme="bdf2"): the step before, on the same nodes / in the same frame
    dt_prev: float | None = None
    a_prev_values: list | None = None
    capacitor_voltage_prev: float = 0.0
    current_prev: float = 0.0
    coil_power: list | None = None
    force_density: list | None = None
    force_points: list | None = None
    # BDF2 by restart (a template deck, :mod:`.template`): a .res whose last solution is the whole x_{n-1}
    res_prev_path: str | None = None
    # applied field (EMModel.applied_field): the deck's unit time function of the state x_n and of x_{n-1}
    # (0 at rest: a run starts with no field, so f(t0) != 0 switches the field on in the first step)
    applied_f: float = 0.0
    applied_f_prev: float = 0.0
    # the persistent getdp's solves so far (:class:`~.persistent_process.FactorReuse`): factorisations and
    # kept-factor corrections
    factorisations: int = 0
    corrections: int = 0
    # a coil conductivity that follows temperature (:mod:`.conductivity`): each coil's σ (S/m) over the last step
    # (the power ``coil_power`` at its end was computed with it)
    coil_sigma: list | None = None

    def to_dict(self) -> dict:
        """The fields as a dict for JSON: lists are shared, not copied (``dataclasses.asdict``'s
        deep copy of the nodal lists took ~25 ms per call at a checkpoint of the demo)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, d: dict) -> "EMState":
        return cls(**d)

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict()))

    @classmethod
    def load(cls, path: str | Path) -> "EMState":
        return cls.from_dict(json.loads(Path(path).read_text()))


def mesh_signature(mesh: EMMesh) -> str:
    h = hashlib.sha1()
    for arr in (mesh.triangles, mesh.tri_tags, mesh.lines, mesh.line_tags):
        h.update(np.ascontiguousarray(arr, dtype=np.int64).tobytes())
    h.update(str(mesh.n_nodes).encode())
    return h.hexdigest()


# ----------------------------------------------------------------------------- results
@dataclass
class EMStepResult:
    """Outputs of one EM step (``n`` implicit sub-steps ending at ``times``).

    Per element of the massive conductors (``elements`` are rows of the mesh's
    ``triangles``): ``force_density`` (n, n_el, 2) N/m^3 and ``joule_density`` (n, n_el)
    W/m^3 are element averages (GetDP's 7-point element integral / element volume
    2 pi r_c A), so sum(force_density * V) equals the total force: conservative for the
    mechanical transfer.  ``force_density_centroid`` is j x B at the centroid and
    ``flux_density`` (n, n_el, 2) B at the centroid.  With ``element_output="last"`` these
    element arrays have one row (the last sub-step), with ``"none"`` no elements.  Per coil: current, voltage drop
    (receptor convention), Joule power, force.  Per conductor: force, Joule power.
    ``probe_b`` (n, n_probes, 2): B at the model's probe points.  ``force_density_start``
    (n_el, 2): with BDF2, the force density at the step's start (zero at a start from rest).
    Totals are physical (2 pi included in axisymmetry; per metre in planar).

    Whole-domain fields at the step's end (``field_output=True`` or
    :meth:`~.solver.GetDPSolver.post_fields`; None otherwise, or when the deck has no
    PostOperation ``EM_Field``): ``b_cells`` (n_triangles, 2) B (T) at the centre of every
    triangle of the mesh, in the GetDP frame (NaN for a triangle outside ``Vol_Mag``; in the
    shell region the values belong to the mapped, infinite domain), and ``a_nodes`` (n_nodes,)
    the nodal unknown at every node: r a_z of the GetDP frame in axisymmetry (= -r a_phi of the
    right-handed (r, phi, z) frame; its contours are flux lines), a_z in planar (Wb/m).

    ``newton_iterations``: with a B–H curve, the linear solves of each sub-step (the first solve and Newton's
    iterations, :func:`~.bh_curve.read_newton`); None for a linear model.
    """

    times: np.ndarray
    dt: float
    elements: np.ndarray
    element_tags: np.ndarray
    force_density: np.ndarray
    force_density_centroid: np.ndarray
    joule_density: np.ndarray
    flux_density: np.ndarray
    coil_current: np.ndarray
    coil_voltage: np.ndarray
    coil_power: np.ndarray
    coil_force: np.ndarray
    conductor_force: np.ndarray
    conductor_power: np.ndarray
    magnetic_energy: np.ndarray
    capacitor_voltage: np.ndarray | None
    circuit_current: np.ndarray | None
    coil_heat: np.ndarray
    coil_temperature_rise: np.ndarray
    probe_b: np.ndarray
    run: RunInfo | None = None
    path: str = ""
    force_density_start: np.ndarray | None = None
    b_cells: np.ndarray | None = None
    a_nodes: np.ndarray | None = None
    newton_iterations: list[int] | None = None

    @property
    def force_density_mean(self) -> np.ndarray:
        """Impulse-consistent force density over the step (N/m^3, per element).

        Implicit Euler: the mean of the sub-step values (its values are first-order, the
        rectangle rule matches).  BDF2 (``force_density_start`` = f at the step's start on
        the same elements): the trapezoid mean, second order like the scheme.
        """
        if self.force_density.shape[0] != len(self.times):
            raise ValueError("force_density_mean needs element_output='all'")
        if self.force_density_start is not None:
            from .bdf2 import trapezoid_mean

            return trapezoid_mean(self.force_density_start, self.force_density)
        return self.force_density.mean(axis=0)

    @property
    def total_conductor_force(self) -> np.ndarray:
        """(n, 2) sum over all massive conductors."""
        return self.conductor_force.sum(axis=1)


def table_lines(coils, applied_field=None) -> list[str]:
    """The lines a run deck defines for its tables: ``Coil_Table_<k>() = {t, I, ...};`` of every coil whose
    waveform is a :class:`CurrentTable` (s, A; the last value held beyond the table: GetDP would extrapolate the
    last segment), and the applied field's (its ``table_lines()``). 2D and 3D decks alike."""
    lines = []
    for k, c in enumerate(coils, start=1):
        if isinstance(c.waveform, CurrentTable):
            times = list(c.waveform.times) + [c.waveform.times[-1] + 1e3]
            values = list(c.waveform.values) + [c.waveform.values[-1]]
            pairs = [f"{t:.17g}, {v:.17g}" for t, v in zip(times, values)]
            body = ",\n  ".join(", ".join(pairs[j:j + 8]) for j in range(0, len(pairs), 8))
            lines.append(f"Coil_Table_{k}() = {{\n  {body}}};")
    if applied_field is not None:
        lines += applied_field.table_lines()
    return lines
