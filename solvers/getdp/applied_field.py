"""A uniform applied magnetic field as a source of the GetDP decks (2D and 3D).

:class:`AppliedField` describes B_app(t) = B0 d f(t): a magnitude ``B0`` (T), a direction ``d``
(normalised here) and a time function f(t) given like a coil's current waveform (a
:class:`~.model.DampedSine` -- constant, exponential decay, sine, damped sine -- or a
:class:`~.model.CurrentTable`, read as dimensionless multipliers of B0).

Formulation: the reduced-field split a = a_r + a_app. The applied potential a_app is known in closed
form (linear in the position: a_app = M (r - r0) with curl a_app = B_app / f); the unknown of the decks
is the reaction field a_r, the field of the coils and of the eddy currents. Why this split rather than
imposing the applied field on the boundary:

- a uniform field does not decay at infinity: n x a = n x a_app on the outer boundary would be wrong with
  the shell transformation to infinity (region 2), whose outer surface stands for infinity; the
  reaction field does vanish there, so the decks' a_r = 0 on the far boundary and the shell act on a_r
  only and stay right;
- the tangential-H Neumann term needs a boundary where the total field is known, which a problem with
  coils or several conductors does not have;
- with a uniform reluctivity (every region of the decks is non-magnetic) curl nu curl a_app = 0, so the
  applied field enters only in the conductors, as the source sigma Dt[a_app] of the eddy currents.

Dt[a_app] is the decks' discrete difference over the step (implicit Euler: f(t_n) - f(t_{n-1}); BDF2:
f(t_n) - (c1 f_{n-1} - c2 f_{n-2})), so that the split is the same scheme as a total-field run: a step of
the applied field switches on within one time step exactly as a step of a coil current does. A run
starts from rest (no field at all): the start state's value of f is 0, not f(t0) -- a field switched on
at t_on = 0 (a ``DampedSine`` with omega = 0, phase = pi/2) is a suddenly applied field.

Symmetry planes and boundaries (checked here, refused with a ``ValueError``):

- 2D axisymmetric: only an axial field (direction (0, +-1), B_z); a_app = B_z r / 2 (r a_phi = B_z r^2 / 2)
  vanishes on the axis by itself.
- 2D planar: any in-plane direction; a_app = B_x (y - y0) - B_y (x - x0). Lines with a = 0 that are not
  the far boundary (physical 11, "axis": a symmetry line with B tangential) must be tangential to B and
  collinear, r0 is put on them.
- 3D: any direction. A symmetry plane with n x a = 0 (physical 14) needs B tangential to it (B . n = 0),
  a plane with n x h = 0 (physical 15) B normal to it (B x n = 0); the gauge M, r0 is solved so that
  n x a_app = 0 on every n x a = 0 plane (e.g. B_z with the planes x = 0, y = 0 and y = L:
  a_app = B_z x e_y), and refused when no linear potential does it.
- The far boundary (physical 12; in 2D also any untagged boundary, where the reaction field's n x h_r
  = 0 is the natural condition) truncates the reaction field only: any direction.

Not modelled: the motional EMF v x B_app of a conductor moving across the applied field. The decks
evaluate a_app at the nodes' current positions and carry a_r with the material, which drops the
term f (a_app(x_n) - a_app(x_{n-1})); exact for conductors at rest and for motions along which a_app
does not change (an axisymmetric blank moving along z in an axial field), an error of order
v B_app otherwise.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .model import CurrentTable, DampedSine

logger = logging.getLogger(__name__)

#: physical ids whose conditions constrain the applied field (as :mod:`.mesh` / :mod:`.mesh3d` define them)
_AXIS_2D, _NEUMANN_2D, _SYM_A_3D, _SYM_H_3D = 11, 13, 14, 15


@dataclass
class AppliedField:
    """A uniform applied field B_app(t) = ``B0`` * d * f(t) (T), d = ``direction`` / |direction|.

    ``direction``: 2 components (x, y) in 2D -- in axisymmetry (r, z): only (0, +-1) --, 3 in 3D (x, y, z).
    ``waveform``: f(t), dimensionless, as a coil's waveform: a :class:`~.model.DampedSine` (its ``I0`` a
    factor of B0; a step switched on at t_on is ``DampedSine(1, 0, 0, pi/2, t_on)``, an exponential decay
    ``omega = 0, phase = pi/2, beta > 0``) or a :class:`~.model.CurrentTable` (values held after its last
    time). ``B0`` may be negative (the field along -d).
    """

    B0: float
    direction: Sequence[float]
    waveform: DampedSine | CurrentTable

    def __post_init__(self) -> None:
        if isinstance(self.waveform, dict):
            self.waveform = (CurrentTable if "times" in self.waveform else DampedSine)(**self.waveform)
        if not isinstance(self.waveform, (DampedSine, CurrentTable)):
            raise ValueError(f"applied field waveform: a DampedSine or a CurrentTable, got {self.waveform!r}")
        self.B0 = float(self.B0)
        d = np.asarray(self.direction, float).ravel()
        if not math.isfinite(self.B0):
            raise ValueError(f"applied field B0 must be finite (T), got {self.B0!r}")
        if d.size not in (2, 3) or not np.all(np.isfinite(d)) or not np.linalg.norm(d) > 0:
            raise ValueError(f"applied field direction: 2 (2D) or 3 (3D) finite components, not all zero; got "
                             f"{list(self.direction)!r}")
        self.direction = tuple(float(x) for x in d)

    # -- values
    @property
    def amplitude(self) -> float:
        """The factor of the deck's unit time function: ``I0`` of a damped sine, 1 for a table."""
        return float(self.waveform.I0) if isinstance(self.waveform, DampedSine) else 1.0

    def unit_vector(self, dim: int) -> np.ndarray:
        """d as ``dim`` components (a 2D direction is refused in 3D and vice versa)."""
        d = np.asarray(self.direction, float)
        if d.size != dim:
            raise ValueError(f"applied field direction has {d.size} components; a {dim}D model needs {dim}")
        return d / np.linalg.norm(d)

    def b_vector(self, dim: int) -> np.ndarray:
        """B_app / f_unit (T): B0 * amplitude * d, the field when the deck's unit time function is 1."""
        return self.B0 * self.amplitude * self.unit_vector(dim)

    def unit_f(self, t) -> np.ndarray | float:
        """The deck's time function Field_F(t) (dimensionless): f(t) / amplitude."""
        w = self.waveform
        if isinstance(w, DampedSine):
            return DampedSine(1.0, w.beta, w.omega, w.phase, w.t_on)(t)
        return w(t)

    def __call__(self, t) -> np.ndarray:
        """B_app(t) (T) at times ``t`` (s): shape (..., dim)."""
        d = np.asarray(self.direction, float)
        return self.B0 * np.asarray(self.waveform(t), float)[..., None] * (d / np.linalg.norm(d))

    # -- deck inputs
    def time_numbers(self) -> dict[str, float]:
        """The deck's ``Field_Wave``, ``Field_beta``, ... of the time function (2D and 3D decks alike)."""
        w = self.waveform
        if isinstance(w, DampedSine):
            return {"Field_Wave": 0, "Field_beta": w.beta, "Field_omega": w.omega, "Field_phase": w.phase, "Field_ton": w.t_on}
        return {"Field_Wave": 1}

    def table_lines(self) -> list[str]:
        """``Field_Table() = {...};`` for a table waveform (the last value held: one more point far after)."""
        w = self.waveform
        if not isinstance(w, CurrentTable):
            return []
        times = list(w.times) + [w.times[-1] + 1e3]
        values = list(w.values) + [w.values[-1]]
        pairs = [f"{t:.17g}, {v:.17g}" for t, v in zip(times, values)]
        body = ",\n  ".join(", ".join(pairs[j:j + 8]) for j in range(0, len(pairs), 8))
        return [f"Field_Table() = {{\n  {body}}};"]

    def numbers_2d(self, axisymmetric: bool, points: np.ndarray, lines: np.ndarray, line_tags: np.ndarray,
                   h0_step: float = 0.0) -> dict[str, float]:
        """The 2D deck's ``-setnumber`` inputs (without ``Field_F1``/``Field_F2``, the state's) on a mesh.

        Raises ``ValueError`` for a radial field in axisymmetry, a field crossing an a = 0 symmetry line
        (physical 11) in planar, and beside the imposed tangential field ``h0_step``.
        """
        if h0_step:
            raise ValueError("an applied field and the imposed tangential field h0_step (boundary 13) are two ways to "
                             "impose an external field: give one")
        b = self.b_vector(2)
        scale = max(abs(self.B0 * self.amplitude), 1e-300)
        if axisymmetric:
            if abs(b[0]) > 1e-12 * scale:
                raise ValueError(f"axisymmetric model: a uniform applied field is axial, direction (0, 1) or (0, -1) "
                                 f"(r, z); got {list(self.direction)!r}")
            b = np.array([0.0, b[1]])
            mx, my, c = -0.5 * b[1], 0.0, 0.0   # GetDP frame: b_y = -(1/r) d(r a_z)/dr
        else:
            mx, my = -b[1], b[0]                # b = (d a_z / dy, -d a_z / dx)
            c = 0.0
            nodes = np.unique(np.asarray(lines)[np.asarray(line_tags) == _AXIS_2D])
            if nodes.size:
                p = np.asarray(points, float)[nodes, :2]
                length = max(float(np.ptp(p, axis=0).max()), 1e-300)
                c = -float(np.mean(p @ [mx, my]))
                resid = np.abs(p @ [mx, my] + c).max()
                if resid > 1e-9 * scale * length:
                    raise ValueError(f"planar applied field along {list(self.direction)!r} crosses the a = 0 "
                                     f"symmetry line(s) (physical {_AXIS_2D}): B must be tangential to them "
                                     f"(and they collinear); use a natural boundary (B normal) there instead")
        out = {"Flag_AppField": 1, "Field_Bx": float(b[0]), "Field_By": float(b[1]), "Field_Mx": mx, "Field_My": my,
               "Field_C": c}
        out.update(self.time_numbers())
        return out

    def numbers_3d(self, planes_a: Sequence[tuple[np.ndarray, float]],
                   planes_h: Sequence[tuple[np.ndarray, float]]) -> dict[str, float]:
        """The 3D deck's inputs for the symmetry planes ``planes_a`` (n x a = 0, physical 14) and
        ``planes_h`` (n x h = 0, physical 15), each (unit normal n, offset n . p) (m).

        The potential a_app = M r + c (T, T m per unit time function) solves, in the least-squares sense
        (minimum norm), curl a_app = B_app / f and n x a_app = 0 on every n x a = 0 plane; raises
        ``ValueError`` when B is not tangential to an n x a = 0 plane or not normal to an n x h = 0 plane,
        or when no linear potential has n x a_app = 0 on all the n x a = 0 planes."""
        b = self.b_vector(3)
        scale = max(abs(self.B0 * self.amplitude), 1e-300)
        for n, _ in planes_a:
            if abs(float(np.dot(n, b))) > 1e-9 * scale:
                raise ValueError(f"applied field along {list(self.direction)!r} crosses a symmetry plane with "
                                 f"n x a = 0 (physical {_SYM_A_3D}, normal {np.round(n, 6).tolist()}): B must be "
                                 "tangential to it")
        for n, _ in planes_h:
            if np.linalg.norm(np.cross(n, b)) > 1e-9 * scale:
                raise ValueError(f"applied field along {list(self.direction)!r} is not normal to a symmetry plane "
                                 f"with n x h = 0 (physical {_SYM_H_3D}, normal {np.round(n, 6).tolist()}): B must "
                                 "be normal to it")
        m, c = linear_potential(b, planes_a)
        logger.debug("applied field B = %s T: a_app = M r + c, M = %s, c = %s (%d n x a = 0 planes, %d n x h = 0)",
                     b.tolist(), m.round(12).tolist(), c.round(15).tolist(), len(planes_a), len(planes_h))
        out: dict[str, float] = {"Flag_AppField": 1, "Field_Bx": float(b[0]), "Field_By": float(b[1]),
                                 "Field_Bz": float(b[2])}
        for i in range(3):
            for j in range(3):
                out[f"Field_M{i + 1}{j + 1}"] = float(m[i, j])
            out[f"Field_c{i + 1}"] = float(c[i])
        out.update(self.time_numbers())
        return out


