"""The implicit integrator (solvers/dolfinx/implicit.py, issue 34 item 1): its element update against the
explicit kernels, the exact tangent (Newton's quadratic convergence), the time schemes against the
single-degree-of-freedom recursion of the same scheme on the mesh's own eigenmode, energy, static steps
against Lamé and a 3D bar, restart, and the one-line stops (singular static system, Newton failure).

References: Newmark's average-acceleration rule is undamped with the frequency tan(w~ dt / 2) = w dt / 2
(Hughes, The Finite Element Method, sec. 9.3); HHT-alpha, Hilber, Hughes & Taylor, Earthquake Eng.
Struct. Dyn. 5 (1977) 283; Lamé's thick cylinder, Timoshenko & Goodier, Theory of Elasticity, sec. 33.
"""
import inspect
import math

import numpy as np
import pytest
import scipy.linalg as sla
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, Material
from pulseform.solvers.dolfinx.implicit import (ImplicitConvergenceError, ImplicitOptions, ImplicitSolver,
                                                ImplicitSolver3D, SingularSystemError)
from pulseform.solvers.dolfinx.implicit_element import CellState, cell_tangent, cell_update
from pulseform.solvers.dolfinx.kernels import (MODE_AXISYMMETRIC, MODE_PLANE_STRAIN, MODE_PLANE_STRESS,
                                               pack_parameters)
from pulseform.solvers.dolfinx.material import CowperSymonds
from pulseform.solvers.dolfinx.reference_kernel import element_step_numpy
from pulseform.solvers.dolfinx.tet_kernel import MODE_SOLID, tet_step

from mech_helpers import central_difference_tangent

ELASTIC = Material(2700.0, 26e9, 70e9, 1e12, 0.0)      # yield far away
PLASTIC = Material(2700.0, 26e9, 70e9, 100e6, 500e6)
L, H, T = 0.1, 0.005, 0.01                               # cantilever length, height, thickness (m)


def _oriented(x, cells):
    """Cells of random nodes ``x`` made positively oriented (2D area, 3D volume)."""
    xe = x[cells]
    if x.shape[1] == 2:
        s = (xe[:, 1, 0] - xe[:, 0, 0]) * (xe[:, 2, 1] - xe[:, 0, 1]) - (xe[:, 2, 0] - xe[:, 0, 0]) * (xe[:, 1, 1] - xe[:, 0, 1])
    else:
        s = np.einsum("ci,ci->c", xe[:, 1] - xe[:, 0], np.cross(xe[:, 2] - xe[:, 0], xe[:, 3] - xe[:, 0]))
    neg = s < 0
    cells[neg, 1], cells[neg, 2] = cells[neg, 2].copy(), cells[neg, 1].copy()
    return cells


@pytest.mark.parametrize("mode", [MODE_PLANE_STRESS, MODE_PLANE_STRAIN, MODE_AXISYMMETRIC, MODE_SOLID])
@pytest.mark.parametrize("material", [PLASTIC, Material(2700.0, 26e9, 70e9, 100e6, 500e6, CowperSymonds(6500.0, 4.0))])
def test_element_update_is_the_explicit_kernels(mode, material):
    """An implicit increment du = dt v gives the explicit kernels' stress, plastic strain, nodal forces and plastic
    work (the same finite-strain update), and the complex-step tangent equals central differences."""
    if mode != MODE_SOLID and material.rate_law is not None:
        pytest.skip("the numpy reference kernel of 2D is rate-independent (the 3D kernel covers the rate law)")
    rng = np.random.default_rng(mode)
    dim = 3 if mode == MODE_SOLID else 2
    nc, nn = 40, dim + 1
    x = rng.random((nc * nn, dim)) * 1e-3 + np.eye(dim)[0] * 1e-3
    cells = _oriented(x, np.arange(nc * nn).reshape(nc, nn))
    v = rng.standard_normal(x.shape) * 5.0
    dt = 1e-7
    stress = rng.standard_normal((nc, 6 if dim == 3 else 4)) * 50e6
    if mode == MODE_PLANE_STRESS:
        stress[:, 2] = 0.0
    ep = rng.random(nc) * 0.01
    prm = pack_parameters(material, mode, 0.01, 0.06, 1.2, False)
    s1, e1, f, acc = stress.copy(), ep.copy(), np.zeros_like(x), np.zeros(3)
    kernel = tet_step if dim == 3 else element_step_numpy
    # kernels that carry a temperature per cell take it last (293.15 K: no thermal softening of these laws)
    temp = [np.full(nc, 293.15)] if "temp" in inspect.signature(getattr(kernel, "py_func", kernel)).parameters else []
    kernel(cells, x, v, dt, prm, s1, e1, f, acc, np.zeros(8), *temp)
    du = (v * dt)[cells]
    st = CellState(x[cells] - du, stress, ep, material, mode, 0.01, dt)
    r = cell_update(st, du)
    fi = np.zeros_like(x)
    np.add.at(fi, cells, r.force)
    assert np.count_nonzero(r.deps_p) > nc // 2                         # the returns are exercised
    assert np.abs(r.stress - s1).max() <= 1e-12 * np.abs(s1).max()
    assert np.abs(ep + r.deps_p - e1).max() <= 1e-12
    assert np.abs(fi - f).max() <= 1e-12 * np.abs(f).max()
    assert r.plastic_work.sum() == pytest.approx(acc[0], rel=1e-12)
    K = cell_tangent(st, du)
    Kfd = central_difference_tangent(cell_update, st, du)
    assert Kfd.shape == K.shape and np.abs(K - Kfd).max() <= 1e-6 * np.abs(K).max()


