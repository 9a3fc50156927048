"""SIGINT / SIGTERM during a run: stop at the next safe point instead of dying mid-write.

While :func:`signals_stop_run` is active, the first SIGINT or SIGTERM only records the signal; the
driver asks :func:`check` at its safe points (after every EM step, after every milestone, after
set-up) and :class:`StopRequested` then unwinds the loop, which writes a checkpoint, the history
and a ``metrics.json`` with ``status = "interrupted"`` (``pulseform run --resume`` continues
exactly). A second SIGINT stops at once (Python's KeyboardInterrupt): the last checkpoint stays.

External programs ignore SIGINT (``child_preexec`` of the getdp runner), so a Ctrl-C in the
terminal lets a running getdp step finish; they die with pulseform through a parent-death signal.
"""

from __future__ import annotations

import logging
import signal
import threading
from contextlib import contextmanager
from typing import Iterator

log = logging.getLogger(__name__)

#: the signals that ask a run to stop; exit code of the CLI = 128 + signal number
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)

_pending: list[int] = []


class StopRequested(Exception):
    """A stop signal arrived; raised at a safe point. ``signum`` is the signal's number."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        self.time: float | None = None  # simulated time of the checkpoint written when it unwound (s)
        super().__init__(f"interrupted by {signal.Signals(signum).name}")


class StudyInterrupted(Exception):
    """A stop signal ended a study (sweep, converge) early: no member started after it, the running ones
    stopped at their next safe point. ``signum``: the signal's number; the message one line for the user."""

    def __init__(self, signum: int, message: str | None = None) -> None:
        self.signum = signum
        super().__init__(message or f"interrupted by {signal.Signals(signum).name}")


def _handler(signum: int, frame) -> None:  # noqa: ARG001 - signal handler signature
    if signum == signal.SIGINT and _pending:
        raise KeyboardInterrupt  # a second Ctrl-C: stop at once
    if not _pending:
        _pending.append(signum)


def pending() -> int | None:
    """The stop signal received so far, or None."""
    return _pending[0] if _pending else None


def check() -> None:
    """Raise :class:`StopRequested` if a stop signal arrived (call at safe points only)."""
    if _pending:
        raise StopRequested(_pending[0])


def rearm() -> None:
    """Put the stop handlers back (a library may have replaced them, e.g. gmsh at import)."""
    if _armed and threading.current_thread() is threading.main_thread():
        for s in STOP_SIGNALS:
            if signal.getsignal(s) is not _handler:
                signal.signal(s, _handler)


_armed = False


@contextmanager
def signals_stop_run(leaving_after_stop: bool = False) -> Iterator[None]:
    """Within the block, SIGINT / SIGTERM request a stop at the next safe point (main thread only;
    elsewhere a no-op). The previous handlers come back afterwards.

    ``leaving_after_stop`` (a process that exits when its run ends: the CLI, a study's member): after a stop,
    SIGTERM stays ignored instead: the run has unwound, written its checkpoint and metrics, and the process only
    leaves with 128 + n; a further SIGTERM (a study's stop to its members, after a Ctrl-C to the process group
    reached them too) must not turn that exit into a kill (-15)."""
    global _armed
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    import gmsh  # noqa: F401 - gmsh 4.8 resets SIGINT when first imported: let it do so before we install

    old = {s: signal.getsignal(s) for s in STOP_SIGNALS}
    _pending.clear()
    for s in STOP_SIGNALS:
        signal.signal(s, _handler)
    _armed = True
    try:
        yield
    finally:
        _armed = False
        ignore_term = leaving_after_stop and bool(_pending)
        for s, h in old.items():
            signal.signal(s, signal.SIG_IGN if ignore_term and s == signal.SIGTERM
                          else (h if h is not None else signal.SIG_DFL))
        _pending.clear()
