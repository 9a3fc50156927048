"""Flow curves (:mod:`pulseform.solvers.dolfinx.flow_curves`) and the temperature per cell, issue 33.

* Each law: one element in uniaxial tension at a constant strain rate (2D: an axisymmetric ring
  triangle, 3D: a tetrahedron) follows the law's curve: after every plastic step its von Mises stress
  equals the law's sigma_y(eps_p, eps_rate, T) written out again here from its textbook formula, to
  1e-6 (the return is converged to round-off: the figure is ~1e-15). The lateral strain rate is
  solved at every step so that the lateral stresses vanish (uniaxial stress), so the strain rate
  the kernel sees is the prescribed one.
* The table law with the linear law's points equals the linear law (a plastic impact).
* Adiabatic heating: the temperature rise of an element driven to eps_p equals
  beta int sigma d eps_p / (rho c_p) (the integral analytic for Swift) within 0.1 %; with the
  Johnson-Cook softening the coupled rise matches an ODE solution of dT/d eps_p = beta sigma(eps_p, T)
  / (rho c_p) (scipy's solve_ivp to 1e-10) within 0.1 %.
* The vectorised kernels' screen (general materials) gives what the scalar path gives.
"""
import math

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import (BodySpec, ExplicitSolver, ExplicitSolver3D, JohnsonCookFlow,
                                       Ludwik, Material, RigidWallSpec, Swift, TabulatedFlow, Voce)
from pulseform.solvers.dolfinx.kernels import (MODE_AXISYMMETRIC, MODE_PLANE_STRAIN, MODE_PLANE_STRESS,
                                               WORK_SIZE, element_step, pack_parameters)
from pulseform.solvers.dolfinx.tet_kernel import MODE_SOLID, tet_step

RHO, G, K = 2700.0, 26e9, 68e9
CP = 896.0       # J/(kg K), AA6061 (ASM handbook)
RATE = 1e3       # 1/s

# Johnson-Cook AA6061-T6 (Lesuer, LLNL UCRL-ID-138010 (2000)): A 324 MPa, B 114 MPa, n 0.42, C 0.002,
# m 1.34, T_melt 855 K, reference rate 1/s
JC = JohnsonCookFlow(A=324e6, B=114e6, n=0.42, C=0.002, reference_strain_rate=1.0,
                     room_temperature=293.15, melting_temperature=855.0, m=1.34)
TABLE = TabulatedFlow(plastic_strain=(0.0, 0.02, 0.05, 0.1, 0.2),
                      yield_stress=((200e6, 230e6, 260e6, 290e6, 310e6),
                                    (220e6, 255e6, 290e6, 320e6, 345e6),
                                    (150e6, 170e6, 195e6, 215e6, 230e6),
                                    (160e6, 185e6, 210e6, 235e6, 250e6)),
                      strain_rates=(1.0, 1e4), temperatures=(293.15, 573.15), extrapolation="linear")


def _pow(k, x, n):
    return k * x ** n if x > 0 else 0.0


