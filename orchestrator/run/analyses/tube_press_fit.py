"""Pulsed tube press fitting (paper sec. 6, Figures 6 and 7): surface displacements, contact pressure.

The case has bodies ``inner`` and ``outer`` (axisymmetric, x = r) and a contact pair inner -> outer.
History columns (means over the surface's nodes, reference configuration picks the nodes):

* ``inner_bore_ur_m``: radial displacement of the inner tube's bore (r = R0), where the pressure acts;
* ``inner_outer_ur_m``: of the inner tube's outer surface (the paper's dotted line);
* ``outer_inner_ur_m``: of the outer tube's inner surface (the paper's thin solid line);
* ``contact_pressure_mean_Pa``: soft-contact stress averaged over the inner tube's outer-surface
  nodes (0 where open), ``contact_pressure_max_Pa`` its maximum; ``contact_closed_fraction``.

Metrics: ``residual_contact_pressure_MPa`` (mean contact stress at the end of the run, after the
final relaxation), with ``[springback] contact = "kept"`` also ``springback_residual_contact_pressure_MPa`` (the
same mean after the static springback) and ``springback_inner_outer_ur_mm``, ``max_radial_displacement_inner_mm`` (largest bore displacement over time),
residual radial displacements, the first-contact time in t* = R0 / sqrt(sigma_s0 / rho), and the
end-state kinetic-to-elastic energy ratio (rest check). Serial runs only.
"""

from __future__ import annotations

import numpy as np
from . import Analysis


VANISH = 0.02  # "near zero": below 2 % of the residual pressure at zero (the smallest) clearance
#: the case's radii (m): inner tube bore R0 and outer radius R1, the outer tube's outer radius, the
#: contact layer h0 (cases/tube_press_fit/case.toml)
R0, R1, R_OUT, H0 = 0.0105, 0.0125, 0.025, 5.0e-5


def outer_sets(c_percent: float) -> list[str]:
    """``--set`` arguments that give the case a radial clearance of ``c_percent`` % of R0 beyond the
    contact layer: the outer tube's inner radius becomes R1 + c R0 + h0 (its outer radius stays)."""
    r2 = R1 + c_percent / 100.0 * R0 + H0
    return ["--set", f"bodies.outer.shape.origin=[{r2:.9g}, 0.0]", "--set", f"bodies.outer.shape.width={R_OUT - r2:.9g}"]


def critical_clearance_of_rows(rows: list[dict]) -> tuple[float, float]:
    """:func:`critical_clearance` of a sweep's rows (``clearance_percent``,
    ``residual_contact_pressure_MPa``; rows without a true ``ok`` left out), % of R0."""
    return critical_clearance([(r["clearance_percent"], r["residual_contact_pressure_MPa"]) for r in rows if r.get("ok")])


def critical_clearance(points: list[tuple[float, float]]) -> tuple[float, float]:
    """Bracket of the critical clearance from a sweep: (last clearance with residual pressure,
    first clearance from which on it stays below ``VANISH`` x the smallest clearance's value).

    Parameters
    ----------
    points : (clearance, residual contact pressure) pairs, any clearance unit, pressure in any unit.

    Returns
    -------
    (low, high) in the clearance unit; (nan, nan) if the pressure never vanishes.
    """
    pts = sorted(points)
    if not pts:
        return float("nan"), float("nan")
    limit = VANISH * pts[0][1]
    for k in range(1, len(pts)):
        if all(p <= limit for _, p in pts[k:]):
            return pts[k - 1][0], pts[k][0]
    return float("nan"), float("nan")


