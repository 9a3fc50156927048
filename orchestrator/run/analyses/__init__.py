"""Case-specific analyses: extra history columns, metrics and plots, chosen by ``analysis = [...]``.

An analysis is a class with

* ``__init__(self, case)``,
* ``record(self, solver, row=None) -> dict[str, float]``: columns added to every history row (SI
  units in names); ``row``: the row's columns so far (time, ``energy_*``, probes, body extremes),
  to reuse instead of computing them again (None: compute them),
* ``metrics(self, solver, history) -> dict[str, float]``: added to ``metrics.json``,
* ``plots(self, history, shapes, folder) -> None``: PNGs into ``plots/``.

Register it in :data:`REGISTRY` by name (the module is imported lazily, so validating a case file
does not import the solvers).
"""

from __future__ import annotations

import importlib

REGISTRY: dict[str, str] = {
    # name: "module:Class" inside pulseform.orchestrator.run.analyses
    "corner_fill": "corner_fill:CornerFill",
    "tube_press_fit": "tube_press_fit:TubePressFit",
}


def create(name: str, case):
    """Instantiate the analysis called ``name`` for ``case``."""
    module, cls = REGISTRY[name].split(":")
    return getattr(importlib.import_module(f"{__name__}.{module}"), cls)(case)
