"""Pictures of the mechanical fields of a results folder, drawn from its field files.

``draw_mechanics(results_dir)`` reads ``fields/*.h5`` (every part of a resumed run, through
:mod:`.mech_fields`) and ``case.toml``, and writes into ``plots/``:

* ``shapes.png``: the outline (boundary edges) of each workpiece at every output time, coloured by
  time, other bodies (die, collar, ...) in grey at the first and last time; 1:1 axes, mm.
* ``deformed_von_mises.png`` and ``deformed_plastic_strain.png``: the deformed bodies (true scale)
  coloured by the cell values of von Mises stress (MPa) and equivalent plastic strain (-) at up
  to six output times, one colour scale over all times and bodies. An axisymmetric model is
  revolved by 270° about the z axis and seen from the open quarter (a 3/4 view that shows the
  r-z section); a planar model is shown as it is (x-y plane, parallel projection); a 3D model is shown
  as its exterior surface, and a 3D wedge model (two symmetry planes through the z-axis) unfolded by its
  symmetry over 270° about z and seen like a revolved one (:mod:`.pictures_wedge`).
* ``deformed_temperature.png``: the same for the temperature (K) of the bodies that carry one (a material with a
  ``specific_heat``), its colour scale from the lowest to the highest value.
* ``mechanics/<field>_<k>.png``: the same at every output time ``k`` (one frame per time, same
  camera and colour scale, for flipping through or an animation).
* ``section_<plane>_{von_mises,plastic_strain}.png`` (3D geometry-file cases: :mod:`.pictures_section3d`):
  the 3D bodies cut by each axis-aligned ``[[symmetry]]`` plane (or y = 0), deformed, at up to six times.

Workpieces are the bodies with ``region = "workpiece"`` (coupled cases), else the bodies that carry
a ``[[loads]]`` pulse, else every body.

The 3D pictures are rendered by pyvista/VTK off-screen (Mesa; no display needed) in a child
process (``python -m pulseform.orchestrator.pictures_renderer RESULTS_DIR``), so that a crash or a hang
of the graphics stack cannot take the run down: it becomes a :class:`PicturesFailed` error, which
the caller reports as a warning. ``shapes.png`` (matplotlib) is drawn first, in this process.
"""

from __future__ import annotations

import json
import math
import logging
import os
import signal
import subprocess
import time
import tomllib
from pathlib import Path

import numpy as np

from .mech_fields import BodyFields, read_fields
from .pictures_child import Renderer, spawn
from .pictures_wedge import UnfoldedBody, Wedge, wedge_planes
from .pictures_solid import boundary_faces, solid_camera, solid_surface
from .units import time_axis

log = logging.getLogger(__name__)

__all__ = ["draw_mechanics", "PicturesFailed", "plot_shapes", "render_fields"]

#: (field in the files, file-name stem, colour-bar title, scale to the shown unit, colour map)
QUANTITIES = (("von_mises_Pa", "von_mises", "von Mises stress [MPa]", 1e-6, "turbo"),
              ("plastic_strain", "plastic_strain", "equivalent plastic strain [-]", 1.0, "viridis"))
#: the temperature picture, drawn when a body carries a temperature (its own colour scale: lowest to highest)
TEMPERATURE = ("temperature_K", "temperature", "temperature [K]", 1.0, "inferno")
MONTAGE_PANELS = 6
REVOLVE_DEG = 270.0
REVOLVE_SEGMENTS = 72
RENDER_TIME_LIMIT_S = 600.0
ELEVATION = 0.4  # camera height over its horizontal distance, 3/4 view of a revolved model
CLIM_PERCENTILE = 99.5  # colour scale top when a few cells stand far out (see _colour_scale)
ABOVE_COLOUR = "magenta"


class PicturesFailed(RuntimeError):
    """The 3D pictures could not be rendered (the message says why, in one line)."""


