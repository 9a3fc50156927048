"""EM pictures of a coupled run, drawn from its results folder (matplotlib, 2D, 1:1 axes).

:func:`draw_em` reads ``fields/em*/em.pvd`` (the EM snapshots at the output times), ``fields/em/
em_peak_current.vtu`` + ``.json`` (the snapshot at the EM step of the largest |coil current|) and
``history.csv`` (the coil current at each snapshot), and writes into ``plots/``:

``em_flux_density_peak_current.png``, ``em_flux_density_last_output.png``
    |B| per cell (T) with flux lines: contours of the nodal potential r·a_φ (axisymmetric) or a_z
    (planar) at equal steps, i.e. equal flux between neighbouring lines (their density shows |B|);
    coil and conductor outlines; zoomed on the coil and the conductors.
``em_force_density_peak_current.png``
    |j × B| (N/m³, log scale) on the conductors at the peak current: the coil/workpiece region and a
    1:1 close-up of the workpiece around the largest force density with the force directions.
``em_magnetic_pressure.png``
    the magnetic pressure on the workpiece surface facing the coil (MPa) vs position (mm) at the peak
    current and at the output times: the force density integrated through the thickness
    (p = ∫ f·n dn, the load the mechanics receives; solid), and at the peak current B_t²/(2 μ0) of the
    air cells along the surface (dashed: the field-side estimate, which ignores the field that leaks
    through the sheet).

Only what the folder holds is drawn: a folder without whole-domain B (a user deck without
PostOperation ``EM_Field``, an older run) gets the maps on the conductors and no flux lines; one
without a peak snapshot uses the last output for the force map.
"""

from __future__ import annotations

import json
import logging
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp.mesh import AIR, coil_tag, conductor_tag

from .em_fields import Snapshot, output_series, peak_file, read_snapshot  # noqa: F401  (read_snapshot: API)
from .history import History
from .plots import _save, plt

log = logging.getLogger(__name__)

MU0 = 4e-7 * np.pi
COIL_TAGS = (coil_tag(0), conductor_tag(0))  # physical ids 101.. of the coils
CONDUCTOR_TAGS = (conductor_tag(0), conductor_tag(100))  # 201 workpiece, 202 die / collar
WORKPIECE = conductor_tag(1)


def _current_at(root: Path, times: list[float]) -> list[float | None]:
    """Coil current (A) of the history row nearest each time (None without history or column)."""
    try:
        h = History.read(root / "history.csv")
        t, i = h.column("time_s"), h.column("coil_current_A")
    except (OSError, ValueError, StopIteration):
        return [None] * len(times)
    if not len(t):
        return [None] * len(times)
    return [float(i[np.argmin(np.abs(t - tt))]) for tt in times]


# ----------------------------------------------------------------------------- geometry helpers
def _edges(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sorted node pairs of every triangle side (3n, 2), owning triangle of each)."""
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    return np.sort(e, axis=1), np.tile(np.arange(len(tri)), 3)


def boundary_segments(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Outline of a set of triangles: (m, 2, 2) segments of the sides used once."""
    e, _ = _edges(tri)
    _, inv, cnt = np.unique(e, axis=0, return_inverse=True, return_counts=True)
    return points[e[cnt[inv.ravel()] == 1]]


def zoom_box(snaps: list[Snapshot], axisymmetric: bool) -> tuple[float, float, float, float]:
    """(xmin, xmax, ymin, ymax) in m: the coil and the workpiece of every snapshot with a margin of
    15 % of the larger side (from the axis on in axisymmetry when it is that close), inside the mesh."""
    pts = []
    for s in snaps:
        sel = ((s.region >= COIL_TAGS[0]) & (s.region < COIL_TAGS[1])) | (s.region == WORKPIECE)
        pts.append(s.points[np.unique(s.triangles[sel])] if sel.any() else s.points)
    p = np.vstack(pts)
    lo, hi = p.min(axis=0), p.max(axis=0)
    pad = 0.15 * float(max(hi - lo))
    x0 = lo[0] - pad
    if axisymmetric and lo[0] - 2 * pad <= 0.0:
        x0 = 0.0
    whole = np.vstack([s.points for s in snaps])  # never beyond the EM mesh (axis, symmetry plane)
    m_lo, m_hi = whole.min(axis=0), whole.max(axis=0)
    return (max(x0, m_lo[0]), min(hi[0] + pad, m_hi[0]), max(lo[1] - pad, m_lo[1]), min(hi[1] + pad, m_hi[1]))


