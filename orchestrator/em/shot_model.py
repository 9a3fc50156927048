"""The EM participants' side of repeated shots (issue 33, ``[em.shots]``; the sequence is
:mod:`pulseform.orchestrator.run.shots`): a new discharge of the same EM model, the same for the 2D model
(:class:`~pulseform.solvers.getdp.model.EMModel`) and the 3D one (:class:`~pulseform.solvers.getdp.solver3d.EM3DModel`):
its bank's ``circuit.V0`` and its coils' ``initial_temperature``."""

from __future__ import annotations

import numpy as np

__all__ = ["begin_model_shot", "model_shot_state", "load_model_shot_state"]


def begin_model_shot(model, voltage: float, coil_temperature: np.ndarray) -> None:
    """Set ``model`` for a new discharge: its bank charged to ``voltage`` (V), its coils at ``coil_temperature``
    (K; their Joule heat counts from here)."""
    if model.circuit is None:
        raise ValueError("a new shot needs a capacitor bank")
    model.circuit.V0 = float(voltage)
    for c, temp in zip(model.coils, np.asarray(coil_temperature, float)):
        c.initial_temperature = float(temp)


def model_shot_state(model) -> dict:
    """What a checkpoint keeps of the current shot: the bank's voltage (V) and the coils' start temperatures (K)."""
    return {"v0": model.circuit.V0 if model.circuit is not None else 0.0,
            "coil_t0": [c.initial_temperature for c in model.coils]}


def load_model_shot_state(model, d: dict) -> None:
    """Restore :func:`model_shot_state` into ``model``."""
    if model.circuit is not None:
        model.circuit.V0 = float(d["v0"])
    for c, temp in zip(model.coils, d["coil_t0"]):
        c.initial_temperature = float(temp)
