"""Case-specific analyses: extra history columns, metrics and plots, chosen by ``analysis = [...]``.

An analysis is a class with

* ``__init__(self, case)``,
* ``record(self, solver, row=None) -> dict[str, float]``: columns added to every history row (SI
  units in names); ``row``: the row's columns so far (time, ``energy_*``, probes, body extremes),
  to reuse instead of computing them again (None: compute them),
* ``metrics(self, solver, history) -> dict[str, float]``: added to ``metrics.json``,
* ``plots(self, history, shapes, folder) -> None``: PNGs into ``plots/``,
* ``springback_metrics(self, sb) -> dict[str, float]``: with ``[springback]``, metrics of the springback
  solver ``sb`` (its bodies after springback; contact pair ``i`` of the case is ``sb.source_pairs.index(i)``
  there, if kept); :class:`Analysis` gives none,
* ``state_dict(self) -> dict[str, np.ndarray]`` / ``load_state_dict(self, state)``: its restart
  state (what it accumulates over the run), saved in the checkpoint under
  ``analysis/<name>/<key>``; :class:`Analysis` gives the defaults (no state).

Register it by name in :data:`pulseform.orchestrator.case.analysis_names.ANALYSES` (``REGISTRY``
here; data only, so that validating a case file checks the names without importing the solvers: the
module is imported when the analysis is created).
"""

from __future__ import annotations

import importlib

from ...case.analysis_names import ANALYSES as REGISTRY  # name -> "module:Class" inside this package

__all__ = ["REGISTRY", "create", "Analysis"]


class Analysis:
    """Base of the analyses: the restart hooks' defaults (an analysis without state)."""

    def state_dict(self) -> dict:
        """Arrays to continue exactly after ``--resume`` (name -> array); none by default."""
        return {}

    def load_state_dict(self, state: dict) -> None:
        """Take back :meth:`state_dict` from a checkpoint (before the first ``record``)."""

    def springback_metrics(self, sb) -> dict:
        """Metrics of the springback solver ``sb`` (``[springback]``, after the run); none by default."""
        return {}


def create(name: str, case):
    """Instantiate the analysis called ``name`` for ``case``."""
    module, cls = REGISTRY[name].split(":")
    return getattr(importlib.import_module(f"{__name__}.{module}"), cls)(case)