def _in_box(points: np.ndarray, tri: np.ndarray, box) -> np.ndarray:
    p = points[tri]
    return ((p[:, :, 0].max(1) >= box[0]) & (p[:, :, 0].min(1) <= box[1])
            & (p[:, :, 1].max(1) >= box[2]) & (p[:, :, 1].min(1) <= box[3]))


def _axes_names(axisymmetric: bool) -> tuple[str, str]:
    return ("r", "z") if axisymmetric else ("x", "y")


def _layout(boxes: list, title: str, max_side: float = 7.5, footnote: bool = False):
    """A figure of 1:1 panels, one per box (m), stacked for wide boxes and side by side for tall
    ones, each as large as fits in ``max_side`` inches, a title on top and a colour-bar axes on
    the right: (figure, [axes...], colour-bar axes)."""
    tall = float(np.mean([(b[3] - b[2]) / (b[1] - b[0]) for b in boxes])) > 1.0
    side = max_side if not tall else max_side / len(boxes) * 1.2
    sizes = []
    for b in boxes:
        w, h = b[1] - b[0], b[3] - b[2]
        k = min(side / w, 7.0 / h) if not tall else min(side / w, 9.0 / h)
        sizes.append((max(w * k, 0.8), max(h * k, 0.8)))
    top, gap, bottom, left, right = 0.9, 0.85, 0.6 + (0.3 if footnote else 0.0), 0.85, 1.3
    if tall:
        width = sum(w for w, _ in sizes) + gap * (len(boxes) - 1)
        height = max(h for _, h in sizes)
    else:
        width = max(w for w, _ in sizes)
        height = sum(h for _, h in sizes) + gap * (len(boxes) - 1)
    fig_w = max(left + width + right, 7.0)
    fig_h = top + height + bottom
    fig = plt.figure(figsize=(fig_w, fig_h))
    axes, x, y = [], left, fig_h - top
    for w, h in sizes:
        if tall:
            axes.append(fig.add_axes([x / fig_w, (y - h) / fig_h, w / fig_w, h / fig_h]))
            x += w + gap
        else:
            y -= h
            axes.append(fig.add_axes([left / fig_w, y / fig_h, w / fig_w, h / fig_h]))
            y -= gap
    cax = fig.add_axes([(left + width + 0.25) / fig_w, bottom / fig_h, 0.18 / fig_w, height / fig_h])
    # centred over the panels where it fits, else over the figure, wrapped to its width (a tall narrow
    # panel: the title is wider than the panel and was cut at the figure's left edge)
    chars = max(int((fig_w - 0.4) * 72 / (10 * 0.6)), 20)  # 10 pt text: ~0.6 em per character; 0.2 in margins
    lines = textwrap.wrap(title, chars) or [""]
    half = 0.5 * max(len(t) for t in lines) * 10 * 0.6 / 72  # inches
    x = min(max(0.5 * (left + width), half + 0.1), fig_w - half - 0.1)
    fig.text(x / fig_w, 1.0 - 0.2 / fig_h, "\n".join(lines), ha="center", va="top", fontsize=10)
    return fig, axes, cax


def _outline(ax, s: Snapshot, workpiece: str = "white", scale: float = 1e3) -> None:
    """Coil (orange), workpiece (``workpiece``) and other conductor (grey) outlines."""
    from matplotlib.collections import LineCollection

    for lo, hi, colour in ((COIL_TAGS[0], COIL_TAGS[1], "tab:orange"), (WORKPIECE, WORKPIECE + 1, workpiece),
                           (WORKPIECE + 1, CONDUCTOR_TAGS[1], "0.6")):
        sel = (s.region >= lo) & (s.region < hi)
        if sel.any():
            seg = boundary_segments(s.points, s.triangles[sel]) * scale
            ax.add_collection(LineCollection(seg, colors=colour, linewidths=0.9, zorder=3))


def _set_box(ax, box, axisymmetric: bool) -> None:
    xn, yn = _axes_names(axisymmetric)
    ax.set_xlim(box[0] * 1e3, box[1] * 1e3)
    ax.set_ylim(box[2] * 1e3, box[3] * 1e3)
    ax.set_aspect("equal")
    ax.set_xlabel(f"{xn} [mm]")
    ax.set_ylabel(f"{yn} [mm]")