def law_value(curve, ep, rate, T):
    """sigma_y of ``curve`` from its textbook formula (independent of the kernels' code)."""
    if isinstance(curve, Swift):
        return curve.K * (curve.eps0 + ep) ** curve.n
    if isinstance(curve, Voce):
        return curve.sigma0 + curve.Q * (1 - math.exp(-curve.b * ep))
    if isinstance(curve, Ludwik):
        return curve.sigma0 + _pow(curve.K, ep, curve.n)
    if isinstance(curve, JohnsonCookFlow):
        rs = max(rate / curve.reference_strain_rate, 1.0)
        ts = min(max((T - curve.room_temperature) / (curve.melting_temperature - curve.room_temperature), 0.0), 1.0)
        return (curve.A + _pow(curve.B, ep, curve.n)) * (1 + curve.C * math.log(rs)) * (1 - ts ** curve.m)
    # table: np.interp per curve in eps_p (the last segment continued), then ln(rate), then T
    eps = np.array(curve.plastic_strain)
    nr, nt = max(len(curve.strain_rates), 1), max(len(curve.temperatures), 1)
    rows = np.array(curve.yield_stress).reshape(nt, nr, len(eps))

    def at(row):
        if ep >= eps[-1]:
            slope = (row[-1] - row[-2]) / (eps[-1] - eps[-2]) if curve.extrapolation == "linear" else 0.0
            return row[-1] + slope * (ep - eps[-1])
        return float(np.interp(ep, eps, row))

    vals = np.array([[at(rows[i, j]) for j in range(nr)] for i in range(nt)])
    by_t = (np.array([np.interp(math.log(rate), np.log(curve.strain_rates), v) for v in vals])
            if nr > 1 else vals[:, 0])
    return float(np.interp(T, curve.temperatures, by_t)) if nt > 1 else float(by_t[0])


LAWS = {"swift": Swift(K=520e6, eps0=0.01, n=0.26), "voce": Voce(sigma0=190e6, Q=120e6, b=12.0),
        "ludwik": Ludwik(sigma0=180e6, K=400e6, n=0.45), "johnson_cook": JC, "table": TABLE}


def _material(curve, thermal=False, T0=293.15):
    return Material(RHO, G, K, 1.0, 0.0, flow_curve=curve, specific_heat=CP if thermal else None,
                    taylor_quinney=0.9, initial_temperature=T0)


