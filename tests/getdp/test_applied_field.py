"""A uniform applied magnetic field (``AppliedField``: the reduced-field split a = a_r + a_app of the
decks) against the analytic diffusion of a suddenly applied field into a conductor.

References (Carslaw & Jaeger, *Conduction of Heat in Solids*, 2nd ed., 1959: the slab with constant
surface value, section 3.4 eq. (4) (series of cosines), and the long cylinder, section 7.4 eq. (5)
(series of J0); the magnetic field obeys the same diffusion equation dH/dt = (1 / (mu0 sigma)) lap H):

- infinitely long cylinder, radius R, axial field H0 switched on at t = 0 (axisymmetric model):
  H_z(r, t) = H0 [1 - 2 sum_n exp(-a_n^2 t / tau) J0(a_n r / R) / (a_n J1(a_n))], tau = mu0 sigma R^2,
  a_n the zeros of J0. The Joule power per unit length follows from J_phi = -dH_z/dr and the
  orthogonality of J1(a_n r / R) on [0, R] (norm R^2 J1(a_n)^2 / 2): P' = (4 pi H0^2 / sigma)
  sum_n exp(-2 a_n^2 t / tau) (its time integral is the field energy pi R^2 mu0 H0^2 / 2: checked
  below);
- slab of thickness 2 d, tangential field H0 switched on at t = 0 (planar 2D, 3D):
  H(x, t) = H0 [1 - (4 / pi) sum_n (-1)^n / (2n + 1) exp(-k_n^2 t / tau) cos(k_n x / d)],
  k_n = (2n + 1) pi / 2, tau = mu0 sigma d^2; Joule power per unit area of the half slab
  P'' = (2 H0^2 / (sigma d)) sum_n exp(-2 k_n^2 t / tau); the force per unit area on the half slab is
  the difference of the magnetic pressures, (B0^2 - B(0, t)^2) / (2 mu0), towards the mid-plane.

The models are exact for these problems (no truncation): the conductor fills the mesh; in axisymmetry
a = 0 on the axis and the natural condition (n x h_r = 0: no reaction field outside an infinite
cylinder or slab) on r = R and on the z = const lines (B normal); in planar a = 0 on the mid-line
x = 0 (B tangential) and natural elsewhere; in 3D a box [0, d] x [0, 1 mm] x [0, 1 mm] with n x a = 0
on x = 0, y = 0, y = 1 mm (physical 14: B_z tangential) and n x h = 0 on z = 0, 1 mm (15: B_z normal).
The remaining errors are the discretisation's: first order in h and dt (implicit Euler; P1 / Whitney
elements), halved by halving both (the ``slow`` tests). Measured errors are in each test's docstring.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.special import j0, j1, jn_zeros

from pulseform.solvers.getdp import (AppliedField, Coil, Conductor, CurrentTable, DampedSine, EMModel, EMState,
                                     GetDPSolver, Rect, coil_conductor_mesh)
from pulseform.solvers.getdp.applied_field import linear_potential
from pulseform.solvers.getdp.harmonic import solve_harmonic
from pulseform.solvers.getdp.mesh import AXIS, OUTER, EMMesh, conductor_tag, gmsh_session
from pulseform.solvers.getdp.mesh3d import SYM_A, SYM_H, generate_tets, read_mesh3d, skin_tag
from pulseform.solvers.getdp.persistent import PersistentGetDPSolver
from pulseform.solvers.getdp.persistent3d import PersistentEM3DStepper
from pulseform.solvers.getdp.solver3d import EM3DModel, model_numbers, solve_transient3d
from pulseform.solvers.getdp.stepper3d import EM3DStepper

from getdp_testlib import needs_getdp

MU0 = 4e-7 * np.pi
SIGMA, R, B0 = 3.5e7, 5e-3, 0.5        # S/m, m (cylinder radius, half-slab thickness), T
TAU = MU0 * SIGMA * R ** 2             # s: 1.10 ms
H0 = B0 / MU0
STEP = DampedSine(1.0, 0.0, 0.0, math.pi / 2, 0.0)   # f = 1 from t = 0 on: a suddenly applied field
A_N = jn_zeros(0, 400)
K_N = (2 * np.arange(400) + 1) * np.pi / 2


def h_cylinder(r, t):
    """H_z / H0 inside the long cylinder (the J0 series)."""
    return 1 - 2 * np.sum(np.exp(-A_N[:, None] ** 2 * t / TAU) * j0(A_N[:, None] * np.asarray(r)[None, :] / R)
                          / (A_N * j1(A_N))[:, None], axis=0)


def h_slab(x, t):
    """H / H0 inside the slab (the cosine series), x from the mid-plane."""
    n = np.arange(len(K_N))
    return 1 - (4 / np.pi) * np.sum(((-1.0) ** n / (2 * n + 1))[:, None] * np.exp(-K_N[:, None] ** 2 * t / TAU)
                                    * np.cos(K_N[:, None] * np.asarray(x)[None, :] / R), axis=0)


def p_cylinder(t):
    """Joule power per unit length of the cylinder (W/m)."""
    return 4 * np.pi * H0 ** 2 / SIGMA * np.sum(np.exp(-2 * A_N ** 2 * t / TAU))


def p_slab(t):
    """Joule power per unit area of the half slab (W/m^2)."""
    return 2 * H0 ** 2 / (SIGMA * R) * np.sum(np.exp(-2 * K_N ** 2 * t / TAU))


def strip_mesh(nx: int) -> EMMesh:
    """The strip [0, R] x [0, R / nx] (one row of 2 nx triangles), all conductor 1, a = 0 on x = 0
    (physical 11: the axis in axisymmetry, the mid-line of the slab in planar), natural elsewhere."""
    x = np.linspace(0.0, R, nx + 1)
    w = R / nx
    pts = np.vstack([np.column_stack([x, np.zeros_like(x)]), np.column_stack([x, np.full_like(x, w)])])
    i = np.arange(nx)
    b0, b1, t0, t1 = i, i + 1, i + nx + 1, i + nx + 2
    tris = np.vstack([np.column_stack([b0, b1, t1]), np.column_stack([b0, t1, t0])])
    return EMMesh(pts, tris, np.full(len(tris), conductor_tag(1)), np.array([[0, nx + 1]]), [AXIS])


def run_2d(work, axisymmetric: bool, nx: int, n_steps: int, t_end: float = 0.2 * TAU):
    mesh = strip_mesh(nx)
    solver = GetDPSolver(EMModel(axisymmetric, conductors=[Conductor(SIGMA)],
                                 applied_field=AppliedField(B0, (0.0, 1.0), STEP)), work)
    res, _ = solver.step(mesh, solver.initial_state(), t_end, n_steps, run_name=f"a{int(axisymmetric)}_{nx}_{n_steps}")
    return mesh, res


#: the times compared (in units of tau): the end and two earlier, where the field has reached the centre
T_CHECK = (0.05, 0.1, 0.2)


def errors_2d(mesh, res, axisymmetric: bool):
    """At the times ``T_CHECK``: (t / tau, max |B_z - exact| / B0 over the element centroids, relative
    Joule power error)."""
    x = mesh.centroids()[res.elements][:, 0]
    width = R / (len(res.elements) // 2)
    out = []
    for k, t in enumerate(res.times):
        if not np.any(np.isclose(t / TAU, T_CHECK, rtol=1e-9)):
            continue
        ex = h_cylinder(x, t) if axisymmetric else h_slab(x, t)
        p_ex = (p_cylinder(t) if axisymmetric else p_slab(t)) * width   # the strip: width x (1 m or 1 rad x 2 pi)
        out.append((t / TAU, np.abs(res.flux_density[k][:, 1] / B0 - ex).max(), res.conductor_power[k, 0] / p_ex - 1))
    return np.array(out)


def test_series_references_hold_the_field_energy():
    """The analytic Joule powers integrate to the field energy stored at the end (a check of the
    reference formulas themselves): pi R^2 B0^2 / (2 mu0) per unit length, d B0^2 / (2 mu0) per area."""
    q_cyl = 4 * np.pi * H0 ** 2 / SIGMA * np.sum(TAU / (2 * A_N ** 2))
    q_slab = 2 * H0 ** 2 / (SIGMA * R) * np.sum(TAU / (2 * K_N ** 2))
    assert q_cyl == pytest.approx(np.pi * R ** 2 * B0 ** 2 / (2 * MU0), rel=2e-3)
    assert q_slab == pytest.approx(R * B0 ** 2 / (2 * MU0), rel=2e-3)
    assert h_cylinder([0.0, R * 0.999999], 1e-3 * TAU)[0] == pytest.approx(0.0, abs=1e-9)
    assert h_slab([0.3 * R], 50 * TAU)[0] == pytest.approx(1.0, abs=1e-12)


@pytest.mark.getdp
@needs_getdp
@pytest.mark.parametrize("axisymmetric", [True, False], ids=["axisymmetric", "planar"])
def test_step_field_diffusion_2d(work, axisymmetric):
    """A suddenly applied B_z = 0.5 T (axisymmetric: long cylinder R = 5 mm; planar: slab 2 x 5 mm),
    sigma = 3.5e7 S/m, to t = 0.2 tau (220 us), 40 elements along the radius (h = 0.125 mm), 40 implicit
    Euler steps. Measured at 0.05 / 0.1 / 0.2 tau: axisymmetric max |B - B_exact| / B0 = 0.023 / 0.013 /
    0.0084 (centre 0.492 vs 0.499 at the end), Joule power +2.8 / +2.0 / +3.3 %; planar 0.022 / 0.013 /
    0.0069, Joule power +1.9 / +0.8 / +0.6 %; force on the half slab vs the magnetic pressure difference
    +0.05 % at 0.2 tau. 0.2 s each."""
    mesh, res = run_2d(work, axisymmetric, 40, 40)
    err = errors_2d(mesh, res, axisymmetric)
    print(f"\n(t/tau, max B error, P rel error):\n{np.round(err, 4)}")
    assert err[:, 1].max() < 0.03
    assert err[-1, 1] < 0.011
    assert np.abs(err[:, 2]).max() < (0.04 if axisymmetric else 0.022)
    assert np.all(err[:, 2] > 0)   # implicit Euler lags: the power decays late
    if not axisymmetric:   # force on the half slab (per metre): the magnetic pressure difference, towards x = 0
        width = R / 40
        b_mid = h_slab([0.0], res.times[-1])[0] * B0
        f_ex = -(B0 ** 2 - b_mid ** 2) / (2 * MU0) * width
        f = res.conductor_force[-1, 0]
        print(f"force {f[0]:.6g} N/m vs {f_ex:.6g}")
        assert f[0] == pytest.approx(f_ex, rel=0.01)
        assert abs(f[1]) < 1e-3 * abs(f_ex)   # 0.9e-4: the diagonals of the strip's triangles


@pytest.mark.getdp
@needs_getdp
@pytest.mark.slow
@pytest.mark.parametrize("axisymmetric", [True, False], ids=["axisymmetric", "planar"])
def test_step_field_diffusion_2d_first_order(work, axisymmetric):
    """Halving h and dt together halves the errors (first order): measured, axisymmetric, max B error
    at 0.2 tau 0.0084 / 0.0042 / 0.0021 and Joule power error at 0.2 tau 3.3 % / 1.7 % / 0.8 % for
    (40, 80, 160) elements and steps; planar 0.0069 / 0.0034 / 0.0017, 0.64 % / 0.32 % / 0.16 %."""
    errs = [errors_2d(*run_2d(work, axisymmetric, n, n), axisymmetric)[-1] for n in (40, 80, 160)]
    print(f"\n(t/tau, max B error, P rel error) at the end: {np.round(errs, 5)}")
    for a, b in zip(errs, errs[1:]):
        assert 1.8 < a[1] / b[1] < 2.2
        assert 1.8 < a[2] / b[2] < 2.2
    assert errs[-1][1] < 0.0025


# ------------------------------------------------------------------------------------------- 3D
def box_mesh(path: Path, h: float, d: float = R, ly: float = 1e-3, lz: float = 1e-3):
    """The box [0, d] x [0, ly] x [0, lz], all conductor 1 (its skin 401): n x a = 0 (14) on x = 0, y = 0,
    y = ly; n x h = 0 (15) on z = 0, z = lz; natural on x = d (tetrahedra of size h)."""
    with gmsh_session("box") as gmsh:
        occ = gmsh.model.occ
        v = occ.addBox(0, 0, 0, d, ly, lz)
        occ.synchronize()
        m = gmsh.model
        m.addPhysicalGroup(3, [v], conductor_tag(1))
        faces = [t for _, t in m.getBoundary([(3, v)], oriented=False)]
        m.addPhysicalGroup(2, faces, skin_tag(1))

        def at(axis, val):
            return [f for f in faces if abs(m.getBoundingBox(2, f)[axis] - val) < 1e-6
                    and abs(m.getBoundingBox(2, f)[axis + 3] - val) < 1e-6]

        m.addPhysicalGroup(2, at(0, 0.0) + at(1, 0.0) + at(1, ly), SYM_A)
        m.addPhysicalGroup(2, at(2, 0.0) + at(2, lz), SYM_H)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)
        generate_tets(gmsh, path)
    return read_mesh3d(path, 360.0, {})


def errors_3d(mesh, res):
    """At the times ``T_CHECK``: (t / tau, volume-weighted rms of B_z / B0 - exact, max |B_x, B_y| / B0, relative
    Joule power error, relative force error vs the pressure difference)."""
    x = mesh.centroids(res.elements)[:, 0]
    vol = mesh.volumes(res.elements)
    area = 1e-3 * 1e-3
    out = []
    for k, t in enumerate(res.times):
        if not np.any(np.isclose(t / TAU, T_CHECK, rtol=1e-9)):
            continue
        b = res.flux_density[k]
        rms = np.sqrt(np.sum((b[:, 2] / B0 - h_slab(x, t)) ** 2 * vol) / vol.sum())
        f_ex = -(B0 ** 2 - (h_slab([0.0], t)[0] * B0) ** 2) / (2 * MU0) * area
        out.append((t / TAU, rms, np.abs(b[:, :2]).max() / B0, res.conductor_power[k, 0] / (p_slab(t) * area) - 1,
                    res.conductor_force[k, 0, 0] / f_ex - 1))
    return np.array(out)


MODEL3D = EM3DModel(conductors=[Conductor(SIGMA)], applied_field=AppliedField(B0, (0.0, 0.0, 1.0), STEP))


@pytest.mark.getdp
@needs_getdp
@pytest.mark.parametrize("scheme", ["euler", "bdf2"])
def test_step_field_diffusion_3d_slab(tmp_path, scheme):
    """3D: the half slab as a box 5 x 1 x 1 mm (254 tetrahedra, h = 0.5 mm, Whitney elements), B_z = 0.5 T
    switched on at t = 0, 20 steps to 0.2 tau. Measured at 0.05 / 0.1 / 0.2 tau, implicit Euler: rms B_z
    error / B0 0.017 / 0.012 / 0.0075, Joule power +2.9 / +1.2 / +0.9 %, force vs the pressure difference
    -1.0 / -0.6 / -0.2 %; BDF2: rms 0.011 / 0.009 / 0.0067, Joule power -0.2 / -0.3 / -0.25 %. 0.3-0.4 s.
    (h = 0.25 mm, 1810 tetrahedra, 40 Euler steps, 5 s: rms 0.0083 / 0.0057 / 0.0037 at 0.055 / 0.105 /
    0.2 tau, power +1.6 / +0.7 / +0.56 %: first order.)"""
    mesh = box_mesh(tmp_path / "box.msh", 0.5e-3)
    res = solve_transient3d(MODEL3D, mesh, 0.2 * TAU, 20, tmp_path / "run", time_scheme=scheme)
    err = errors_3d(mesh, res)
    print(f"\n{mesh.n_tets} tets; (t/tau, rms B_z error, max |B_xy|, P rel error, F rel error):\n{np.round(err, 4)}")
    assert err[:, 1].max() < 0.018
    assert err[-1, 1] < 0.009
    assert err[:, 2].max() < 0.06      # the transverse field of the Whitney elements' jumps
    assert np.abs(err[:, 3]).max() < (0.03 if scheme == "euler" else 0.004)
    assert np.abs(err[:, 4]).max() < 0.015


@pytest.mark.getdp
@needs_getdp
def test_3d_stepper_bdf2_matches_one_run(tmp_path):
    """One getdp process per step (:class:`EM3DStepper`, BDF2 from a written x~ and the applied field's
    combination c1 f_n - c2 f_{n-1}) and the persistent 3D process (restarted mid-run from a completed
    state) equal the one-process BDF2 run, with a decaying sine field whose history matters (round-off)."""
    mesh = box_mesh(tmp_path / "box.msh", 0.5e-3)
    model = EM3DModel(conductors=[Conductor(SIGMA)],
                      applied_field=AppliedField(B0, (0.0, 0.0, -1.0), DampedSine(1.0, 2e3, 2 * np.pi * 2e3)))
    t_end, n = 0.1 * TAU, 5
    ref = solve_transient3d(model, mesh, t_end, n, tmp_path / "one", time_scheme="bdf2")
    stepper = EM3DStepper(model, tmp_path / "steps", "bdf2")
    state, power = stepper.initial_state(), []
    for k in range(1, n + 1):
        res, state = stepper.step(mesh, state, t_end * k / n)
        power.append(res.conductor_power[-1, 0])
    print(f"\nper-step {power}\none run  {ref.conductor_power[:, 0].tolist()}")
    np.testing.assert_allclose(power, ref.conductor_power[:, 0], rtol=1e-10)
    # the per-element tables written after the time loop (element_output="last") equal the loop's own
    f_ref = ref.force_density[-1]
    np.testing.assert_allclose(res.force_density[-1], f_ref, rtol=0, atol=1e-7 * np.abs(f_ref).max())
    np.testing.assert_allclose(res.joule_density[-1], ref.joule_density[-1], rtol=1e-7)
    # the persistent 3D process (the history of the applied function on GetDP's run-time variables), also
    # after a new process is seeded with two states from a completed state in mid-run
    # The persistent process's magnetic energy comes from the sources, 1/2 (j, a) over the conductor
    # (Flag_WSources, the reaction field's with an applied field): the whole-domain W of the one run.
    persistent = PersistentEM3DStepper(model, tmp_path / "persistent")
    state, power, energy = persistent.initial_state(), [], []
    try:
        for k in range(1, n + 1):
            if k == 3:
                state = persistent.complete_state(state)
                persistent.close()
                persistent = PersistentEM3DStepper(model, tmp_path / "persistent_b")
            res, state = persistent.step(mesh, state, t_end * k / n)
            power.append(res.conductor_power[-1, 0])
            energy.append(res.magnetic_energy[-1])
    finally:
        persistent.close()
    print(f"persistent {power}\nenergy: persistent (sources) {energy}, one run (whole domain) "
          f"{ref.magnetic_energy.tolist()}")
    np.testing.assert_allclose(power, ref.conductor_power[:, 0], rtol=1e-10)
    assert ref.magnetic_energy[-1] > 0
    np.testing.assert_allclose(energy, ref.magnetic_energy, rtol=1e-10)


# ------------------------------------------------------------------------------------ with coils, BDF2
@pytest.mark.getdp
@needs_getdp
def test_superposes_with_a_coil(work):
    """The problem is linear: B at probes and the coil's voltage with a coil and an applied field together
    equal the sums of the two alone (a 5-turn coil under a disk, axisymmetric, a shell; the field a
    damped sine of B0 = 0.2 T). Measured: 1e-14 of max |B|."""
    turns = [Rect(0.010 + i * 0.004, -0.003, 0.013 + i * 0.004, -0.001) for i in range(5)]
    mesh = coil_conductor_mesh([turns], [Rect(0.0, 0.0, 0.06, 0.001)], r_domain=0.15, r_shell=0.1875,
                               h_fine=4e-3, h_coarse=4e-2, h_conductor=2e-3)
    field = AppliedField(0.2, (0.0, 1.0), DampedSine(1.0, 5e3, 2e5))
    probes = [(0.03, 0.0005), (0.02, 0.005), (0.08, -0.01)]
    out = {}
    # the field alone: the same mesh and coil region, the coil at zero current (without the coil in the
    # model its region would not belong to the domain)
    for name, amp, app in (("both", 10e3, field), ("coil", 10e3, None), ("field", 0.0, field)):
        model = EMModel(True, coils=[Coil(5, waveform=DampedSine(amp, 1e4, 1e5))], conductors=[Conductor(2.5e7)],
                        shell=(0.15, 0.1875), probes=probes, applied_field=app)
        solver = GetDPSolver(model, work / name)
        res, _ = solver.step(mesh, solver.initial_state(), 20e-6, 20, element_output="none")
        out[name] = res
    b_sum = out["coil"].probe_b + out["field"].probe_b
    scale = np.abs(out["both"].probe_b).max()
    print(f"\nmax |B_both - (B_coil + B_field)| / max|B| = {np.abs(out['both'].probe_b - b_sum).max() / scale:.2e}")
    np.testing.assert_allclose(out["both"].probe_b, b_sum, rtol=0, atol=1e-9 * scale)
    v_sum = out["coil"].coil_voltage + out["field"].coil_voltage
    np.testing.assert_allclose(out["both"].coil_voltage, v_sum, rtol=0, atol=1e-9 * np.abs(v_sum).max())
    # the field alone induces a voltage in the coil (its flux through the turns)
    assert np.abs(out["field"].coil_voltage).max() > 1e-3 * np.abs(out["coil"].coil_voltage).max()


@pytest.mark.getdp
@needs_getdp
def test_persistent_bdf2_equals_per_step_with_an_applied_field(work):
    """BDF2 with an applied field: the persistent getdp (the history of the applied function on GetDP's
    run-time variables) equals the per-step path (Python's c1 f_{n-1} - c2 f_{n-2}, the Init path) on
    variable steps, also after a checkpoint through JSON seeds a new process (two-state seed);
    the waveform a table (its values are what the deck interpolates)."""
    mesh = strip_mesh(20)
    table = CurrentTable([0.0, 20e-6, 60e-6, 1e-3], [0.0, 1.0, 0.3, 0.3])
    model = EMModel(True, conductors=[Conductor(SIGMA)], applied_field=AppliedField(-B0, (0.0, 1.0), table))
    times = np.cumsum([5e-6, 5e-6, 2e-6, 9e-6, 5e-6, 12e-6, 7e-6, 20e-6])

    def march(solver, restart_at=None):
        state, p = solver.initial_state(), []
        for k, t in enumerate(times):
            if k == restart_at:
                full = solver.checkpoint_state(state)
                state = EMState.from_dict(json.loads(json.dumps(full.to_dict())))
                solver.close()
                solver = PersistentGetDPSolver(model, work / "restarted")
            res, state = solver.step(mesh, state, float(t), 1, run_name=f"s{k}")
            p.append(res.conductor_power[-1, 0])
        solver.close()
        return np.array(p), state

    ref, s_ref = march(GetDPSolver(model, work / "per_step", time_scheme="bdf2"))
    per, s_per = march(PersistentGetDPSolver(model, work / "persistent"))
    res, _ = march(PersistentGetDPSolver(model, work / "persistent_b"), restart_at=4)
    print(f"\nper step {ref}\npersistent {per}\nrestarted {res}")
    np.testing.assert_allclose(per, ref, rtol=1e-10)
    np.testing.assert_allclose(res, ref, rtol=1e-10)
    assert s_ref.applied_f == s_per.applied_f == 0.3   # the table held after 60 us
    assert ref.max() > 0


# ------------------------------------------------------------------------------------------ refusals
def test_refused_directions_and_inputs(tmp_path):
    """One clear ValueError for what the decks cannot represent."""
    mesh = strip_mesh(4)
    cond = [Conductor(SIGMA)]
    with pytest.raises(ValueError, match="axial"):        # a radial uniform field in axisymmetry
        GetDPSolver(EMModel(True, conductors=cond, applied_field=AppliedField(1.0, (1.0, 0.0), STEP)),
                    tmp_path)._numbers(mesh)
    with pytest.raises(ValueError, match="crosses the a = 0"):   # planar B_x across the a = 0 line x = 0
        GetDPSolver(EMModel(False, conductors=cond, applied_field=AppliedField(1.0, (1.0, 0.2), STEP)),
                    tmp_path)._numbers(mesh)
    nb = GetDPSolver(EMModel(False, conductors=cond, applied_field=AppliedField(2.0, (0.0, -1.0), STEP)),
                     tmp_path)._numbers(mesh)
    assert (nb["Field_Bx"], nb["Field_By"], nb["Field_Mx"], nb["Field_My"], nb["Field_C"]) == (0.0, -2.0, 2.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="two ways"):
        EMModel(False, conductors=cond, h0_step=1e5, applied_field=AppliedField(1.0, (0.0, 1.0), STEP))
    with pytest.raises(ValueError, match="3D model needs 3"):
        EM3DModel(conductors=cond, applied_field=AppliedField(1.0, (0.0, 1.0), STEP))
    with pytest.raises(ValueError, match="not all zero"):
        AppliedField(1.0, (0.0, 0.0, 0.0), STEP)
    with pytest.raises(ValueError, match="finite"):
        AppliedField(float("nan"), (0.0, 0.0, 1.0), STEP)
    with pytest.raises(ValueError, match="time-harmonic"):
        solve_harmonic(EMModel(False, conductors=cond, applied_field=AppliedField(1.0, (0.0, 1.0), STEP)), mesh,
                       1e3, [], tmp_path)
    with pytest.raises(ValueError, match="TimeTheta"):
        GetDPSolver(EMModel(False, conductors=cond, applied_field=AppliedField(1.0, (0.0, 1.0), STEP)), tmp_path,
                    extra_numbers={"TimeTheta": 0.5})._numbers(mesh)


def test_refused_3d_directions(tmp_path):
    """3D: B across an n x a = 0 plane (14) or along an n x h = 0 plane (15) is refused; B_z on the box
    gets the potential B_z x e_y (n x a_app = 0 on x = 0, y = 0 and y = 1 mm)."""
    mesh = box_mesh(tmp_path / "box.msh", 0.5e-3)
    for d, what in (((1.0, 0.0, 0.0), "crosses a symmetry plane"), ((0.0, 1.0, 0.0), "crosses a symmetry plane"),
                    ((0.6, 0.0, 0.8), "crosses a symmetry plane")):
        model = EM3DModel(conductors=[Conductor(SIGMA)], applied_field=AppliedField(1.0, d, STEP))
        with pytest.raises(ValueError, match=what):
            model_numbers(model, mesh)
    nb, _ = model_numbers(EM3DModel(conductors=[Conductor(SIGMA)], applied_field=AppliedField(2.0, (0, 0, 1), STEP)),
                          mesh)
    m = np.array([[nb[f"Field_M{i}{j}"] for j in (1, 2, 3)] for i in (1, 2, 3)])
    np.testing.assert_allclose(m, [[0, 0, 0], [2.0, 0, 0], [0, 0, 0]], atol=1e-12)
    np.testing.assert_allclose([nb["Field_c1"], nb["Field_c2"], nb["Field_c3"]], 0.0, atol=1e-12 * 2.0 * 5e-3)
    # a plane n x h = 0 needs B normal: B_z with the plane x = 0 of type 15
    planes_h = [(np.array([1.0, 0.0, 0.0]), 0.0)]
    with pytest.raises(ValueError, match="not normal"):
        AppliedField(1.0, (0, 0, 1), STEP).numbers_3d([], planes_h)
    # B_z with the four n x a = 0 planes x = 0, 1 and y = 0, 1 (a square duct): no linear potential has
    # n x a = 0 on all four; B_y with x = 0, 1 has one, a = B_y z e_x
    sq = [(np.array([1.0, 0, 0]), 0.0), (np.array([1.0, 0, 0]), 1.0), (np.array([0, 1.0, 0]), 0.0),
          (np.array([0, 1.0, 0]), 1.0)]
    with pytest.raises(ValueError, match="do not fit"):
        linear_potential(np.array([0.0, 0.0, 1.0]), sq)
    m, c = linear_potential(np.array([0.0, 1.0, 0.0]), sq[:2])
    np.testing.assert_allclose(m, [[0, 0, 1.0], [0, 0, 0], [0, 0, 0]], atol=1e-12)   # a = B_y z e_x
