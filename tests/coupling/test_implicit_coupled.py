"""Coupled GetDP runs with implicit mechanics (issue 34 item 2, first piece): the same staggered loop, one implicit
step per EM step (coupling.n = 1), iterated to the coupled solution. A slow device with a deformable part —
cases/two_coils_plate driven at 50 Hz, a clamped aluminium plate pushed at 100 Hz — runs in 0.25 ms steps (the
explicit solver: 3.8e-8 s); against the explicit solver over 20 ms and on the demo's forming pulse (slow)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))

#: two_coils_plate at mains frequency: both coils on undamped 50 Hz sines (10 kA and 6 kA per turn)
SLOW = ["--set", "em.sources.main.frequency=50", "--set", "em.sources.main.decay=0",
        "--set", "em.sources.main.amplitude=10e3", "--set", "em.sources.late.frequency=50",
        "--set", "em.sources.late.decay=0", "--set", "em.sources.late.amplitude=6e3", "--set", "output.plots=false"]
IMPLICIT = ["--set", "mechanics.integrator=implicit", "--set", "coupling.n=1"]
#: the coupled solution at every EM step: a step of the order of the plate's period (1.5 kHz) needs it
ITERATE = ["--set", "coupling.iterate=true"]


def _run(case: str, out: Path, *sets: str) -> dict:
    r = subprocess.run([EXE, "run", str(REPO / "cases" / case), "--out", str(out), "--quiet", *sets],
                       capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads((out / "metrics.json").read_text())


def _deflection(out: Path) -> tuple[np.ndarray, np.ndarray]:
    """Time (s) and the plate's largest |u_y| (m) of a run's history."""
    h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    return h["time_s"], h["plate_max_uy_m"]


@pytest.mark.getdp
def test_slow_device_with_a_deformable_part(tmp_path):
    """10 ms (one period of the 100 Hz force) in 40 HHT steps of 0.25 ms, one getdp step each, iterated to the
    coupled solution (coupling.iterate): seconds on this machine (the explicit solver at its 3.8e-8 s stable step:
    2.6e5 steps); the plate follows the force — as far down in the second half-period as in the first, not
    further (the staggered scheme without iterations gains energy at this step: 3 x the deflection in 20 ms) —
    and is back near its rest at 10 ms, where the force vanishes."""
    out = tmp_path / "out"
    m = _run("two_coils_plate", out, *SLOW, *IMPLICIT, *ITERATE, "--set", "time.end=0.01",
             "--set", "mechanics.implicit.dt=2.5e-4", "--set", "mechanics.implicit.scheme=hht",
             "--set", "output.field_interval=5e-3")
    t, u = _deflection(out)
    first, second = u[t <= 5e-3].max(), u[t > 5e-3].max()
    print({k: m[k] for k in ("mech_steps", "em_steps", "wall_time_s", "coupling_iterations_max", "energy_error_rel")},
          "largest deflection per half-period (mm)", first * 1e3, second * 1e3, "at 10 ms", u[-1] * 1e3)
    assert m["mech_steps"] == 40 and m["em_steps"] == 40 and m["coupling_unconverged_steps"] == 0
    assert 5e-5 < first and second <= 1.02 * first
    assert u[-1] < 0.1 * first
    assert m["energy_error_rel"] < 1e-2


@pytest.mark.getdp
@pytest.mark.slow
def test_slow_device_implicit_matches_explicit(tmp_path):
    """20 ms of the slow device: implicit, 80 steps of 0.25 ms (trapezoidal and HHT alpha = -0.1, iterated
    coupling), against explicit (5.2e5 steps, coupling.n = 200): the largest deflection within 1 % (measured
    -0.11 % and +0.58 %) and the deflection at every 2.5 ms within 3 % of it (measured 1.6 % trapezoidal, 2.1 % HHT at the
    first peak, where the explicit run carries the plate's 1.5 kHz ringing that a 0.25 ms step does not resolve). The
    implicit runs take 11-12 s, the explicit one 30 s."""
    common = [*SLOW, "--set", "time.end=0.02", "--set", "output.field_interval=5e-3"]
    _run("two_coils_plate", tmp_path / "exp", *common, "--set", "coupling.n=200")
    te, ue = _deflection(tmp_path / "exp")
    probe = np.arange(2.5e-3, 0.02 + 1e-9, 2.5e-3)
    for scheme in ("trapezoidal", "hht"):
        out = tmp_path / scheme
        _run("two_coils_plate", out, *common, *IMPLICIT, *ITERATE, "--set", "mechanics.implicit.dt=2.5e-4",
             "--set", f"mechanics.implicit.scheme={scheme}")
        ti, ui = _deflection(out)
        dev = np.abs(np.interp(probe, ti, ui) - np.interp(probe, te, ue)).max() / ue.max()
        print(scheme, "largest", ui.max(), "explicit", ue.max(), "largest deviation at the probe times", dev)
        assert ui.max() == pytest.approx(ue.max(), rel=0.01)
        assert dev < 0.03


@pytest.mark.getdp
@pytest.mark.slow
def test_forming_pulse_implicit_matches_explicit(tmp_path):
    """The demo (cases/emf_sheet_bulge, 60 us of its bank discharge) with one implicit step per EM step of 0.45 us
    against its explicit run (20 steps per EM step): the largest deflection, the plastic work and the impulse within
    0.5 % (measured -0.02 %, -0.02 %, +0.01 %)."""
    off = ["--set", "output.plots=false"]
    ex = _run("emf_sheet_bulge", tmp_path / "exp", *off)
    im = _run("emf_sheet_bulge", tmp_path / "imp", *off, *IMPLICIT, "--set", "mechanics.implicit.dt=0.45e-6")
    for key in ("sheet_max_uy_mm", "plastic_work_J", "force_impulse_Ns"):
        print(key, ex[key], im[key])
        assert im[key] == pytest.approx(ex[key], rel=0.005)
