"""The cantilever strip of issue 34 item 4 (bending that does not lock), shared by its tests and
``bench/cantilever_locking.py``: a strip of length L, width b and thickness t (x, y, z), built in at x = 0 and
loaded by a transverse tip force P (-z), on a box mesh of ``create_box`` bricks (six tetrahedra each) with a
chosen number of elements through the thickness.

Half the width is modelled (the plane y = 0 is a symmetry plane: u_y = 0 there). The root is beam theory's
built-in end: the root face x = 0 holds u_x = 0 (its plane section stays plane and upright) and the root
nodes on the symmetry plane nearest the mid-thickness hold u_z = 0 (the node at z = t / 2 of a ten-node body
of an odd number of layers; the two beside it of a linear one); nothing else, so that the root contracts
sideways and through the thickness and curls sideways (anticlastic curvature) as the rest of the strip does.
A root held in z along a line across the width, or over its face, keeps the anticlastic or the through-thickness
strain there at zero: plane strain, which raises the plastic moment there by up to 2 / sqrt(3) and moves the
hinge off the root (measured: the tip deflection of three layers does not run away at 1.07 M_p / L). The tip force is spread over the tip face by tributary area; the tip deflection
is the area-weighted mean of -u_z over that face.

Beam theory (Euler-Bernoulli, with Timoshenko's shear term; Cowper's shear coefficient of a rectangle
kappa = 10 (1 + nu) / (12 + 11 nu)): delta = P L^3 / (3 E I) + P L / (kappa G b t), I = b t^3 / 12. The
plastic hinge of an elastic-perfectly plastic strip forms at the root when P L = M_p = sigma_y b t^2 / 4.
"""
from __future__ import annotations

from dataclasses import dataclass

import logging
import math

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI
from scipy.integrate import quad

from pulseform.solvers.dolfinx.body import BodySpec
from pulseform.solvers.dolfinx.material import Material
from pulseform.solvers.dolfinx.tet10_kernel import tet10_cell_steps

__all__ = ["Strip", "strip_body", "tip_load", "tip_deflection", "beam_deflection", "hinge_load",
           "beam_plastic_deflection", "plane_strip_body", "relax_to_rest", "relaxed_levels", "runaway",
           "regular_step"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Strip:
    """The strip's dimensions (m) and mesh: ``n_length`` x ``n_width`` (of the half width) x ``n_thick``
    bricks; ``grading`` p > 1 crowds the bricks towards the root (x = L s^p, s uniform in [0, 1]), where a
    plastic hinge concentrates the curvature."""

    length: float = 0.04
    width: float = 0.005
    thickness: float = 0.001
    n_length: int = 40
    n_width: int = 2
    n_thick: int = 3
    grading: float = 1.0


def strip_body(strip: Strip, material: Material, element: str = "tet4", name: str = "strip") -> BodySpec:
    """The strip's body: half the width on a box mesh (one process), the root and symmetry supports."""
    msh = dmesh.create_box(MPI.COMM_SELF, [np.zeros(3), np.array([strip.length, 0.5 * strip.width,
                                                                   strip.thickness])],
                           [strip.n_length, strip.n_width, strip.n_thick])
    if strip.grading != 1.0:
        gx = msh.geometry.x
        gx[:, 0] = strip.length * (gx[:, 0] / strip.length) ** strip.grading
    tol = 1e-9 * strip.length

    def root(x):
        return np.abs(x[0]) < tol

    def root_axis(x):
        line = root(x) & (np.abs(x[1]) < tol)
        dz = np.abs(x[2] - 0.5 * strip.thickness)
        return line & (dz <= dz[line].min() + tol)

    fixed = ((root, (0,)), (root_axis, (2,)), (lambda x: np.abs(x[1]) < tol, (1,)))
    return BodySpec(name, msh, material, initial_velocity=(0.0, 0.0, 0.0), fixed=fixed, element=element)


def plane_strip_body(strip: Strip, material: Material, element: str = "tet4", name: str = "strip") -> BodySpec:
    """The strip's 2D body (plane stress; ``element`` "tet4" linear or "tri6" six-node triangles): a rectangle
    L x t of n_length x n_thick squares cut in two (one process), the root supports."""
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.zeros(2), np.array([strip.length, strip.thickness])],
                                 [strip.n_length, strip.n_thick])
    if strip.grading != 1.0:
        gx = msh.geometry.x
        gx[:, 0] = strip.length * (gx[:, 0] / strip.length) ** strip.grading
    tol = 1e-9 * strip.length

    def root(x):
        return np.abs(x[0]) < tol

    def root_axis(x):
        dy = np.abs(x[1] - 0.5 * strip.thickness)
        return root(x) & (dy <= dy[root(x)].min() + tol)

    return BodySpec(name, msh, material, fixed=((root, (0,)), (root_axis, (1,))), element=element)