def applied_start(f_now: float, f_prev: float, t: float, dt_prev: float | None, t_end: float,
                  bdf2_restart: bool) -> float:
    """The applied field's unit time function of a run's start state (the step t -> ``t_end``, s): ``f_now``
    (implicit Euler, or a BDF2 step from fields at rest), or with a BDF2 restart the combination
    c1 f_{n-1} - c2 f_{n-2} that the restarted x~ is of the unknowns (``dt_prev`` the last step, s)."""
    if not bdf2_restart:
        return float(f_now)
    from .bdf2 import bdf2_coefficients

    _, c1, c2 = bdf2_coefficients(t_end - t, dt_prev)
    return float(c1 * f_now - c2 * f_prev)


def _cross_matrix(n: np.ndarray) -> np.ndarray:
    """[n]x: the matrix of v -> n x v."""
    return np.array([[0.0, -n[2], n[1]], [n[2], 0.0, -n[0]], [-n[1], n[0], 0.0]])


def linear_potential(b: np.ndarray, planes: Sequence[tuple[np.ndarray, float]]) -> tuple[np.ndarray, np.ndarray]:
    """(M, c) of a = M r + c with curl a = ``b`` (uniform) and n x a = 0 on every plane (n, d) of ``planes``
    (points r with n . r = d): the minimum-norm least-squares solution of these linear equations in the
    12 unknowns; raises ``ValueError`` when it leaves a residual (no such linear potential)."""
    rows: list[np.ndarray] = []
    rhs: list[float] = []
    # curl (M r) = (M32 - M23, M13 - M31, M21 - M12); unknowns x = (M.ravel() row-major, c)
    for (i, j), (k, l), comp in (((2, 1), (1, 2), 0), ((0, 2), (2, 0), 1), ((1, 0), (0, 1), 2)):
        r = np.zeros(12)
        r[3 * i + j], r[3 * k + l] = 1.0, -1.0
        rows.append(r)
        rhs.append(float(b[comp]))
    for n, d in planes:
        n = np.asarray(n, float) / np.linalg.norm(n)
        p0 = n * d   # a point of the plane
        cx = _cross_matrix(n)
        t1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)
        for v, with_c in ((p0, True), (t1, False), (t2, False)):
            # n x (M v + c) = 0: rows of [n]x applied to (M v) (+ c)
            for a in range(3):
                r = np.zeros(12)
                for i in range(3):
                    r[3 * i:3 * i + 3] += cx[a, i] * v
                    if with_c:
                        r[9 + i] += cx[a, i]
                rows.append(r)
                rhs.append(0.0)
    A, y = np.array(rows), np.array(rhs)
    x, *_ = np.linalg.lstsq(A, y, rcond=None)
    scale = max(float(np.linalg.norm(b)), 1e-300)
    if np.abs(A @ x - y).max() > 1e-9 * scale * max(1.0, max((abs(d) for _, d in planes), default=1.0)):
        raise ValueError("no uniform-field potential a = M r + c has n x a = 0 on all the symmetry planes with "
                         f"n x a = 0 (physical {_SYM_A_3D}) for B along {np.round(b / scale, 6).tolist()}: "
                         "the planes do not fit that direction")
    return x[:9].reshape(3, 3), x[9:]


