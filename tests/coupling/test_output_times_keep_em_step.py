"""Output times do not change the EM step a case sets (issue 32, items 4 and 9).

Fake participants (a rigid body under an analytic force, :mod:`pulseform.orchestrator.coupling.fakes`), the
driver's own milestone helpers (``milestones``, ``default_interval``, ``fixed_em_step``, ``landing_note``) and
the staggered loop: seconds.

* item 4: a case whose EM step is set (here 1 µs: every body rigid, no stability limit) and whose default
  output interval end / 20 is shorter than that step took EM steps of end / 20 (0.5 µs over 10 µs);
* item 9: 1.7 s of a 50 Hz levitation at 40 EM steps per period (0.5 ms), n = 1: the mechanics' clock, a sum
  of 0.5 ms steps, drifts by ~1e-13 s, and a remaining time that much above a whole number of steps split
  EM steps into two substeps (3747 mechanical steps for 3400 EM steps here, 4056 in the issue's run) or
  shortened the EM steps before an output time (n = 20: 3409 EM steps instead of 3400).
"""

import math

import numpy as np
import pytest

from pulseform.orchestrator.coupling.fakes import AnalyticForce, RigidAxialBody
from pulseform.orchestrator.coupling.loop import LoopOptions, StaggeredLoop, clock_round_off
from pulseform.orchestrator.run.output_times import default_interval, fixed_em_step, landing_note, milestones

NODES = np.array([[0.0, 0.0], [1.0, 0.0]])


def _loop(dt, n, force=lambda t: 0.0):
    body = RigidAxialBody("b", NODES, 1.0, dt=dt)
    return StaggeredLoop(AnalyticForce("b", len(NODES), force), body, LoopOptions(n=n, n_min=1, n_max=n)), body


def _run(loop, body, stops):
    """EM step lengths (s) of a run through ``stops``, as the driver runs them."""
    steps = []
    for stop in stops:
        loop.run_until(stop, lambda row: steps.append(row["dt_s"] * row["substeps"]))
        assert body.time == pytest.approx(stop, rel=1e-12, abs=0.0)
    return np.array(steps)


def test_default_output_interval_keeps_the_em_step():
    """10 µs at a set EM step of 1 µs: the default interval end / 20 = 0.5 µs made every EM step 0.5 µs
    (the issue's 0.42 % against the user's own getdp run at 1 µs); now it is a whole number of EM steps
    and the run takes 10 steps of 1 µs, without a warning."""
    end, dt = 10e-6, 1e-6
    loop, body = _loop(dt, 1)
    h = fixed_em_step(loop, all_rigid=True)
    assert h == dt
    old = _run(*_loop(dt, 1), milestones(end, end / 20.0))
    assert len(old) == 20 and old.max() == pytest.approx(0.5e-6)       # what the issue saw
    stops = milestones(end, default_interval(end, h))
    steps = _run(loop, body, stops)
    assert len(steps) == 10 and np.allclose(steps, dt, rtol=1e-12, atol=0.0)
    assert landing_note(stops, h) is None


def test_output_times_that_cannot_agree_give_one_line_that_says_what_the_run_does():
    """A given interval (1.5 µs) that is not a whole number of 1 µs EM steps: the run takes equal EM steps of
    0.75 µs, and the note says so with the figures the loop takes; an end (10.5 µs) beyond the last whole
    step: the last interval's step only."""
    loop, body = _loop(1e-6, 1)
    stops = milestones(9e-6, 1.5e-6)
    steps = _run(loop, body, stops)
    assert np.allclose(steps, 0.75e-6, rtol=1e-12)
    note = landing_note(stops, 1e-6)
    assert note.startswith("output.field_interval: ") and "\n" not in note
    assert "6 of 6 output intervals" in note and "down to 7.5e-07 s (25 % shorter)" in note
    stops = milestones(10.5e-6, default_interval(10.5e-6, 1e-6))
    note = landing_note(stops, 1e-6)
    assert note.startswith("time.end: 1.05e-05 s is not a whole multiple") and "5e-07 s (50 % shorter)" in note
    steps = _run(*_loop(1e-6, 1), stops)
    assert np.allclose(steps[:-1], 1e-6, rtol=1e-12) and steps[-1] == pytest.approx(0.5e-6, rel=1e-12)


def test_no_fixed_em_step_without_one_set():
    """A stability-limited step (a deformable body's, no ``time.dt_max`` below it) and adaptive n set none;
    ``time.dt_max`` below the stable step sets n × dt_max."""
    body = RigidAxialBody("b", NODES, 1.0, dt=2e-8)
    load = AnalyticForce("b", 2, lambda t: 0.0)
    assert fixed_em_step(StaggeredLoop(load, body, LoopOptions(n=20)), all_rigid=False) is None
    assert fixed_em_step(StaggeredLoop(load, body, LoopOptions(n=20, adaptive=True)), all_rigid=True) is None
    assert fixed_em_step(StaggeredLoop(load, body, LoopOptions(n=20), dt_max=1e-8), all_rigid=False) == 20 * 1e-8
    assert default_interval(60e-6, None) == 3e-6


@pytest.mark.parametrize("n", [1, 20])
def test_levitation_run_takes_one_mechanical_step_per_em_step(n):
    """1.7 s of a 50 Hz AC force (40 EM steps per period: 0.5 ms) on a rigid plate, default outputs: 3400 EM
    steps of 0.5 ms and exactly n mechanical steps each (before: n = 1 took 3747 mechanical steps, n = 20 took
    3409 EM steps, some of 0.25 ms)."""
    period, end = 0.02, 1.7
    h = period / 40
    loop, body = _loop(h / n, n, lambda t: 10.0 * math.sin(2 * math.pi * t / period) ** 2)
    stops = milestones(end, default_interval(end, fixed_em_step(loop, all_rigid=True)))
    steps = _run(loop, body, stops)
    assert loop.counters.em_steps == 3400 and body.step_count == 3400 * n
    assert np.allclose(steps, h, rtol=1e-9, atol=0.0)


def test_clock_round_off_bounds_the_measured_drift():
    """The bound ε·t·(t/dt) against a clock that adds dt: 3400 steps of 0.5 ms, 68000 of 25 µs, the demo's
    2760 of 22.457 ns."""
    for dt, n in ((5e-4, 3400), (2.5e-5, 68000), (2.2457e-8, 2760)):
        t, drift = 0.0, 0.0
        for i in range(1, n + 1):
            t += dt
            drift = max(drift, abs(t - i * dt))
        assert 0.0 < drift <= clock_round_off(n * dt, dt) < 1e-5 * dt  # the slack: round-off, not a step
