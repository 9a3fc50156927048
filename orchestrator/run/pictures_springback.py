"""``plots/springback_<body>.png``: a planar or axisymmetric body before springback (its last field output at
time.end, grey) and after it (``fields/springback/``, coloured by the springback displacement), 1:1, with the
springback also drawn magnified when it is too small to see; from the field files, so ``pulseform plot`` draws it
again. 3D bodies: :mod:`.pictures_springback3d` (drawn by the 3D renderer with the other pyvista pictures)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from .mech_fields import read_fields, read_folder
from .pictures_mech import _save_fig, boundary_edges

log = logging.getLogger(__name__)

__all__ = ["draw_springback", "magnification"]

#: the springback is drawn magnified when its largest value is below VISIBLE of the body's size, by the power of
#: ten that makes it at least SHOWN of it
VISIBLE, SHOWN = 0.005, 0.02


def magnification(size: float, dmax: float) -> float:
    """The factor the springback is drawn with: 1 when its largest value ``dmax`` is at least VISIBLE of the body's
    ``size`` (both m), else the power of ten that makes it at least SHOWN of it."""
    return 1.0 if dmax >= VISIBLE * size or dmax == 0.0 else float(10 ** np.ceil(np.log10(SHOWN * size / dmax)))


def draw_springback(results_dir: Path, case=None) -> list[Path]:
    """Draw ``plots/springback_<body>.png`` for every 2D body of ``fields/springback/``; returns the pictures
    (``case``: unused, the signature of the other picture groups)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    root = Path(results_dir)
    (root / "plots").mkdir(exist_ok=True)
    after = read_folder(root / "fields" / "springback")
    before = read_fields(root)
    out = []
    for name, a in after.items():
        if a.solid:
            continue  # the 3D renderer's (pictures_springback3d)
        if name not in before:
            log.info("pictures: no springback picture of %s (no field file before springback)", name)
            continue
        b = before[name]
        x0 = b.current(len(b.times) - 1)
        x1 = a.current(len(a.times) - 1)
        d = x1 - x0
        dmax = float(np.linalg.norm(d, axis=1).max())
        gain = magnification(float(np.ptp(x0, axis=0).max()), dmax)
        edges, _ = boundary_edges(b.triangles)
        fig, ax = plt.subplots(figsize=(9.0, 5.0))
        ax.add_collection(LineCollection(x0[edges] * 1e3, colors="0.5", linewidths=1.0, linestyles="dashed",
                                         label="before springback (time.end)"))
        norm = np.linalg.norm(d, axis=1)
        seg = (x0 + gain * d)[edges] * 1e3
        lc = LineCollection(seg, cmap="viridis", linewidths=1.6,
                            label="after springback" + (f" (springback x {gain:g})" if gain != 1.0 else ""))
        lc.set_array(0.5 * (norm[edges[:, 0]] + norm[edges[:, 1]]) * 1e3)
        ax.add_collection(lc)
        fig.colorbar(lc, ax=ax, label="springback displacement [mm]", fraction=0.04, pad=0.02)
        pts = np.vstack([x0, x0 + gain * d]) * 1e3
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = 0.05 * max(float((hi - lo).max()), 1e-9)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal", adjustable="datalim")
        axi = a.axisymmetric
        ax.set_xlabel("r [mm]" if axi else "x [mm]")
        ax.set_ylabel("z [mm]" if axi else "y [mm]")
        ax.set_title(f"{name}: springback, largest {dmax * 1e3:.3g} mm", fontsize=10)
        ax.legend(fontsize=8, loc="best")
        ax.grid(alpha=0.3)
        fig.tight_layout()
        out.append(_save_fig(fig, root / "plots" / f"springback_{name}.png"))
    return out
