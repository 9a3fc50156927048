"""A gmsh job started in a forked child and collected later (solvers/getdp/runner.ChildCall): a run
starts the EM meshing before it imports DOLFINx (orchestrator/run/runner._early_em_geometry)."""

from __future__ import annotations

import os
import time

import pytest

from pulseform.solvers.getdp.runner import ChildCall, TimeLimitExceeded


def _square(x: float, sleep_s: float = 0.0) -> float:
    time.sleep(sleep_s)
    return x * x


def _gone(pid: int) -> bool:
    """True once ``pid`` is reaped (no zombie left behind)."""
    try:
        os.waitpid(pid, os.WNOHANG)
    except ChildProcessError:
        return True
    return False


def test_answer_ready_before_the_limit_is_taken_after_it():
    call = ChildCall(_square, 3.0, time_limit=0.5, what="squaring")
    pid = call.pid
    time.sleep(0.8)  # the parent is busy (importing DOLFINx) past the child's limit; the child was done
    assert call.result() == 9.0
    assert _gone(pid)
    with pytest.raises(RuntimeError, match="already taken"):
        call.result()


def test_a_child_over_its_limit_is_killed_and_reaped():
    call = ChildCall(_square, 2.0, 30.0, time_limit=0.3, what="a slow square")
    pid = call.pid
    t0 = time.monotonic()
    with pytest.raises(TimeLimitExceeded, match="a slow square exceeded its time limit of 0.3 s"):
        call.result()
    assert time.monotonic() - t0 < 5.0
    assert _gone(pid)


def test_cancel_ends_an_unwanted_child():
    call = ChildCall(_square, 2.0, 30.0, time_limit=None, what="a slow square")
    pid = call.pid
    call.cancel()
    assert _gone(pid)
    call.cancel()  # twice: nothing left to do
