"""Which EM steps fetch their whole-domain fields on the persistent getdp (em_participant.peak_is_near):
the peak-current snapshot needs the fields of the step of the largest |I|, and a persistent process
holds a step's fields only until its next step, so rising steps near the peak fetch them."""

import numpy as np
import pytest

from pulseform.orchestrator.em_participant import PEAK_LOOKAHEAD_STEPS, peak_is_near


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
