"""Pressure pulses on the bodies of a 3D model (``coupling.load = "pressure"`` with ``[[loads]]`` in a coupled
3D geometry-file case): the counterpart of its GetDP-coupled run that ``pulseform compare`` uses.

The pulses of :class:`~.participants.PressurePulses` (eq. 7, 8 as follower pressures, evaluated per EM step at
``t_mid`` and held over the step), with what a 3D model of part of a device needs:

- a load's ``surface`` box is read with the 3D semantics of :func:`~.pulses.box_marker` (x, y, z bounds and
  the distance rmin/rmax from the z-axis, inclusive); a boundary triangle of the body is loaded when its three
  nodes lie in the box on the body's reference configuration (:func:`loaded_triangles`);
- the model is the whole device over ``symmetry_factor`` (the [[symmetry]] planes, or a wedge's 360 / angle:
  :func:`~..mesh.geometry3d.symmetry_factor`): the history carries the device's columns ``device_force_z_N``
  and ``device_impulse_z_Ns`` (the model's × the factor), and the metrics the device's impulse, peak force,
  plastic work and final kinetic energy under the 2D names (``sector_*``: the modelled part's, the names of
  :class:`~..em.participant3d.GetDPLoad3D`), so that the pressure run and the coupled run report alike.

Forces in N (the modelled part's unless ``device_``), times in s, pressures in Pa, areas in m².
"""

from __future__ import annotations

import numpy as np

from ..case.model import Load
from ..coupling.interfaces import LoadStep
from .participants import PressureMechanics, PressurePulses
from ..mesh.markers import box_marker

#: faces of a tetrahedron (local node indices), outward for a positively oriented one
_TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])


def box_nodes(box, X0: np.ndarray) -> np.ndarray:
    """Nodes (bool per row of ``X0``, (N, 3) m) inside ``box`` with the 3D semantics of
    :func:`~.pulses.box_marker` (x, y, z bounds and the distance from the z-axis, inclusive)."""
    return np.asarray(box_marker(box)(np.asarray(X0, dtype=float).T), dtype=bool)


def loaded_triangles(triangles: np.ndarray, marked: np.ndarray) -> np.ndarray:
    """The boundary triangles (rows of ``triangles``, (n, 3) node rows) whose three nodes are marked."""
    return triangles[marked[triangles[:, 0]] & marked[triangles[:, 1]] & marked[triangles[:, 2]]]


