"""A progress bar over simulated time (tqdm on stderr); silent with ``quiet``."""

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
        self._bar = None if quiet else tqdm(total=1000, desc=desc, leave=True, mininterval=0.5,
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
