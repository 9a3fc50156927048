"""The forming limit diagram (FLD) of each body whose material has a forming limit curve:
``plots/<body>_fld.png``, drawn with matplotlib from the field files (:mod:`.mech_fields`).

Every cell's minor and major true strains (ε2, ε1) at the last output time, coloured by zone (safe,
marginal, failed: :mod:`pulseform.orchestrator.mech.forming_limit`), over the curve, the curve lowered by
its safety margin (the marginal zone between them) and the strain paths of uniaxial tension
(ε2 = −ε1/2), plane strain (ε2 = 0) and equibiaxial stretching (ε2 = ε1) for orientation.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ..mech.forming_limit import ZONES, FormingLimitCurve, flc_bodies
from .mech_fields import read_fields
from .units import time_axis

log = logging.getLogger(__name__)

__all__ = ["draw_fld", "plot_fld"]

#: colours of the zones safe, marginal, failed
ZONE_COLOURS = ("tab:green", "orange", "tab:red")


def draw_fld(results_dir: Path, case) -> list[Path]:
    """``plots/<body>_fld.png`` of every body of ``case`` with a forming limit curve, from the last output
    time of its field file."""
    root = Path(results_dir)
    fields = read_fields(root)
    out = []
    for name, curve in flc_bodies(case).items():
        if name not in fields:
            continue
        bf = fields[name]
        k = len(bf.times) - 1
        d = bf.read(k, ("minor_strain", "major_strain"))
        out.append(plot_fld(curve, d["minor_strain"], d["major_strain"], root / "plots" / f"{name}_fld.png",
                            f"{case.case.name}: {name}, t = {bf.times[k] * time_axis(case.time.end).scale:.4g} "
                            f"{time_axis(case.time.end).unit}"))
    return out


def plot_fld(curve: FormingLimitCurve, minor: np.ndarray, major: np.ndarray, path: Path, title: str = "") -> Path:
    """The forming limit diagram of the cells' strains ``minor``, ``major`` (-) under ``curve``, into ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    minor, major = np.asarray(minor, dtype=float), np.asarray(major, dtype=float)
    zone = curve.zone(curve.margin(minor, major)).astype(int)
    lo = min(float(curve.minor[0]), float(minor.min(initial=0.0))) - 0.05
    hi = max(float(curve.minor[-1]), float(minor.max(initial=0.0))) + 0.05
    top = 1.15 * max(float(curve.major.max()), float(major.max(initial=0.0)), 0.05)
    bottom = min(0.0, float(major.min(initial=0.0)) - 0.02)
    e2 = np.unique(np.concatenate([[lo], curve.minor[(curve.minor > lo) & (curve.minor < hi)], [hi]]))
    limit = curve.limit(e2)
    fig, ax = plt.subplots(figsize=(7, 5.5))
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.11, top=0.91)
    ax.fill_between(e2, limit, top, color=ZONE_COLOURS[2], alpha=0.08, lw=0)
    ax.fill_between(e2, limit - curve.safety_margin, limit, color=ZONE_COLOURS[1], alpha=0.15, lw=0)
    ax.plot(e2, limit, "k-", lw=1.6, label="forming limit curve (flat beyond its points)")
    ax.plot(curve.minor, curve.major, "ko", ms=3)
    if curve.safety_margin > 0:
        ax.plot(e2, limit - curve.safety_margin, "k--", lw=0.9, label=f"safety margin {curve.safety_margin:g}")
    u, q = max(lo, -top / 2), min(hi, top)   # ends of the uniaxial and equibiaxial paths on the axes
    for (x1, y1), text in (((u, -2 * u), "uniaxial"), ((0.0, top), "plane strain"), ((q, q), "equibiaxial")):
        ax.plot([0.0, x1], [0.0, y1], color="0.6", lw=0.6, ls=":")
        ax.annotate(text, (x1, 0.97 * y1), fontsize=7, color="0.45", va="top",
                    ha="right" if x1 > 0 else "left" if x1 < 0 else "center")
    for z in (0, 1, 2):
        sel = zone == z
        if sel.any():
            ax.scatter(minor[sel], major[sel], s=6, color=ZONE_COLOURS[z], label=f"{ZONES[z]}: {int(sel.sum())} cells",
                       zorder=3)
    if len(minor):
        w = int(np.argmin(curve.margin(minor, major)))
        ax.scatter([minor[w]], [major[w]], s=60, facecolors="none", edgecolors="k", zorder=4,
                   label=f"least margin {float(curve.margin(minor[w], major[w])):.3g}")
    ax.set_xlim(lo, hi)
    ax.set_ylim(bottom, top)
    ax.set_xlabel("minor true strain ε2 [-]")
    ax.set_ylabel("major true strain ε1 [-]")
    ax.set_title(f"Forming limit diagram, {title}" if title else "Forming limit diagram", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower left" if hi > -lo else "lower right")
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=100)
    plt.close(fig)
    tmp.replace(path)
    return path
