"""The EM field snapshots of the GetDP load: whole-domain fields at the output milestones and the
snapshot at the peak coil current (:class:`EMSnapshots`, a part of
:class:`~.participant.GetDPLoad`), and the ``.vtu`` data of one EM step (:func:`_snapshot`).

A milestone's EM step prints B on every cell and the nodal potential itself (``field_output``);
any other step's whole-domain fields are post-processed from its saved solution while its run
folder exists (:meth:`EMSnapshots._fields`). The peak-current step is tracked as the steps come
(:meth:`EMSnapshots._track_peak`); a persistent getdp keeps a step's fields only until its next
step, so there a rising step fetches them when the peak is near (:func:`peak_is_near`).
"""

from __future__ import annotations

import logging
import time

import numpy as np

log = logging.getLogger(__name__)


class EMSnapshots:
    """The load's EM field snapshots, a part of :class:`~.participant.GetDPLoad` (which holds the
    solver, the current mesh, the latest step ``last``, the timers and the peak state
    ``peak_abs_current``, ``_peak``, ``_fetched_peak``, ``_rise``, ``_post_fields_ok``,
    ``field_times``)."""

    def request_fields(self, times) -> None:
        """The EM steps that end at ``times`` (s; the output milestones) also print B on every
        cell and the nodal potential (``GetDPSolver.step(field_output=True)``): only the steps
        whose snapshot is written pay for the whole-domain tables."""
        self.field_times = np.asarray(times, float)

    def _wants_fields(self, t1: float) -> bool:
        ft = self.field_times
        return ft is not None and ft.size > 0 and float(np.abs(ft - t1).min()) <= 1e-9 * max(abs(t1), 1e-300)

    def _fields(self, result, mesh) -> None:
        """Whole-domain fields of a step that did not print them: post-process its saved solution
        (its run folder must still exist: the latest two are kept)."""
        if getattr(result, "b_cells", None) is not None or not self._post_fields_ok:
            return
        c0 = time.perf_counter()
        try:
            self._post_fields_ok = self.solver.post_fields(result, mesh)
        finally:
            self.timers["getdp_process_s"] += time.perf_counter() - c0
        if not self._post_fields_ok:
            log.info("the EM deck has no PostOperation EM_Field: EM snapshots hold B on the conductors only")

    def _track_peak(self, t1: float, x_em: np.ndarray, result) -> None:
        """Keep the EM step with the largest |coil current| (end of step) as the peak snapshot.

        The whole-domain fields of that step are fetched (:meth:`_fields`) once a later step
        shows a smaller current, while the step's run folder still exists; a milestone step has
        them already. A persistent getdp holds a step's fields only until its next step: there a
        rising step's fields are fetched when the peak is near (:func:`peak_is_near`: at most
        :data:`PEAK_LOOKAHEAD_STEPS` steps ahead by the current's curvature), the last fetched
        candidate standing in should the prediction miss (logged)."""
        if result.coil_current.shape[1] == 0:
            return
        last = result.coil_current[-1]
        current = float(last[int(np.argmax(np.abs(last)))])  # the coil with the largest |current| (one coil: it)
        expire = self.solver.fields_expire
        p = self._peak
        if p is not None and p["t"] == t1:  # a repeated (iterated) EM step replaces its earlier try
            self.peak_abs_current, self._peak = p["before"], p["previous"]
            self._rise = self._rise[:-1]
            p = self._peak
        self._rise = (self._rise + [(t1, abs(current))])[-3:]
        if abs(current) > self.peak_abs_current:
            if p is not None:
                p["previous"] = None  # keep one level: only the latest step can be repeated
                if p.get("fetched"):
                    self._fetched_peak = p
            self._peak = {"t": t1, "current": current, "x": x_em, "result": result, "mesh": self.geometry.mesh,
                          "before": self.peak_abs_current, "previous": p, "written": False,
                          "fetched": not expire or getattr(result, "b_cells", None) is not None}  # a milestone's
            self.peak_abs_current = abs(current)
            if expire and peak_is_near(self._rise):  # fetch now: the next step would lose them
                self._fields(result, self.geometry.mesh)
                self._peak["fetched"] = True
        elif p is not None and not p["written"]:
            if not p["fetched"]:  # the peak came sooner than predicted: keep the last fetched step
                fallback = self._fetched_peak
                log.warning("EM snapshot at the peak coil current: the peak (t = %.6g s, %.6g A) came sooner "
                            "than predicted; the snapshot is the step at t = %s", p["t"], p["current"],
                            "none" if fallback is None else f"{fallback['t']:.6g} s ({fallback['current']:.6g} A)")
                self._peak = p = fallback
            if p is not None and not p["written"]:
                self._fields(p["result"], p["mesh"])

    def take_peak_snapshot(self) -> tuple | None:
        """(t, coil current, points, triangles, cell data, point data) of the peak-current step if it
        is new since the last call, else None (the driver writes it at milestones and checkpoints)."""
        p = self._peak
        if p is None or p["written"]:
            return None
        p["written"] = True
        try:
            self._fields(p["result"], p["mesh"])
            return (p["t"], p["current"], *_snapshot(p["mesh"], p["x"], p["result"], self.axisymmetric))
        except Exception as exc:  # an output: never the end of the run
            log.warning("no EM snapshot at the peak coil current (t = %.6g s): %s", p["t"], exc)
            return None

    def snapshot(self) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]] | None:
        """The latest step's EM mesh, per-element fields (force and Joule density on the conductors,
        zero elsewhere; B on every cell) and nodal potential (see :func:`_snapshot`)."""
        if self.last is None:
            return None
        x, r, mesh = self.last
        self._fields(r, mesh)  # a no-op when the step printed them (a milestone)
        return _snapshot(mesh, x, r, self.axisymmetric)