def _cantilever(nx, ny, options, material=ELASTIC, supported=True):
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([0.0, 0.0]), np.array([L, H])], [nx, ny],
                                 diagonal=dmesh.DiagonalType.crossed)
    fixed = ((lambda x: np.isclose(x[0], 0.0), (0, 1)),) if supported else ()
    return ImplicitSolver([BodySpec("beam", msh, material, fixed=fixed)], options, formulation="plane_stress",
                          thickness=T, comm=msh.comm)


def _first_mode(s):
    """The mesh's first bending eigenpair (omega in rad/s, mode shape (N, 2)) from the solver's own tangent and
    lumped mass (scipy's dense symmetric eigensolver: the independent reference of the time scheme)."""
    b = s.bodies["beam"]
    res = s._cells("beam", b, np.zeros(b.cells.shape + (2,)), s.options.dt)
    K = s._assemble([("beam", b, res)], 0.0, 1.0).toarray()
    free = ~s._mask["beam"].ravel()
    Kf = 0.5 * (K[free][:, free] + K[free][:, free].T)
    m = np.repeat(b.mass, 2)[free]
    w2, vec = sla.eigh(Kf, np.diag(m), subset_by_index=[0, 0])
    phi = np.zeros(b.x.size)
    phi[free] = vec[:, 0] / math.sqrt(vec[:, 0] @ (m * vec[:, 0]))
    return math.sqrt(w2[0]), phi.reshape(-1, 2), np.repeat(b.mass, 2)


def _sdof(omega, dt, alpha, q0dot, n):
    """The HHT-alpha recursion (alpha = 0: trapezoidal) of q'' + omega^2 q = 0 from q = 0, q' = q0dot: q_1 .. q_n."""
    beta, gamma = 0.25 * (1 - alpha) ** 2, 0.5 - alpha
    w2 = omega * omega
    # unknowns at n+1 from those at n: [1 + ..] solved in closed form for a^{n+1}
    q, v, a, out = 0.0, q0dot, 0.0, []
    for _ in range(n):
        # a1 + (1 + alpha) w2 q1 - alpha w2 q = 0,  q1 = q + dt v + dt^2 ((1/2 - beta) a + beta a1)
        qp = q + dt * v + dt * dt * (0.5 - beta) * a
        a1 = -((1 + alpha) * w2 * qp - alpha * w2 * q) / (1 + (1 + alpha) * w2 * beta * dt * dt)
        q1 = qp + beta * dt * dt * a1
        v = v + dt * ((1 - gamma) * a + gamma * a1)
        q, a = q1, a1
        out.append(q)
    return np.array(out)