def boundary_triangles(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """The exterior faces (n, 3) of a tetrahedral mesh (``points`` (N, 3) m, ``tets`` (m, 4)), each ordered
    so that its normal (p1 − p0) × (p2 − p0) points out of the mesh, whatever the cells' orientation."""
    tets = np.asarray(tets)
    faces = tets[:, _TET_FACES].reshape(-1, 3)
    _, first, count = np.unique(np.sort(faces, axis=1), axis=0, return_index=True, return_counts=True)
    rows = first[count == 1]
    faces, cells = faces[rows], rows // 4
    opposite = tets[cells, (rows % 4)]   # the cell's node that is not on the face
    p0 = points[faces[:, 0]]
    normal = np.cross(points[faces[:, 1]] - p0, points[faces[:, 2]] - p0)
    inward = np.einsum("ij,ij->i", normal, points[opposite] - p0) > 0.0
    faces[inward] = faces[inward][:, [0, 2, 1]]
    return faces


def area_vectors(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area vectors (n, 3) (m²) ½ (p1 − p0) × (p2 − p0) of triangles (node rows of ``points`` (N, 3) m)."""
    p0 = points[triangles[:, 0]]
    return 0.5 * np.cross(points[triangles[:, 1]] - p0, points[triangles[:, 2]] - p0)


def loaded_surface(points: np.ndarray, tets: np.ndarray, box) -> tuple[float, np.ndarray]:
    """(Reference area (m²), inward area vector S (m²)) of the exterior triangles of a tetrahedral body
    (``points`` (N, 3) m, ``tets`` (m, 4)) with their three nodes in ``box`` (:func:`box_nodes`): the surface a
    pressure pulse with that box loads. A uniform pressure p on it pushes with the resultant p S (S = 0 for a
    closed surface: a whole tube's bore)."""
    tris = loaded_triangles(boundary_triangles(points, tets), box_nodes(box, points))
    av = area_vectors(points, tris)
    return float(np.linalg.norm(av, axis=1).sum()), -av.sum(axis=0)


class PressurePulses3D(PressurePulses):
    """:class:`PressurePulses` on the 3D bodies of a model of ``1 / symmetry_factor`` of a device (module
    docstring).

    Parameters
    ----------
    loads : tuple of Load
        The [[loads]] pulses (surface boxes with 3D bounds, m).
    symmetry_factor : float
        Whole device / modelled part: the device's forces are the model's times this.
    damping, damping_until, damping_from, kinetic_until
        As :class:`PressurePulses` (1/s, s, s, s).
    """

    def __init__(self, loads: tuple[Load, ...], symmetry_factor: float, damping: float = 0.0,
                 damping_until: float = float("inf"), damping_from: float = 0.0, kinetic_until: float = 0.0) -> None:
        super().__init__(loads, damping, damping_until, damping_from, kinetic_until)
        self.symmetry_factor = float(symmetry_factor)
        #: 1 along the axes the whole device has a resultant on, 0 where a symmetry plane's mirror cancels it
        #: (:func:`~pulseform.orchestrator.run.participants3d.device_axes`; set by the caller)
        self.device_axes = np.ones(3)
        self.impulse_device = 0.0  # Σ s F_z (t1 − t0) over the EM steps (N·s), the device's
        self.areas: list[float] = []  # the pulses' loaded reference areas (m², the model's): loaded_areas

    def _loaded_nodes(self, i: int, mechanics: PressureMechanics) -> np.ndarray:
        """Nodes of pulse i's box on the body's reference configuration (cached per pulse)."""
        if i not in self._masks:
            ld = self.loads[i]
            self._masks[i] = box_nodes(ld.surface, mechanics.reference_positions()[ld.body])
        return self._masks[i]

    def load(self, t0: float, t1: float, t_mid: float, mechanics: PressureMechanics) -> LoadStep:
        """:meth:`PressurePulses.load` plus the device's axial force and its running impulse."""
        step = super().load(t0, t1, t_mid, mechanics)
        fz = float(mechanics.total_force(step.forces)[2]) if step.forces else 0.0
        sz = self.symmetry_factor * self.device_axes[2]
        self.impulse_device += sz * fz * (t1 - t0)
        step.values.update({"device_force_z_N": sz * fz, "device_impulse_z_Ns": self.impulse_device})
        return step

    def loaded_areas(self, mechanics: PressureMechanics, bodies: dict) -> list[float]:
        """Reference area (m²) of each pulse's loaded triangles (this rank's), kept for :meth:`run_metrics`
        (``load<i>_area_m2``); ``bodies``: the solver's 3D bodies by name (their ``segments``: the boundary
        triangles, ``X0``)."""
        self.areas = []
        for i, ld in enumerate(self.loads):
            b = bodies[ld.body]
            tris = loaded_triangles(b.segments, self._loaded_nodes(i, mechanics))
            self.areas.append(float(np.linalg.norm(area_vectors(b.X0, tris), axis=1).sum()))
        return list(self.areas)

    @property
    def columns(self) -> tuple[str, ...]:
        """The model's resultant, each pulse's pressure, the device's axial force and impulse."""
        return ("force_x_N", "force_y_N", "force_z_N") + tuple(f"load{i}_pressure_Pa" for i in range(len(self.loads))) \
            + ("device_force_z_N", "device_impulse_z_Ns")

    def run_metrics(self, history, counters) -> dict[str, float]:
        """The pulses' start times, their loaded areas and the device's figures under the 2D names (impulse,
        peak force, plastic work, final kinetic energy: the model's × symmetry factor; ``sector_*`` the
        modelled part's)."""
        s = self.symmetry_factor
        sz = s * self.device_axes[2]
        impulse_z = float(counters.impulse[2]) if len(counters.impulse) > 2 else 0.0
        last = {k: float(history.column(f"energy_{k}_J")[-1]) for k in ("plastic", "kinetic")}
        return {**super().run_metrics(history, counters),
                "force_impulse_z_Ns": sz * impulse_z, "force_impulse_Ns": sz * abs(impulse_z),
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
