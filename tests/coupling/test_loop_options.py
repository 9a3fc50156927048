"""``LoopOptions`` of a coupled case come from the case's ``[coupling]`` table by field name."""

from __future__ import annotations

import dataclasses

import pytest

from pulseform.orchestrator.case.model import Coupling
from pulseform.orchestrator.coupling.loop import LoopOptions


def test_options_take_every_shared_field_of_the_coupling_table():
    cp = Coupling(n=7, adaptive=True, n_min=2, n_max=50, adapt_tol=0.1, iterate=True, iterate_tol=1e-4,
                  iterate_max=3)
    opts = LoopOptions.from_coupling(cp)
    shared = {f.name for f in dataclasses.fields(LoopOptions)} & {f.name for f in dataclasses.fields(Coupling)}
    assert shared == {"n", "adaptive", "n_min", "n_max", "adapt_tol", "iterate", "iterate_tol", "iterate_max"}
    assert all(getattr(opts, name) == getattr(cp, name) for name in shared)
    assert (opts.landing, opts.max_growth, opts.block) == ("even", 2.0, 1)  # the loop's own defaults


def test_overrides_and_checks_apply():
    assert LoopOptions.from_coupling(Coupling(), landing="last").landing == "last"
    with pytest.raises(ValueError):
        LoopOptions.from_coupling(Coupling(n=5, n_max=5), n_max=4)
