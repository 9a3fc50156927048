"""Case-specific analyses: extra history columns, metrics and plots, chosen by ``analysis = [...]``.

An analysis is a class with

* ``__init__(self, case)``,
* ``record(self, solver, row=None) -> dict[str, float]``: columns added to every history row (SI
  units in names); ``row``: the row's columns so far (time, ``energy_*``, probes, body extremes),
  to reuse instead of computing them again (None: compute them),
* ``metrics(self, solver, history) -> dict[str, float]``: added to ``metrics.json``,
* ``plots(self, history, shapes, folder) -> None``: PNGs into ``plots/``.

Register it by name in :data:`pulseform.orchestrator.case.analysis_names.ANALYSES` (``REGISTRY``
here; data only, so that validating a case file checks the names without importing the solvers: the
module is imported when the analysis is created).
"""

from __future__ import annotations

import importlib

from ...case.analysis_names import ANALYSES as REGISTRY  # name -> "module:Class" inside this package

__all__ = ["REGISTRY", "create"]


def create(name: str, case):
    """Instantiate the analysis called ``name`` for ``case``."""
    module, cls = REGISTRY[name].split(":")
    return getattr(importlib.import_module(f"{__name__}.{module}"), cls)(case)
