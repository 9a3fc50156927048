"""What a case adds to the driver's run beside its participants (:mod:`.driver`): an observer called
after every EM step, with history columns, checkpoint state and metrics of its own (a case with a
``[racetrack]`` table had one until issue 29). :class:`NoObserver` is the one of every case."""

from __future__ import annotations

import numpy as np


class NoObserver:
    """The observer of a case without one: no columns, no state, no metrics."""

    #: its history columns (:meth:`values` gives them for each row)
    columns: tuple[str, ...] = ()

    def on_em_step(self, row: dict[str, float]) -> None:
        """After every EM step (``row``: the loop's scalars of the step, SI units): nothing."""

    def values(self) -> dict[str, float]:
        """The history columns of the current state: none."""
        return {}

    def flush(self) -> None:
        """Write what the observer keeps in memory (at a checkpoint): nothing."""

    def metrics(self, history, counters) -> dict:
        """Its figures for ``metrics.json``: none."""
        return {}

    def state_dict(self) -> dict[str, np.ndarray]:
        """Its state for a checkpoint: none."""
        return {}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`: nothing."""
