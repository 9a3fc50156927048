"""The ``[em]`` table of a coupled case: the coil's source (a capacitor bank, a prescribed current or named
``[[em.sources]]`` with ``[[em.coils]]``), an applied field, the time scheme and how getdp runs (SI units,
validated; the geometry tables are :mod:`.em_model`'s)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from .conductivity import ConductivityCurve, check_below_melting
from .em_applied import AppliedField
from .em_sources import CoilConnection, Source, check_sources
from .schema import SchemaError, spec


@dataclass(frozen=True, kw_only=True)
class CapacitorBank:
    """Capacitor bank C charged to V0 discharging through R_ext, L_ext and the coil."""

    capacitance: float = spec(unit="F", gt=0.0, doc="bank capacitance C")
    voltage: float = spec(unit="V", gt=0.0, doc="charging voltage V0")
    resistance: float = spec(0.0, unit="Ω", ge=0.0, doc="external resistance R_ext")
    inductance: float = spec(0.0, unit="H", ge=0.0, doc="external inductance L_ext")


@dataclass(frozen=True, kw_only=True)
class DampedSineCurrent:
    """Prescribed coil current I(t) = I0 e^(−βt) sin(ωt)."""

    amplitude: float = spec(unit="A", gt=0.0, doc="I0: the peak current of one turn, not rms (a coil of N turns "
                                                   "carries N·I0 ampere-turns at the peak)")
    beta: float = spec(unit="1/s", ge=0.0, doc="decay rate β")
    omega: float = spec(unit="rad/s", gt=0.0, doc="angular frequency ω")


#: copper's melting temperature (K): the coil's σ(T) table must stay below it unless it names its own
COPPER_MELTING_K = 1357.77


@dataclass(frozen=True, kw_only=True)
class Shots:
    """Repeated discharges of the bank with a pause between them (lumped cooling to ambient)."""

    count: int = spec(ge=1, le=1000, doc="number of discharges N")
    pause: float = spec(unit="s", gt=0.0, doc="time between the end of a shot's window (time.end) and the next "
                                              "discharge")
    voltages: tuple[float, ...] = spec((), unit="V", gt=0.0, doc="charging voltage of each shot (default: the "
                                                                 "bank's voltage every shot)")
    ambient_temperature: float = spec(293.15, unit="K", gt=0.0, doc="temperature the coil and the bodies cool "
                                                                    "towards during a pause")
    coil_heat_transfer: float = spec(0.0, unit="W/(m²·K)", ge=0.0, doc="h of the coil's surface to ambient "
                                                                      "(lumped: dT/dt = −h A (T − T_amb)/(m c_p))")
    body_heat_transfer: float = spec(0.0, unit="W/(m²·K)", ge=0.0, doc="h of every deformable body's surface to "
                                                                      "ambient, lumped per body, applied to every "
                                                                      "cell")


@dataclass(frozen=True, kw_only=True)
class EM:
    """Electromagnetic model (GetDP): coil, its source, and what to keep."""

    coil_conductivity: float = spec(5.8e7, unit="S/m", gt=0.0, doc="coil conductor (copper)")
    coil_density: float = spec(8960.0, unit="kg/m^3", gt=0.0, doc="for the coil's adiabatic heating")
    coil_heat_capacity: float = spec(385.0, unit="J/(kg·K)", gt=0.0, doc="for the coil's adiabatic heating")
    coil_conductivity_curve: ConductivityCurve | None = spec(
        None, doc="[em.coil_conductivity_curve] σ(T) of the coil in place of the constant coil_conductivity: "
                  "type = 'table' or 'linear_resistivity' (σ_ref = coil_conductivity); the coil is one lumped body "
                  "heated adiabatically during a shot, its resistance follows its temperature every EM step (2D "
                  "and 3D, on either getdp; docs/guide/em.md)")
    coil_initial_temperature: float = spec(293.15, unit="K", gt=0.0, doc="the coil's temperature at the start "
                                                                         "(its σ(T); shots: cooled towards ambient)")
    shots: Shots | None = spec(None, doc="[em.shots] repeated discharges with cooling between them (count, pause, "
                                         "voltages, heat transfer to ambient; docs/guide/em.md, Repeated shots)")
    circuit: CapacitorBank | None = spec(None, doc="capacitor-bank discharge (give this, current or sources; a "
                                                   "'getdp_template' deck's own bank when none is given)")
    current: DampedSineCurrent | None = spec(None, doc="prescribed coil current (give this, circuit or sources; a "
                                                       "'getdp_template' deck's own Current_2D when none is given)")
    sources: tuple[Source, ...] = spec((), doc="[[em.sources]] named current sources and at most one bank (give "
                                          "these with [[em.coils]], or circuit, or current)")
    coils: tuple[CoilConnection, ...] = spec((), doc="[[em.coils]] each coil of the geometry on a source, with its "
                                                 "orientation; coils on a bank are in series on it")
    applied_field: AppliedField | None = spec(None, doc="[em.applied_field] a uniform applied magnetic field beside "
                                                       "the coils, type = 'dc' | 'sine' | 'table' (time function as a "
                                                       "source's, times the magnitude)")
    keep_runs: bool = spec(False, doc="keep every getdp run folder (default: the last two)")
    time_scheme: Literal["euler", "bdf2"] = spec(
        "euler", doc="EM time scheme: 'euler' (implicit Euler, first order: damps the bank's ringing by "
                     "(ω dt)²/2 per step; sub-steps allowed) or 'bdf2' (second order, one step per getdp run "
                     "from a shifted state: coupling.em_substeps = 1; docs/coupling.md)")
    getdp_process: Literal["auto", "persistent", "per_step"] = spec(
        "auto", doc="how getdp runs: 'persistent' (one process advances every EM step, moving its mesh: "
                    "bdf2 only, ~8x less EM time on the demo), 'per_step' (a getdp process per EM step), "
                    "'auto' (persistent with bdf2 where the deck has Resolution EM_Persistent, else per_step)")
    factor_reuse_tol: float = spec(
        1e-10, unit="-", ge=0.0, lt=1e-3,
        doc="persistent getdp: each EM step assembles its own system and solves it by GCR preconditioned with "
            "the LU factors of an earlier step until |b − A x| ≤ tol |b| (the same system's answer to that "
            "residual; docs/getdp.md, Kept factors); 0 factorises every step; not used with a B–H curve (each "
            "Newton iteration factorises). History: em_factorisations, em_corrections")
    factor_reuse_max_corrections: int = spec(
        20, ge=1, le=50, doc="GCR iterations before an EM step factorises its own matrix (and the next one does "
                             "when a step needed more than 3/4 of them); each keeps two vectors in getdp")
    newton_tolerance: float = spec(
        1e-8, unit="-", gt=0.0, lt=0.1,
        doc="with a B–H curve (materials.<name>.bh_curve): Newton's iterations of an EM step end when the residual "
            "norm is this fraction of the right-hand side's norm (history: em_newton_iterations)")
    newton_max_iterations: int = spec(
        30, ge=1, le=1000, doc="with a B–H curve: the most Newton iterations per EM step; a step still above "
                               "newton_tolerance stops the run (results so far kept)")
    remesh_quality: float = spec(0.3, unit="-", gt=0.0, lt=1.0,
                                 doc="remesh the air when the worst element quality 4√3A/Σl² falls below this "
                                     "fraction of the fresh mesh's worst")

    @property
    def has_bank(self) -> bool:
        """A capacitor bank drives coils (``circuit``, or a ``bank`` source): the history's
        ``capacitor_voltage_V`` is its voltage (without one, the column is 0)."""
        return self.circuit is not None or any(s.type == "bank" for s in self.sources)

    def validate(self, path: str) -> None:
        given = [k for k in ("circuit", "current", "sources") if getattr(self, k)]
        if not given:  # the geometry decides: an applied field alone (.geometry3d), a template deck's own source
            return  # (.model), else refused there
        if len(given) != 1:
            raise SchemaError(f"{path}.{given[1] if given else 'circuit'}", "give exactly one of circuit (capacitor "
                              "bank), current or [[em.sources]] with [[em.coils]]")
        if self.sources:
            check_sources(self.sources, self.coils, path)
        elif self.coils:
            raise SchemaError(f"{path}.coils", "[[em.coils]] connect coils to [[em.sources]]: give the sources "
                              "(or drop the coils and keep em.circuit / em.current)")
        cc = self.coil_conductivity_curve
        if cc is not None:
            check_below_melting(cc, f"{path}.coil_conductivity_curve",
                                cc.melting_temperature if cc.melting_temperature is not None else COPPER_MELTING_K)
            if not self.coil_initial_temperature < (cc.melting_temperature or COPPER_MELTING_K):
                raise SchemaError(f"{path}.coil_initial_temperature",
                                  f"got {self.coil_initial_temperature:g}; must be below the coil's melting "
                                  f"temperature {cc.melting_temperature or COPPER_MELTING_K:g} (K)")
        if self.shots is not None and not self.has_bank:
            raise SchemaError(f"{path}.shots", "repeated shots are capacitor-bank discharges: give em.circuit or a "
                                               "'bank' source")
        if self.shots is not None and self.shots.voltages and len(self.shots.voltages) != self.shots.count:
            raise SchemaError(f"{path}.shots.voltages", f"got {len(self.shots.voltages)} voltages; needs "
                                                        f"{self.shots.count}, one per shot (or none: the bank's)")
        if self.getdp_process == "persistent" and self.time_scheme != "bdf2":
            raise SchemaError(f"{path}.getdp_process", "got 'persistent'; the persistent getdp implements "
                              "em.time_scheme = 'bdf2' only: set it, or getdp_process = 'auto' or 'per_step'")
