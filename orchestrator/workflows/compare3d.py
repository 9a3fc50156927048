"""What ``pulseform compare`` does on a 3D model (``mechanics.formulation = "3d"``: a geometry file of part of a
device between its [[symmetry]] planes).

- The loaded surface: a geometry file does not know which face the coil pushes, so it is given: ``--surface`` a
  box (a TOML inline table with the 3D bounds of :func:`~..mech.pulses.box_marker`: x, y, z, rmin/rmax about
  the z-axis, m) and ``--body`` the loaded body (default: the only deformable one). The loaded triangles are
  those the pressure run loads (:mod:`~..mech.pulses3d`: the body's exterior triangles with three nodes in the
  box), read from the coupled run's body mesh in ``fields/``: their reference area A and inward area vector S
  (a uniform pressure p on them pushes with p S).
- The pressure: the coupled run's force on the model (``force_{x,y,z}_N``) along S over |S|,
  p(t) = F(t)·S / |S|², the pressure whose pulse gives the pressure run the coupled run's force along S on
  exactly the area it loads (on a flat face |S| = A). The device's area is A × the symmetry factor (the
  coupled run's ``symmetry_factor``); the nominal annulus π(rmax² − rmin²) of a box with radial bounds on a
  face normal to z is reported beside it (the mesh's triangles straddling rmin and rmax are not loaded).
- The final shapes: the 3D final positions of the same nodes (both runs mesh the same file: the same nodes);
  the picture is the profile of the loaded surface: each loaded node's final position along S against its
  reference distance from the z-axis (or its z, when the surface spans more along z: a bore).
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np

from ..case.model import Box
from ..case.schema import SchemaError
from ..mech.pulses3d import box_nodes, loaded_surface


def parse_surface(text: str) -> dict[str, float]:
    """The ``--surface`` box: a TOML inline table of bounds (m) -> a dict of floats; raises ValueError in one
    line (unknown key, not a number, empty box)."""
    try:
        raw = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"--surface {text!r}: not a TOML inline table ({exc}); e.g. "
                         "'{rmin = 0.01, rmax = 0.034, zmin = 1.4e-3, zmax = 1.6e-3}'") from None
    if not isinstance(raw, dict) or not raw:
        raise ValueError(f"--surface {text!r}: give a table of bounds, e.g. '{{zmin = 1.4e-3, zmax = 1.6e-3}}'")
    keys = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax", "rmin", "rmax")
    for k, v in raw.items():
        if k not in keys:
            raise ValueError(f"--surface: unknown bound {k!r}; allowed: {', '.join(keys)} (m)")
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError(f"--surface: {k} = {v!r} is not a number (m)")
    box = {k: float(v) for k, v in raw.items()}
    try:
        Box(**box).validate("--surface")
    except SchemaError as exc:
        raise ValueError(f"--surface: {exc}") from None
    return box


def loading_3d(folder: Path, body: str, box: dict) -> tuple[float, np.ndarray]:
    """(The model's loaded area A (m²), its inward area vector S (m²)) of ``body``'s mesh in the run folder
    ``folder`` (its ``fields/``) and the box (module docstring)."""
    from ..run.mech_fields import FieldFileError, read_fields
    from .compare import CompareError

    try:
        bf = read_fields(folder)[body]
    except (FieldFileError, KeyError) as exc:
        raise CompareError(f"compare: no mesh of body {body!r} in {folder / 'fields'} ({exc})", run_failed=True) from None
    if not bf.solid:
        raise CompareError(f"compare: the body {body!r} of {folder} is not a 3D mesh")
    area, s = loaded_surface(bf.points, bf.triangles, Box(**box))
    if area <= 0.0:
        raise CompareError(f"compare: --surface {box} holds no exterior triangle of body {body!r} (all three nodes "
                           "inside; bounds x, y, z, and rmin/rmax about the z-axis, m)")
    if float(np.linalg.norm(s)) <= 1e-9 * area:
        raise CompareError(f"compare: the pressure on --surface {box} of {body!r} has no resultant (a closed "
                           "surface): bound it to the part the coil pushes")
    return area, s


def nominal_area(box: dict, direction: np.ndarray) -> float | None:
    """The whole annulus π(rmax² − rmin²) (m²) of a box with a finite ``rmax`` loading a face normal to z
    (``direction`` the unit area vector); None for any other box."""
    rmax = box.get("rmax", math.inf)
    if not math.isfinite(rmax) or abs(abs(float(direction[2])) - 1.0) > 1e-9:
        return None
    return math.pi * (rmax ** 2 - box.get("rmin", 0.0) ** 2)


def surface_profile(x: np.ndarray, u: np.ndarray, box: dict, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """(Abscissa (m), final position along ``direction`` (m), the abscissa's name) of the body's nodes in ``box``
    (reference ``x`` and displacement ``u``, (N, 3) m), ordered by the abscissa: the reference distance from the
    z-axis, or z when the loaded nodes span more along z."""
    on = box_nodes(Box(**box), x)
    r, z = np.hypot(x[on, 0], x[on, 1]), x[on, 2]
    a, name = (r, "r") if np.ptp(r) >= np.ptp(z) else (z, "z")
    order = np.argsort(a, kind="stable")
    return a[order], ((x[on] + u[on]) @ direction)[order], name


def plot_profile(ax, shape_c, shape_p, box: dict, direction: np.ndarray) -> None:
    """The loaded surface's profile of both runs on ``ax`` (mm): ``shape_*`` are (reference, displacement)
    (N, 3) arrays (m); ``direction`` the loaded surface's unit area vector."""
    for (x, u), lab, st in ((shape_c, "coupled", ".-"), (shape_p, "pressure", "x--")):
        a, y, name = surface_profile(x, u, box, direction)
        ax.plot(a * 1e3, y * 1e3, st, ms=2.5, lw=0.8, label=lab)
    d = ", ".join(f"{c:.3g}" for c in direction)
    ax.set(xlabel=f"{name} (mm)", ylabel=f"final position along [{d}] (mm)")
