"""Filament models of coaxial coils and a conductor moving along the axis: a coil driven by a
capacitor bank (:class:`FilamentActuator`, the reference of the actuator case, a Thomson-coil actuator
launching a disk) and coils on prescribed currents (:class:`DrivenFilaments`, the reference of the
TEAM 28 levitation case: a plate over two opposed 50 Hz coils).

The conductor's section is cut into rectangular filaments, each a coaxial ring carrying a uniform
current density (an R-L loop); the coil's turns are in series with the bank (C, V0, R_ext, L_ext).
All loops couple through their mutual inductances (Maxwell's formula averaged over Gauss points of
the sections, Rosa's self-inductance: :mod:`.lumped`). With the flux linkages ψ = L(z) i as the
state, Faraday's law is simply

    dψ_coil/dt = u_C − (R_coil + R_ext) i_coil,   dψ_k/dt = −R_k i_k,   C du_C/dt = −i_coil,

the motional EMF being contained in L(z); the axial force on the conductor is
i_coil Σ_k i_k ∂M_coil,k/∂z, its motion m z'' = F − m g, resting on a support at z = 0 while the
force does not lift it. With prescribed coil currents I(t) the state is the filaments' ψ alone
(ψ = L_ff i + M(z)ᵀ I). This is the classic filament method of induction-launcher and actuator
design; it converges to the eddy-current solution as the filaments resolve the skin depth.

Units: m, s, A, V, H, Ohm, F, N, kg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.linalg import cho_factor, cho_solve

from .lumped import _gauss_points, coil_inductance, mutual_inductance, mutual_inductance_gradient, \
    ring_resistance, ring_self_inductance

__all__ = ["filament_grid", "FilamentActuator", "DrivenFilaments"]

Rect = tuple[float, float, float, float]


def filament_grid(rect: Rect, n_r: int, n_z: int) -> list[Rect]:
    """The section ``(r0, z0, r1, z1)`` (m) cut into ``n_r`` × ``n_z`` equal rectangular filaments."""
    r = np.linspace(rect[0], rect[2], n_r + 1)
    z = np.linspace(rect[1], rect[3], n_z + 1)
    return [(r[i], z[j], r[i + 1], z[j + 1]) for i in range(n_r) for j in range(n_z)]


def _points(rects: Sequence[Rect], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Gauss points (r, z, weight) of every rectangle and the rectangle each belongs to."""
    r, z, w, owner = [], [], [], []
    for k, rect in enumerate(rects):
        rr, zz, ww = _gauss_points(rect, n)
        r.append(rr), z.append(zz), w.append(ww), owner.append(np.full(len(rr), k))
    return np.concatenate(r), np.concatenate(z), np.concatenate(w), np.concatenate(owner)


def _mutual_matrix(rects: Sequence[Rect]) -> np.ndarray:
    """Inductance matrix (H) of coaxial one-turn loops of rectangular section: Rosa's self-inductance
    (the section's geometric mean distance) on the diagonal, Maxwell's filament formula between the
    sections' centres off it — for nearly square filaments the centre distance is their geometric
    mean distance to 0.2 % (adjacent squares), while flat filaments overestimate the coupling of
    neighbours and make the matrix indefinite (refused)."""
    c = np.array([[0.5 * (a[0] + a[2]), 0.5 * (a[1] + a[3])] for a in rects])
    out = mutual_inductance(c[:, None, 0], c[None, :, 0], c[None, :, 1] - c[:, None, 1])
    for k, (r0, z0, r1, z1) in enumerate(rects):
        out[k, k] = ring_self_inductance(0.5 * (r0 + r1), r1 - r0, z1 - z0)
    smallest = float(np.linalg.eigvalsh(out).min())
    if smallest <= 0.0:
        raise ValueError(f"filament inductance matrix not positive definite (smallest eigenvalue {smallest:.3g} H): "
                         "use nearly square filaments, not thin at the axis")
    return out


