"""The case file's materials (``[materials.<name>]``): elasticity, the linear law or a flow curve, a rate law, a
temperature per cell, a conductivity that follows it, a forming limit curve. Part of :mod:`.model`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from .conductivity import ConductivityCurve, LinearResistivitySpec, check_below_melting
from .flow import FlowCurveTable, JohnsonCookFlowTable, TableFlowTable, initial_yield_stress
from .forming_limit import FormingLimitTable
from .magnetic import BHCurveTable
from .schema import SchemaError, spec

__all__ = ["CowperSymondsTable", "JohnsonCookTable", "MaterialTable"]


# --------------------------------------------------------------------------- materials
@dataclass(frozen=True, kw_only=True)
class CowperSymondsTable:
    """Cowper–Symonds rate law: σ_s · (1 + (ε̇_p / D)^(1/q))."""

    type: Literal["cowper_symonds"] = spec(doc="rate law kind")
    D: float = spec(unit="1/s", gt=0.0, doc="reference strain rate D")
    q: float = spec(unit="-", gt=0.0, doc="exponent q")


@dataclass(frozen=True, kw_only=True)
class JohnsonCookTable:
    """Johnson–Cook rate term: σ_s · (1 + C ln(ε̇_p / ε̇_0)) for ε̇_p > ε̇_0."""

    type: Literal["johnson_cook"] = spec(doc="rate law kind")
    C: float = spec(unit="-", ge=0.0, doc="rate sensitivity C")
    reference_strain_rate: float = spec(1.0, unit="1/s", gt=0.0, doc="reference strain rate ε̇_0")


@dataclass(frozen=True, kw_only=True)
class MaterialTable:
    """Elastic–plastic material with linear isotropic hardening σ_s = σ0 + A ε_p (paper, sec. 4–5), or a flow
    curve; optionally a temperature per cell (adiabatic heating by the plastic work)."""

    density: float = spec(unit="kg/m^3", gt=0.0, doc="mass density ρ")
    shear_modulus: float = spec(unit="Pa", gt=0.0, doc="shear modulus G")
    bulk_modulus: float = spec(unit="Pa", gt=0.0, doc="bulk modulus K")
    yield_stress: float | None = spec(None, unit="Pa", gt=0.0, doc="initial yield stress σ0 of the linear law "
                                                                   "(required without flow_curve)")
    hardening_modulus: float = spec(0.0, unit="Pa", ge=0.0, doc="linear hardening modulus A")
    electrical_conductivity: float = spec(0.0, unit="S/m", ge=0.0, doc="σ for eddy currents (EM); left at 0 on a "
                                                                      "'getdp_template' deck's conductor: the deck's own")
    rate_law: CowperSymondsTable | JohnsonCookTable | None = spec(None, doc="optional strain-rate hardening")
    flow_curve: FlowCurveTable | None = spec(None, doc="flow curve σ_y(ε_p, ε̇, T) in place of the linear law "
                                                       "(yield_stress, hardening_modulus)")
    specific_heat: float | None = spec(None, unit="J/(kg·K)", gt=0.0, doc="c_p: a temperature per cell, raised "
                                       "adiabatically by β × the plastic work; unset: no temperature")
    taylor_quinney: float = spec(0.9, unit="-", ge=0.0, le=1.0, doc="β, the share of the plastic work that heats")
    initial_temperature: float = spec(293.15, unit="K", gt=0.0, doc="temperature of every cell at the start")
    melting_temperature: float | None = spec(
        None, unit="K", gt=0.0, doc="the run stops in one line when a cell of a body of this material reaches it "
                                    "(default: the Johnson–Cook flow curve's T_melt, else the conductivity_curve's; "
                                    "needs specific_heat)")
    conductivity_curve: ConductivityCurve | None = spec(
        None, doc="[materials.<name>.conductivity_curve] σ(T) of a conductor body in place of the constant "
                  "electrical_conductivity: type = 'table' (temperatures, conductivities) or 'linear_resistivity' "
                  "(ρ = ρ_ref (1 + α (T − T_ref))); GetDP gets σ per element from the cells' temperatures every EM "
                  "step (needs specific_heat; 2D and 3D, on either getdp; docs/guide/em.md)")
    relative_permeability: float = spec(
        1.0, unit="-", gt=0.0, le=1e6, doc="μ_r of the material's EM regions (conductor bodies, 2D and 3D), constant; "
                                           "1: vacuum (the default)")
    bh_curve: BHCurveTable | None = spec(
        None, doc="[materials.<name>.bh_curve] a magnetisation curve B(H) in place of relative_permeability: "
                  "field_strength (A/m) and flux_density (T), piecewise linear from the origin, the vacuum slope "
                  "beyond the last point; every EM step is then solved by Newton's method (em.newton_tolerance; "
                  "getdp per step; docs/guide/em.md)")
    forming_limit: FormingLimitTable | None = spec(
        None, doc="[materials.<name>.forming_limit] forming limit curve of a sheet of this material: its bodies "
                  "get per-element major/minor true strains and the margin below the curve (fields, history "
                  "<body>_flc_margin_min, summary, plots/<body>_fld.png; docs/mechanics.md)")

    def validate(self, path: str) -> None:
        fc = self.flow_curve
        if fc is None and self.yield_stress is None:
            raise SchemaError(f"{path}.yield_stress", "missing required key (a number > 0, in Pa), or give a "
                                                      "flow_curve")
        if fc is not None and self.yield_stress is not None:
            raise SchemaError(f"{path}.yield_stress", "give either yield_stress (with hardening_modulus: the linear "
                                                      "law) or flow_curve, not both")
        if self.rate_law is not None and (isinstance(fc, JohnsonCookFlowTable) or (
                isinstance(fc, TableFlowTable) and len(fc.strain_rates) > 1)):
            raise SchemaError(f"{path}.rate_law", "the flow_curve has its own strain-rate term (Johnson–Cook, or "
                                                  "curves per strain rate); remove rate_law")
        cc = self.conductivity_curve
        if self.melting_temperature is not None:
            if self.specific_heat is None:
                raise SchemaError(f"{path}.melting_temperature", "needs specific_heat (J/(kg·K)): without a "
                                                                 "temperature per cell no cell can reach it")
            if not self.initial_temperature < self.melting_temperature:
                raise SchemaError(f"{path}.initial_temperature",
                                  f"got {self.initial_temperature:g}; must be below melting_temperature = "
                                  f"{self.melting_temperature:g} (K)")
        if cc is not None:
            melt = cc.melting_temperature if cc.melting_temperature is not None else self.melting_limit
            check_below_melting(cc, f"{path}.conductivity_curve", melt)
            if cc.melting_temperature is not None and not self.initial_temperature < cc.melting_temperature:
                raise SchemaError(f"{path}.initial_temperature",
                                  f"got {self.initial_temperature:g}; must be below the conductivity_curve's "
                                  f"melting_temperature = {cc.melting_temperature:g} (K)")
            if self.specific_heat is None:
                raise SchemaError(f"{path}.conductivity_curve", "needs specific_heat (J/(kg·K)): σ follows the "
                                                                "temperature of the cells")
            if isinstance(cc, LinearResistivitySpec) and not self.electrical_conductivity > 0:
                raise SchemaError(f"{path}.electrical_conductivity", "must be > 0 (S/m): the linear_resistivity "
                                                                     "law's σ at its reference_temperature")
        if self.bh_curve is not None and self.relative_permeability != 1.0:
            raise SchemaError(f"{path}.relative_permeability", f"got {self.relative_permeability:g}; give either "
                              "relative_permeability or bh_curve, not both")
        if isinstance(fc, JohnsonCookFlowTable) and not self.initial_temperature < fc.melting_temperature:
            raise SchemaError(f"{path}.initial_temperature",
                              f"got {self.initial_temperature:g}; must be below the flow curve's melting_temperature "
                              f"= {fc.melting_temperature:g} (K)")

    @property
    def melting_limit(self) -> float | None:
        """The temperature (K) at which a cell counts as molten and the run stops: ``melting_temperature``, else
        the Johnson–Cook flow curve's T_melt, else the conductivity curve's melting temperature; None: none."""
        if self.melting_temperature is not None:
            return self.melting_temperature
        if isinstance(self.flow_curve, JohnsonCookFlowTable):
            return self.flow_curve.melting_temperature
        cc = self.conductivity_curve
        return cc.melting_temperature if cc is not None else None

    @property
    def initial_yield_stress(self) -> float:
        """σ0 of the linear law, or the flow curve's yield stress at zero plastic strain, Pa."""
        return self.yield_stress if self.flow_curve is None else initial_yield_stress(self.flow_curve)


