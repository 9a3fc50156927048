"""The EM picture of a coupled 3D (sector) run: the Lorentz force density on the sheet at the peak coil
current, from ``fields/em3d/em_peak_current.vtu`` (:mod:`.em_fields3d`), drawn with matplotlib.

``em3d_current_density_peak_current.png``: every conductor (the bodies and the fixed ones, a field shaper's
induced current) at the peak coil current, their exterior faces coloured by the eddy current density |j| of the
tetrahedron behind each (from ``fields/em3d/em_peak_current_conductors.vtu``), a 3/4 view (matplotlib).

``em3d_force_density_peak_current.png``: left, the sheet's tetrahedra seen in the meridian plane
(r, z of their centroids, z stretched: the sheet is thin) coloured by the axial force density f_z
(GN/m^3); right, the axial force per unit radius of the whole device, 2π/α Σ f_z V per radial bin
(N/mm; α the sector angle from the nodes' azimuths), which integrates to the device's force.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp.mesh3d import tet_volumes

from .em_fields3d import CONDUCTORS_PEAK, read_peak3d
from .pictures_solid import VIEW, boundary_faces

log = logging.getLogger(__name__)

PICTURE = "em3d_force_density_peak_current.png"
CURRENT_PICTURE = "em3d_current_density_peak_current.png"


def draw_em3d(results_dir: Path) -> list[Path]:
    """Draw the 3D EM pictures into ``plots/`` of a coupled 3D results folder (module docstring); [] without
    peak snapshots."""
    return _draw_force_density(Path(results_dir)) + draw_current_density(Path(results_dir))


def _save(fig, out: Path) -> Path:
    """Save ``fig`` atomically at ``out`` (a PNG of ``plots/``) and close it."""
    import matplotlib.pyplot as plt

    out.parent.mkdir(exist_ok=True)
    tmp = out.with_name(f".{out.stem}.tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(out)
    return out


def draw_current_density(root: Path) -> list[Path]:
    """``em3d_current_density_peak_current.png`` (module docstring); [] without the conductors' snapshot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    snap = read_peak3d(root, CONDUCTORS_PEAK)
    if snap is None or "current_density_magnitude_A_m2" not in snap.cells:
        return []
    faces, owner = boundary_faces(snap.tets)
    j = snap.cells["current_density_magnitude_A_m2"][owner] / 1e6   # A/mm^2
    p = snap.points * 1e3
    fig = plt.figure(figsize=(9, 6.5))
    ax = fig.add_subplot(projection="3d")
    norm = matplotlib.colors.Normalize(0.0, float(np.percentile(j, 99.5)) or 1.0)
    cmap = matplotlib.colormaps["inferno"]
    ax.add_collection3d(Poly3DCollection(p[faces], facecolors=cmap(norm(j)), edgecolors="none"))
    lo, hi = p.min(axis=0), p.max(axis=0)
    centre, half = 0.5 * (lo + hi), 0.5 * float((hi - lo).max())
    ax.set(xlim=(centre[0] - half, centre[0] + half), ylim=(centre[1] - half, centre[1] + half),
           zlim=(centre[2] - half, centre[2] + half), xlabel="x [mm]", ylabel="y [mm]", zlabel="z [mm]")
    view = VIEW / np.linalg.norm(VIEW)
    ax.view_init(elev=float(np.degrees(np.arcsin(view[2]))), azim=float(np.degrees(np.arctan2(view[1], view[0]))))
    fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.7,
                 label="eddy current density |j| [A/mm²] (scale to the 99.5th percentile)")
    names = sorted({int(k) for k in snap.cells["conductor"]})
    ax.set_title(f"{root.name}: conductors {names} (200 + k) at the peak coil current, t = {snap.t * 1e6:.3g} µs, "
                 f"I = {snap.current / 1e3:.4g} kA", fontsize=9)
    return [_save(fig, root / "plots" / CURRENT_PICTURE)]


def _draw_force_density(root: Path) -> list[Path]:
    """``em3d_force_density_peak_current.png`` (module docstring); [] without the sheet's peak snapshot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    snap = read_peak3d(root)
    if snap is None:
        return []
    c = snap.points[snap.tets].mean(axis=1)
    r, z = np.hypot(c[:, 0], c[:, 1]), c[:, 2]
    fz = snap.cells["force_density_N_m3"][:, 2]
    vol = tet_volumes(snap.points, snap.tets)
    alpha = float(np.arctan2(snap.points[:, 1], snap.points[:, 0]).max())
    edges = np.linspace(0.0, r.max() * (1 + 1e-9), 61)
    per_bin = np.bincount(np.digitize(r, edges) - 1, weights=fz * vol, minlength=len(edges) - 1)[: len(edges) - 1]
    line = 2.0 * np.pi / max(alpha, 1e-12) * per_bin / (np.diff(edges) * 1e3)   # N per mm of radius
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.2), gridspec_kw={"width_ratios": [1.4, 1]})
    lim = float(np.abs(fz).max()) / 1e9 or 1.0
    sc = a.scatter(r * 1e3, z * 1e3, c=fz / 1e9, s=4, cmap="coolwarm", vmin=-lim, vmax=lim)
    fig.colorbar(sc, ax=a, label="axial force density f_z [GN/m³]")
    a.set_xlabel("r [mm]")
    a.set_ylabel("z [mm]")
    a.set_title("sheet tetrahedra (centroids), meridian view")
    b.step(0.5 * (edges[1:] + edges[:-1]) * 1e3, line, where="mid")
    b.set_xlabel("r [mm]")
    b.set_ylabel("axial force per radius, device [N/mm]")
    b.set_title(f"Σ = {2 * np.pi / max(alpha, 1e-12) * float(fz @ vol):.4g} N")
    b.grid(True, alpha=0.3)
    fig.suptitle(f"{root.name}: Lorentz force density at the peak coil current, t = {snap.t * 1e6:.3g} µs, "
                 f"I = {snap.current / 1e3:.4g} kA (sector {np.degrees(alpha):.3g}°)")
    fig.tight_layout()
    return [_save(fig, root / "plots" / PICTURE)]