class Element:
    """One element (axisymmetric triangle away from the axis: stress [rr, zz, hoop, rz]; or a
    tetrahedron: [xx, yy, zz, ...]) under v = L xm on the mid-step configuration (the kernels' own),
    L = diag(lateral, ..., axial rate): the lateral rate solved each step for zero lateral stress."""

    def __init__(self, mat, dim):
        self.dim = dim
        if dim == 2:
            self.x = np.array([[0.01, 0.0], [0.011, 0.0], [0.01, 0.001]])
            self.cells = np.array([[0, 1, 2]], np.int32)
            self.prm = pack_parameters(mat, MODE_AXISYMMETRIC, 1.0, 0.0, 0.0, False)
            self.kernel = element_step
            self.work = np.empty(WORK_SIZE)
            self.stress = np.zeros((1, 4))
        else:
            self.x = np.array([[0.0, 0.0, 0.0], [1e-3, 0.0, 0.0], [0.0, 1e-3, 0.0], [0.0, 0.0, 1e-3]])
            self.cells = np.array([[0, 1, 2, 3]], np.int32)
            self.prm = pack_parameters(mat, MODE_SOLID, 1.0, 0.0, 0.0, False)
            self.kernel = tet_step
            self.work = np.empty(0)  # not used by tet_step
            self.stress = np.zeros((1, 6))
        self.eps = np.zeros(1)
        self.temp = np.full(1, mat.initial_temperature)
        self.acc = np.zeros(3)
        self.lateral = -0.5 * RATE

    def _try(self, lat, dt):
        L = np.full(self.dim, lat)
        L[-1] = RATE
        # v = L xm with xm = x + dt/2 v (x the start-of-step positions): v = L x / (1 - dt/2 L)
        v = self.x * (L / (1.0 - 0.5 * dt * L))
        x1 = self.x + dt * v
        st, ep, tp, acc = self.stress.copy(), self.eps.copy(), self.temp.copy(), np.zeros(3)
        self.kernel(self.cells, x1, v, dt, self.prm, st, ep, np.zeros_like(x1), acc, self.work, tp)
        return st, ep, tp, acc, x1

    def step(self, dt):
        """One step: the lateral rate by the secant method on the lateral stress (round-off)."""
        a0, a1 = self.lateral, self.lateral * (1 + 1e-3)
        r0 = self._try(a0, dt)[0][0, 0]
        for _ in range(30):
            st = self._try(a1, dt)[0]
            r1 = st[0, 0]
            if r1 == r0 or abs(r1) <= 1e-13 * abs(st[0, 1 if self.dim == 2 else 2]):
                break
            a0, a1, r0 = a1, a1 - r1 * (a1 - a0) / (r1 - r0), r1
        self.lateral = a1
        T_before = float(self.temp[0])
        self.stress, self.eps, self.temp, acc, self.x = self._try(a1, dt)
        self.acc += acc
        return T_before

    def rate(self):
        """The equivalent strain rate sqrt(2/3 d':d') of the last step's d = diag(a, a, RATE), 1/s
        (the axial rate once the lateral rate is -RATE/2; above it by the elastic compressibility)."""
        return 2.0 / 3.0 * abs(RATE - self.lateral)

    def von_mises(self):
        s = self.stress[0]
        if self.dim == 2:
            s = np.array([s[0], s[1], s[2], s[3], 0.0, 0.0])
        p = s[:3].mean()
        d = s[:3] - p
        return math.sqrt(1.5 * ((d ** 2).sum() + 2 * (s[3:] ** 2).sum()))

    def axial(self):
        return self.stress[0, 1] if self.dim == 2 else self.stress[0, 2]

    def lateral_stress(self):
        return self.stress[0, 0]


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("law", sorted(LAWS))
def test_uniaxial_tension_follows_the_law(law, dim):
    """After every plastic step: von Mises = axial stress = sigma_y(eps_p, rate, T) to 1e-6; the table
    at 400 K (between its temperatures) and an eps_p beyond its last point (linear extrapolation);
    Johnson-Cook at 400 K (thermal softening) and at the rate 1e3/s (rate term)."""
    curve = LAWS[law]
    T0 = 400.0 if law in ("table", "johnson_cook") else 293.15
    el = Element(_material(curve, T0=T0), dim)
    dt = 0.25 / RATE / 1000          # axial strain 0.25 in 1000 steps: beyond the table's 0.2
    worst, plastic = 0.0, 0
    for _ in range(1000):
        T = el.step(dt)
        if el.eps[0] > 0:
            plastic += 1
            expect = law_value(curve, el.eps[0], el.rate(), T)
            worst = max(worst, abs(el.von_mises() - expect) / expect)
            assert abs(el.lateral_stress()) <= 1e-9 * expect
            assert el.axial() == pytest.approx(el.von_mises(), rel=1e-9)
    assert plastic > 900 and el.eps[0] > 0.2
    assert worst <= 1e-6, worst


@pytest.mark.parametrize("dim", [2, 3])
def test_adiabatic_heating_equals_the_plastic_work(dim):
    """Swift law, no softening: Delta T = beta int_0^eps_p sigma d eps_p / (rho c_p), the integral
    K / (n + 1) ((eps_0 + eps_p)^(n+1) - eps_0^(n+1)), within 0.1 %; the kernel's plastic
    dissipation (acc[0], J) is the same heat over the element volume."""
    sw = LAWS["swift"]
    el = Element(_material(sw, thermal=True), dim)
    dt = 0.6 / RATE / 1000
    for _ in range(1000):
        el.step(dt)
    ep = el.eps[0]
    work = sw.K / (sw.n + 1) * ((sw.eps0 + ep) ** (sw.n + 1) - sw.eps0 ** (sw.n + 1))
    dT = 0.9 * work / (RHO * CP)
    assert dT > 70.0
    assert el.temp[0] - 293.15 == pytest.approx(dT, rel=1e-3)