@pytest.mark.parametrize("alpha", [0.0, -0.1])
def test_free_vibration_follows_the_scheme_on_the_mesh_eigenmode(alpha):
    """A cantilever started with a small velocity in its first (discrete) eigenmode: the modal coordinate of the
    finite-element run follows the scalar recursion of the same scheme step by step (trapezoidal: undamped, the
    frequency 2 atan(w dt / 2) / dt; HHT: its amplitude decay too), for a coarse step of T/12."""
    s = _cantilever(20, 2, ImplicitOptions(dt=1.0, scheme="hht" if alpha else "trapezoidal", alpha=alpha))
    omega, phi, m = _first_mode(s)
    dt = 2 * math.pi / omega / 12
    s.options = ImplicitOptions(dt=dt, scheme="hht" if alpha else "trapezoidal", alpha=alpha)
    b = s.bodies["beam"]
    b.v[...] = 1e-4 * phi / np.abs(phi).max()               # tip speed 0.1 mm/s: geometric nonlinearity ~1e-9
    q0dot = float(np.sum(m * phi.ravel() * b.v.ravel()))
    s._KE0 = s._kinetic()
    s._E0 = s._stored_energy()
    q = []
    for _ in range(30):
        s.advance(dt, 1)
        q.append(float(np.sum(m * phi.ravel() * b.u.ravel())))
    ref = _sdof(omega, dt, alpha, q0dot, 30)
    err = np.abs(np.array(q) - ref).max() / np.abs(ref).max()
    print(f"alpha {alpha}: omega {omega:.6g} rad/s, modal deviation from the recursion {err:.2e}")
    assert err < 1e-5
    e = s.energies()
    if alpha == 0.0:   # Newmark's rule conserves energy: its ledger closes to the Newton tolerance
        assert abs(e["algorithmic_dissipation_J"]) < 1e-7 * s.initial_energy
        assert abs(e["kinetic_J"] + e["elastic_J"] - s.initial_energy) < 1e-5 * s.initial_energy
    else:              # HHT removes energy, and the ledger says how much
        assert e["algorithmic_dissipation_J"] > 0.05 * s.initial_energy
        assert abs(e["balance_error_J"]) < 1e-5 * s.initial_energy


def test_step_convergence_order_is_two():
    """The trapezoidal rule's phase error on the mesh eigenmode falls as dt^2: the fitted order over T/8, T/16,
    T/32 (against the exact modal solution sin(omega t)) lies within 0.1 of 2."""
    s0 = _cantilever(20, 2, ImplicitOptions(dt=1.0))
    omega, phi, m = _first_mode(s0)
    period = 2 * math.pi / omega
    errs, steps = [], [8, 16, 32]
    for n in steps:
        s = _cantilever(20, 2, ImplicitOptions(dt=period / n))
        b = s.bodies["beam"]
        b.v[...] = 1e-4 * phi / np.abs(phi).max()
        q0dot = float(np.sum(m * phi.ravel() * b.v.ravel()))
        s.advance(period / n, n // 2)                            # half a period
        q = float(np.sum(m * phi.ravel() * b.u.ravel()))
        exact = q0dot / omega * math.sin(omega * s.time)
        errs.append(abs(q - exact) / (q0dot / omega))
    order = np.polyfit(np.log(steps), np.log(errs), 1)[0]
    print("half-period errors", errs, "order", -order)
    assert abs(-order - 2.0) < 0.1


def test_newton_converges_quadratically_past_yield():
    """One static step takes the cantilever past yield under an end shear of 1.2 times the plastic-hinge load
    (plastic cells at the clamp): Newton's relative residuals fall quadratically (the consistent tangent);
    measured 1.0 0.98 1.2e-2 2.4e-3 6.5e-7 6.6e-12 (rates 2.36, 1.81 once the plastic zone is set)."""
    s = _cantilever(20, 4, ImplicitOptions(dt=1e-3, scheme="static"), material=PLASTIC)
    b = s.bodies["beam"]
    tip = np.isclose(b.X0[:, 0], L)
    f = np.zeros_like(b.x)
    f[tip, 1] = -1.2 * 100e6 * T * H * H / 4 / L / tip.sum()     # 1.2 x the plastic-hinge load sigma_0 t h^2 / 4 / L
    s.advance(1e-3, 1, {"beam": f})
    r = s.last_residuals
    print("Newton relative residuals:", " ".join(f"{x:.2e}" for x in r))
    assert b.eps_p.max() > 1e-4 and np.count_nonzero(b.eps_p) >= 3 and r[-1] <= 1e-8
    tail = [x for x in r if 1e-13 < x < 1e-2]
    assert len(tail) >= 2
    rates = [math.log(tail[i + 1]) / math.log(tail[i]) for i in range(len(tail) - 1)]
    print("convergence rates log r_k+1 / log r_k:", rates)
    assert min(rates) > 1.7


def test_static_lame_cylinder_axisymmetric():
    """A static step of an axisymmetric thick cylinder (ends held along the axis) under inner pressure: the radial
    displacement of the bore and the outer surface within 1 % of Lamé's (Timoshenko & Goodier, sec. 33)."""
    a, b_, h, p = 0.1, 0.2, 0.02, 100e6
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([a, 0.0]), np.array([b_, h])], [20, 4])
    ends = lambda x: np.isclose(x[1], 0.0) | np.isclose(x[1], h)  # noqa: E731
    s = ImplicitSolver([BodySpec("tube", msh, ELASTIC, fixed=((ends, (1,)),))], ImplicitOptions(dt=1.0, scheme="static"),
                       formulation="axisymmetric", comm=msh.comm)
    tube = s.bodies["tube"]
    s.advance(1.0, 1, {"tube": s.pressure_nodal_forces("tube", lambda x: x[0] < a + 1e-9, p)})
    E, nu = ELASTIC.youngs_modulus, ELASTIC.poisson_ratio
    A = p * a * a / (b_ * b_ - a * a)
    B = A * b_ * b_
    u = lambda r: (1 + nu) / E * ((1 - 2 * nu) * A * r + B / r)  # noqa: E731
    for r in (a, b_):
        got = tube.u[np.isclose(tube.X0[:, 0], r), 0].mean()
        assert got == pytest.approx(u(r), rel=1e-2)