def _tip_weights(body, strip: Strip) -> np.ndarray:
    """Tributary area (m^2) of every node on the tip face x = L (zero elsewhere)."""
    tol = 1e-9 * strip.length
    segs = body.segments[np.all(np.abs(body.X0[body.segments][:, :, 0] - strip.length) < tol, axis=1)]
    return body.tributary_areas(segs, body.X0)


def tip_load(body, strip: Strip, force: float) -> np.ndarray:
    """Nodal forces (N, 3), N, of a tip force ``force`` (N, on the whole width; -z) on the half strip (2D: (N, 2),
    along -y)."""
    w = _tip_weights(body, strip)
    f = np.zeros_like(body.x)
    if body.gdim == 2:                      # the whole width: the solver's thickness
        f[:, 1] = -force * w / w.sum()
    else:
        f[:, 2] = -0.5 * force * w / w.sum()
    return f


def tip_deflection(body, strip: Strip) -> float:
    """The tip's deflection (m, positive down): the area-weighted mean of -u_z (2D: -u_y) over the tip face."""
    w = _tip_weights(body, strip)
    k = body.gdim - 1
    return float(-np.dot(w, body.x[:, k] - body.X0[:, k]) / w.sum())


def beam_deflection(strip: Strip, material: Material, force: float, shear: bool = True) -> float:
    """Beam theory's tip deflection (m) of the strip under a tip force ``force`` (N): Euler-Bernoulli
    P L^3 / (3 E I), plus Timoshenko's P L / (kappa G A) with Cowper's kappa when ``shear``."""
    G, K = material.shear_modulus, material.bulk_modulus
    E = 9.0 * K * G / (3.0 * K + G)
    nu = (3.0 * K - 2.0 * G) / (2.0 * (3.0 * K + G))
    L, b, t = strip.length, strip.width, strip.thickness
    d = force * L ** 3 / (3.0 * E * b * t ** 3 / 12.0)
    if shear:
        d += force * L / (10.0 * (1.0 + nu) / (12.0 + 11.0 * nu) * G * b * t)
    return d


def hinge_load(strip: Strip, material: Material) -> float:
    """The tip force (N) of the plastic hinge at the root of an elastic-perfectly plastic strip,
    M_p / L = sigma_y b t^2 / (4 L)."""
    return material.yield_stress * strip.width * strip.thickness ** 2 / (4.0 * strip.length)


def beam_plastic_deflection(strip: Strip, material: Material, force: float) -> float:
    """Beam theory's tip deflection (m, Euler-Bernoulli, small deflections) of the elastic-perfectly plastic
    strip under a tip force ``force`` < M_p / L (N): the rectangle's moment-curvature law, kappa = M / E I up to
    M_y = sigma_y b t^2 / 6 and kappa_y / sqrt(3 - 2 M / M_y) beyond, integrated as delta = int kappa (L - x) dx.
    The deflection at the hinge load is finite (40/27 of the elastic one there); the compliance d delta / dP grows
    without bound as the load approaches it."""
    L = strip.length
    EI = L ** 3 / (3.0 * beam_deflection(strip, material, 1.0, shear=False))
    My = material.yield_stress * strip.width * strip.thickness ** 2 / 6.0
    P = float(force)
    if P * L >= 1.5 * My:
        raise ValueError(f"tip force {P} N is not below the hinge load {1.5 * My / L} N")

    def kappa(x: float) -> float:
        M = P * (L - x)
        return M / EI if M <= My else My / EI / math.sqrt(3.0 - 2.0 * M / My)

    pts = [L * (1.0 - My / (P * L))] if P * L > My else None
    return quad(lambda x: kappa(x) * (L - x), 0.0, L, points=pts, limit=200)[0]


