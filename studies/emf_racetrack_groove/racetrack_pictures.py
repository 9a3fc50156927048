"""Pictures of the study's coupled racetrack run (:mod:`racetrack_run`), drawn from its output folder (the
sections y = 0 are also drawn for every 3D geometry-file case by the product:
orchestrator/run/pictures_section3d.py).

* ``plots/section_y0_{von_mises,plastic_strain}.png`` (matplotlib): the deformed sheet and die in the
  symmetry plane y = 0 (the faces of their tetrahedra on that plane, true scale), coloured by the
  cell values, at up to six output times; the groove is the notch in the die above the winding;
* ``plots/force_density_peak.png`` (matplotlib): the sheet's Lorentz force density f_z at the peak
  coil current on its lower face (top view of the quarter, the coil's turns outlined) and in the
  section y = 0 through the thickness (where the eddy currents flow: the skin);
* ``plots/deformed_sheet_{plastic_strain,von_mises}.png`` and ``plots/deformed_die_von_mises.png``
  (pyvista, off-screen): the deformed sheet seen from above (the die would hide it) and the die seen
  from below (its groove), true scale, at four output times, one colour scale per picture; rendered in
  a child process (``python racetrack_pictures.py ROOT FOLDER``).

Lengths are shown in mm, stresses in MPa, force densities in GN/m^3.
"""

from __future__ import annotations

import json
import logging
import subprocess
import sys
from pathlib import Path

import numpy as np

from pulseform.orchestrator.run.mech_fields import read_fields
from pulseform.orchestrator.run.pictures_mech import _pick, _save_fig
from pulseform.orchestrator.run.pictures_solid import boundary_faces

log = logging.getLogger(__name__)

__all__ = ["draw_racetrack", "plane_faces", "plot_sections", "plot_force_density"]

PANELS = 6


def plane_faces(points: np.ndarray, tets: np.ndarray, axis: int, value: float, tol: float = 1e-9):
    """Boundary faces (F, 3) of ``tets`` whose three nodes lie on the plane x_axis = value (reference
    coordinates ``points``, m), and the cell of each."""
    faces, owner = boundary_faces(tets)
    on = np.all(np.abs(points[faces, axis] - value) <= tol, axis=1)
    return faces[on], owner[on]