def _when(s: Snapshot) -> str:
    text = f"t = {s.t * 1e6:.2f} µs"
    if s.current is not None:
        text += f", coil current {s.current / 1e3:.2f} kA"
    return text + (f" ({s.label})" if s.label else "")


# ----------------------------------------------------------------------------- pictures
def plot_flux_density(s: Snapshot, box, axisymmetric: bool, path: Path, n_lines: int = 30) -> Path:
    """|B| per cell with flux lines (equal-flux contours of the nodal potential)."""
    from matplotlib.tri import Triangulation

    vis = _in_box(s.points, s.triangles, box)
    if not s.b_everywhere():
        vis &= (s.region >= COIL_TAGS[0])  # B only where it was written (conductors)
    x, y = s.points[:, 0] * 1e3, s.points[:, 1] * 1e3
    bmag = s.magnitude("flux_density_T")
    fig, (ax,), cax = _layout([box], f"Magnetic flux density, {_when(s)}", footnote=True)
    vmax = float(np.percentile(bmag[vis], 99.5)) if vis.any() else 1.0
    pc = ax.tripcolor(Triangulation(x, y, s.triangles[vis]), facecolors=bmag[vis], cmap="magma",
                      vmin=0.0, vmax=max(vmax, 1e-12), shading="flat", rasterized=True)
    fig.colorbar(pc, cax=cax, label="|B| [T]")
    note = "B on the conductors only (no whole-domain field in this folder)"
    pot = s.potential
    if pot is not None:
        name, a = pot
        keep = _in_box(s.points, s.triangles, box)
        nodes = np.unique(s.triangles[keep])
        lo, hi = float(a[nodes].min()), float(a[nodes].max())
        if hi > lo:
            levels = np.linspace(lo, hi, n_lines + 2)[1:-1]
            ax.tricontour(Triangulation(x, y, s.triangles[keep]), a, levels=levels, colors="0.85",
                          linewidths=0.6, linestyles="solid", alpha=0.9)
            step = levels[1] - levels[0]
            if name == "r_a_phi_Wb":
                note = (f"flux lines: contours of r·a_φ, {2 * np.pi * step * 1e6:.3g} µWb of flux between "
                        "neighbouring lines")
            else:
                note = f"flux lines: contours of a_z, {step * 1e6:.3g} µWb/m of flux between neighbouring lines"
    _outline(ax, s)
    _set_box(ax, box, axisymmetric)
    fig.text(0.01, 0.01, note + "; coil outlined in orange, workpiece in white", fontsize=8, va="bottom")
    return _save(fig, path)


def _close_up(s: Snapshot, centre: np.ndarray) -> tuple[float, float, float, float]:
    """A 4:1 window around ``centre`` (m), 1.6 workpiece thicknesses across, along the workpiece."""
    sel = s.region == WORKPIECE
    p = s.points[np.unique(s.triangles[sel])] if sel.any() else s.points
    ext = p.max(axis=0) - p.min(axis=0)
    thick = float(ext.min())
    if thick <= 0:
        thick = float(ext.max()) / 10 or 1e-3
    along = int(np.argmax(ext))
    half = np.array([0.0, 0.0])
    half[along], half[1 - along] = 3.2 * thick, 0.8 * thick
    lo = p.min(axis=0)
    c = centre.copy()
    c[1 - along] = lo[1 - along] + 0.5 * ext[1 - along] if ext[1 - along] < 1.6 * thick else c[1 - along]
    return c[0] - half[0], c[0] + half[0], c[1] - half[1], c[1] + half[1]