def relax_to_rest(solver, strip: Strip, force: float, reference: float, rounds: int,
                  residual: float | None = None) -> float:
    """The tip deflection (m) of ``solver``'s strip under the tip ``force`` (N), relaxed to rest by the explicit
    solver's kinetic damping: up to ``rounds`` rounds of 500 stable steps, until a round changes the deflection by
    less than 1e-5 of ``reference`` (m) and the kinetic energy is below 1e-9 J (dynamic relaxation); with
    ``residual``, also until the out-of-balance force (m a on the free components, N) is below ``residual`` times
    the tip force in norm: a strip that kinetic damping has just stopped off its equilibrium starts from rest, and
    its first round can change the deflection by less than the tolerance."""
    solver.kinetic_damping = True
    b = solver.bodies["strip"]
    f = {"strip": tip_load(b, strip, force)}
    prev = math.inf
    for _ in range(rounds):
        solver.advance(solver.stable_time_step(), 500, f)
        d = tip_deflection(b, strip)
        if (abs(d - prev) < 1e-5 * reference and solver.energies()["kinetic_J"] < 1e-9
                and (residual is None or np.linalg.norm(b.mass[:, None] * b.a)
                     < residual * np.linalg.norm(f["strip"]))):
            break
        prev = d
    log.info("tip force %.6g N: tip deflection %.6g m at rest, %d steps so far", force, d, solver.step_count)
    return d


def relaxed_levels(solver, strip: Strip, force: float, fractions, reference: float, rounds: int,
                   ratio: float = 10.0, approach=(0.6, 0.8, 0.9), residual: float = 1e-3) -> list:
    """The tip deflections (in units of ``reference``, m) of ``solver``'s strip under the tip forces
    ``fractions`` x ``force`` (N) in order, each relaxed to rest (:func:`relax_to_rest` with ``residual``, at most
    ``rounds`` rounds) from the previous level's state, up to the first level whose compliance (the difference
    quotient over the fractions) reaches ``ratio``: the levels after it do not change :func:`runaway`. The strip
    comes to the first level through the ``approach`` fractions (relaxed, not returned): a level applied at once
    overshoots by part of its increment before kinetic damping stops it, plastically near the hinge (the 20 mm
    strip jumped to 0.97 M_p / L ends 4.6 % beyond the static deflection, through 0.6, 0.8 and 0.9 within 0.1 %)."""
    for f in approach:
        relax_to_rest(solver, strip, f * force, reference, rounds, residual)
    d = []
    for f in fractions:
        d.append(relax_to_rest(solver, strip, f * force, reference, rounds, residual) / reference)
        if len(d) > 1 and (d[-1] - d[-2]) / (f - fractions[len(d) - 2]) >= ratio:
            break
    return d


def regular_step(solver, strip: Strip) -> float:
    """The critical step (CFL 1, at rest, s) of the regular bricks of ``solver``'s ten-node strip: the smallest of
    its cells whose centroid is in the outer half (x > L / 2), away from the root bricks that grading thins
    (selective mass scaling's target, ``ExplicitSolver3D(mass_scaling_dt=)``)."""
    b = solver.bodies["strip"]
    dts = np.empty(len(b.cells))
    tet10_cell_steps(b.cells, b.X0, solver._prm["strip"], solver._kernels["strip"].factor, np.empty(0), dts)
    return float(dts[b.X0[b.cells[:, :4], 0].mean(axis=1) > 0.5 * strip.length].min())


def static_levels(solver, strip: Strip, forces) -> list:
    """The tip deflections (m) of ``solver``'s strip (a static implicit solver) after one static step to each tip
    force of ``forces`` (N), in order, each from the previous one's equilibrium."""
    b = solver.bodies["strip"]
    out = []
    for P in forces:
        solver.advance(1.0, 1, {"strip": tip_load(b, strip, P)})
        out.append(tip_deflection(b, strip))
    return out


def beam_runaway(strip: Strip, material: Material) -> float:
    """Beam theory's runaway load (a fraction of :func:`hinge_load`): :func:`runaway` of the rectangle's
    moment-curvature deflection (:func:`beam_plastic_deflection`, in units of the elastic deflection at the hinge
    load) on load steps of 0.0005 from 0.97 (0.9915 for the strips of the tests)."""
    Pp = hinge_load(strip, material)
    d_el = beam_deflection(strip, material, Pp, shear=False)
    fb = np.round(np.arange(0.97, 0.9976, 0.0005), 5)
    return runaway(fb, [beam_plastic_deflection(strip, material, f * Pp) / d_el for f in fb])


def runaway(fractions, deflections, ratio: float = 10.0) -> float:
    """The load fraction at which the compliance (difference quotients of ``deflections`` over ``fractions``, in the
    units of their ratio) first reaches ``ratio``, interpolated linearly between interval midpoints."""
    f = np.asarray(fractions, float)
    q = np.diff(np.asarray(deflections, float)) / np.diff(f)
    mid = 0.5 * (f[1:] + f[:-1])
    k = int(np.flatnonzero(q >= ratio)[0])
    assert k > 0, "the compliance is already past the ratio at the first load step"
    return mid[k - 1] + (ratio - q[k - 1]) / (q[k] - q[k - 1]) * (mid[k] - mid[k - 1])