@pytest.mark.parametrize("dim", [2, 3])
def test_adiabatic_softening_johnson_cook(dim):
    """Johnson-Cook from 500 K: the coupled rise T(eps_p) of the element against the ODE
    dT/d eps_p = beta sigma_JC(eps_p, rate, T) / (rho c_p) solved to 1e-10 (scipy), within 0.1 %,
    and the stress on the softened curve."""
    from scipy.integrate import solve_ivp

    el = Element(_material(JC, thermal=True, T0=500.0), dim)
    dt = 0.6 / RATE / 1000
    for _ in range(1000):
        el.step(dt)
    ep = el.eps[0]
    sol = solve_ivp(lambda e, T: [0.9 * law_value(JC, e, el.rate(), T[0]) / (RHO * CP)], (0.0, ep), [500.0],
                    rtol=1e-11, atol=1e-10)
    T_ode = sol.y[0, -1]
    assert T_ode - 500.0 > 40.0
    assert el.temp[0] - 500.0 == pytest.approx(T_ode - 500.0, rel=1e-3)


def _impact(mat, formulation="plane_strain", n=10, steps=120, dim=2):
    if dim == 2:   # axisymmetric: a ring pressed onto a rigid mandrel at r = 10 mm
        r0 = 0.01 if formulation == "axisymmetric" else 0.0
        msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([r0, 0.0]), np.array([r0 + 0.01, 0.01])], [n, n])
        s = ExplicitSolver([BodySpec("b", msh, mat, initial_velocity=(-150.0, 0.0))], formulation=formulation,
                           rigid_walls=(RigidWallSpec((r0, 0.0), (1.0, 0.0)),), comm=msh.comm)
    else:
        msh = dmesh.create_box(MPI.COMM_SELF, [np.zeros(3), np.array([0.01, 0.005, 0.005])], [6, 3, 3])
        s = ExplicitSolver3D([BodySpec("b", msh, mat, initial_velocity=(-150.0, 0.0, 0.0))],
                             rigid_walls=(RigidWallSpec((0.0, 0.0, 0.0), (1.0, 0.0, 0.0)),), comm=msh.comm)
    dt = 0.5 * s.stable_time_step()
    s.advance(dt, steps)
    return s


@pytest.mark.parametrize("dim,formulation", [(2, "plane_strain"), (2, "plane_stress"), (2, "axisymmetric"),
                                             (3, "3d")])
def test_table_of_the_linear_law_equals_the_linear_law(dim, formulation):
    """A table through points of sigma_0 + A eps_p (extrapolated linearly) gives the linear law's impact to
    round-off (the Newton return of the table converges in one step on a straight segment)."""
    lin = Material(RHO, G, K, 200e6, 500e6)
    eps = (0.0, 0.05, 0.1)
    tab = Material(RHO, G, K, 200e6, 500e6, flow_curve=TabulatedFlow(
        plastic_strain=eps, yield_stress=(tuple(200e6 + 500e6 * e for e in eps),), extrapolation="linear"))
    a = _impact(lin, formulation, dim=dim).bodies["b"]
    b = _impact(tab, formulation, dim=dim).bodies["b"]
    assert (a.eps_p > 0).sum() > 10 and a.eps_p.max() > 0.1   # beyond the table: extrapolated
    assert np.allclose(a.eps_p, b.eps_p, rtol=1e-9, atol=1e-14)
    assert np.abs(a.cell_stress - b.cell_stress).max() <= 1e-9 * np.abs(a.cell_stress).max()
    assert np.abs(a.x - b.x).max() <= 1e-12 * np.abs(a.x).max()