#: a rising step's whole-domain fields are fetched on the persistent getdp when the current's peak is
#: predicted within this many EM steps (a smooth discharge: the prediction is good to a step)
PEAK_LOOKAHEAD_STEPS = 3.0


def peak_is_near(rise: list[tuple[float, float]], lookahead: float = PEAK_LOOKAHEAD_STEPS) -> bool:
    """True if the last of ``rise`` ((t, |I|) of the last three EM steps, s and A) may be the peak of
    |I| or precede it by at most ``lookahead`` steps: the rate of rise, extrapolated linearly in time,
    reaches zero within ``lookahead`` steps of the last length. A rate that does not fall: False (far
    from a peak); a rate that is not positive, or fewer than three steps (the start of a run or of a
    resumed segment: nothing to predict from): True."""
    if len(rise) < 3:
        return True
    (t0, a0), (t1, a1), (t2, a2) = rise
    if not (t2 > t1 > t0):
        return True
    r1, r2 = (a1 - a0) / (t1 - t0), (a2 - a1) / (t2 - t1)
    if r2 <= 0.0:
        return True
    slope = (r2 - r1) / (0.5 * (t2 - t0))  # d(rate)/dt between the two steps' centres
    if slope >= 0.0:
        return False
    return r2 / -slope <= lookahead * (t2 - t1) + 0.5 * (t2 - t1)


def _snapshot(mesh, x: np.ndarray, r, axisymmetric: bool):
    """(points, triangles, cell data, point data) of one EM step for the ``.vtu`` files.

    Cell data: ``region`` (physical id), ``force_density_N_m3`` and ``joule_power_density_W_m3``
    (element averages on the conductors, zero elsewhere), ``flux_density_T`` (B at the cell
    centre: on every cell when the step has whole-domain fields, else on the conductors only).
    Point data, with whole-domain fields: ``r_a_phi_Wb`` (axisymmetric; r·a_φ, T·m² = Wb per
    radian: 2π r a_φ is the flux through the circle of radius r) or ``a_z_Wb_m`` (planar); its
    contours are the flux lines.  Signs: GetDP's frame, i.e. a positive coil current flowing along
    −e_φ (axisymmetric) or +z (planar), so that B = curl a holds with the written values.
    """
    m = len(mesh.triangles)
    f, p, b = np.zeros((m, 3)), np.zeros(m), np.zeros((m, 3))
    f[r.elements, :2] = r.force_density[-1]
    p[r.elements] = r.joule_density[-1]
    point_data = {}
    if getattr(r, "b_cells", None) is not None and getattr(r, "a_nodes", None) is not None:
        b[:, :2] = np.nan_to_num(r.b_cells)
        if axisymmetric:
            point_data["r_a_phi_Wb"] = -r.a_nodes  # getdp's unknown is r a_z of its frame, z = -e_phi
        else:
            point_data["a_z_Wb_m"] = r.a_nodes.copy()
    else:
        b[r.elements, :2] = r.flux_density[-1]
    data = {"region": mesh.tri_tags.astype(np.int32), "force_density_N_m3": f,
            "joule_power_density_W_m3": p, "flux_density_T": b}
    return x, mesh.triangles, data, point_data