def plot_sections(root: Path, folder: Path) -> list[Path]:
    """The y = 0 sections of the deformed bodies at up to :data:`PANELS` output times (module docstring)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation

    bodies = read_fields(root)
    ref = max(bodies.values(), key=lambda b: len(b.times))
    picks = _pick(len(ref.times), PANELS)
    sec = {n: plane_faces(b.points, b.triangles, 1, 0.0) for n, b in bodies.items()}
    paths = []
    for field, stem, title, scale, cmap in (("von_mises_Pa", "von_mises", "von Mises stress [MPa]", 1e-6, "turbo"),
                                            ("plastic_strain", "plastic_strain", "equivalent plastic strain [-]", 1.0,
                                             "viridis")):
        data = {n: [b.read(k, ("displacement_m", field)) for k in picks] for n, b in bodies.items()}
        top = max(float(np.percentile(d[field][sec[n][1]], 99.5)) * scale for n in bodies for d in data[n] if sec[n][1].size)
        top = top if top > 0 else 1.0
        cols = 2
        rows = int(np.ceil(len(picks) / cols))
        fig, axes = plt.subplots(rows, cols, figsize=(12, 2.6 * rows + 0.8), squeeze=False, constrained_layout=True)
        for i, k in enumerate(picks):
            ax = axes[i // cols, i % cols]
            for n, b in bodies.items():
                faces, owner = sec[n]
                if not faces.size:
                    continue
                d = data[n][i]
                x = (b.points + d["displacement_m"]) * 1e3
                tri = Triangulation(x[:, 0], x[:, 2], faces)
                pc = ax.tripcolor(tri, facecolors=d[field][owner] * scale, cmap=cmap, vmin=0.0, vmax=top,
                                  edgecolors="face", linewidth=0.0)
            ax.set_aspect("equal")
            ax.set_title(f"t = {ref.times[k] * 1e6:.3g} µs", fontsize=10)
            ax.set_xlabel("x [mm]")
            ax.set_ylabel("z [mm]")
        for j in range(len(picks), rows * cols):
            axes[j // cols, j % cols].axis("off")
        fig.colorbar(pc, ax=axes, label=title, shrink=0.8, extend="max")
        fig.suptitle(f"racetrack: sheet (below) and die (above) in the symmetry plane y = 0, true scale")
        paths.append(_save_fig(fig, folder / f"section_y0_{stem}.png"))
        plt.close(fig)
    return paths


def plot_force_density(root: Path, folder: Path, turns: list[tuple[float, float]] | None = None,
                       half_straight: float | None = None) -> Path | None:
    """The sheet's force density f_z at the peak current: lower face (top view) and section y = 0;
    ``turns`` ((inner, outer) half widths, m) and ``half_straight`` (m) outline the coil."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation

    path = Path(root) / "em" / "force_density_peak.npz"
    if not path.is_file():
        log.info("no %s: no force density picture", path)
        return None
    d = np.load(path)
    sheet = d["body"] == 0
    tets, x, f = d["cells"][sheet], d["points"], d["force_density"][sheet] * 1e-9
    x0 = d["reference_points"]
    low, low_owner = plane_faces(x0, tets, 2, x0[np.unique(tets), 2].min(), tol=1e-7)
    mid, mid_owner = plane_faces(x0, tets, 1, 0.0, tol=1e-7)
    vmax = float(np.percentile(np.abs(f[:, 2]), 99.5)) or 1.0
    fig, (a0, a1) = plt.subplots(2, 1, figsize=(8.5, 10), gridspec_kw={"height_ratios": [3.2, 1]},
                                 constrained_layout=True, sharex=True)
    tri = Triangulation(x0[:, 0] * 1e3, x0[:, 1] * 1e3, low)
    pc = a0.tripcolor(tri, facecolors=f[low_owner, 2], cmap="RdBu_r", vmin=-vmax, vmax=vmax)
    if turns and half_straight is not None:
        for r0, r1 in turns:
            for r in (r0, r1):
                phi = np.linspace(0, np.pi / 2, 40)
                a0.plot(np.r_[r, r, r * np.cos(phi)] * 1e3, np.r_[0, half_straight, half_straight + r * np.sin(phi)] * 1e3,
                        color="k", lw=0.6, alpha=0.6)
    a0.set_aspect("equal")
    reach = np.abs(f[low_owner, 2]) > 0.01 * vmax   # zoom to where the force is
    if reach.any():
        xy = x0[low[reach].ravel()] * 1e3
        a0.set_xlim(0, min(xy[:, 0].max() + 3, x0[:, 0].max() * 1e3))
        a0.set_ylim(0, min(xy[:, 1].max() + 3, x0[:, 1].max() * 1e3))
    a0.set_ylabel("y [mm]")
    a0.set_title("sheet's lower face, reference positions (coil turns outlined)")
    tri = Triangulation(x[:, 0] * 1e3, x[:, 2] * 1e3, mid)
    a1.tripcolor(tri, facecolors=f[mid_owner, 2], cmap="RdBu_r", vmin=-vmax, vmax=vmax)
    a1.set_xlabel("x [mm]")
    a1.set_ylabel("z [mm]")
    zs = x[np.unique(mid), 2] * 1e3
    a1.set_ylim(zs.min() - 0.2, zs.max() + 0.2)
    a1.set_title("section y = 0 through the thickness, current positions (z stretched)", fontsize=10)
    fig.colorbar(pc, ax=[a0, a1], label="Lorentz force density f_z [GN/m³]", shrink=0.7, extend="both")
    fig.suptitle(f"racetrack: force density at the peak coil current ({float(d['coil_current_A']) / 1e3:.1f} kA, "
                 f"t = {float(d['time_s']) * 1e6:.3g} µs)")
    out = _save_fig(fig, Path(folder) / "force_density_peak.png")
    plt.close(fig)
    return out


def draw_racetrack(root: Path, geometry=None, *, three_d: bool = True) -> list[Path]:
    """Every picture of the module docstring for the run folder ``root``; ``geometry`` (a
    ``RacetrackGroove``) outlines the coil in the force picture; ``three_d``: also the pyvista views."""
    root = Path(root)
    folder = root / "plots"
    folder.mkdir(parents=True, exist_ok=True)
    paths = plot_sections(root, folder)
    turns = [geometry.turn_x(i) for i in range(geometry.turns)] if geometry is not None else None
    fd = plot_force_density(root, folder, turns, geometry.half_straight if geometry is not None else None)
    paths += [fd] if fd else []
    if three_d:
        paths += render_3d_isolated(root, folder)
    return paths