def plot_force_density(s: Snapshot, box, axisymmetric: bool, path: Path) -> Path:
    """|j × B| on the conductors (log scale): the coil/workpiece region and a 1:1 close-up with arrows."""
    from matplotlib.colors import LogNorm
    from matplotlib.tri import Triangulation

    f = s.cells["force_density_N_m3"][:, :2]
    fmag = np.linalg.norm(f, axis=1)
    on = fmag > 0
    x, y = s.points[:, 0] * 1e3, s.points[:, 1] * 1e3
    cen = s.points[s.triangles].mean(axis=1)
    zoom = _close_up(s, cen[np.argmax(fmag)] if on.any() else s.points.mean(axis=0))
    fig, (top, bottom), cax = _layout([box, zoom], f"Lorentz force density, {_when(s)}")
    if not on.any():
        for ax in (top, bottom):
            ax.text(0.5, 0.5, "no force density in this snapshot", ha="center", transform=ax.transAxes)
        return _save(fig, path)
    fmax = float(fmag.max())
    norm = LogNorm(vmin=fmax * 1e-3, vmax=fmax)
    tri_on = Triangulation(x, y, s.triangles[on])
    colours = np.clip(fmag[on], fmax * 1e-3, None)
    coil = (s.region >= COIL_TAGS[0]) & (s.region < COIL_TAGS[1])
    for ax in (top, bottom):
        ax.set_facecolor("0.93")
        if coil.any():
            ax.tripcolor(Triangulation(x, y, s.triangles[coil]), facecolors=np.ones(coil.sum()), cmap="Oranges",
                         vmin=0, vmax=3, shading="flat", rasterized=True)
        pc = ax.tripcolor(tri_on, facecolors=colours, cmap="inferno", norm=norm, shading="flat", rasterized=True)
    fig.colorbar(pc, cax=cax, label="|j × B| [N/m³]")
    _outline(top, s, workpiece="0.3")
    _set_box(top, box, axisymmetric)
    win = on & _in_box(s.points, s.triangles, zoom)
    idx = np.flatnonzero(win)
    if len(idx) > 160:
        idx = idx[np.argsort(fmag[idx])[::-1][:160]]  # the strongest cells
    u = f[idx] / np.maximum(fmag[idx], 1e-300)[:, None]
    bottom.quiver(cen[idx, 0] * 1e3, cen[idx, 1] * 1e3, u[:, 0], u[:, 1], color="cyan", scale=5.0,
                  scale_units="inches", units="inches", width=0.012, zorder=4)  # arrows 0.2 inch long
    _outline(bottom, s, workpiece="0.3")
    _set_box(bottom, zoom, axisymmetric)
    bottom.set_title("close-up at the largest |j × B|\n(arrows: its direction)", fontsize=9)
    top.add_patch(plt.Rectangle((zoom[0] * 1e3, zoom[2] * 1e3), (zoom[1] - zoom[0]) * 1e3,
                                (zoom[3] - zoom[2]) * 1e3, fill=False, ec="cyan", lw=1.0, zorder=5))
    return _save(fig, path)


@dataclass
class FacingSurface:
    """The workpiece surface facing the coil: its sides, ordered along ``axis`` (0: x/r, 1: y/z)."""

    axis: int
    a: np.ndarray  # (m, 2) first end of each side (m)
    b: np.ndarray  # (m, 2) second end
    normal: np.ndarray  # (m, 2) unit normal out of the workpiece (towards the coil)
    air: np.ndarray  # (m,) the air triangle across each side (-1 if none)

    @property
    def position(self) -> np.ndarray:
        return 0.5 * (self.a[:, self.axis] + self.b[:, self.axis])


