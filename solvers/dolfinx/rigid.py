"""Rigid bodies: conductors that translate without deforming (actuator armatures, jumping rings,
levitated plates, projectiles), integrated by the same central differences as the explicit solver.

A rigid body carries its nodes (the EM mesh's nodes of that conductor follow them) and moves by one
translation u(t): along the axis only in axisymmetry, in x and y in plane models, in x, y and z in 3D
(each component may be fixed; the dimension is the length of ``free``). Forces are resultants: the sum of the nodal forces handed to :meth:`RigidBody.advance`,
held from the current time on (as for the deformable bodies), plus gravity. A constant force is
integrated exactly (central differences are exact for quadratic trajectories).

End stops (:class:`EndStop`) are planes the body's translation cannot pass, e.g. the support a disk
rests on or a limit of travel: a body on a stop that the forces push into it stays there at rest
(the stop's reaction takes the pushing force, no drift, no penetration); a body that reaches a stop
is put on it and its normal velocity reversed times the coefficient of restitution (0: it stays).

Units: m, m/s, m/s^2, kg, N, s, J.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

__all__ = ["EndStop", "RigidBody"]


@dataclass(frozen=True)
class EndStop:
    """A limit of a rigid body's translation: component ``axis`` (0: x or r, 1: y or z in 2D; 2: z in 3D) of the
    translation stays >= ``position`` (m) when ``side`` is +1 (a support below), <= when -1 (a stop
    above); ``restitution`` in [0, 1] is the ratio of rebound to impact speed."""

    axis: int
    position: float
    side: int = 1
    restitution: float = 0.0

    def __post_init__(self) -> None:
        if self.axis not in (0, 1, 2):
            raise ValueError(f"end stop axis must be 0 (x/r), 1 (y/z) or 2 (z in 3D), got {self.axis}")
        if self.side not in (1, -1):
            raise ValueError(f"end stop side must be +1 (stays above) or -1 (stays below), got {self.side}")
        if not 0.0 <= self.restitution <= 1.0:
            raise ValueError(f"end stop restitution must be in [0, 1], got {self.restitution}")

    def gap(self, u: np.ndarray) -> float:
        """Signed distance (m) of the translation ``u`` from the stop; < 0: beyond it."""
        return self.side * (float(u[self.axis]) - self.position)


@dataclass
class RigidBody:
    """One rigid body.

    Parameters
    ----------
    name : str
        Body name (the key of its forces and positions).
    nodes : ndarray (N, dim)
        Node coordinates at zero translation, m (dim = len(free): 2, or 3 in 3D).
    mass : float
        kg (an axisymmetric body: the whole ring's mass).
    free : (bool, bool) or (bool, bool, bool)
        Which translation components move: (False, True) in axisymmetry (axial only); three in 3D.
    gravity : tuple of dim floats
        Acceleration of gravity, m/s^2 (e.g. (0, -9.81)); default zero.
    offset : tuple of dim floats
        Initial translation, m; default zero.
    velocity : tuple of dim floats
        Initial velocity, m/s; default zero.
    stops : tuple of EndStop
        Limits of the translation.
    reference : tuple of dim floats, optional
        The body's reference point at zero translation, m: the point whose position the history reports
        (``<body>_position_<c>_m``); default the mean of ``nodes``.
    """

    name: str
    nodes: np.ndarray
    mass: float
    free: tuple[bool, ...] = (False, True)
    gravity: tuple[float, ...] | None = None
    offset: tuple[float, ...] | None = None
    velocity: tuple[float, ...] | None = None
    stops: tuple[EndStop, ...] = ()
    reference: tuple[float, ...] | None = None
    #: translation (m), velocity at the last half step (m/s), acceleration (m/s^2), applied force (N)
    u: np.ndarray = field(init=False)
    v: np.ndarray = field(init=False)
    a: np.ndarray = field(init=False)
    force: np.ndarray = field(init=False)
    time: float = field(init=False, default=0.0)
    step_count: int = field(init=False, default=0)
    #: kinetic energy taken by impacts on the stops (J); work of the applied force and gravity over
    #: the body's displacement (J)
    stop_dissipated_J: float = field(init=False, default=0.0)
    work_J: float = field(init=False, default=0.0)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mass) and self.mass > 0.0):
            raise ValueError(f"rigid body {self.name!r}: mass must be > 0 kg, got {self.mass}")
        dim = self.dim = len(self.free)
        if dim not in (2, 3):
            raise ValueError(f"rigid body {self.name!r}: free has 2 or 3 components, got {self.free!r}")
        zero = (0.0,) * dim
        self.gravity = zero if self.gravity is None else tuple(self.gravity)
        self.offset = zero if self.offset is None else tuple(self.offset)
        self.velocity = zero if self.velocity is None else tuple(self.velocity)
        for key in ("gravity", "offset", "velocity"):
            if len(getattr(self, key)) != dim:
                raise ValueError(f"rigid body {self.name!r}: {key} needs {dim} components, got {getattr(self, key)!r}")
        if any(st.axis >= dim for st in self.stops):
            raise ValueError(f"rigid body {self.name!r}: an end stop's axis is beyond the {dim} components")
        self.nodes = np.asarray(self.nodes, float)[:, :dim].copy()
        self.reference = tuple(self.nodes.mean(axis=0)) if self.reference is None else tuple(self.reference)
        if len(self.reference) != dim:
            raise ValueError(f"rigid body {self.name!r}: reference needs {dim} components, got {self.reference!r}")
        self._mask = np.array(self.free, bool)
        self.u = np.array(self.offset, float) * self._mask
        self.v = np.array(self.velocity, float) * self._mask
        self.force = np.zeros(dim)
        self._dt_prev = 0.0
        for s in self.stops:
            if s.gap(self.u) < -1e-15 * max(1.0, abs(s.position)):
                raise ValueError(f"rigid body {self.name!r}: the initial offset {tuple(self.u)} m is beyond "
                                 f"an end stop at {s.position} m (axis {s.axis})")
        self.a = self._acceleration()

    # ------------------------------------------------------------------ stepping
    def stable_time_step(self) -> float:
        """No stability limit (s): inf."""
        return math.inf

    def _acceleration(self) -> np.ndarray:
        """(force / mass + gravity) on the free components, zero where a stop holds the body."""
        a = (self.force / self.mass + np.asarray(self.gravity, float)) * self._mask
        for s in self.stops:
            if s.gap(self.u) <= 0.0 and s.side * a[s.axis] < 0.0 and s.side * self.v[s.axis] <= 0.0:
                a[s.axis] = 0.0  # resting on the stop: its reaction takes the push
        return a

    def advance(self, dt: float, n_steps: int, force: np.ndarray | None = None) -> None:
        """``n_steps`` central-difference steps of ``dt`` (s) with the resultant ``force`` (N, shape
        (dim,)) held from now on (None: no applied force).

        The work ledger is the explicit solver's: f·Δu of the held force and gravity per step, and where the
        force changes, the change of the kinetic energy at the current time (its velocity estimate
        v^{n-1/2} + dt/2 a^n takes the new force): the work of the switch. Then the kinetic energy at the
        current time minus the work is constant to round-off (the stops' losses aside), and the work is the
        scheme's second-order ∫ F·v dt; without the switch term, a force changing at every EM step leaves
        a first-order error Σ dt/2 ΔF·v that adds up over the cycles of an AC force (issue 32).
        """
        ke_old = self.kinetic_energy()
        self.force = np.zeros(self.dim) if force is None else np.asarray(force, float).reshape(self.dim).copy()
        self.work_J += self.kinetic_energy() - ke_old
        f_total = (self.force + self.mass * np.asarray(self.gravity, float)) * self._mask
        for _ in range(int(n_steps)):
            self.a = self._acceleration()
            self.v = self.v + 0.5 * (self._dt_prev + dt) * self.a
            u_old = self.u
            self.u = self.u + dt * self.v
            for s in self.stops:
                if s.gap(self.u) < 0.0:
                    i = s.axis
                    self.u[i] = s.position
                    vn = self.v[i]
                    if s.side * vn < 0.0:
                        ke = 0.5 * self.mass * vn * vn
                        self.v[i] = -s.restitution * vn
                        self.stop_dissipated_J += ke * (1.0 - s.restitution ** 2)
            self.work_J += float(np.dot(f_total, self.u - u_old))
            self._dt_prev = dt
            self.time += dt
            self.step_count += 1

    def rest(self) -> None:
        """Set the body at rest where it is (a stage of a chained run that zeroes the velocities): velocity zero
        at the present time, the next step starting as from an initial rest (central differences: its first half
        step, dt/2 of acceleration); the force held and the ledger's totals kept."""
        self.v = np.zeros(self.dim)
        self._dt_prev = 0.0
        self.a = self._acceleration()

    def recast(self, kind: type) -> "RigidBody":
        """This body stepped by ``kind`` (:class:`RigidBody` or a subclass with the same fields, e.g. the held force
        of implicit runs) from its present state: position, force, totals and clock the same, and the same velocity
        at the present time (:meth:`velocity_now`; central differences hold the last half step's, v − dt/2 a)."""
        now = self.velocity_now()
        new = kind(**{f.name: getattr(self, f.name) for f in fields(self) if f.init})
        new.load_state_dict(self.state_dict())
        new.v = now
        new.v = now - (new.velocity_now() - now)
        return new

    # ------------------------------------------------------------------ outputs
    def positions(self) -> np.ndarray:
        """Node coordinates (N, dim), m."""
        return self.nodes + self.u

    def velocity_now(self) -> np.ndarray:
        """Velocity at the current time (m/s): the last half-step velocity plus half a step of the
        current acceleration (exact for a constant force)."""
        return self.v + 0.5 * self._dt_prev * self._acceleration()

    def kinetic_energy(self) -> float:
        """J, from :meth:`velocity_now`."""
        w = self.velocity_now()
        return 0.5 * self.mass * float(np.dot(w, w))

    def history(self) -> dict[str, float]:
        """History values of each free component, named ``<body>_<quantity>_<x|y|z>_<unit>``: the position
        of the reference point (m, :attr:`reference` + translation), the translation from the start
        (``travel``, m), velocity (m/s), acceleration (m/s^2), applied force (N)."""
        out = {}
        for i, c in enumerate("xyz"[:self.dim]):
            if self._mask[i]:
                out[f"{self.name}_position_{c}_m"] = float(self.reference[i] + self.u[i])
                out[f"{self.name}_travel_{c}_m"] = float(self.u[i])
                out[f"{self.name}_velocity_{c}_m_s"] = float(self.velocity_now()[i])
                out[f"{self.name}_acceleration_{c}_m_s2"] = float(self._acceleration()[i])
                out[f"{self.name}_force_{c}_N"] = float(self.force[i])
        return out

    # ------------------------------------------------------------------ restart
    def state_dict(self) -> dict[str, np.ndarray]:
        """Everything :meth:`load_state_dict` needs to continue bit for bit."""
        return {"vectors": np.concatenate([self.u, self.v, self.a, self.force]),
                "scalars": np.array([self.time, self.step_count, self._dt_prev, self.stop_dissipated_J, self.work_J])}

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        """Restore a :meth:`state_dict`."""
        vec, sc = np.asarray(d["vectors"], float), np.asarray(d["scalars"], float)
        d = self.dim
        self.u, self.v, self.a, self.force = (vec[i * d:(i + 1) * d].copy() for i in range(4))
        self.time, self.step_count, self._dt_prev = float(sc[0]), int(sc[1]), float(sc[2])
        self.stop_dissipated_J, self.work_J = float(sc[3]), float(sc[4])
