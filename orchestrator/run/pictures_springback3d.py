"""``plots/springback_[<stage>_]<body>.png`` of a 3D body (tetrahedra): its exterior surface before springback (the
output it started from, translucent grey) and after it (``fields/springback/``, coloured by the springback
displacement, mm), in the 3/4 view of the other 3D pictures, the springback magnified when it is too small to see
(:func:`.pictures_springback.magnification`, said in the title). Rendered with pyvista by the 3D renderer
(:func:`.pictures_mech.render_fields`); the 2D bodies' picture is :mod:`.pictures_springback`'s."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from .pictures_solid import boundary_faces, solid_camera
from .pictures_springback import magnification, springback_states, stage_of

log = logging.getLogger(__name__)

__all__ = ["render_springback3d"]


def render_springback3d(results_dir: Path) -> list[Path]:
    """Draw ``plots/springback_[<stage>_]<body>.png`` for every 3D body that sprang back
    (:func:`.pictures_springback.springback_states`); returns the pictures."""
    root = Path(results_dir)
    states = [st for st in springback_states(root) if st[1].solid]
    if not states:
        return []
    import pyvista as pv

    from .pictures_mech import _screenshot

    out = []
    for picture, a, x0, x1 in states:
        name = a.body
        d = x1 - x0
        norm = np.linalg.norm(d, axis=1)
        dmax = float(norm.max())
        gain = magnification(float(np.ptp(x0, axis=0).max()), dmax)
        faces, _ = boundary_faces(a.triangles)
        flat = np.column_stack([np.full(len(faces), 3), faces]).ravel()
        shown = pv.PolyData((x0 + gain * d) * 1e3, flat)
        shown.point_data["springback_mm"] = norm * 1e3
        p = pv.Plotter(off_screen=True, window_size=(1000, 650))
        p.set_background("white")
        p.add_mesh(pv.PolyData(x0 * 1e3, flat), color=(0.6, 0.6, 0.6), opacity=0.25, render=False,
                   label="before springback")
        p.add_mesh(shown, scalars="springback_mm", cmap="viridis", render=False,
                   scalar_bar_args=dict(title="springback displacement [mm]", vertical=True, position_x=0.86,
                                        position_y=0.15, height=0.7, width=0.06, title_font_size=14,
                                        label_font_size=12, n_labels=5, fmt="%.3g", color="black"))
        bounds = shown.bounds
        lo = np.minimum(np.array(bounds[::2]), x0.min(axis=0) * 1e3)
        hi = np.maximum(np.array(bounds[1::2]), x0.max(axis=0) * 1e3)
        solid_camera(p, (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
        p.camera.zoom(0.85)  # room for the colour bar on the right
        p.add_axes(color="black", xlabel="x", ylabel="y", zlabel="z")
        drawn = f", drawn x {gain:g}" if gain != 1.0 else ""
        stage = stage_of(picture, name)
        p.add_text(f"{name}: springback{f' ({stage})' if stage else ''}, largest {dmax * 1e3:.3g} mm{drawn}\n"
                   "grey: before springback; coloured: after (mm)", position="upper_left",
                   font_size=11, color="black", render=False)
        out.append(_screenshot(p, root / "plots" / picture))
        p.close()
        log.info("pictures: springback of %s drawn (largest %.3g mm%s)", name, dmax * 1e3, drawn)
    return out
