"""A 3D GetDP load whose EM mesh stops following the bodies when the air mesh would break.

The fall-back of the 3D air remesh (:mod:`.remesh3d`, docs/coupling.md, "Coupling in 3D"): the
harmonic air motion of :class:`~pulseform.orchestrator.mesh.motion3d.MeshMover3D` cannot keep a valid mesh once a body
slides a gap's width past another (a sheet wrapping the edge of a die's groove: the single layer of
air tetrahedra in the gap inverts). :class:`FreezingGetDPLoad3D` then keeps the last valid EM mesh for
every later step: the EM state carries on (same connectivity), the forces are those on the frozen
geometry, still handed to the bodies' nodes (the ledger holds; the mechanics moves on). This is an
approximation — after the freeze the EM no longer sees the bodies move — that the history flags
(``em_mesh_frozen``) and the run reports (:attr:`frozen_at`); where the forces have decayed when it
happens, its effect is small (say how much in the run's report). Choose ``freeze=False`` to stop
instead (the :class:`~pulseform.orchestrator.mesh.motion.MeshQualityError` propagates).

Checkpoints (:meth:`FreezingGetDPLoad3D.state_dict`): those of :class:`GetDPLoad3D` with the freeze (its
time, reason and the device impulse until then) and the last valid EM node positions (``freeze/*``), so
that a resume freezes, or goes on from, the same mesh. Metrics (:meth:`FreezingGetDPLoad3D.run_metrics`):
``em_mesh_frozen_at_s`` (NaN: never) and, once frozen, ``impulse_after_freeze_device_z_Ns`` (GetDP's
force integrals after the freeze, the device's).
"""

from __future__ import annotations

import logging

import numpy as np

from ..coupling.interfaces import LoadStep
from ..mesh.motion import MeshQualityError
from .participant3d import GetDPLoad3D

log = logging.getLogger(__name__)

__all__ = ["FreezingGetDPLoad3D"]


class FreezingGetDPLoad3D(GetDPLoad3D):
    """:class:`GetDPLoad3D` that freezes its EM mesh at the last valid one instead of stopping
    (module docstring). Same constructor, plus ``freeze`` (bool, default True)."""

    def __init__(self, *args, freeze: bool = True, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.columns = tuple(self.columns) + ("em_mesh_frozen",)
        self.freeze = freeze
        self.frozen_at: float | None = None
        self.freeze_reason = ""
        self.impulse_at_freeze = float("nan")   # the device's impulse (N s) until the freeze
        self._last_valid = self.mesh.points.copy()
        self.last_forces: dict = {}   # the nodal forces (N) per body of the last step

    def follow(self, t0: float, mechanics) -> None:
        """As :meth:`GetDPLoad3D.follow`, or the last valid mesh once frozen (t0 in s)."""
        if self.frozen_at is None:
            try:
                super().follow(t0, mechanics)
                self._last_valid = self._moved[1]
                return
            except MeshQualityError as err:
                if not self.freeze:
                    raise
                self.frozen_at, self.freeze_reason, self.impulse_at_freeze = t0, str(err), self.impulse_device
                log.warning("t = %.4g s: the EM mesh is frozen from here on (%s)", t0, err)
        self._moved = (t0, self._last_valid)

    def load(self, t0: float, t1: float, t_mid: float, mechanics) -> LoadStep:
        """As :meth:`GetDPLoad3D.load`, with the history flag ``em_mesh_frozen`` (0 or 1); keeps the
        step's nodal forces in ``last_forces``."""
        if self._moved is None or self._moved[0] != t0:
            self.follow(t0, mechanics)
        step = super().load(t0, t1, t_mid, mechanics)
        step.values["em_mesh_frozen"] = float(self.frozen_at is not None)
        self.last_forces = step.forces
        return step

    def state_dict(self) -> dict[str, np.ndarray]:
        """:meth:`GetDPLoad3D.state_dict` with ``freeze/last_valid`` (the last valid EM node positions, m) and,
        once frozen, ``freeze/frozen_at`` (s) and ``freeze/reason``."""
        out = super().state_dict()
        out["freeze/last_valid"] = np.array(self._last_valid, dtype=float)
        if self.frozen_at is not None:
            out["freeze/frozen_at"] = np.float64(self.frozen_at)
            out["freeze/reason"] = np.array(self.freeze_reason)
            out["freeze/impulse_at"] = np.float64(self.impulse_at_freeze)
        return out

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict` (a checkpoint without ``freeze/*``: as before, not frozen). A checkpoint
        written after a 3D air remesh (``remesh/*``) is refused: only a remeshing load restores its mesh."""
        if any(k.startswith("remesh/") for k in state):
            raise ValueError("the checkpoint holds a remeshed 3D EM mesh: resume it with the air remesh on "
                             "(geometry.on_mesh_break = \"remesh\")")
        super().load_state_dict(state)
        if "freeze/last_valid" in state:
            self._last_valid = np.array(state["freeze/last_valid"], dtype=float)
        if "freeze/frozen_at" in state:
            self.frozen_at, self.freeze_reason = float(state["freeze/frozen_at"]), str(state["freeze/reason"])
            self.impulse_at_freeze = float(state.get("freeze/impulse_at", np.nan))

    def run_metrics(self, history, counters) -> dict[str, float]:
        """:meth:`GetDPLoad3D.run_metrics` with the freeze (module docstring)."""
        out = super().run_metrics(history, counters)
        out["em_mesh_frozen_at_s"] = float("nan") if self.frozen_at is None else float(self.frozen_at)
        if self.frozen_at is not None:
            log.warning("the EM mesh was frozen at t = %.6g s: %s", self.frozen_at, self.freeze_reason)
            out["impulse_after_freeze_device_z_Ns"] = self.impulse_device - self.impulse_at_freeze
        return out
