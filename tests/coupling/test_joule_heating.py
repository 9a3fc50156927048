"""Joule heating of the workpiece (issue 33): the heat GetDP's eddy currents put into the sheet of the demo
(cases/emf_sheet_bulge, a short coarse run, Taylor–Quinney β = 0 so that only Joule heat counts) equals the
time integral of GetDP's own Joule power of the sheet, ∫∫ |j|²/σ dV dt (the history's
``workpiece_joule_power_W``, GetDP's region integral, times each EM step), within 0.5 %: the heat of every
mechanical cell, ρ c_p (T − T0) V summed over the sheet from the field file, goes through the element-to-cell
hand-over (orchestrator/em/joule_heat.py), the volumes and the 2π of the axisymmetric ring. The same in 3D on
the demo's sector (tetrahedra)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.getdp

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))
RHO, CP, T0 = 2735.0, 896.0, 293.15


def test_joule_heat_of_the_sheet_equals_getdp_joule_power(tmp_path):
    import h5py

    from pulseform.orchestrator.run.history import History

    out = tmp_path / "run"
    r = subprocess.run([EXE, "run", str(REPO / "cases/emf_sheet_bulge"), "--out", str(out), "--quiet",
                        "--set", "time.end=6e-6", "--set", "output.field_interval=3e-6",
                        "--set", f"materials.al_blank.specific_heat={CP}",
                        "--set", "materials.al_blank.taylor_quinney=0",
                        "--set", "geometry.mesh_size_sheet=1e-3", "--set", "output.plots=false"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    h = History.read(out / "history.csv")
    t, P = h.column("time_s"), h.column("workpiece_joule_power_W")
    assert len(t) >= 8                                            # a row per EM step (history_every = 1)
    e_getdp = float(np.sum(P[1:] * np.diff(t)))                  # the step's end value times the step
    with h5py.File(next((out / "fields").glob("*_sheet.h5"))) as f:
        pts, tri = f["Mesh/points"][:, :2], f["Mesh/triangles"][...]
        last = f[sorted(k for k in f if k.startswith("Step_"))[-1]]
        assert float(last.attrs["time"]) == pytest.approx(6e-6)
        p = (pts + last["displacement_m"][:, :2])[tri]
        T = last["temperature_K"][...]
    area = 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                        - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))
    volume = 2.0 * np.pi * p[:, :, 0].mean(axis=1) * area
    heat = RHO * CP * float(np.sum(volume * (T - T0)))
    assert e_getdp > 1.0                                          # J: the sheet did heat
    assert heat == pytest.approx(e_getdp, rel=5e-3)
    assert h.column("sheet_temperature_max_K")[-1] > h.column("sheet_temperature_mean_K")[-1] > T0


def test_joule_heat_of_the_3d_sector_equals_getdp_joule_power(tmp_path):
    """The same in 3D: the demo's 1.25° sector (cases/emf_sheet_bulge_3d, coarse, 3 µs): the tetrahedra's heat
    equals GetDP's Joule power of the sheet (the modelled sector's) integrated over the EM steps, 0.5 %."""
    import h5py

    from pulseform.orchestrator.run.history import History

    out = tmp_path / "run3d"
    r = subprocess.run([EXE, "run", str(REPO / "cases/emf_sheet_bulge_3d"), "--out", str(out), "--quiet",
                        "--set", "time.end=3e-6", "--set", "output.field_interval=1.5e-6",
                        "--set", "geometry.mesh_size_factor=2", "--set", f"materials.al_blank.specific_heat={CP}",
                        "--set", "materials.al_blank.taylor_quinney=0", "--set", "output.plots=false"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    h = History.read(out / "history.csv")
    t, P = h.column("time_s"), h.column("workpiece_joule_power_W")
    e_getdp = float(np.sum(P[1:] * np.diff(t)))
    with h5py.File(next((out / "fields").glob("*_sheet.h5"))) as f:
        pts, tets = f["Mesh/points"][...], f["Mesh/tetrahedra"][...]
        last = f[sorted(k for k in f if k.startswith("Step_"))[-1]]
        p = (pts + last["displacement_m"][...])[tets]
        T = last["temperature_K"][...]
    volume = np.abs(np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))) / 6.0
    heat = RHO * CP * float(np.sum(volume * (T - T0)))
    assert e_getdp > 0.0 and T.max() > T0
    assert heat == pytest.approx(e_getdp, rel=5e-3)
