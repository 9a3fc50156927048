"""Progress bars (tqdm on stderr; silent with ``quiet``): a run over simulated time, a study over its members."""

from __future__ import annotations

from tqdm import tqdm


class Progress:
    """Context manager showing how much of ``[0, end]`` seconds has been simulated.

    Parameters
    ----------
    end : float
        Simulated end time (s).
    quiet : bool
        Show nothing.
    desc : str
        Label on the left of the bar.
    """

    def __init__(self, end: float, *, quiet: bool = False, desc: str = "") -> None:
        self.end = end
        import sys

        self._bar = None if quiet or not sys.stderr.isatty() else tqdm(total=1000, desc=desc, leave=True, mininterval=0.5,
                                            bar_format="{desc}: {percentage:3.0f}%|{bar}| "
                                                       "[{elapsed}<{remaining}{postfix}]")
        self._shown = 0

    def update_to(self, t: float) -> None:
        """Move the bar to simulated time ``t`` (s)."""
        if self._bar is None:
            return
        target = min(1000, int(1000 * t / self.end))
        if target > self._shown:
            self._bar.set_postfix_str(f"t = {t:.4g} s", refresh=False)
            self._bar.update(target - self._shown)
            self._shown = target

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        if self._bar is not None:
            self._bar.close()


class StudyProgress:
    """A study's members: a bar over the members that ended (tqdm, on a terminal and without ``quiet``) with the
    counts done / failed / running, and one log line per member that ends with the counts and the time left
    (INFO; DEBUG while the bar shows them).

    The time left is the members left times the mean wall time per ended member of this session, divided
    by the members running at once (the rate so far); thread-safe (members end in threads).

    Parameters
    ----------
    total : int
        Members of the study.
    already : tuple of int
        (done, failed) members recorded before this session (a resumed study).
    quiet : bool
        No bar (the log lines stay).
    """

    def __init__(self, total: int, already: tuple[int, int] = (0, 0), *, quiet: bool = False) -> None:
        import threading
        import time

        self.total = total
        self.done, self.failed = already
        self.running = 0
        self._ended_here = 0
        self.eta_s = float("nan")
        self._t0 = time.perf_counter()
        self._lock = threading.Lock()
        import sys

        self._bar = None if quiet or not sys.stderr.isatty() else tqdm(total=total, initial=self.done + self.failed, desc="members", leave=True,
                                            mininterval=0.5, unit="member",
                                            bar_format="{desc}: {n_fmt}/{total_fmt}|{bar}| [{elapsed}{postfix}]")
        self._show()

    def started(self, _member=None) -> None:
        """A member started."""
        with self._lock:
            self.running += 1
            self._show()

    def ended(self, ok: bool, what: str = "") -> None:
        """A member ended (``ok``: exit code 0); logs ``what`` with the counts and the time left."""
        import logging
        import time

        with self._lock:
            self.running = max(0, self.running - 1)
            self.done += ok
            self.failed += not ok
            self._ended_here += 1
            left = self.total - self.done - self.failed
            rate = self._ended_here / max(time.perf_counter() - self._t0, 1e-9)  # members per second
            self.eta_s = left / rate if left else 0.0
            if self._bar is not None:
                self._bar.update(1)
            self._show()
            level = logging.INFO if self._bar is None else logging.DEBUG
            logging.getLogger(__name__).log(level, "%s: %d/%d ended (done %d, failed %d, running %d; ~%s left)", what,
                                             self.done + self.failed, self.total, self.done, self.failed,
                                             self.running, _duration(self.eta_s))

    def _show(self) -> None:
        if self._bar is not None:
            eta = f", ~{_duration(self.eta_s)} left" if self._ended_here else ""
            self._bar.set_postfix_str(f"done {self.done}, failed {self.failed}, running {self.running}{eta}")

    def close(self) -> None:
        """End the bar."""
        if self._bar is not None:
            self._bar.close()


def _duration(seconds: float) -> str:
    """``42 s``, ``3.5 min`` or ``2.1 h``."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"