def render_3d_isolated(root: Path, folder: Path, time_limit: float = 600.0) -> list[Path]:
    """:func:`render_3d` in a child process (``python`` this file): VTK aborted the process once
    (std::bad_alloc in the scalar bar's layout, after a run in the same process), which must not take
    the caller down; a failure is logged as a warning and gives no paths."""
    argv = [sys.executable, str(Path(__file__).resolve()), str(root), str(folder)]
    try:
        r = subprocess.run(argv, capture_output=True, text=True, timeout=time_limit)
    except subprocess.TimeoutExpired:
        log.warning("3D pictures: no result within %g s", time_limit)
        return []
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("[")]
    if r.returncode != 0 or not lines:
        log.warning("3D pictures not drawn (exit code %s): %s", r.returncode, r.stderr.strip().splitlines()[-1:] )
        return []
    return [Path(x) for x in json.loads(lines[-1])]


#: (body, field, file stem, colour-bar title, scale, colour map, camera direction from the centre)
VIEWS_3D = (("sheet", "plastic_strain", "deformed_sheet_plastic_strain", "equivalent plastic strain [-]", 1.0,
             "viridis", (0.7, -1.6, 0.8)),
            ("sheet", "von_mises_Pa", "deformed_sheet_von_mises", "von Mises stress [MPa]", 1e-6, "turbo",
             (0.7, -1.6, 0.8)),
            ("die", "von_mises_Pa", "deformed_die_von_mises", "von Mises stress [MPa]", 1e-6, "turbo",
             (1.0, -1.3, -1.4)))


def render_3d(root: Path, folder: Path, panels: int = 4) -> list[Path]:
    """The pyvista pictures of the module docstring (off-screen, in this process)."""
    import pyvista as pv

    from pulseform.orchestrator.run.pictures_mech import _screenshot
    from pulseform.orchestrator.run.pictures_solid import solid_surface

    pv.OFF_SCREEN = True
    pv.global_theme.multi_samples = 0
    folder = Path(folder)
    bodies = read_fields(root)
    paths = []
    for name, fld, stem, title, scale, cmap, view in VIEWS_3D:
        b = bodies[name]
        picks = [k for k in range(1, len(b.times))][-panels:] if len(b.times) <= panels + 1 \
            else _pick(len(b.times), panels)
        faces, owner = boundary_faces(b.triangles)
        meshes, top = [], 0.0
        for k in picks:
            d = b.read(k, ("displacement_m", fld))
            vals = np.asarray(d[fld], float) * scale
            pts, flat, v = solid_surface((b.points + d["displacement_m"]) * 1e3, faces, owner, vals)
            m = pv.PolyData(pts, flat)
            m.cell_data["value"] = v
            meshes.append(m)
            top = max(top, float(np.percentile(vals, 99.5)))
        cols = 2
        rows = int(np.ceil(len(picks) / cols))
        p = pv.Plotter(off_screen=True, shape=(rows + 1, cols), row_weights=[1.0] * rows + [0.22],
                       groups=[(rows, np.s_[:])], window_size=(700 * cols, 460 * rows + 110), border=False)
        p.set_background("white")
        for i, (k, m) in enumerate(zip(picks, meshes)):
            p.subplot(i // cols, i % cols)
            p.add_mesh(m, scalars="value", cmap=cmap, clim=(0.0, top or 1.0), show_scalar_bar=False,
                       above_color="magenta", show_edges=False, render=False)
            p.add_text(f"{name}, t = {b.times[k] * 1e6:.3g} µs" + (" (from below)" if view[2] < 0 else ""),
                       position="upper_left", font_size=11, color="black", render=False)
            c = np.array(m.center)
            size = max(np.ptp(m.points, axis=0))
            d = np.array(view) / np.linalg.norm(view)
            p.camera_position = [tuple(c + 2.0 * size * d), tuple(c), (0.0, 0.0, 1.0)]
            p.camera.zoom(1.25 if view[2] > 0 else 0.9)
            p.add_axes(color="black")
        p.subplot(rows, 0)
        p.add_text(f"racetrack, quarter model (planes x = 0, y = 0), true scale, mm; above the 99.5th percentile: "
                   f"magenta", position="upper_left", font_size=9, color="black", render=False)
        p.add_scalar_bar(title=title, vertical=False, position_x=0.2, position_y=0.1, width=0.6, height=0.45,
                         title_font_size=12, label_font_size=11, n_labels=5, fmt="%.3g", color="black",
                         mapper=next(iter(p.renderers[0].actors.values())).mapper)
        paths.append(_screenshot(p, folder / f"{stem}.png"))
        p.close()
    return paths


def main(argv: list[str] | None = None) -> int:
    """``python racetrack_pictures.py ROOT FOLDER``: the 3D pictures; prints
    their paths as one JSON list."""
    args = sys.argv[1:] if argv is None else argv
    print(json.dumps([str(p) for p in render_3d(Path(args[0]), Path(args[1]))]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
