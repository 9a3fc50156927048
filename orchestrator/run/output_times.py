"""The output times of a run and the EM step they leave: the milestones, the EM step a case sets (when no
stability limit chooses it), the default output interval of whole EM steps, and the one line saying what a run
does where its output times are not whole multiples of that step (issue 32: the EM step a user sets is the
step the run takes)."""
from __future__ import annotations

import numpy as np

from ..coupling.loop import StaggeredLoop

__all__ = ["milestones", "fixed_em_step", "default_interval", "landing_note"]


def milestones(end: float, interval: float) -> np.ndarray:
    """Output times interval, 2·interval, ... up to and including ``end`` (s)."""
    n = max(1, int(np.floor(end / interval + 1e-9)))
    times = interval * np.arange(1, n + 1)
    if end - times[-1] > 1e-12 * end:
        times = np.append(times, end)
    times[-1] = min(times[-1], end)
    return times


def fixed_em_step(loop: StaggeredLoop, all_rigid: bool) -> float | None:
    """The EM step (s) the case sets, n × the mechanical step, when no stability limit chooses it: every
    body rigid (the step from ``coupling.steps_per_period``, ``geometry.em_step`` or ``time.dt_max``), or
    ``time.dt_max`` below the deformable bodies' stable step; None otherwise, for the mechanics alone
    (``landing = "last"``) and with adaptive n."""
    o = loop.options
    if o.landing != "even" or o.adaptive:
        return None
    stable = loop.mech.stable_time_step()
    if all_rigid:
        dt = stable if loop.dt_max is None else min(stable, loop.dt_max)
    elif loop.dt_max is not None and loop.dt_max < stable:
        dt = loop.dt_max
    else:
        return None
    return o.n * dt


def default_interval(end: float, em_step: float | None) -> float:
    """The output interval (s) when the case gives none: ``end`` / 20, a whole number of EM steps when
    the case sets the EM step (``em_step``, s; :func:`fixed_em_step`), so that output times do not
    change it."""
    interval = end / 20.0
    if em_step is None:
        return interval
    return em_step * max(1, round(interval / em_step))


def landing_note(stops: np.ndarray, em_step: float | None) -> str | None:
    """One line saying what the run does where the output times ``stops`` (s) are not whole multiples
    of the EM step the case sets (``em_step``, s; :func:`fixed_em_step`): the EM steps to each output
    time are made equal (``StaggeredLoop.substeps``), so shorter; None where they all are whole
    multiples, or no EM step is set."""
    if em_step is None:
        return None
    lengths = np.diff(np.concatenate([[0.0], stops]))
    steps = lengths / np.ceil(lengths / em_step * (1.0 - 1e-9))
    short = steps < em_step * (1.0 - 1e-9)
    if not short.any():
        return None
    shortest = f"down to {steps.min():.6g} s ({100.0 * (1.0 - steps.min() / em_step):.3g} % shorter)"
    if not short[:-1].any():
        return (f"time.end: {stops[-1]:.6g} s is not a whole multiple of the EM step {em_step:.6g} s: the run "
                f"lands on it with equal shorter EM steps in the last output interval, {shortest}")
    return (f"output.field_interval: output times every {lengths[0]:.6g} s are not whole multiples of the EM step "
            f"{em_step:.6g} s: the run lands on them with equal shorter EM steps in {int(short.sum())} of "
            f"{len(stops)} output intervals, {shortest}; an interval of whole EM steps keeps the step")