# --------------------------------------------------------------------------------------- helpers
def workpieces(results_dir: Path, bodies: list[str]) -> list[str]:
    """The workpiece bodies among ``bodies`` (see the module docstring)."""
    try:
        case = tomllib.loads((Path(results_dir) / "case.toml").read_text())
    except (OSError, tomllib.TOMLDecodeError):
        return list(bodies)
    specs = case.get("bodies", [])
    work = [b.get("name") for b in specs if b.get("region") == "workpiece"]
    if not work:
        loaded = {ld.get("body") for ld in case.get("loads", [])}
        work = [b.get("name") for b in specs if b.get("name") in loaded]
    work = [n for n in work if n in bodies]
    return work or list(bodies)


def boundary_edges(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Edges (E, 2) that belong to one triangle only, and that triangle's index (E,)."""
    e = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    owner = np.tile(np.arange(len(triangles)), 3)
    _, idx, cnt = np.unique(np.sort(e, axis=1), axis=0, return_index=True, return_counts=True)
    keep = idx[cnt == 1]
    return e[keep], owner[keep]


def _run_name(results_dir: Path) -> str:
    try:
        return str(tomllib.loads((Path(results_dir) / "case.toml").read_text())["case"]["name"])
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        return Path(results_dir).name


def _save_fig(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=100)
    plt.close(fig)
    os.replace(tmp, path)
    return path


# --------------------------------------------------------------------------------------- shapes
def plot_shapes(bodies: dict[str, BodyFields], work: list[str], folder: Path, title: str = "") -> Path:
    """``shapes.png``: workpiece outlines at every output time (coloured by time), the other bodies
    in grey at the first (dashed) and last time; 1:1 axes in mm."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    first = next(iter(bodies.values()))
    axis = time_axis(float(max(b.times[-1] for b in bodies.values())))
    tmax = max(float(max(b.times[-1] for b in bodies.values())), 1e-300)
    cmap = plt.get_cmap("viridis")
    segs_all = []
    lines = []  # (segments mm, colour, width, style, label)
    for name, b in bodies.items():
        edges, _ = boundary_edges(b.triangles)
        if name in work:
            for k, t in enumerate(b.times):
                x = b.current(k) * 1e3
                lines.append((x[edges], cmap(float(t) / tmax), 0.9, "solid", None))
        else:
            for k, style, lab in ((0, "dashed", f"{name}, t = 0"), (len(b.times) - 1, "solid", f"{name}, last output")):
                x = b.current(k) * 1e3
                lines.append((x[edges], "0.45", 0.8, style, lab))
    for seg, *_ in lines:
        segs_all.append(seg.reshape(-1, 2))
    pts = np.vstack(segs_all)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = np.maximum(hi - lo, 1e-9)
    width = 9.0
    height = float(np.clip(width * 0.8 * span[1] / span[0] + 1.2, 3.0, 9.0))
    fig, ax = plt.subplots(figsize=(width, height))
    for seg, colour, lw, style, lab in lines:
        ax.add_collection(LineCollection(seg, colors=[colour], linewidths=lw, linestyles=style, label=lab))
    pad = 0.03 * span.max()
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal", adjustable="datalim")
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(0, tmax * axis.scale))
    fig.colorbar(sm, ax=ax, label=f"output {axis.label}", fraction=0.04, pad=0.02)
    axi = first.axisymmetric
    ax.set_xlabel("r [mm]" if axi else "x [mm]")
    ax.set_ylabel("z [mm]" if axi else "y [mm]")
    names = ", ".join(n for n in bodies if n in work)
    ax.set_title(f"{title}: outline of {names} at each field output (1:1)" if title else
                 f"outline of {names} at each field output (1:1)", fontsize=10)
    if any(lab for *_, lab in lines):
        ax.legend(fontsize=8, loc="best")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save_fig(fig, folder / "shapes.png")


# --------------------------------------------------------------------------------------- 3D meshes
def _revolved(points2: np.ndarray, triangles: np.ndarray, edges: np.ndarray, owner: np.ndarray,
              values: np.ndarray):
    """Surface of the 2D (r, z) mesh revolved by REVOLVE_DEG about z: the swept boundary edges
    (quads) and the two r-z sections (triangles); cell values carried over. Returns (points (P, 3),
    faces (flat VTK array), cell values)."""
    n = len(points2)
    th = np.radians(np.linspace(0.0, REVOLVE_DEG, REVOLVE_SEGMENTS + 1))
    scale = max(float(np.abs(points2).max()), 1e-30)
    on_axis = np.abs(points2[edges, 0]).max(axis=1) <= 1e-9 * scale
    edges, owner = edges[~on_axis], owner[~on_axis]
    ring_nodes = np.unique(edges)
    local = np.full(n, -1)
    local[ring_nodes] = np.arange(len(ring_nodes))
    r, z = points2[ring_nodes, 0], points2[ring_nodes, 1]
    rings = np.stack([np.outer(np.cos(th), r), np.outer(np.sin(th), r), np.tile(z, (len(th), 1))], axis=2)
    rings = rings.reshape(-1, 3)  # index j * R + local
    R = len(ring_nodes)
    cut0 = np.column_stack([points2[:, 0], np.zeros(n), points2[:, 1]])
    cut1 = np.column_stack([points2[:, 0] * np.cos(th[-1]), points2[:, 0] * np.sin(th[-1]), points2[:, 1]])
    pts = np.vstack([rings, cut0, cut1])
    a, b = local[edges[:, 0]], local[edges[:, 1]]
    j = np.arange(REVOLVE_SEGMENTS)[:, None]
    quads = np.stack([j * R + a, j * R + b, (j + 1) * R + b, (j + 1) * R + a], axis=2).reshape(-1, 4)
    off0, off1 = len(rings), len(rings) + n
    tris = np.vstack([triangles + off0, triangles + off1])
    faces = np.concatenate([np.column_stack([np.full(len(quads), 4), quads]).ravel(),
                            np.column_stack([np.full(len(tris), 3), tris]).ravel()])
    vals = np.concatenate([np.tile(values[owner], REVOLVE_SEGMENTS), values, values])
    return pts, faces, vals


def _planar(points2: np.ndarray, triangles: np.ndarray, values: np.ndarray):
    pts = np.column_stack([points2, np.zeros(len(points2))])
    faces = np.column_stack([np.full(len(triangles), 3), triangles]).ravel()
    return pts, faces, values


class _Scene:
    """Per body the 3D (revolved) or planar surface of the deformed mesh at one output time, mm."""

    def __init__(self, bodies: dict[str, BodyFields], wedge: list[np.ndarray] | None = None):
        self.bodies = bodies
        self.axi = next(iter(bodies.values())).axisymmetric
        self.solid = next(iter(bodies.values())).solid  # 3D bodies: the surface of the tetrahedra
        # a wedge model (two symmetry planes through z, their normals ``wedge``): unfolded over 270 deg about z
        # by its own symmetry and seen as a revolved axisymmetric model is (.pictures_wedge)
        self.unfolded = None
        if self.solid and wedge is not None:
            w = Wedge.of(wedge, np.vstack([b.points for b in bodies.values()]))
            self.unfolded = {n: UnfoldedBody(w, b.points, b.triangles) for n, b in bodies.items()}
            self.solid, self.axi = False, True
            self.wedge_deg = math.degrees(w.angle)
        else:
            self.edges = {n: (boundary_faces if self.solid else boundary_edges)(b.triangles)
                          for n, b in bodies.items()}

    def surface(self, name: str, k: int, field: str, scale: float):
        import pyvista as pv

        b = self.bodies[name]
        d = b.read(k, ("displacement_m", field))
        vals = np.asarray(d[field], dtype=float).ravel() * scale
        x = (b.points[:, :2] + d["displacement_m"][:, :2]) * 1e3
        if self.unfolded is not None:
            pts, faces, v = self.unfolded[name].surface((b.points + d["displacement_m"]) * 1e3, vals)
        elif self.solid:
            pts, faces, v = solid_surface((b.points + d["displacement_m"]) * 1e3, *self.edges[name], vals)
        elif self.axi:
            pts, faces, v = _revolved(x, b.triangles, *self.edges[name], vals)
        else:
            pts, faces, v = _planar(x, b.triangles, vals)
        mesh = pv.PolyData(pts, faces)
        mesh.cell_data["value"] = v
        return mesh, vals

    def camera(self, plotter, bounds) -> None:
        """3/4 view into the open quarter (axisymmetric) or the x-y plane (planar)."""
        if self.solid:
            return solid_camera(plotter, bounds)
        xmin, xmax, ymin, ymax, zmin, zmax = bounds
        centre = np.array([(xmin + xmax) / 2, (ymin + ymax) / 2, (zmin + zmax) / 2])
        size = max(xmax - xmin, ymax - ymin, zmax - zmin, 1e-9)
        if self.axi:
            direction = np.array([np.cos(np.radians(315.0)), np.sin(np.radians(315.0)), ELEVATION])
            direction /= np.linalg.norm(direction)
            plotter.camera_position = [tuple(centre + 2.6 * size * direction), tuple(centre), (0.0, 0.0, 1.0)]
        else:
            plotter.view_xy()
            plotter.enable_parallel_projection()
        plotter.reset_camera(bounds=bounds)
        plotter.camera.zoom(1.5 if self.axi else 1.05)


def _bounds(meshes) -> tuple[float, ...]:
    b = np.array([m.bounds for m in meshes])
    return (b[:, 0].min(), b[:, 1].max(), b[:, 2].min(), b[:, 3].max(), b[:, 4].min(), b[:, 5].max())


def _pick(n: int, k: int) -> list[int]:
    """Up to k indices out of range(n), evenly spread, with the first after t = 0 and the last."""
    if n <= k:
        return list(range(n))
    return sorted(set(np.linspace(1, n - 1, k).round().astype(int).tolist()))


def render_fields(results_dir: Path) -> list[Path]:
    """The pyvista pictures (montages and frames; see the module docstring), in this process."""
    import pyvista as pv

    pv.OFF_SCREEN = True
    pv.global_theme.multi_samples = 0  # no MSAA: software rendering (llvmpipe) pays for every sample
    root = Path(results_dir)
    bodies = read_fields(root)
    scene = _Scene(bodies, wedge_planes(root))
    name = _run_name(root)
    ref = max(bodies.values(), key=lambda b: len(b.times))
    times = ref.times
    axis = time_axis(float(times[-1]))
    folder = root / "plots"
    frames_dir = folder / "mechanics"
    frames_dir.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    where = "revolved 270° about the z axis" if scene.axi else "3D" if scene.solid else "x-y plane"
    if scene.unfolded is not None:
        where = f"the {scene.wedge_deg:.4g}° wedge unfolded by its symmetry over 270° about the z axis"

    def tlabel(t: float) -> str:
        return f"t = {t * axis.scale:.4g} {axis.unit}"

    heated = {n: b for n, b in bodies.items() if TEMPERATURE[0] in b.names(0)}
    for field, stem, title, scale, cmap in QUANTITIES + ((TEMPERATURE,) if heated else ()):
        shown_bodies = heated if field == TEMPERATURE[0] else bodies
        # every time's surfaces (small: surfaces only); one colour scale over all times and bodies
        per_time, raw = [], []
        for k in range(len(times)):
            meshes = {}
            for n, b in shown_bodies.items():
                meshes[n], v = scene.surface(n, min(k, len(b.times) - 1), field, scale)
                raw.append(v)
            per_time.append(meshes)
        clim, note = _colour_scale(np.concatenate(raw), title)
        if field == TEMPERATURE[0]:
            values = np.concatenate(raw)
            clim, note = (float(values.min()), max(float(values.max()), float(values.min()) + 1e-9)), ""
        bounds = _bounds([m for meshes in per_time for m in meshes.values()])
        shown = dict(scalars="value", cmap=cmap, clim=clim, above_color=ABOVE_COLOUR if note else None,
                     render=False)
        bar = dict(title=title, vertical=True, position_x=0.86, position_y=0.15, height=0.7, width=0.06,
                   title_font_size=14, label_font_size=12, n_labels=5, fmt="%.3g", color="black")

        # one frame per output time, same camera and colour scale
        p = pv.Plotter(off_screen=True, window_size=(1000, 600))
        p.set_background("white")
        live = {n: m.copy() for n, m in per_time[0].items()}  # the plotter's meshes, updated in place
        for m in live.values():
            p.add_mesh(m, scalar_bar_args=bar, **shown)
        scene.camera(p, bounds)
        p.add_axes(color="black", xlabel="x", ylabel="y", zlabel="z")
        text = p.add_text("", position="upper_left", font_size=11, color="black", render=False)
        if note:
            p.add_text(note, position="lower_right", font_size=9, color="black", render=False)
        for k, t in enumerate(times):
            for n, m in per_time[k].items():
                live[n].points[:] = m.points  # same topology at every output
                live[n].cell_data["value"][:] = m.cell_data["value"]
                live[n].Modified()
            text.SetText(2, f"{name}: {title.split(' [')[0]}, {tlabel(float(t))}\n"
                            f"{', '.join(shown_bodies)} ({where}; mm)")
            paths.append(_screenshot(p, frames_dir / f"{stem}_{k:04d}.png"))
        p.close()

        # montage: up to MONTAGE_PANELS output times on one picture, the colour bar in a row below
        picks = _pick(len(times), MONTAGE_PANELS)
        cols = min(3, len(picks))
        rows = int(np.ceil(len(picks) / cols))
        p = pv.Plotter(off_screen=True, shape=(rows + 1, cols), row_weights=[1.0] * rows + [0.28],
                       groups=[(rows, np.s_[:])], window_size=(520 * cols, 380 * rows + 110), border=False)
        p.set_background("white")
        for i, k in enumerate(picks):
            p.subplot(i // cols, i % cols)
            for n, m in per_time[k].items():
                p.add_mesh(m, show_scalar_bar=False, **shown)
            p.add_text(tlabel(float(times[k])), position="upper_left", font_size=10, color="black", render=False)
            scene.camera(p, bounds)
        p.subplot(rows, 0)
        p.add_text(f"{name}: {', '.join(shown_bodies)} ({where}; mm)" + (f"; {note}" if note else ""),
                   position="upper_left", font_size=9, color="black", render=False)
        p.add_scalar_bar(title=title, vertical=False, position_x=0.2, position_y=0.1, width=0.6, height=0.5,
                         title_font_size=12, label_font_size=10, n_labels=5, fmt="%.3g", color="black",
                         mapper=next(iter(p.renderers[0].actors.values())).mapper)
        paths.append(_screenshot(p, folder / f"deformed_{stem}.png"))
        p.close()
    from .pictures_springback3d import render_springback3d

    return paths + render_springback3d(root)


def _colour_scale(values: np.ndarray, title: str) -> tuple[tuple[float, float], str]:
    """Colour range (0, top) over all times and bodies: the largest value, or, when a few cells
    stand far out (a singular cell at a corner or on the axis), the CLIM_PERCENTILE percentile,
    with a note naming the cap and the maximum (cells above it are drawn in ABOVE_COLOUR)."""
    vmax = float(values.max()) if values.size else 0.0
    if vmax <= 0.0:
        return (0.0, 1.0), ""
    top = float(np.percentile(values, CLIM_PERCENTILE))
    if top <= 0.0 or vmax <= 1.25 * top:
        return (0.0, vmax), ""
    unit = title[title.find("[") + 1:title.find("]")] if "[" in title else ""
    return (0.0, top), (f"colour scale capped at the {CLIM_PERCENTILE:g}th percentile {top:.3g} {unit}: "
                        f"cells above in {ABOVE_COLOUR} (max {vmax:.3g} {unit})")


def _screenshot(p, out: Path) -> Path:
    from PIL import Image

    p.render()  # pyvista's screenshot() renders only the first time
    img = p.screenshot(None, return_img=True)
    tmp = out.with_name(f".{out.stem}.tmp.png")
    Image.fromarray(img).save(tmp, compress_level=1)  # fast zlib level: encoding dominated otherwise
    os.replace(tmp, out)
    return out


# --------------------------------------------------------------------------------------- entry
def _outlines(bodies: dict[str, BodyFields], root: Path) -> list[Path]:
    """[shapes.png] of 2D bodies; for 3D bodies no outlines (their deformed surfaces are the 3D pictures) but,
    in a 3D geometry-file case, the sections of the bodies by its symmetry planes (:mod:`.pictures_section3d`;
    a failure there is logged and costs no other picture)."""
    if any(b.solid for b in bodies.values()):
        log.info("shapes.png (outlines of 2D bodies) not drawn for 3D bodies")
        from .pictures_section3d import draw_sections3d

        try:
            return draw_sections3d(root)
        except Exception as exc:  # the sections must not cost the 3D pictures drawn beside them
            log.warning("section pictures not drawn: %s: %s", type(exc).__name__, " ".join(str(exc).split())[:200])
            log.debug("section pictures", exc_info=True)
            return []
    return [plot_shapes(bodies, workpieces(root, list(bodies)), root / "plots", _run_name(root))]


def draw_mechanics(results_dir: Path, *, isolated: bool = True,
                   time_limit: float = RENDER_TIME_LIMIT_S, wait: bool = True,
                   renderer: Renderer | None = None):
    """Draw the mechanical pictures of a results folder from its field files (see the module
    docstring); returns the paths written. ``isolated``: render the 3D pictures in a child process
    (a crash or a hang of the graphics stack then raises :class:`PicturesFailed`). ``wait=False``
    (isolated only): start the child, draw shapes.png, and return a function that waits for the
    child and returns every path, so that the caller draws its own pictures meanwhile; its
    ``cancel()`` kills the child instead. ``renderer``: a :class:`Renderer` started earlier
    (isolated only), used instead of a new child when it is still alive."""
    root = Path(results_dir)
    if not isolated:
        bodies = read_fields(root)
        (root / "plots").mkdir(exist_ok=True)
        return _outlines(bodies, root) \
            + render_fields(root)
    (root / "plots").mkdir(exist_ok=True)
    child = renderer.take(root) if renderer is not None else None
    if child is None:
        child = spawn([str(root)])
    deadline = time.monotonic() + time_limit
    try:
        bodies = read_fields(root)
        paths = _outlines(bodies, root)
    except BaseException:
        child.kill()
        child.communicate()
        raise

    def finish() -> list[Path]:
        if cancelled:
            return paths
        try:
            out, err = child.communicate(timeout=max(deadline - time.monotonic(), 0.0))
        except subprocess.TimeoutExpired:
            child.kill()
            child.communicate()
            raise PicturesFailed(f"3D pictures: rendering took more than {time_limit:g} s; "
                                 f"{len(paths)} picture(s) drawn") from None
        except BaseException:
            child.kill()
            child.communicate()
            raise
        lines = [ln for ln in out.splitlines() if ln.startswith("[")]
        if child.returncode != 0 or not lines:
            errs = [ln for ln in err.splitlines() if ln.strip() and "bad X server" not in ln]
            if child.returncode < 0:
                why = f"the renderer was killed by {signal.Signals(-child.returncode).name}"
            else:
                why = errs[-1].strip() if errs else f"exit code {child.returncode}"
            log.debug("3D pictures: child stderr:\n%s", err[-4000:])
            raise PicturesFailed(f"3D pictures not drawn ({why[:200]}); shapes.png was drawn")
        return paths + [Path(p) for p in json.loads(lines[-1])]

    cancelled: list[bool] = []

    def cancel() -> None:
        """Stop the 3D renderer (a stop signal during the pictures)."""
        cancelled.append(True)
        if child.poll() is None:
            child.kill()
        child.communicate()

    finish.cancel = cancel
    return finish() if wait else finish