def facing_surface(s: Snapshot) -> FacingSurface | None:
    """Sides of workpiece triangles that border air and whose outward normal points towards the
    nearest coil node (n·(c − m) > 0), ordered along the surface's longer extent."""
    wp = np.flatnonzero(s.region == WORKPIECE)
    coil = (s.region >= COIL_TAGS[0]) & (s.region < COIL_TAGS[1])
    if not len(wp) or not coil.any():
        return None
    e, owner = _edges(s.triangles)
    _, inv = np.unique(e, axis=0, return_inverse=True)
    inv = inv.ravel()
    order = np.argsort(inv, kind="stable")
    first = np.full(inv.max() + 1, -1)
    second = np.full(inv.max() + 1, -1)
    for k in order:  # the (at most two) triangles of every side
        key = inv[k]
        if first[key] < 0:
            first[key] = owner[k]
        else:
            second[key] = owner[k]
    is_wp = s.region == WORKPIECE
    rows = []
    for k in np.flatnonzero(is_wp[owner]):
        key = inv[k]
        other = second[key] if first[key] == owner[k] else first[key]
        if other >= 0 and s.region[other] != AIR:
            continue  # inside the workpiece, or against the coil or a die
        rows.append((k, other))
    if not rows:
        return None
    ks = np.array([r[0] for r in rows])
    air = np.array([r[1] for r in rows])
    a, b = s.points[e[ks, 0]], s.points[e[ks, 1]]
    mid = 0.5 * (a + b)
    t = b - a
    n = np.column_stack([t[:, 1], -t[:, 0]]) / np.linalg.norm(t, axis=1)[:, None]
    inside = s.points[s.triangles[owner[ks]]].mean(axis=1)
    n *= np.sign(np.einsum("ij,ij->i", n, mid - inside))[:, None]  # out of the workpiece
    coil_nodes = s.points[np.unique(s.triangles[coil])]
    d2 = ((mid[:, None, :] - coil_nodes[None, :, :]) ** 2).sum(-1)
    towards = coil_nodes[np.argmin(d2, axis=1)] - mid
    keep = (np.einsum("ij,ij->i", n, towards) > 0) & (air >= 0)
    if not keep.any():
        return None
    a, b, n, air = a[keep], b[keep], n[keep], air[keep]
    ext = np.vstack([a, b]).max(axis=0) - np.vstack([a, b]).min(axis=0)
    axis = int(np.argmax(ext))
    o = np.argsort(0.5 * (a[:, axis] + b[:, axis]))
    return FacingSurface(axis, a[o], b[o], n[o], air[o])


def surface_pressure(s: Snapshot, surf: FacingSurface, axisymmetric: bool) -> tuple[np.ndarray, np.ndarray]:
    """(p_force, p_field) in Pa on each side of ``surf``.

    p_force: the workpiece's force density pushed away from the coil (f·(−n)) integrated through the
    thickness: each cell's force f V (V = 2π r_c A in axisymmetry) is shared among the sides whose
    extent along the surface overlaps the cell's, in proportion to the overlap, and divided by the
    side's area (2π r L, or L per metre in planar).  Its sum over the surface is the workpiece's
    normal force.  p_field: B_t²/(2 μ0) with B of the air cell across each side (t: the side's
    tangent).
    """
    ax = surf.axis
    lo = np.minimum(surf.a[:, ax], surf.b[:, ax])
    hi = np.maximum(surf.a[:, ax], surf.b[:, ax])
    length = np.linalg.norm(surf.b - surf.a, axis=1)
    mid = 0.5 * (surf.a + surf.b)
    area = 2 * np.pi * mid[:, 0] * length if axisymmetric else length
    wp = np.flatnonzero(s.region == WORKPIECE)
    p = s.points[s.triangles[wp]]
    d1, d2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    a_cell = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    vol = 2 * np.pi * p[:, :, 0].mean(axis=1) * a_cell if axisymmetric else a_cell
    force = s.cells["force_density_N_m3"][wp, :2] * vol[:, None]  # N per cell
    c_lo, c_hi = p[:, :, ax].min(axis=1), p[:, :, ax].max(axis=1)
    overlap = np.clip(np.minimum(c_hi[:, None], hi[None, :]) - np.maximum(c_lo[:, None], lo[None, :]), 0.0, None)
    width = np.maximum(c_hi - c_lo, 1e-300)
    share = overlap / width[:, None]
    share /= np.maximum(share.sum(axis=1, keepdims=True), 1e-300)  # every cell counted once
    fn = -(share * np.einsum("ck,sk->cs", force, surf.normal)).sum(axis=0)
    p_force = fn / np.maximum(area, 1e-300)
    b = s.cells["flux_density_T"][surf.air, :2]
    tangent = (surf.b - surf.a) / np.maximum(length, 1e-300)[:, None]
    bt = np.einsum("ij,ij->i", b, tangent)
    return p_force, bt ** 2 / (2 * MU0)


