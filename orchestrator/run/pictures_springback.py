"""``plots/springback_[<stage>_]<body>.png``: a planar or axisymmetric body before springback (the field output the
springback started from: time.end, or the end of the stage before a springback stage; grey) and after it
(``fields/springback/``, coloured by the springback displacement), 1:1, with the
springback also drawn magnified when it is too small to see; from the field files, so ``pulseform plot`` draws it
again. 3D bodies: :mod:`.pictures_springback3d` (drawn by the 3D renderer with the other pyvista pictures)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from .mech_fields import BodyFields, read_files
from .pictures_mech import _run_name, _save_fig, boundary_edges

log = logging.getLogger(__name__)

__all__ = ["draw_springback", "magnification", "springback_states", "stage_of"]

#: the springback is drawn magnified when its largest value is below VISIBLE of the body's size, by the power of
#: ten that makes it at least SHOWN of it
VISIBLE, SHOWN = 0.005, 0.02


def magnification(size: float, dmax: float) -> float:
    """The factor the springback is drawn with: 1 when its largest value ``dmax`` is at least VISIBLE of the body's
    ``size`` (both m), else the power of ten that makes it at least SHOWN of it."""
    return 1.0 if dmax >= VISIBLE * size or dmax == 0.0 else float(10 ** np.ceil(np.log10(SHOWN * size / dmax)))


def stage_of(picture: str, body: str) -> str:
    """The springback stage a picture ``springback_[<stage>_]<body>.png`` shows ('' for the case's ``[springback]``)."""
    return picture[len("springback_"):-len(body) - len(".png")].rstrip("_")


def _positions(b: BodyFields, k: int) -> np.ndarray:
    """(N, 3) node positions of output ``k``, m (z = 0 for a 2D body)."""
    u = b.read(k, ("displacement_m",))["displacement_m"]
    x = np.zeros((len(b.points), 3))
    x[:, :u.shape[1]] = b.points[:, :u.shape[1]] + u
    return x


def _ended_at(files: list[Path], body: str, t: float) -> BodyFields | None:
    """The body's series in the one of its run field ``files`` whose last output is at ``t`` (s): the state a
    springback at ``t`` started from (in a staged run the next stage's file starts at ``t`` with the released state)."""
    for f in files:
        b = read_files([f]).get(body)
        if b is not None and len(b.times) and abs(float(b.times[-1]) - t) <= 1e-9 * max(abs(t), 1e-30):
            return b
    return None


def springback_states(results_dir: Path) -> list[tuple[str, BodyFields, np.ndarray, np.ndarray]]:
    """Per body and springback field file (``fields/springback/<case>[_<stage>]_<body>.h5``: the case's
    ``[springback]``, or each springback stage of ``[[stages]]``): (picture name ``springback_[<stage>_]<body>.png``,
    the body's fields after springback, its node positions before (the run's output the springback started from)
    and after, (N, 3) m)."""
    root = Path(results_dir)
    files = sorted((root / "fields" / "springback").glob("*.h5"))
    run_files = sorted((root / "fields").glob("*.h5"))
    case = _run_name(root)
    out = []
    for f in files:
        label = f.stem[len(case) + 1:] if f.stem.startswith(case + "_") else f.stem
        for name, a in read_files([f]).items():
            t = float(a.times[-1])
            b = _ended_at(run_files, name, t)
            if b is None:
                log.info("pictures: no springback picture of %s (no field file ending at t = %.6g s)", name, t)
                continue
            out.append((f"springback_{label}.png", a, _positions(b, len(b.times) - 1), _positions(a, len(a.times) - 1)))
    return out


def draw_springback(results_dir: Path, case=None) -> list[Path]:
    """Draw ``plots/springback_[<stage>_]<body>.png`` for every 2D body that sprang back
    (:func:`springback_states`); returns the pictures (``case``: unused, the signature of the other picture
    groups)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    root = Path(results_dir)
    (root / "plots").mkdir(exist_ok=True)
    out = []
    for picture, a, x0, x1 in springback_states(root):
        if a.solid:
            continue  # the 3D renderer's (pictures_springback3d)
        name = a.body
        x0, x1 = x0[:, :2], x1[:, :2]
        d = x1 - x0
        dmax = float(np.linalg.norm(d, axis=1).max())
        gain = magnification(float(np.ptp(x0, axis=0).max()), dmax)
        edges, _ = boundary_edges(a.triangles)
        fig, ax = plt.subplots(figsize=(9.0, 5.0))
        ax.add_collection(LineCollection(x0[edges] * 1e3, colors="0.5", linewidths=1.0, linestyles="dashed",
                                         label="before springback"))
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
        stage = stage_of(picture, name)
        ax.set_title(f"{name}: springback{f' ({stage})' if stage else ''}, largest {dmax * 1e3:.3g} mm", fontsize=10)
        ax.legend(fontsize=8, loc="best")
        ax.grid(alpha=0.3)
        fig.tight_layout()
        out.append(_save_fig(fig, root / "plots" / picture))
    return out