@pytest.mark.parametrize("mode", [MODE_PLANE_STRESS, MODE_PLANE_STRAIN, MODE_AXISYMMETRIC])
def test_screened_batches_equal_the_scalar_update(mode):
    """A general material (Johnson-Cook, temperature per cell): the vectorised batches screen the
    elastic cells and the scalar update does the others; each cell gets what the scalar update alone
    gives (bitwise), its temperature too; yielding cells land on the softened, rate-hardened curve."""
    from pulseform.solvers.dolfinx.element_math import BATCH, OUT_ROWS, cell_update

    mat = _material(JC, thermal=True)
    rng = np.random.default_rng(3)
    nc = 2 * BATCH + 37
    x = np.zeros((3 * nc, 2))
    base = np.array([[0.0, 0.0], [1e-3, 0.0], [0.0, 1e-3]])
    for e in range(nc):
        x[3 * e:3 * e + 3] = base + rng.normal(scale=1e-4, size=(3, 2)) + [0.01 + 2e-3 * e, 0.0]
    cells = np.arange(3 * nc, dtype=np.int32).reshape(nc, 3)
    v = rng.normal(scale=30.0, size=x.shape)
    dt = 2e-8
    stress0 = rng.normal(scale=250e6, size=(nc, 4))
    if mode == MODE_PLANE_STRESS:
        stress0[:, 2] = 0.0
    temp0 = rng.uniform(293.15, 700.0, size=nc)
    prm = pack_parameters(mat, mode, 1e-3, 0.06, 1.2, True)
    st, ep, f, acc, tp = stress0.copy(), np.full(nc, 0.01), np.zeros_like(x), np.zeros(3), temp0.copy()
    element_step(cells, x, v, dt, prm, st, ep, f, acc, np.empty(WORK_SIZE), tp)
    assert 20 < (ep > 0.01).sum() < nc - 20        # both kinds of cells
    out = np.zeros(OUT_ROWS)
    for e in range(nc):
        cell_update(*x[cells[e]].ravel(), *v[cells[e]].ravel(), *stress0[e], 0.01, dt, prm, out, temp0[e])
        assert np.array_equal(st[e], out[:4]) and ep[e] == out[4] and tp[e] == out[16]
        assert (tp[e] > temp0[e]) == (ep[e] > 0.01)


@pytest.mark.parametrize("dim", [2, 3])
def test_temperature_restarts_bitwise(dim):
    """A Johnson-Cook impact with a temperature per cell, stopped and restarted from ``state_dict``
    (the run's checkpoint), continues bit for bit: positions, stresses, plastic strains, temperatures."""
    mat = _material(JC, thermal=True)
    a = _impact(mat, dim=dim, steps=60)
    state = a.state_dict()
    assert "b/temperature" in state
    dt = a._dt_prev
    a.advance(dt, 40)
    b = _impact(mat, dim=dim, steps=1)
    b.load_state_dict(state)
    b.advance(dt, 40)
    ba, bb = a.bodies["b"], b.bodies["b"]
    assert ba.temperature.max() > 300.0
    for key in ("x", "cell_stress", "eps_p", "temperature"):
        assert np.array_equal(getattr(ba, key), getattr(bb, key)), key


def test_no_temperature_without_specific_heat():
    """Without a specific heat the cells keep the initial temperature (plastic work not turned into heat),
    the checkpoint has no temperature (the state of the runs before issue 33), and Joule heat is ignored."""
    s = _impact(_material(JC), steps=60)
    b = s.bodies["b"]
    assert b.eps_p.max() > 0 and np.all(b.temperature == 293.15)
    assert "b/temperature" not in s.state_dict()
    s.add_heat("b", np.full(len(b.cells), 1e9))
    assert np.all(b.temperature == 293.15)


def test_joule_heat_adds_adiabatically():
    """``add_heat``: T += e / (rho c_p) per cell, in the compiled path's arrays (the next steps see it)."""
    s = _impact(_material(LAWS["voce"], thermal=True), steps=1)
    b = s.bodies["b"]
    T0 = b.temperature.copy()
    e = np.linspace(0.0, 1e8, len(b.cells))
    s.add_heat("b", e)
    assert np.allclose(b.temperature - T0, e / (RHO * CP), rtol=1e-14, atol=1e-12)   # K: T0 + x - T0 rounds
    assert s.compiled is not None and np.shares_memory(b.temperature, s.compiled.B.temp)


