"""Exact restart of :class:`~.solver.ExplicitSolver`: the full state as a dict of arrays."""
from __future__ import annotations

from typing import Dict, Mapping

import numpy as np

__all__ = ["state_dict", "load_state_dict"]

_ACC_KEYS = ("plastic_J", "viscous_J", "external_work_J", "wall_dissipated_J", "kinetic_damping_J")


def _state_keys(body) -> tuple[str, ...]:
    """The body's state arrays: the temperature per cell only where the material carries one (the
    state of every other body is what it was before temperatures existed)."""
    keys = ("x", "v", "a", "cell_stress", "eps_p")
    return keys + ("temperature",) if body.material.thermal else keys


def _mass_scale(solver, name: str) -> np.ndarray:
    """Body ``name``'s density factors of selective mass scaling (:mod:`.mass_scaling`; empty: none)."""
    return getattr(getattr(solver, "_kernels", {}).get(name), "rho_scale", np.empty(0))


def state_dict(solver) -> Dict[str, np.ndarray]:
    """Complete solver state as arrays (exact restart with :meth:`load_state_dict`)."""
    d: Dict[str, np.ndarray] = {
        "time": np.array(solver.time), "step_count": np.array(solver.step_count),
        "dt_prev": np.array(solver._dt_prev), "dt_crit": np.array(solver._dt_crit),
        "E0": np.array(solver._E0), "contact_stored": np.array(solver._contact_stored),
        "acc": np.array([solver._acc[k] for k in _ACC_KEYS]),
        "contact_work": np.array(solver._contact_work),
        "contact_stored0": np.array(solver._contact_stored0),
        "kinetic_damping_ke": np.array([solver._ke_half[n] for n in solver.bodies])}
    for n, f in solver._fsurf_prev.items():
        d[f"{n}/contact_force"] = f.copy()
    for (ip, k), (si, mj) in solver._active.items():
        d[f"active/{ip}/{k}/slave"] = si.copy()
        d[f"active/{ip}/{k}/segment"] = mj.copy()
    for n, b in solver.bodies.items():
        for key in _state_keys(b):
            d[f"{n}/{key}"] = getattr(b, key).copy()
        d[f"{n}/fext"] = solver._fext[n].copy()
        if _mass_scale(solver, n).size:      # a scaled run only: the states of others keep their keys
            d[f"{n}/mass_scale"] = _mass_scale(solver, n).copy()
    for i, out in enumerate(solver._contact_out):
        if out is not None:
            d[f"contact{i}/p"], d[f"contact{i}/h"], d[f"contact{i}/X"] = (a.copy() for a in out)
    return d

def load_state_dict(solver, d: Mapping[str, np.ndarray]) -> None:
    """Restore a state written by :meth:`state_dict` (same meshes and partitioning)."""
    for n, b in solver.bodies.items():
        for key in _state_keys(b):
            if f"{n}/{key}" not in d:
                raise ValueError(f"state has no {n}/{key} (written without a temperature per cell?)")
            arr = np.asarray(d[f"{n}/{key}"])
            cur = getattr(b, key)
            if arr.shape != cur.shape:
                raise ValueError(f"state for {n}/{key} has shape {arr.shape}, need {cur.shape}")
            cur[...] = arr
        scale = np.asarray(d.get(f"{n}/mass_scale", np.empty(0)), dtype=float)
        if not np.array_equal(scale, _mass_scale(solver, n)):
            raise ValueError(f"state for body {n!r} was written with other selective mass scaling "
                             "(mass_scaling_dt) than the solver's")
        solver._fext[n][...] = np.asarray(d[f"{n}/fext"], dtype=float)
        solver._fext_nonzero[n] = bool(np.any(solver._fext[n]))
    solver.time = float(d["time"])
    solver.step_count = int(d["step_count"])
    solver._dt_prev = float(d["dt_prev"])
    solver._dt_crit = float(d["dt_crit"])
    solver._E0 = float(d["E0"])
    solver._contact_stored = float(d["contact_stored"])
    for k, val in zip(_ACC_KEYS, np.asarray(d["acc"])):
        solver._acc[k] = float(val)
    solver._contact_work = float(d["contact_work"])
    solver._contact_stored0 = float(d["contact_stored0"])
    ke = np.asarray(d.get("kinetic_damping_ke", np.zeros(len(solver.bodies))))
    solver._ke_half = {n: float(v) for n, v in zip(solver.bodies, ke)}
    for n in solver._fsurf_prev:
        solver._fsurf_prev[n][...] = np.asarray(d[f"{n}/contact_force"], dtype=float)
    solver._active = {}
    for key in d:
        if key.startswith("active/") and key.endswith("/slave"):
            _, ip, k, _ = key.split("/")
            solver._active[(int(ip), int(k))] = (
                np.array(d[key], dtype=np.int64),
                np.array(d[f"active/{ip}/{k}/segment"], dtype=np.int64))
    for i in range(len(solver._contact_out)):
        if f"contact{i}/p" in d:
            solver._contact_out[i] = tuple(np.array(d[f"contact{i}/{k}"]) for k in "phX")
        else:
            solver._contact_out[i] = None
