"""Read the mechanical field files of a results folder (``fields/<case>[_partN]_<body>.xdmf/.h5``,
written by :class:`pulseform.solvers.dolfinx.FieldWriter`; layout in its module docstring).

A resumed run writes a new ``_partN`` file per segment; :func:`read_fields` joins every body's parts
into one time series (a time written twice, at the start of a part, is taken from the later part).
Arrays are read lazily, per output time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

FORMAT = "pulseform mechanical fields 1"
STRESS_COMPONENTS = ("xx", "yy", "zz", "xy", "yz", "xz")


class FieldFileError(ValueError):
    """A results folder has no (readable) mechanical field files."""


@dataclass
class BodyFields:
    """One body's fields over every output time of a results folder."""

    body: str
    formulation: str
    points: np.ndarray          # (N, 3) reference coordinates, m (x = r, y = z in axisymmetry)
    triangles: np.ndarray       # (C, 3) node indices; (C, 4) tetrahedra of a 3D body
    times: np.ndarray           # (T,) output times, s, increasing
    _where: list = field(default_factory=list, repr=False)  # per time: (h5 path, group name)

    @property
    def axisymmetric(self) -> bool:
        return self.formulation == "axisymmetric"

    @property
    def solid(self) -> bool:
        """A 3D body (tetrahedra, points (x, y, z))."""
        return self.formulation == "3d"

    def read(self, k: int, names: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
        """Fields of output ``k`` (all, or ``names``): displacement_m, velocity_m_s (N, 3);
        stress_Pa (C, 6: xx yy zz xy yz xz), von_mises_Pa, plastic_strain (C,); temperature_K (C,) of a body
        that carries a temperature."""
        import h5py

        path, group = self._where[k]
        with h5py.File(path, "r") as f:
            g = f[group]
            return {n: g[n][...] for n in (names or tuple(g.keys()))}

    def names(self, k: int) -> tuple[str, ...]:
        """The fields stored at output ``k`` (``temperature_K`` only for a body that carries a temperature)."""
        import h5py

        path, group = self._where[k]
        with h5py.File(path, "r") as f:
            return tuple(f[group].keys())

    def displacement(self, k: int) -> np.ndarray:
        """(N, 2) displacement at output ``k``, m."""
        return self.read(k, ("displacement_m",))["displacement_m"][:, :2]

    def current(self, k: int) -> np.ndarray:
        """(N, 2) current node positions at output ``k``, m."""
        return self.points[:, :2] + self.displacement(k)


def _read_file(path: Path):
    import h5py

    with h5py.File(path, "r") as f:
        if f.attrs.get("format") != FORMAT:
            raise FieldFileError(f"{path}: not a pulseform field file of format {FORMAT!r}")
        body = str(f.attrs["body"])
        form = str(f.attrs["formulation"])
        pts = f["Mesh/points"][...]
        cells = next(k for k in ("triangles", "tetrahedra", "tetrahedra10", "triangles6") if f"Mesh/{k}" in f)
        corners = {"tetrahedra10": 4, "triangles6": 3}.get(cells)
        tris = f[f"Mesh/{cells}"][...][:, :corners]               # quadratic cells: their corners
        steps = sorted((float(f[g].attrs["time"]), g) for g in f if g.startswith("Step_"))
    return body, form, pts, tris, steps


def read_fields(results_dir: Path) -> dict[str, BodyFields]:
    """Every body's fields of the results folder, by body name (in the order of the files)."""
    return read_folder(Path(results_dir) / "fields")


def read_folder(folder: Path) -> dict[str, BodyFields]:
    """Every body's fields in the field files ``folder/*.h5`` (the run's ``fields/``, or ``fields/springback/``)."""
    files = sorted(folder.glob("*.h5")) if folder.is_dir() else []
    if not files:
        raise FieldFileError(f"{folder}: no field files (*.h5)")
    return read_files(files)


def read_files(files: list[Path]) -> dict[str, BodyFields]:
    """Every body's fields in the field files ``files``: a body's files are parts of one series, by time."""
    parts: dict[str, list] = {}
    for path in files:
        body, form, pts, tris, steps = _read_file(path)
        parts.setdefault(body, []).append((path, form, pts, tris, steps))
    out = {}
    for body, entries in parts.items():
        entries.sort(key=lambda e: e[4][0][0] if e[4] else np.inf)  # parts in time order
        _, form, pts, tris, _ = entries[0]
        by_time: dict[float, tuple[Path, str]] = {}
        for path, _, p, t, steps in entries:
            if p.shape != pts.shape or t.shape != tris.shape:
                raise FieldFileError(f"{path}: a different mesh from the other parts of body {body!r}")
            for time, group in steps:
                by_time[time] = (path, group)  # a later part wins
        times = np.array(sorted(by_time))
        out[body] = BodyFields(body, form, pts, tris, times, [by_time[t] for t in times])
    return out