def plot_pressure(snaps: list[Snapshot], peak: Snapshot | None, axisymmetric: bool, path: Path) -> Path | None:
    """Magnetic pressure (MPa) on the facing surface vs position (mm) at the given times."""
    fig, ax = plt.subplots(figsize=(10, 4.8))
    fig.subplots_adjust(left=0.08, right=0.7, bottom=0.12, top=0.9)
    cmap = plt.get_cmap("viridis")
    tmax = max([s.t for s in snaps] + ([peak.t] if peak else []) + [1e-300])
    drawn = False
    name = None
    for s in snaps:
        surf = facing_surface(s)
        if surf is None:
            continue
        pf, _ = surface_pressure(s, surf, axisymmetric)
        name = _axes_names(axisymmetric)[surf.axis]
        ax.plot(surf.position * 1e3, pf / 1e6, color=cmap(s.t / tmax), lw=1.2,
                label=f"{s.t * 1e6:.1f} µs" + (f" ({s.current / 1e3:.1f} kA)" if s.current is not None else ""))
        drawn = True
    if peak is not None:
        surf = facing_surface(peak)
        if surf is not None:
            pf, pb = surface_pressure(peak, surf, axisymmetric)
            name = _axes_names(axisymmetric)[surf.axis]
            ax.plot(surf.position * 1e3, pf / 1e6, color="crimson", lw=2.0,
                    label=f"peak current {peak.t * 1e6:.1f} µs" + (f" ({peak.current / 1e3:.1f} kA)"
                                                                   if peak.current is not None else ""))
            if peak.b_everywhere():
                ax.plot(surf.position * 1e3, pb / 1e6, color="crimson", lw=1.0, ls="--",
                        label="peak: $B_t^2/2\\mu_0$ of the air cells")
            drawn = True
    if not drawn:
        plt.close(fig)
        return None
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel(f"{name} along the surface facing the coil [mm]")
    ax.set_ylabel("magnetic pressure [MPa]")
    ax.set_title("Magnetic pressure on the workpiece: force density integrated through the thickness", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), title="time (coil current)",
              title_fontsize=7)
    return _save(fig, path)


# ----------------------------------------------------------------------------- entry point
def draw_em(results_dir: Path) -> list[Path]:
    """Draw the EM pictures of a coupled run's results folder into its ``plots/``; returns their paths.

    Reads only files (``fields/em*/``, ``history.csv``), so ``pulseform plot`` can call it on any
    results folder; draws nothing (an empty list) when the folder has no EM snapshot, e.g. a coupled
    case run with ``coupling.load = "pressure"``.
    """
    root = Path(results_dir)
    folder = root / "plots"
    folder.mkdir(exist_ok=True)
    series = output_series(root)
    peak_meta = peak_file(root)
    if not series and peak_meta is None:
        log.info("EM pictures: no EM snapshot in %s", root / "fields")
        return []
    currents = _current_at(root, [t for t, _ in series])
    snaps = [read_snapshot(p, t, i) for (t, p), i in zip(series, currents)]
    peak = read_snapshot(peak_meta[2], peak_meta[0], peak_meta[1], "peak current") if peak_meta else None
    ref = snaps[-1] if snaps else peak
    pot = ref.potential
    axisymmetric = pot[0] == "r_a_phi_Wb" if pot is not None else _axisymmetric_from_case(root)
    box = zoom_box([s for s in (peak, snaps[-1] if snaps else None) if s is not None], axisymmetric)
    paths = []
    if peak is not None:
        paths.append(plot_flux_density(peak, box, axisymmetric, folder / "em_flux_density_peak_current.png"))
    if snaps:
        last = snaps[-1]
        last.label = "last output"
        paths.append(plot_flux_density(last, box, axisymmetric, folder / "em_flux_density_last_output.png"))
        last.label = ""
    force_snap = peak if peak is not None else max(snaps, key=lambda s: float(s.magnitude("force_density_N_m3").max()))
    if force_snap is not peak:
        force_snap.label = "largest force of the outputs; no peak-current snapshot in this folder"
    paths.append(plot_force_density(force_snap, box, axisymmetric, folder / "em_force_density_peak_current.png"))
    pick = np.unique(np.linspace(0, len(snaps) - 1, min(len(snaps), 8)).round().astype(int)) if snaps else []
    shown = [snaps[i] for i in pick]  # at most 8 output times
    p = plot_pressure(shown, peak, axisymmetric, folder / "em_magnetic_pressure.png")
    if p is not None:
        paths.append(p)
    return paths


def _axisymmetric_from_case(root: Path) -> bool:
    import tomllib

    try:
        data = tomllib.loads((root / "case.toml").read_text())
        return data.get("mechanics", {}).get("formulation", "axisymmetric") == "axisymmetric"
    except (OSError, ValueError):
        return True