class TubePressFit(Analysis):
    """History columns, metrics and plots of the press-fitting case."""

    def __init__(self, case) -> None:
        self.case = case
        self.pair = next(i for i, c in enumerate(case.contact) if c.slave == "inner" and c.master == "outer")
        self.h0 = case.contact[self.pair].h0
        inner = next(b for b in case.bodies if b.name == "inner")
        outer = next(b for b in case.bodies if b.name == "outer")
        self.R0 = inner.shape.origin[0]
        self.R1 = inner.shape.origin[0] + inner.shape.width          # inner tube's outer radius
        self.R2 = outer.shape.origin[0]                               # outer tube's inner radius
        self.clearance = self.R2 - self.R1 - self.h0                  # gap beyond the force layer
        mat = case.materials[inner.material]
        self.t_star = self.R0 / np.sqrt(mat.initial_yield_stress / mat.density)
        self._nodes = None

    def _setup(self, solver) -> None:
        if solver.comm.size > 1:
            raise NotImplementedError("tube_press_fit analysis: serial runs only")
        i, o = solver.bodies["inner"], solver.bodies["outer"]
        tol = 1e-9
        self._nodes = {
            "bore": np.flatnonzero(np.abs(i.X0[: i.n_owned, 0] - self.R0) < tol),
            "inner_outer": np.flatnonzero(np.abs(i.X0[: i.n_owned, 0] - self.R1) < tol),
            "outer_inner": np.flatnonzero(np.abs(o.X0[: o.n_owned, 0] - self.R2) < tol),
        }

    def record(self, solver, row: dict[str, float] | None = None, pair: int | None = None) -> dict[str, float]:
        if self._nodes is None:
            self._setup(solver)
        i, o = solver.bodies["inner"], solver.bodies["outer"]
        n = self._nodes
        gids, _, p, _ = solver.contact_pressure(self.pair if pair is None else pair)
        n_surf = max(len(n["inner_outer"]), 1)
        return {
            "inner_bore_ur_m": float(i.u[n["bore"], 0].mean()),
            "inner_outer_ur_m": float(i.u[n["inner_outer"], 0].mean()),
            "outer_inner_ur_m": float(o.u[n["outer_inner"], 0].mean()),
            "contact_pressure_mean_Pa": float(p.sum() / n_surf) if len(p) else 0.0,
            "contact_pressure_max_Pa": float(p.max()) if len(p) else 0.0,
            "contact_closed_fraction": float(len(p) / n_surf),
        }

    def metrics(self, solver, history) -> dict[str, float]:
        t = history.column("time_s")
        pm = history.column("contact_pressure_mean_Pa")
        bore = history.column("inner_bore_ur_m")
        closed = np.flatnonzero(history.column("contact_closed_fraction") > 0)
        e = solver.energies()
        return {
            "residual_contact_pressure_MPa": float(pm[-1]) / 1e6,
            "max_radial_displacement_inner_mm": float(bore.max()) * 1e3,
            "residual_bore_ur_mm": float(bore[-1]) * 1e3,
            "residual_inner_outer_ur_mm": float(history.column("inner_outer_ur_m")[-1]) * 1e3,
            "residual_outer_inner_ur_mm": float(history.column("outer_inner_ur_m")[-1]) * 1e3,
            "contact_pressure_peak_MPa": float(history.column("contact_pressure_max_Pa").max()) / 1e6,
            "clearance_mm": self.clearance * 1e3,
            "clearance_over_R0": self.clearance / self.R0,
            "first_contact_t_over_tstar": float(t[closed[0]] / self.t_star) if len(closed) else float("nan"),
            "t_star_s": self.t_star,
            "final_kinetic_to_elastic": e["kinetic_J"] / max(e["elastic_J"], 1e-300),
        }

    def springback_metrics(self, sb) -> dict[str, float]:
        """The residual contact pressure after springback with contact kept (the mean over the inner tube's outer
        surface, 0 where open, as ``residual_contact_pressure_MPa``) and the contact surfaces' radial displacements,
        from the springback solver ``sb``; none if the pair was not kept."""
        if self.pair not in getattr(sb, "source_pairs", []):
            return {}
        r = self.record(sb, pair=sb.source_pairs.index(self.pair))
        return {"springback_residual_contact_pressure_MPa": r["contact_pressure_mean_Pa"] / 1e6,
                "springback_inner_outer_ur_mm": r["inner_outer_ur_m"] * 1e3,
                "springback_outer_inner_ur_mm": r["outer_inner_ur_m"] * 1e3}

    def plots(self, history, shapes, folder) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        tau = history.column("time_s") / self.t_star
        fig, ax = plt.subplots(2, 1, figsize=(7, 7), sharex=True)
        gap0 = self.R2 - self.R1  # clearance + h0: shifted so that touching curves mean contact
        ui = (history.column("inner_outer_ur_m") - gap0) / self.R0
        uo = history.column("outer_inner_ur_m") / self.R0
        ax[0].plot(tau, ui, ":", label="inner tube, outer surface (minus the initial gap)")
        ax[0].plot(tau, uo, "-", lw=0.8, label="outer tube, inner surface")
        closed = history.column("contact_closed_fraction") > 0.5
        ax[0].plot(tau[closed], uo[closed], ".", ms=2, color="k", label="in contact (joint motion)")
        ax[0].text(0.98, 0.02, "ΔR of the inner tube's outer surface = plotted + (c + h0) / R0", ha="right",
                   transform=ax[0].transAxes, fontsize=7)
        ax[0].set_ylabel("ΔR / R0")
        ax[0].legend(fontsize=8)
        ax[0].set_title(f"Press fit, clearance {100 * self.clearance / self.R0:.2f} % of R0 (cf. paper Fig. 6)")
        ax[1].plot(tau, history.column("contact_pressure_mean_Pa") / 1e6, label="mean over the surface")
        ax[1].plot(tau, history.column("contact_pressure_max_Pa") / 1e6, lw=0.6, label="max")
        ax[1].set_ylabel("contact pressure (MPa)")
        ax[1].set_xlabel("t / (R0 / sqrt(σs0 / ρ))")
        ax[1].legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(folder / "press_fit_displacements.png", dpi=110)
        plt.close(fig)
