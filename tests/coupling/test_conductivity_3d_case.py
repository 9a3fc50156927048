"""A conductivity that follows temperature through a 3D case file (issue 33, item 3): the demo's 1.25° sector
(cases/emf_sheet_bulge_3d, coarse, 3 µs, BDF2; 'auto' runs getdp per step with a σ(T) law).

Reference: a conductor whose σ(T) is the same number at every temperature it reaches is, for GetDP, a conductor of
that constant σ. The sheet gets a table law flat at 2.5e7 S/m from its initial temperature up (its cells heat by
their Joule heat: every cell's temperature goes through the hand-over from the mechanical tetrahedra to the EM
tetrahedra and back as σ per element), the coil a table law flat at 5.8e7 S/m from 293.15 K up (its lumped
temperature rises). Their ``electrical_conductivity`` / ``em.coil_conductivity`` are set to other values (1e7 S/m),
which GetDP would take if the laws did not reach it. The run must equal the run with the constant conductivities
(2.5e7 and 5.8e7 S/m, no law) on the per-step getdp: every physical column of history.csv to 1e-12 (the same
matrix entries: ``InterpolationLinear[ElementNum[]]`` at a listed tag is exact), where the unused values alone
would change the coil current by tens of percent.

And a run with linear laws stopped by SIGINT after its first checkpoint and resumed equals the uninterrupted run
bit for bit (the coil's lumped heat is part of the checkpoint: without it the resumed coil is cold again).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = [pytest.mark.getdp, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))
COMMON = ["--set", "time.end=3e-6", "--set", "output.field_interval=1.5e-6", "--set", "geometry.mesh_size_factor=2",
          "--set", "materials.al_blank.specific_heat=896.0", "--set", "output.plots=false",
          "--set", "em.getdp_process='per_step'"]


def _run(out: Path, sets: list[str]):
    from pulseform.orchestrator.run.history import History

    args = [EXE, "run", str(REPO / "cases/emf_sheet_bulge_3d"), "--out", str(out), "--quiet", *COMMON]
    for s in sets:
        args += ["--set", s]
    r = subprocess.run(args, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    return History.read(out / "history.csv")


def test_flat_laws_equal_constant_conductivities_in_3d(tmp_path):
    const = _run(tmp_path / "constant", ["em.coil_conductivity=5.8e7"])
    law = _run(tmp_path / "law", [
        "materials.al_blank.electrical_conductivity=1e7",
        "materials.al_blank.conductivity_curve={type = 'table', temperatures = [250.0, 293.15, 900.0], "
        "conductivities = [3e7, 2.5e7, 2.5e7]}",
        "em.coil_conductivity=1e7",
        "em.coil_conductivity_curve={type = 'table', temperatures = [250.0, 293.15, 1300.0], "
        "conductivities = [7e7, 5.8e7, 5.8e7]}"])
    cols = ["coil_current_A", "capacitor_voltage_V", "force_z_N", "workpiece_joule_power_W", "magnetic_energy_J",
            "coil_joule_heat_J", "device_impulse_z_Ns"]
    worst = 0.0
    for c in cols:
        a, b = const.column(c), law.column(c)
        assert a.shape == b.shape and np.abs(a).max() > 0, c
        err = np.abs(b - a).max() / np.abs(a).max()
        worst = max(worst, err)
        assert err < 1e-12, (c, err)
    t_max = law.column("sheet_temperature_max_K")
    print(f"\n{len(const.column('time_s'))} rows; worst relative difference {worst:.1e}; sheet up to "
          f"{t_max.max():.4f} K")
    assert t_max.max() > 293.15   # the cells heated: their temperatures went to GetDP every step


def test_sigma_of_t_in_3d_resumes_bitwise(tmp_path):
    """Linear laws on the sheet and on a coil that heats fast (its heat capacity 1/50 of copper's), stopped by SIGINT
    after the first checkpoint and resumed: the outputs equal the uninterrupted run's bit for bit (the checkpoint
    keeps the coil's heat and last power and σ, the cells keep their temperatures)."""
    from .resume_check import assert_coupled3d_outputs_bitwise, sigint_then_resume

    sets = ["materials.al_blank.conductivity_curve={type = 'linear_resistivity', temperature_coefficient = 4e-3}",
            "em.coil_conductivity_curve={type = 'linear_resistivity', temperature_coefficient = 3.9e-3}",
            "em.coil_heat_capacity=7.7"]
    ref = tmp_path / "ref"
    h = _run(ref, sets)
    assert h.column("coil_joule_heat_J")[-1] > 0
    args = [EXE, "run", str(REPO / "cases/emf_sheet_bulge_3d"), "--out", str(tmp_path / "out"), "--quiet", *COMMON]
    for s in sets:
        args += ["--set", s]
    proc, err, _, resumed = sigint_then_resume(args, tmp_path / "out", delay=0.05)
    assert proc.returncode == 130, err[-2000:]
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert_coupled3d_outputs_bitwise(ref, tmp_path / "out")
