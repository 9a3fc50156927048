"""Which EM steps fetch their whole-domain fields on the persistent getdp (em/snapshots.peak_is_near):
the peak-current snapshot needs the fields of the step of the largest |I|, and a persistent process
holds a step's fields only until its next step, so rising steps near the peak fetch them."""

import numpy as np
import pytest

from pulseform.orchestrator.em.snapshots import PEAK_LOOKAHEAD_STEPS, peak_is_near
from warm_cli import pulseform_cli


def _flags(t, current):
    """peak_is_near at every rising step that sets a new maximum of |I| (as _track_peak asks it)."""
    out, best = {}, 0.0
    for k in range(len(t)):
        if abs(current[k]) > best:
            best = abs(current[k])
            out[k] = peak_is_near([(t[j], abs(current[j])) for j in range(max(0, k - 2), k + 1)])
    return out


@pytest.mark.parametrize("steps_per_quarter", [8, 40, 200])
@pytest.mark.parametrize("jitter", [0.0, 0.3])
def test_the_peak_step_always_fetches_and_few_others_do(steps_per_quarter, jitter):
    """A damped discharge I = e^(-bt) sin(wt) (the demo's bank rings like this), steps of equal or
    jittered length (ratios up to 1.9, as the landing on output times allows): the step of the
    largest |I| is always flagged, and at most LOOKAHEAD + 2 rising steps before it (the demo: 5
    field fetches instead of ~40)."""
    rng = np.random.default_rng(1)
    w, b = 1e5, 1e4
    dt = (np.pi / 2 / w) / steps_per_quarter * (1 + jitter * rng.uniform(-1, 1, 4 * steps_per_quarter))
    t = np.cumsum(dt)
    current = np.exp(-b * t) * np.sin(w * t) * 26e3
    flags = _flags(t, current)
    first_peak = int(np.argmax(np.abs(current[: 3 * steps_per_quarter])))
    assert flags[first_peak], "the peak step must fetch its fields"
    before = [k for k, f in flags.items() if f and k < first_peak and k >= 2]
    assert len(before) <= PEAK_LOOKAHEAD_STEPS + 2, before


def test_far_from_the_peak_and_edge_cases():
    assert not peak_is_near([(0.0, 0.0), (1.0, 1.0), (2.0, 3.0)])  # accelerating rise
    assert peak_is_near([(0.0, 0.0), (1.0, 1.0)])  # the first steps of a run (or after --resume)
    assert peak_is_near([(0.0, 0.0), (1.0, 2.0), (2.0, 2.1)])  # rate from 2 to 0.1 per step: a step away
    assert not peak_is_near([(0.0, 0.0), (1.0, 10.0), (2.0, 19.0)])  # rate 10 -> 9: ~9 steps away


def test_the_demos_peak_snapshot_is_the_peak_step(tmp_path):
    """The demo to 20 us on the persistent getdp: the peak-current snapshot (fields fetched only
    near the predicted peak) is the EM step of the largest |I| in history.csv, with no "came sooner
    than predicted" fallback in run.log."""
    import json
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    out = tmp_path / "demo"
    r = pulseform_cli(["run", str(repo / "cases/emf_sheet_bulge"), "--out", str(out), "--quiet",
                       "--set", "time.end=2e-5", "--set", "output.field_interval=1e-5", "--set", "output.plots=false"])
    assert r.returncode == 0, r.stderr[-3000:]
    assert "sooner than predicted" not in (out / "run.log").read_text()
    peak = json.loads((out / "fields/em/em_peak_current.json").read_text())
    h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    k = int(np.argmax(np.abs(h["coil_current_A"])))
    assert peak["time_s"] == pytest.approx(h["time_s"][k], rel=1e-9)  # the snapshot is the peak step's
    assert abs(peak["coil_current_A"]) == pytest.approx(np.abs(h["coil_current_A"]).max(), rel=1e-9)