def _coupling_table(rc: np.ndarray, zc: np.ndarray, wc: np.ndarray, filaments: Sequence[Rect], gauss: int,
                    zs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(M, ∂M/∂z) (H, H/m), shape ``(len(zs), len(filaments))``: the mutual inductance between a
    source given by points (``rc``, ``zc``, m) of weights ``wc`` (turns; the sum is the source's
    turn count) and each filament averaged over its ``gauss`` × ``gauss`` Gauss points, with the
    filaments lifted by each height of ``zs`` (m)."""
    rf, zf, wf, _ = _points(filaments, gauss)  # gauss² consecutive points per filament
    shape = (len(zs), len(filaments), gauss * gauss)
    dz = zs[:, None] + zf[None, :]
    m = np.zeros((len(zs), len(filaments)))
    dm = np.zeros_like(m)
    for a in range(len(rc)):
        m += wc[a] * (wf * mutual_inductance(rc[a], rf, dz - zc[a])).reshape(shape).sum(axis=2)
        dm += wc[a] * (wf * mutual_inductance_gradient(rc[a], rf, dz - zc[a])).reshape(shape).sum(axis=2)
    return m, dm


def _from_rest(rhs: Callable[[float, np.ndarray, bool], np.ndarray], y0: np.ndarray, t_end: float, rtol: float,
               atol: np.ndarray, force: Callable[[float, np.ndarray], float], weight: float, z_index: int,
               relands: bool = False, max_phases: int = 1000) -> list:
    """Integrate ``rhs(t, y, resting)`` (Radau) from ``y0``, the conductor resting on its support
    (z = ``y[z_index]`` = 0) until its axial force ``force(t, y)`` (N) exceeds its ``weight`` (N),
    then free. Back on its support (z < 0, moving down): with ``relands`` it rests there again
    (an inelastic stop, as pulseform's rigid-body stops) until lifted again; otherwise ValueError.
    Returns the phases' scipy solutions (dense), in order."""
    from scipy.integrate import solve_ivp

    def lift(t, y, resting):
        return force(t, y) - weight
    lift.terminal, lift.direction = True, 1.0

    def land(t, y, resting):
        return y[z_index] + 1e-12
    land.terminal, land.direction = True, -1.0

    sols, t0, resting = [], 0.0, True
    for _ in range(max_phases):
        if resting and force(t0, y0) > weight:  # lifted at once
            resting = False
        sol = solve_ivp(rhs, (t0, t_end), y0, method="Radau", rtol=rtol, atol=atol, args=(resting,),
                        events=lift if resting else land, dense_output=True)
        if not sol.success:
            raise RuntimeError(f"filament model: {sol.message}")
        sols.append(sol)
        if sol.status != 1:  # reached t_end
            return sols
        if not resting and not relands:
            raise ValueError(f"filament model: the conductor is back on its support at t = {sol.t[-1]:.6g} s")
        t0, y0 = sol.t[-1], sol.y[:, -1].copy()
        if not resting:  # the stop: on the support, at rest
            y0[z_index], y0[z_index + 1] = 0.0, 0.0
        resting = not resting
    raise RuntimeError(f"filament model: more than {max_phases} lifts and landings before t = {t_end:g} s")


@dataclass
class FilamentActuator:
    """A coil in series with a capacitor bank and a coaxial conductor cut into filaments, the
    conductor a rigid body moving along the axis from its place in the geometry (z = 0: resting on
    its support).

    Parameters
    ----------
    turns : list of (r0, z0, r1, z1)
        The coil's turns in series (m), one turn each, copper of conductivity ``coil_sigma`` (S/m).
    filaments : list of (r0, z0, r1, z1)
        The conductor's filaments at z = 0 (m), conductivity ``sigma`` (S/m).
    capacitance, voltage, resistance, inductance : float
        The bank C (F) charged to V0 (V) and its leads' R_ext (Ohm) and L_ext (H).
    mass : float
        The conductor's mass (kg); ``gravity`` (m/s², towards −z).
    z_max : float
        Largest travel (m) of the tabulated coil–filament coupling (cubic splines in z).
    gauss : int
        Gauss points per direction averaging the coil–filament mutual inductances (the filaments among
        themselves: :func:`_mutual_matrix`).
    """

    turns: Sequence[Rect]
    filaments: Sequence[Rect]
    sigma: float
    capacitance: float
    voltage: float
    resistance: float
    inductance: float
    mass: float
    coil_sigma: float = 5.8e7
    gravity: float = 0.0
    z_max: float = 0.02
    gauss: int = 2
    _splines: tuple = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.l_coil = coil_inductance(self.turns) + self.inductance
        self.r_coil = sum(ring_resistance(0.5 * (a[0] + a[2]), a[2] - a[0], a[3] - a[1], self.coil_sigma)
                          for a in self.turns) + self.resistance
        self.l_ff = _mutual_matrix(self.filaments)
        self.r_f = np.array([ring_resistance(0.5 * (a[0] + a[2]), a[2] - a[0], a[3] - a[1], self.sigma)
                             for a in self.filaments])
        zs = np.linspace(0.0, self.z_max, 161)
        rc, zc, wc, _ = _points(self.turns, self.gauss)
        m, dm = _coupling_table(rc, zc, wc, self.filaments, self.gauss, zs)
        self._splines = (CubicSpline(zs, m), CubicSpline(zs, dm))

    def matrix(self, z: float) -> tuple[np.ndarray, np.ndarray]:
        """(L(z), ∂M_coil/∂z) (H, H/m): the loops' inductance matrix, coil first, with the conductor
        lifted by z (m), and the coil–filament coupling's gradient."""
        mc, dmc = self._splines[0](z), self._splines[1](z)
        n = len(self.filaments) + 1
        a = np.empty((n, n))
        a[0, 0], a[0, 1:], a[1:, 0], a[1:, 1:] = self.l_coil, mc, mc, self.l_ff
        return a, dmc

    def _currents(self, y: np.ndarray) -> tuple[np.ndarray, float]:
        """(loop currents (A), coil first; axial force on the conductor (N)) of the state ``y``."""
        n = len(self.filaments)
        a, dmc = self.matrix(min(max(y[n + 2], 0.0), self.z_max))
        i = np.linalg.solve(a, y[1:n + 2])
        return i, i[0] * float(dmc @ i[1:])

    def rhs(self, t: float, y: np.ndarray, resting: bool = False) -> np.ndarray:
        """d(u_C, ψ_coil, ψ_1..ψ_N, z, w)/dt; ``resting``: the conductor held on its support."""
        n = len(self.filaments)
        i, force = self._currents(y)
        out = np.empty_like(y)
        out[0] = -i[0] / self.capacitance
        out[1] = y[0] - self.r_coil * i[0]
        out[2:n + 2] = -self.r_f * i[1:]
        out[n + 2] = 0.0 if resting else y[n + 3]
        out[n + 3] = 0.0 if resting else force / self.mass - self.gravity
        return out

    def solve(self, t_end: float, t_eval: np.ndarray, rtol: float = 1e-7) -> dict[str, np.ndarray]:
        """Integrate from the charged bank, the conductor at rest on its support, to ``t_end`` (s)
        (Radau): held on the support until the force exceeds its weight, then free (a return to the
        support ends the integration there: ValueError). Returns the arrays ``time_s``,
        ``coil_current_A``, ``capacitor_voltage_V``, ``force_N``, ``position_m``, ``velocity_m_s`` at
        ``t_eval``."""
        n = len(self.filaments)
        y0 = np.zeros(n + 4)
        y0[0] = self.voltage
        scale = np.concatenate([[self.voltage], np.full(n + 1, self.l_coil * self.voltage), [1e-3, 1.0]])
        sols = _from_rest(self.rhs, y0, t_end, rtol, 1e-9 * scale, lambda t, y: self._currents(y)[1],
                          self.mass * self.gravity, n + 2)
        out = {k: np.empty(len(t_eval)) for k in ("coil_current_A", "force_N", "capacitor_voltage_V",
                                                  "position_m", "velocity_m_s")}
        for k, tk in enumerate(t_eval):
            sol = next((s for s in sols if tk <= s.t[-1]), sols[-1])
            y = sol.sol(tk)
            i, force = self._currents(y)
            out["coil_current_A"][k], out["force_N"][k] = i[0], force
            out["capacitor_voltage_V"][k], out["position_m"][k], out["velocity_m_s"][k] = y[0], y[n + 2], y[n + 3]
        out["time_s"] = np.asarray(t_eval, float)
        return out


@dataclass
class DrivenFilaments:
    """Coaxial coils carrying prescribed currents and a coaxial conductor cut into filaments, the
    conductor a rigid body moving along the axis from its place in the geometry (z = 0: resting on
    its support): the electrodynamic levitation device (TEAM Workshop Problem 28) and any plate or
    ring over stranded coils on current sources.

    With the filaments' flux linkages ψ = L_ff i + M(z)ᵀ I(t) as the state (I the coils' currents),
    Faraday's law is dψ_k/dt = −R_k i_k; the axial force on the conductor is Σ_c I_c Σ_k i_k ∂M_ck/∂z,
    its motion m z'' = F − m g; on its support it rests until the force exceeds its weight, and a
    return to the support stops it there (an inelastic stop, as the rigid bodies' ``stops``).

    Parameters
    ----------
    coils : list of (windings, turns)
        Each coil's rectangular windings ``(r0, z0, r1, z1)`` (m) and its turns in series, spread
        uniformly over the windings' total area (a stranded coil: no eddy currents in it).
    currents : callable
        ``currents(t)`` -> each coil's current per turn (A) at time ``t`` (s), signed.
    filaments : list of (r0, z0, r1, z1)
        The conductor's filaments at z = 0 (m), conductivity ``sigma`` (S/m).
    mass : float
        The conductor's mass (kg); ``gravity`` (m/s², towards −z).
    z_max : float
        Largest travel (m) of the tabulated coil–filament coupling (cubic splines in z).
    gauss : int
        Gauss points per direction of each filament and of each cell of the coils' windings.
    coil_cell : float
        Largest side (m) of the cells the windings are cut into for averaging the coupling (a winding
        of several centimetres next to the conductor needs more than one cell's Gauss points).
    """

    coils: Sequence[tuple[Sequence[Rect], float]]
    currents: Callable[[float], np.ndarray]
    filaments: Sequence[Rect]
    sigma: float
    mass: float
    gravity: float = 0.0
    z_max: float = 0.02
    gauss: int = 2
    coil_cell: float = 4e-3
    _splines: tuple = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.l_ff = _mutual_matrix(self.filaments)
        self._l_ff_factor = cho_factor(self.l_ff)
        self.r_f = np.array([ring_resistance(0.5 * (a[0] + a[2]), a[2] - a[0], a[3] - a[1], self.sigma)
                             for a in self.filaments])
        zs = np.linspace(0.0, self.z_max, 161)
        m = np.zeros((len(zs), len(self.coils), len(self.filaments)))
        dm = np.zeros_like(m)
        for c, (windings, turns) in enumerate(self.coils):
            area = sum((w[2] - w[0]) * (w[3] - w[1]) for w in windings)
            for w in windings:
                n_r = max(1, math.ceil((w[2] - w[0]) / self.coil_cell - 1e-9))
                n_z = max(1, math.ceil((w[3] - w[1]) / self.coil_cell - 1e-9))
                rc, zc, wc, _ = _points(filament_grid(w, n_r, n_z), self.gauss)
                share = turns * (w[2] - w[0]) * (w[3] - w[1]) / area / (n_r * n_z)  # turns of one cell
                mw, dmw = _coupling_table(rc, zc, share * wc, self.filaments, self.gauss, zs)
                m[:, c] += mw
                dm[:, c] += dmw
        self._splines = (CubicSpline(zs, m), CubicSpline(zs, dm))

    def coupling(self, z: float) -> tuple[np.ndarray, np.ndarray]:
        """(M, ∂M/∂z) (H, H/m), shape (coils, filaments), with the conductor lifted by ``z`` (m)."""
        return self._splines[0](z), self._splines[1](z)

    def _currents(self, t: float, y: np.ndarray) -> tuple[np.ndarray, float]:
        """(filament currents (A), axial force on the conductor (N)) of the state ``y`` at ``t``."""
        n = len(self.filaments)
        m, dm = self.coupling(min(max(y[n], 0.0), self.z_max))
        coil = np.asarray(self.currents(t), float)
        i = cho_solve(self._l_ff_factor, y[:n] - coil @ m)
        return i, float(coil @ (dm @ i))

    def rhs(self, t: float, y: np.ndarray, resting: bool = False) -> np.ndarray:
        """d(ψ_1..ψ_N, z, w)/dt; ``resting``: the conductor held on its support."""
        n = len(self.filaments)
        i, force = self._currents(t, y)
        out = np.empty_like(y)
        out[:n] = -self.r_f * i
        out[n] = 0.0 if resting else y[n + 1]
        out[n + 1] = 0.0 if resting else force / self.mass - self.gravity
        return out

    def solve(self, t_end: float, t_eval: np.ndarray, rtol: float = 1e-7) -> dict[str, np.ndarray]:
        """Integrate from rest (no current in the conductor, on its support) to ``t_end`` (s) (Radau).
        Returns the arrays ``time_s``, ``position_m`` (the rise from the support), ``velocity_m_s``,
        ``force_N`` and ``conductor_current_A`` (the filaments' total) at ``t_eval``."""
        n = len(self.filaments)
        peak = max(float(np.abs(np.asarray(self.currents(t), float)).max())
                   for t in np.linspace(0.0, t_end, 2001))
        m0, _ = self.coupling(0.0)
        scale = np.concatenate([np.abs(m0).max(axis=0) * max(peak, 1e-30), [1e-3, 1.0]])
        sols = _from_rest(self.rhs, np.zeros(n + 2), t_end, rtol, 1e-9 * scale,
                          lambda t, y: self._currents(t, y)[1], self.mass * self.gravity, n, relands=True)
        out = {k: np.empty(len(t_eval)) for k in ("position_m", "velocity_m_s", "force_N", "conductor_current_A")}
        for k, tk in enumerate(t_eval):
            sol = next((s for s in sols if tk <= s.t[-1]), sols[-1])
            y = sol.sol(tk)
            i, force = self._currents(tk, y)
            out["position_m"][k], out["velocity_m_s"][k] = y[n], y[n + 1]
            out["force_N"][k], out["conductor_current_A"][k] = force, float(i.sum())
        out["time_s"] = np.asarray(t_eval, float)
        return out
