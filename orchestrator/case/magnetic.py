"""Case-file keys of a material's magnetic behaviour (issue 35): ``relative_permeability`` and the B–H curve
``[materials.<name>.bh_curve]``, their one-line checks, and the GetDP curve they make
(:class:`pulseform.solvers.getdp.bh_curve.BHCurve`: piecewise linear from the origin, the vacuum slope beyond
the last point; docs/guide/em.md, Magnetic materials).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pulseform.solvers.getdp.bh_curve import BHCurve

from .deck_magnetic import magnetic_deck_refusal
from .em_cores import check_core_materials
from .flow import check_increasing
from .schema import SchemaError, spec

__all__ = ["BHCurveTable", "bh_curve", "magnetic_keywords", "check_magnetic_em", "MAX_BH_POINTS"]

#: the most points a B–H table may give
MAX_BH_POINTS = 1000


@dataclass(frozen=True, kw_only=True)
class BHCurveTable:
    """A magnetisation curve B(H), piecewise linear through the points from the origin (0, 0) (added when the
    table does not start there), the vacuum slope μ0 beyond the last point."""

    field_strength: tuple[float, ...] = spec(
        unit="A/m", ge=0.0, doc="H of the curve's points, strictly increasing (2 to 1000 points besides the origin)")
    flux_density: tuple[float, ...] = spec(
        unit="T", ge=0.0, doc="B at those H, strictly increasing; the last point must have B >= μ0 H (the curve "
                              "goes on with the vacuum slope μ0)")

    def validate(self, path: str) -> None:
        h, b = self.field_strength, self.flux_density
        if len(h) > MAX_BH_POINTS + 1:
            raise SchemaError(f"{path}.field_strength", f"got {len(h)} points; give at most {MAX_BH_POINTS}")
        if len(b) != len(h):
            raise SchemaError(f"{path}.flux_density", f"got {len(b)} values for {len(h)} field strengths; give one "
                                                      "flux density (T) per field strength")
        for key, values, unit in (("field_strength", h, "A/m"), ("flux_density", b, "T")):
            for i, v in enumerate(values):
                if not math.isfinite(v):
                    raise SchemaError(f"{path}.{key}[{i}]", f"got {v!r}; every value must be a finite number >= 0 "
                                                            f"({unit})")
            check_increasing(values, f"{path}.{key}", unit)
        try:
            BHCurve(h=tuple(h), b=tuple(b))
        except ValueError as exc:   # too few points (the H column), B < mu0 H at the top (the B column)
            key = "flux_density" if "mu0" in str(exc) else "field_strength"
            raise SchemaError(f"{path}.{key}", f"{exc} (H in A/m, B in T)") from None


def bh_curve(table: BHCurveTable | None) -> BHCurve | None:
    """The GetDP curve of ``table`` (None without one)."""
    if table is None:
        return None
    return BHCurve(h=tuple(table.field_strength), b=tuple(table.flux_density))


def magnetic_keywords(material) -> dict:
    """A material's ``mu_r`` and ``bh_curve`` as the keywords of a GetDP conductor
    (:class:`pulseform.solvers.getdp.model.Conductor`, :class:`~pulseform.solvers.getdp.model.MagneticCore`)."""
    return {"mu_r": material.relative_permeability, "bh_curve": bh_curve(material.bh_curve)}


def check_magnetic_em(case) -> None:
    """Magnetic materials of a coupled case's bodies and cores (``[[geometry.cores]]``, whose materials must be
    magnetic): on pulseform's own decks or a user deck that includes the runner's magnetic block
    (:func:`.deck_magnetic.magnetic_deck_refusal`), no applied field (its reduced-field source needs μ0
    everywhere) (one line naming the key otherwise). A B–H curve runs on either
    getdp (per step or persistent: Newton's iterations in each EM step)."""
    check_core_materials(case)
    cores = getattr(case.geometry, "cores", ()) or ()
    keys = [(f"materials.{m}", case.materials[m]) for m in [b.material for b in case.bodies] + [c.material
                                                                                             for c in cores]
            if m in case.materials]
    magnetic = [(k, m) for k, m in keys if m.bh_curve is not None or m.relative_permeability != 1.0]
    if not magnetic:
        return
    key, mat = magnetic[0]
    key += ".bh_curve" if mat.bh_curve is not None else ".relative_permeability"
    g = case.geometry
    if getattr(g, "type", None) == "user_deck":
        refusal = magnetic_deck_refusal(g, key)
        if refusal is not None:
            raise SchemaError(key, refusal)
    if case.em.applied_field is not None:
        raise SchemaError(key, "a magnetic material and em.applied_field: the applied field's reduced-field source "
                               "is exact only with μ0 everywhere; drive the field with a coil instead")