def planes_of_faces(points: np.ndarray, faces: np.ndarray, tol: float = 1e-9) -> list[tuple[np.ndarray, float]]:
    """The distinct planes (unit normal n, offset n . p; m) of triangles ``faces`` (rows of node indices
    into ``points``), merging coplanar triangles (normals to ``tol``, offsets to ``tol`` times the size).
    Raises ``ValueError`` for a non-planar group of faces (it must be made of planes)."""
    p = np.asarray(points, float)[np.asarray(faces, np.int64)]
    if len(p) == 0:
        return []
    nrm = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    # orient: first non-zero component positive
    k = np.argmax(np.abs(nrm) > 1e-6, axis=1)
    nrm *= np.sign(nrm[np.arange(len(nrm)), k])[:, None]
    off = np.einsum("ij,ij->i", nrm, p[:, 0])
    size = max(float(np.ptp(p.reshape(-1, 3), axis=0).max()), 1e-300)
    planes: list[tuple[np.ndarray, float]] = []
    for n, d in zip(nrm, off):
        if not any(np.abs(n - m).max() < 1e-6 and abs(d - e) < 1e-6 * size for m, e in planes):
            planes.append((n, float(d)))
    if len(planes) > 64:
        raise ValueError(f"symmetry faces make {len(planes)} planes: not a set of planes")
    return planes


__all__ = ["AppliedField", "linear_potential", "planes_of_faces"]