def test_static_bar_3d():
    """A 3D bar pulled by an end force in one static step (uniform stress: exact for P1 tetrahedra): the end
    displacement F L / (E A) to the geometric nonlinearity of the small strain (1e-5)."""
    msh = dmesh.create_box(MPI.COMM_SELF, [np.array([0.0, 0.0, 0.0]), np.array([0.1, 0.01, 0.01])], [10, 2, 2])
    fixed = ((lambda x: np.isclose(x[0], 0.0), (0,)), (lambda x: np.isclose(x[1], 0.0), (1,)),
             (lambda x: np.isclose(x[2], 0.0), (2,)))
    s = ImplicitSolver3D([BodySpec("bar", msh, ELASTIC, initial_velocity=(0.0, 0.0, 0.0), fixed=fixed)],
                         ImplicitOptions(dt=1.0, scheme="static"), comm=msh.comm)
    b = s.bodies["bar"]
    end = np.isclose(b.X0[:, 0], 0.1)
    stress = 1e-5 * ELASTIC.youngs_modulus
    f = s.pressure_nodal_forces("bar", lambda x: x[0] > 0.1 - 1e-9, -stress)
    s.advance(1.0, 1, {"bar": f})
    assert b.u[end, 0].mean() == pytest.approx(1e-5 * 0.1, rel=1e-4)
    assert b.cell_stress[:, 0] == pytest.approx(stress, rel=1e-4)


def test_restart_continues_bit_for_bit():
    """state_dict / load_state_dict: a run interrupted after 3 steps continues to the same bits."""
    opts = ImplicitOptions(dt=2e-5, scheme="hht", alpha=-0.05)
    s1 = _cantilever(10, 2, opts, material=PLASTIC)
    f = np.zeros_like(s1.bodies["beam"].x)
    f[np.isclose(s1.bodies["beam"].X0[:, 0], L), 1] = -30.0
    s1.advance(2e-5, 3, {"beam": f})
    state = s1.state_dict()
    s1.advance(2e-5, 3, {"beam": f})
    s2 = _cantilever(10, 2, opts, material=PLASTIC)
    s2.load_state_dict(state)
    s2.advance(2e-5, 3, {"beam": f})
    for key in ("x", "v", "a", "cell_stress", "eps_p"):
        assert np.array_equal(getattr(s1.bodies["beam"], key), getattr(s2.bodies["beam"], key)), key
    assert s1.energies() == s2.energies()


def test_static_step_of_an_unsupported_body_is_one_line():
    """A body without supports in a static step: SingularSystemError, one line naming the body and the free
    motions, before any change of state."""
    s = _cantilever(10, 2, ImplicitOptions(dt=1.0, scheme="static"), supported=False)
    with pytest.raises(SingularSystemError) as err:
        s.advance(1.0, 1)
    msg = str(err.value)
    print(msg)
    assert "\n" not in msg and "'beam'" in msg and "translation x" in msg and "rotation z" in msg
    assert s.time == 0.0 and s.step_count == 0


