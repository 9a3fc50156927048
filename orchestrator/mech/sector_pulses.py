"""Pressure pulses on the sheet of a 3D sector (``coupling.load = "pressure"`` in a coupled 3D case).

The pulses of :class:`~.participants.PressurePulses` (eq. 7, 8 as follower pressures, evaluated per EM
step at ``t_mid`` and held over the step), with two differences that make a sector's pressure run the
counterpart of its coupled run:

- a load's ``surface`` box is read in the sector's (r, z) coordinates of the axisymmetric case
  (``xmin``/``xmax`` bound r = sqrt(x² + y²), ``ymin``/``ymax`` bound z), so the [[loads]] of the
  2D case act unchanged on its sector; a boundary triangle is loaded when its three vertices lie in
  the box on the body's reference configuration;
- the history and metrics carry the coupled sector's device columns: ``device_force_z_N`` and
  ``device_impulse_z_Ns`` (the sector's × ``symmetry_factor`` = 360 / angle), and the device's
  impulse, peak force, plastic work and final kinetic energy under the 2D names
  (:meth:`SectorPressurePulses.run_metrics`, as :class:`~..em.participant3d.GetDPLoad3D` does).

Forces in N (the modelled sector's unless ``device_``), times in s, pressures in Pa.
"""

from __future__ import annotations

import numpy as np

from ..case.model import Load
from ..coupling.interfaces import LoadStep
from .participants import PressureMechanics, PressurePulses
from .pulses import box_marker


def rz_marker(box, X0: np.ndarray) -> np.ndarray:
    """Nodes (bool per row of ``X0``, (N, 3) m) inside ``box`` read as r = sqrt(x² + y²) in
    [xmin, xmax] and z in [ymin, ymax] (inclusive)."""
    rz = np.zeros((3, X0.shape[0]))
    rz[0] = np.hypot(X0[:, 0], X0[:, 1])
    rz[1] = X0[:, 2]
    return np.asarray(box_marker(box)(rz), dtype=bool)


def loaded_triangles(segments: np.ndarray, marked: np.ndarray) -> np.ndarray:
    """The boundary triangles (rows of ``segments``, (n, 3) node rows) whose three nodes are marked."""
    return segments[marked[segments[:, 0]] & marked[segments[:, 1]] & marked[segments[:, 2]]]


class SectorPressurePulses(PressurePulses):
    """:class:`PressurePulses` on a 3D sector (module docstring).

    Parameters
    ----------
    loads : tuple of Load
        The [[loads]] pulses (surface boxes in (r, z), m).
    symmetry_factor : float
        360 / sector angle: the device's forces are the sector's times this.
    damping, damping_until, damping_from, kinetic_until
        As :class:`PressurePulses` (1/s, s, s, s).
    """

    def __init__(self, loads: tuple[Load, ...], symmetry_factor: float, damping: float = 0.0,
                 damping_until: float = float("inf"), damping_from: float = 0.0, kinetic_until: float = 0.0) -> None:
        super().__init__(loads, damping, damping_until, damping_from, kinetic_until)
        self.symmetry_factor = float(symmetry_factor)
        self.impulse_device = 0.0  # Σ s F_z (t1 − t0) over the EM steps (N·s), the device's
        self.areas: list[float] = []  # the pulses' loaded reference areas (m², the sector's): loaded_areas

    def _loaded_nodes(self, i: int, mechanics: PressureMechanics) -> np.ndarray:
        """Nodes of pulse i's (r, z) box on the body's reference configuration (cached per pulse)."""
        if i not in self._masks:
            ld = self.loads[i]
            self._masks[i] = rz_marker(ld.surface, mechanics.reference_positions()[ld.body])
        return self._masks[i]

    def load(self, t0: float, t1: float, t_mid: float, mechanics: PressureMechanics) -> LoadStep:
        """:meth:`PressurePulses.load` plus the device's axial force and its running impulse."""
        step = super().load(t0, t1, t_mid, mechanics)
        fz = float(mechanics.total_force(step.forces)[2]) if step.forces else 0.0
        self.impulse_device += self.symmetry_factor * fz * (t1 - t0)
        step.values.update({"device_force_z_N": self.symmetry_factor * fz, "device_impulse_z_Ns": self.impulse_device})
        return step

    def loaded_areas(self, mechanics: PressureMechanics, bodies: dict) -> list[float]:
        """Reference area (m²) of each pulse's loaded triangles (this rank's), kept for :meth:`run_metrics`
        (``load<i>_area_m2``); ``bodies``: the solver's 3D bodies by name (their ``segments``, ``X0``)."""
        self.areas = []
        for i, ld in enumerate(self.loads):
            b = bodies[ld.body]
            tris = loaded_triangles(b.segments, self._loaded_nodes(i, mechanics))
            p0 = b.X0[tris[:, 0]]
            av = 0.5 * np.cross(b.X0[tris[:, 1]] - p0, b.X0[tris[:, 2]] - p0)
            self.areas.append(float(np.linalg.norm(av, axis=1).sum()))
        return list(self.areas)

    @property
    def columns(self) -> tuple[str, ...]:
        """The sector's resultant, each pulse's pressure, the device's axial force and impulse."""
        return ("force_x_N", "force_y_N", "force_z_N") + tuple(f"load{i}_pressure_Pa" for i in range(len(self.loads))) \
            + ("device_force_z_N", "device_impulse_z_Ns")

    def run_metrics(self, history, counters) -> dict[str, float]:
        """The pulses' start times and the coupled sector's device figures under the 2D names (impulse,
        peak force, plastic work, final kinetic energy: the sector's × symmetry factor; ``sector_*``
        the modelled sector's)."""
        s = self.symmetry_factor
        impulse_z = float(counters.impulse[2]) if len(counters.impulse) > 2 else 0.0
        last = {k: float(history.column(f"energy_{k}_J")[-1]) for k in ("plastic", "kinetic")}
        return {**super().run_metrics(history, counters),
                "force_impulse_z_Ns": s * impulse_z, "force_impulse_Ns": s * abs(impulse_z),
                "sector_force_impulse_z_Ns": impulse_z,
                "plastic_work_J": s * last["plastic"], "kinetic_energy_final_J": s * last["kinetic"],
                "sector_plastic_work_J": last["plastic"],
                "force_peak_N": float(np.abs(history.column("device_force_z_N")).max()),
                "symmetry_factor": s, **{f"load{i}_area_m2": a for i, a in enumerate(self.areas)}}

    def state_dict(self) -> dict[str, np.ndarray]:
        """The trigger shifts and the device's running impulse."""
        return {**super().state_dict(), "impulse_device": np.float64(self.impulse_device)}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        super().load_state_dict(state)
        if "impulse_device" in state:
            self.impulse_device = float(state["impulse_device"])