@pytest.mark.parametrize("thermal", [False, True])
def test_3d_screened_batches_equal_the_scalar_kernel(thermal):
    """3D, a general material (Johnson-Cook, with or without a temperature per cell): the vectorised
    kernel (screened batches, yielding cells by the scalar kernel one at a time) gives the scalar
    kernel's bits: stresses, plastic strains, temperatures, forces, critical step, dissipation; and on
    two threads (several chunks) the same again."""
    from pulseform.solvers.dolfinx.tet_batch import TET_WORK_SIZE, tet_step_batched
    from pulseform.solvers.dolfinx.tet_kernel import TET_CHUNK
    from pulseform.solvers.dolfinx.tet_threads import tet_step_threaded, tet_thread_arrays

    msh = dmesh.create_box(MPI.COMM_SELF, [np.zeros(3), np.array([0.02, 0.01, 0.01])], [40, 20, 20])
    s = ExplicitSolver3D([BodySpec("b", msh, _material(JC, thermal=thermal), initial_velocity=(0.0, 0.0, 0.0))],
                         comm=msh.comm)
    b = s.bodies["b"]
    assert len(b.cells) > TET_CHUNK                     # several chunks: the threaded kernel's gather
    rng = np.random.default_rng(5)
    v = rng.normal(scale=5.0, size=b.v.shape)
    dt = 0.3 * s.stable_time_step()
    x = b.x + dt * v
    stress0 = rng.normal(scale=120e6, size=b.cell_stress.shape)
    temp0 = rng.uniform(293.15, 600.0, size=len(b.cells))
    prm = s._prm["b"]
    runs = []
    for kern in ("scalar", "batched", "threads"):
        st, ep, f, acc, tp = stress0.copy(), np.full(len(b.cells), 0.01), np.zeros_like(x), np.zeros(3), temp0.copy()
        if kern == "scalar":
            d = tet_step(b.cells, x, v, dt, prm, st, ep, f, acc, np.empty(TET_WORK_SIZE), tp)
        elif kern == "batched":
            d = tet_step_batched(b.cells, x, v, dt, prm, st, ep, f, acc, np.empty(TET_WORK_SIZE), tp)
        else:
            import numba
            numba.set_num_threads(2)
            d = tet_step_threaded(b.cells, x, v, dt, prm, st, ep, f, acc, tet_thread_arrays(b.cells, len(x)), tp)
        runs.append((st, ep, f, acc, tp, d))
    ref = runs[0]
    assert 0.05 * len(b.cells) < (ref[1] > 0.01).sum() < 0.95 * len(b.cells)   # both kinds of cells
    assert np.array_equal(ref[4] > temp0, ref[1] > 0.01) if thermal else np.array_equal(ref[4], temp0)
    for run in runs[1:]:
        for a, c in zip(ref, run):
            assert np.array_equal(a, c)


def test_2d_threads_give_the_serial_bits_with_a_general_material():
    """2D compiled steps on 2 threads (two chunks of cells) with Johnson-Cook and a temperature per cell: the
    one-thread bits (positions, stresses, plastic strains, temperatures, energy ledger)."""
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 threads")
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([0.0, 0.0]), np.array([0.01, 0.01])], [70, 70])
    runs = []
    for threads in (1, 2):
        s = ExplicitSolver([BodySpec("b", msh, _material(JC, thermal=True), initial_velocity=(-150.0, 0.0))],
                           formulation="plane_strain", rigid_walls=(RigidWallSpec((0.0, 0.0), (1.0, 0.0)),),
                           comm=msh.comm, threads=threads)
        s.advance(0.5 * s.stable_time_step(), 60)
        runs.append(s)
    a, b = (r.bodies["b"] for r in runs)
    assert len(a.cells) > 8192 and a.temperature.max() > 300.0
    for key in ("x", "cell_stress", "eps_p", "temperature"):
        assert np.array_equal(getattr(a, key), getattr(b, key)), key
    assert runs[0].energies() == runs[1].energies()