def test_newton_failure_is_one_line_and_keeps_the_last_state():
    """Newton allowed one iteration and no cut on a plastic step: ImplicitConvergenceError, one line with the
    time, step and residuals; the state is that of the last converged step."""
    s = _cantilever(10, 2, ImplicitOptions(dt=1e-3, scheme="static", newton_max=1, max_cuts=1), material=PLASTIC)
    b = s.bodies["beam"]
    f = np.zeros_like(b.x)
    f[np.isclose(b.X0[:, 0], L), 1] = -2.0 * 100e6 * T * H * H / 4 / L / 3
    x0 = b.x.copy()
    with pytest.raises(ImplicitConvergenceError) as err:
        s.advance(1e-3, 1, {"beam": f})
    msg = str(err.value)
    print(msg)
    assert "\n" not in msg and "Newton did not converge" in msg and "after 1 cuts" in msg
    assert s.step_count == 0 and np.array_equal(b.x, x0)


def test_options_are_checked():
    """Bad options name the option and the allowed values."""
    with pytest.raises(ValueError, match="alpha must lie in"):
        ImplicitOptions(dt=1e-3, scheme="hht", alpha=-0.5)
    with pytest.raises(ValueError, match="scheme must be one of"):
        ImplicitOptions(dt=1e-3, scheme="euler")
    with pytest.raises(ValueError, match="needs scheme 'hht'"):
        ImplicitOptions(dt=1e-3, alpha=-0.1)


@pytest.mark.slow
def test_cantilever_first_frequency_euler_bernoulli():
    """The first bending period of a cantilever (L/h = 20, plane stress, 160 x 8 crossed P1 cells, lumped mass),
    from a trapezoidal free vibration of 40 steps per period started in the Euler-Bernoulli mode shape: within
    1 % of Euler-Bernoulli's 2 pi / ((1.8751/L)^2 sqrt(E I / (rho A))). Measured -0.22 % (coarser meshes are too
    stiff: P1 triangles lock in bending, -1.4 % at 80 x 8, -4.7 % at 80 x 8 right-diagonal cells)."""
    bl = 1.8751040687
    E, rho = ELASTIC.youngs_modulus, ELASTIC.density
    period = 2 * math.pi / (bl ** 2 / L ** 2 * math.sqrt(E * H * H / (12 * rho)))
    s = _cantilever(160, 8, ImplicitOptions(dt=period / 40))
    b = s.bodies["beam"]
    k = (math.cosh(bl) + math.cos(bl)) / (math.sinh(bl) + math.sin(bl))
    xi = b.X0[:, 0] / L
    b.v[:, 1] = 1e-3 * 0.5 * (np.cosh(bl * xi) - np.cos(bl * xi) - k * (np.sinh(bl * xi) - np.sin(bl * xi)))
    b.v[s._mask["beam"]] = 0.0
    tip = np.isclose(b.X0[:, 0], L)
    ts, us = [0.0], [0.0]
    for _ in range(int(2.2 * 40)):
        s.advance(period / 40, 1)
        ts.append(s.time)
        us.append(b.u[tip, 1].mean())
    ts, us = np.array(ts), np.array(us)
    i = np.flatnonzero(np.sign(us[1:]) != np.sign(us[:-1]))[1:]   # zero crossings after the start
    zc = ts[i] + (ts[i + 1] - ts[i]) * us[i] / (us[i] - us[i + 1])
    measured = 2 * np.diff(zc).mean()
    print(f"period {measured:.6e} s, Euler-Bernoulli {period:.6e} s, {100 * (measured / period - 1):+.3f} %")
    assert measured == pytest.approx(period, rel=0.01)


def test_materials_the_return_mapping_does_not_know_are_refused(monkeypatch):
    """A material with a flow curve or a temperature (attributes of other materials) is named by
    ``unsupported_material``, and the solver refuses such a body in one line, never integrating it with the linear
    law."""
    from types import SimpleNamespace

    from pulseform.solvers.dolfinx import implicit as implicit_mod
    from pulseform.solvers.dolfinx.implicit_flow import unsupported_material

    assert unsupported_material(PLASTIC) == ""
    assert unsupported_material(SimpleNamespace(flow_curve=SimpleNamespace(), thermal=False)).startswith("flow curve")
    assert unsupported_material(SimpleNamespace(flow_curve=None, thermal=True)).startswith("temperature")
    monkeypatch.setattr(implicit_mod, "unsupported_material", lambda m: "flow curve (Swift)")
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([0.0, 0.0]), np.array([L, H])], [4, 1])
    with pytest.raises(ValueError, match="body 'beam': the implicit integrator's return mapping has no flow curve"):
        ImplicitSolver([BodySpec("beam", msh, PLASTIC)], ImplicitOptions(dt=1e-3), comm=msh.comm)
