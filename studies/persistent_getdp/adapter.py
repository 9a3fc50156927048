"""Study adapter: a duck-typed stand-in for GetDPSolver (BDF2) that drives ONE persistent getdp
(:class:`persistent.PersistentGetDP`), so the product's coupled loop (GetDPLoad) runs unchanged on
the persistent path when ``pulseform.orchestrator.em_participant.GetDPSolver`` is replaced by
:func:`install` (demo.py does it in a child process; nothing in the product is edited).

Per EM step it sends the node positions, gets the globals and the per-element force table, and
keeps in Python what the per-process path keeps in EMState: the force density at the step's start
(trapezoid mean), the coil power (trapezoid heat) and the previous circuit values (for a restart).
B and the Joule density are asked for only when the loop reads them (a field output): a query
message after the step.  A mesh of other connectivity (remesh) ends the process and starts a new
one seeded with both BDF2 states, interpolated in material coordinates (persistent.seed_from_state).
A repeated step (coupling.iterate: the loop restores the EM state and calls step again for the
same step) is sent as a "redo": getdp restores the step's start vectors and steps again on the new
geometry.  Not covered here: resume from a product checkpoint (the restart mechanism itself is
checked in restart.py), a remesh inside an iterated step.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from persistent import FLAG_ELEM, FLAG_FIELDS, FLAG_STATE, PersistentGetDP, seed_from_state, state_from_query

from pulseform.solvers.getdp import EMState, coil_tag
from pulseform.solvers.getdp.bdf2 import trapezoid_mean
from pulseform.solvers.getdp.runner import RunInfo
from pulseform.solvers.getdp.solver import _element_volumes


class PResult:
    """The attributes of EMStepResult that the coupled loop reads (one step, BDF2)."""

    def __init__(self, adapter, out, t0, mesh):
        m = adapter.model
        self._adapter, self._k = adapter, out.k
        self.times = np.array([out.t])
        self.dt = out.t - t0
        self.elements = out.elements
        self.element_tags = mesh.tri_tags[out.elements]
        self.force_density = out.force_density[None]
        self.force_density_centroid = np.zeros_like(self.force_density)
        self.coil_current = out.coil[None, :, 0]
        self.coil_voltage = -out.coil[None, :, 1]
        self.coil_power = out.coil[None, :, 2]
        self.coil_force = out.coil[None, :, 3:5]
        self.conductor_power = out.cond[None, :, 0]
        self.conductor_force = out.cond[None, :, 1:3]
        self.magnetic_energy = out.glob[None, 0]
        self.capacitor_voltage = out.glob[None, 1] if m.circuit is not None else None
        self.circuit_current = out.glob[None, 2] if m.circuit is not None else None
        self.probe_b = np.zeros((1, 0, 2))
        self.force_density_start = None
        self._fields = None

    @property
    def force_density_mean(self):
        if self.force_density_start is None:
            return self.force_density[-1]
        return trapezoid_mean(self.force_density_start, self.force_density)

    def _get_fields(self):
        if self._fields is None:
            if self._adapter.p.k != self._k:
                raise RuntimeError("fields of an older step: the persistent getdp has moved on")
            q = self._adapter.p.query(FLAG_FIELDS)
            self._fields = (q.joule_density[None], q.flux_density[None])
        return self._fields

    joule_density = property(lambda self: self._get_fields()[0])
    flux_density = property(lambda self: self._get_fields()[1])


class PersistentSolverAdapter:
    #: PersistentGetDP(lean=...) for every process (install(lean=True) sets it)
    lean = False

    def __init__(self, model, work_dir, *, time_scheme="euler", **_ignored):
        if time_scheme != "bdf2":
            raise ValueError("the persistent study path implements BDF2 only")
        self.model = model
        self.work_dir = Path(work_dir).resolve()
        self.timeout = None
        self.time_scheme = time_scheme
        self.p: PersistentGetDP | None = None
        self.segment = 0
        self.f_prev = None
        self.power_prev = None
        self.circuit_prev = None   # (Vc, I) of x_{n-1}
        self.material_prev = None
        self.mass_cp = None
        self._last_call = None   # (state.step_index, state.t) of the last step: a repeat is a redo
        self._backup = None      # Python-side history before the last step

    def initial_state(self, t0: float = 0.0) -> EMState:
        v0 = self.model.circuit.V0 if self.model.circuit else 0.0
        return EMState(t=float(t0), capacitor_voltage=v0, current=0.0, coil_heat=[0.0] * len(self.model.coils))

    def _new_process(self):
        self.segment += 1
        return PersistentGetDP(self.model, self.work_dir / f"persistent_{self.segment:03d}",
                               step_time_limit=self.timeout or 600.0, verbosity=2, lean=self.lean)

    def step(self, mesh, state: EMState, t_end: float, n_sub: int = 1, *, material_points=None, run_name=None,
             force_init_path: bool = False, element_output: str = "all"):
        if n_sub != 1:
            raise ValueError("BDF2: one step per EM step")
        mat = mesh.points if material_points is None else np.asarray(material_points, float)
        if self.p is None:
            if state.t != 0.0 or state.a_values is not None:
                raise NotImplementedError("study adapter: no resume from a per-process checkpoint")
            self.p = self._new_process()
            self.p.start(mesh)
            self.mass_cp = np.array([c.density * c.heat_capacity * _element_volumes(
                mesh, np.flatnonzero(mesh.tri_tags == coil_tag(k)), self.model.axisymmetric).sum()
                for k, c in enumerate(self.model.coils, start=1)])
        elif not (np.array_equal(mesh.triangles, self.p.mesh.triangles)
                  and np.array_equal(mesh.tri_tags, self.p.mesh.tri_tags)):
            # remesh: both BDF2 states of the old process, interpolated in material coordinates
            old = self.p
            q = old.query(FLAG_STATE)
            st = state_from_query(old, q, self.material_prev, self.circuit_prev, self.dt_prev)
            old.close()
            self.p = self._new_process()
            init, init2 = seed_from_state(self.p, mesh, mat, st)
            self.p.start(mesh, t1=state.t, t2=state.t - self.dt_prev, dt_prev=self.dt_prev, step0=old.k,
                         init=init, init2=init2)
            self.f_prev = None   # other elements: the start value is matched in material coordinates below
        t0 = state.t
        redo = self._last_call == (state.step_index, state.t)   # coupling.iterate repeats the step
        if redo:
            self.f_prev, self.power_prev, self.circuit_prev, self.dt_prev, self.material_prev = self._backup
        else:
            self._backup = (self.f_prev, self.power_prev, self.circuit_prev, getattr(self, "dt_prev", None),
                            self.material_prev)
        self._last_call = (state.step_index, state.t)
        out = self.p.step(mesh.points, float(t_end), FLAG_ELEM, redo=redo)
        r = PResult(self, out, t0, mesh)
        centroids = mat[mesh.triangles[out.elements]].mean(axis=1)
        if state.t == 0.0 and self.f_prev is None:
            r.force_density_start = np.zeros_like(out.force_density)
        elif self.f_prev is not None:
            from pulseform.solvers.getdp.bdf2 import match_rows

            scale = max(float(np.abs(centroids).max()), 1e-30)
            idx = match_rows(centroids, self.f_prev[1], 1e-9 * scale)
            if idx is not None:
                r.force_density_start = self.f_prev[0][idx]
        self.f_prev = (out.force_density.copy(), centroids)
        p_start = self.power_prev if self.power_prev is not None else np.zeros(len(self.model.coils))
        heat = np.asarray(state.coil_heat or [0.0] * len(self.model.coils), float) \
            + trapezoid_mean(p_start, r.coil_power) * r.dt
        r.coil_heat = heat
        r.coil_temperature_rise = heat / self.mass_cp
        self.power_prev = r.coil_power[-1].copy()
        r.run = RunInfo(argv=self.p.argv, run_dir=self.p.run_dir, log_path=self.p.log_path,
                        wall_time=out.timing["getdp_s"])
        r.path = str(self.p.run_dir)
        self.circuit_prev = (state.capacitor_voltage, state.current)
        self.dt_prev = r.dt
        self.material_prev = mat.copy()
        new_state = EMState(t=float(t_end), step_index=state.step_index + 1,
                            capacitor_voltage=float(out.glob[1]), current=float(out.glob[2]),
                            coil_heat=heat.tolist(), dt_prev=r.dt)
        return r, new_state

    def close(self):
        if self.p is not None:
            self.p.close()
            self.p = None


def install(lean: bool = False):
    """Replace GetDPSolver in the coupled loop by the adapter; GetDPLoad.close also ends getdp."""
    import pulseform.orchestrator.em_participant as ep

    PersistentSolverAdapter.lean = lean

    ep.GetDPSolver = PersistentSolverAdapter
    original_close = ep.GetDPLoad.close

    def close(self):
        if hasattr(self.solver, "close") and isinstance(self.solver, PersistentSolverAdapter):
            self.solver.close()
        original_close(self)

    ep.GetDPLoad.close = close
