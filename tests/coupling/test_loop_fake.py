"""The staggered loop with fake participants (preCICE's solid-fake idea): seconds, exact references."""

import math

import numpy as np
import pytest

from pulseform.orchestrator.coupling.loop import StaggeredLoop
from pulseform.orchestrator.mesh.motion import MeshMover, MeshQualityError, triangle_quality
from pulseform.orchestrator.coupling.fakes import AnalyticForce, RigidAxialBody
from pulseform.orchestrator.coupling.interfaces import LoadCapabilities, LoadStep, plain_total
from pulseform.orchestrator.coupling.transfer import cell_force_integral, cell_to_nodal_forces

from .meshes import rect_mesh

NODES = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]])


@pytest.mark.parametrize("n", [1, 3, 10])
def test_constant_force_and_gravity_exact(n):
    """y(t) = v0 t + ½ (F/m − g) t²: central difference with a half-step start is exact."""
    m, g, F, v0, T = 2.5, 9.81, 40.0, -0.3, 0.0137
    body = RigidAxialBody("slug", NODES, m, gravity=g, velocity=v0, dt=1.7e-4)
    loop = StaggeredLoop(AnalyticForce("slug", 3, lambda t: F), body, n)
    loop.run_until(T)
    a = F / m - g
    assert body.time == pytest.approx(T, rel=1e-14)
    assert body.y == pytest.approx(v0 * T + 0.5 * a * T * T, rel=1e-11)
    assert body.positions()["slug"][2, 1] == pytest.approx(1.0 + body.y, rel=1e-12)
    assert loop.counters.impulse[1] == pytest.approx(F * T, rel=1e-12)


def _sine_error(n: int, dt: float) -> float:
    m, F0, w, T = 1.0, 1.0, 2 * math.pi * 50.0, 0.013
    body = RigidAxialBody("b", NODES, m, dt=dt)
    StaggeredLoop(AnalyticForce("b", 3, lambda t: F0 * math.sin(w * t)), body, n).run_until(T)
    exact = F0 / (m * w) * (T - math.sin(w * T) / w)
    return abs(body.y - exact) / abs(exact)


def test_held_force_converges_second_order_in_em_step():
    """F = F0 sin(ωt) held at the EM-step midpoint over n = 10 substeps: error ∝ dt_em²
    (midpoint rule for the impulse of each EM step); reference y = F0/(mω)(t − sin(ωt)/ω)."""
    dts = np.array([4e-5, 2e-5, 1e-5, 5e-6])
    errs = np.array([_sine_error(10, dt) for dt in dts])
    rate = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert 1.8 < rate < 2.2, (errs, rate)


def test_subcycling_error_grows_with_n():
    """Same mechanical step: the hold error grows with n (the loop really holds the force)."""
    e1, e10 = _sine_error(1, 1e-5), _sine_error(10, 1e-5)
    assert e10 > 10 * e1


def test_resume_from_state_is_bitwise():
    """Stop at a milestone, save both participants and the counters, restore into fresh objects."""
    f = lambda t: 3.0 * math.sin(700.0 * t) + 1.0  # noqa: E731

    def make():
        body = RigidAxialBody("b", NODES, 0.7, gravity=1.0, dt=3e-5)
        return body, StaggeredLoop(AnalyticForce("b", 3, f), body, 4)

    body, loop = make()
    loop.run_until(0.01)
    loop.run_until(0.02)
    ref = (body.y, body.v, loop.counters.impulse.copy())
    body, loop = make()
    loop.run_until(0.01)
    saved = (body.state_dict(), loop.counters.state_dict())
    body2, loop2 = make()
    body2.load_state_dict(saved[0])
    loop2.counters.load_state_dict(saved[1])
    loop2.run_until(0.02)
    assert (body2.y, body2.v) == ref[:2]
    assert np.array_equal(loop2.counters.impulse, ref[2])


class PrescribedMotion:
    """Mechanics fake: a conductor block translated rigidly by u(t) = (0, A sin(ωt))."""

    def __init__(self, nodes, dt, amplitude, omega):
        self.x0, self.dt, self.A, self.w = nodes.copy(), dt, amplitude, omega
        self.time, self.step_count = 0.0, 0

    def stable_time_step(self):
        return self.dt

    def advance(self, dt, n_steps, forces):
        self.time += dt * n_steps
        self.step_count += n_steps

    def positions(self):
        return {"block": self.x0 + np.array([0.0, self.A * math.sin(self.w * self.time)])}

    def total_force(self, forces):
        return plain_total(forces)

    def state_dict(self):
        return {}

    def load_state_dict(self, state):
        pass


class UniformDensityOnMovedMesh(LoadCapabilities):
    """Load fake: moves the whole EM mesh with the block (air smoothed), applies f = const on the block."""

    def __init__(self, x, cells, block_cells, block_nodes, fixed_nodes, f):
        self.cells, self.block_cells, self.block_nodes, self.f = cells, block_cells, block_nodes, f
        self.mover = MeshMover(x, cells, np.concatenate([block_nodes, fixed_nodes]), min_quality=0.1)
        self.qmin = 1.0

    def load(self, t0, t1, t_mid, mech):
        xb = mech.positions()["block"]
        u = np.zeros((self.mover.x_ref.shape[0], 2))
        u[self.block_nodes] = xb - mech.x0
        x = self.mover.moved(u)
        self.qmin = min(self.qmin, triangle_quality(x, self.cells).min())
        cells = self.cells[self.block_cells]
        f = np.repeat(self.f[None, :], len(cells), axis=0)
        F = cell_to_nodal_forces(x, cells, f, axisymmetric=True)
        ref = cell_force_integral(x, cells, f, axisymmetric=True)
        return LoadStep({"block": F[self.block_nodes]}, ref, {})

    def state_dict(self):
        return {}

    def load_state_dict(self, state):
        pass


def test_prescribed_motion_moves_mesh_and_conserves_force():
    """A conductor block oscillating in an axisymmetric air box: the mesh follows without losing
    quality, the ledger stays at round-off, and the total axial force of a uniform density
    f_z on a translated ring is f_z·V, V = π (b² − a²) h (translation along z keeps V)."""
    x, cells = rect_mesh(20, 20, 0.0, 0.1, -0.05, 0.05)
    cen = x[cells].mean(1)
    a, b, h = 0.03, 0.06, 0.01
    block_cells = np.flatnonzero((cen[:, 0] > a) & (cen[:, 0] < b) & (np.abs(cen[:, 1]) < h / 2))
    block_nodes = np.unique(cells[block_cells])
    outer = np.flatnonzero((x[:, 0] < 1e-12) | (x[:, 0] > 0.1 - 1e-12) | (np.abs(x[:, 1]) > 0.05 - 1e-12))
    mech = PrescribedMotion(x[block_nodes], 1e-6, amplitude=0.01, omega=2 * math.pi * 1e3)
    f = np.array([0.0, 2.0e9])
    load = UniformDensityOnMovedMesh(x, cells, block_cells, block_nodes, outer, f)
    loop = StaggeredLoop(load, mech, n=25)
    rows = []
    loop.run_until(0.5e-3, rows.append)
    V = math.pi * (b * b - a * a) * h
    assert loop.counters.em_steps == 20
    assert loop.counters.ledger_max < 1e-12
    assert all(r["force_y_N"] == pytest.approx(f[1] * V, rel=1e-12) for r in rows)
    assert 0.3 < load.qmin  # 10 mm amplitude on 5 mm cells: smoothed, never degenerate


def test_harmonic_extension_reproduces_linear_fields():
    """A linear boundary displacement extends to the same linear field inside (P1 Laplace is exact
    for linear functions); with the x component prescribed on the boundary only and y also on an
    inner line, each component is solved on its own."""
    x, cells = rect_mesh(9, 7, 0.0, 0.09, -0.03, 0.04, jitter=0.3)
    boundary = np.flatnonzero(np.isclose(x[:, 0], 0.0) | np.isclose(x[:, 0], 0.09)
                              | np.isclose(x[:, 1], -0.03) | np.isclose(x[:, 1], 0.04))
    lin = np.stack([1e-3 + 0.02 * x[:, 0] - 0.01 * x[:, 1], -2e-3 + 0.03 * x[:, 0] + 0.015 * x[:, 1]], axis=1)
    mover = MeshMover(x, cells, (boundary, boundary))
    assert np.allclose(mover.displace(lin), lin, atol=1e-15)
    partial = MeshMover(x, cells, (boundary, boundary[::2]))
    u = partial.displace(lin)
    assert np.allclose(u[:, 0], lin[:, 0], atol=1e-15)


def test_inverted_element_never_passes():
    """Moving a node through its neighbour raises before the mesh could reach GetDP."""
    x, cells = rect_mesh(4, 4)
    boundary = np.flatnonzero((x[:, 0] % 1.0 < 1e-12) | (x[:, 1] % 1.0 < 1e-12))
    mover = MeshMover(x, cells, boundary)
    u = np.zeros((len(x), 2))
    u[1, 0] = 2.0  # boundary node (0, 0.25) pushed far across the box
    with pytest.raises(MeshQualityError):
        mover.moved(u)


def test_adaptive_n_grows_after_the_pulse_and_stays_accurate():
    """A sin² pulse (1 ms) then no force: adaptive n doubles once the resultant stops changing.
    Reference: n = 1 with a 10× smaller step (converged to 1e-12 here)."""
    from pulseform.orchestrator.coupling.loop import LoopOptions

    w = 2 * math.pi * 1e3
    force = lambda t: 100.0 * math.sin(w * t) ** 2 if t < math.pi / w else 0.0  # noqa: E731

    def run(opts, dt):
        body = RigidAxialBody("b", NODES, 1.0, dt=dt)
        loop = StaggeredLoop(AnalyticForce("b", 3, force), body, opts)
        loop.run_until(5e-3)
        return body.y, loop.counters

    y_ref, _ = run(LoopOptions(n=1, n_min=1, n_max=1), 1e-7)
    y_fix, c_fix = run(LoopOptions(n=1, n_min=1, n_max=1), 1e-6)
    y_ad, c_ad = run(LoopOptions(n=1, adaptive=True, n_min=1, n_max=512, adapt_tol=0.05), 1e-6)
    assert c_ad.n == 512
    assert c_ad.em_steps < 0.1 * c_fix.em_steps
    assert abs(y_ad - y_ref) / abs(y_ref) < 2e-3
    assert abs(y_fix - y_ref) / abs(y_ref) < 1e-9


class Spring(LoadCapabilities):
    """Load fake whose force depends on the geometry: F = −K y (a stiff EM-like feedback)."""

    def __init__(self, K):
        self.K = K

    def load(self, t0, t1, t_mid, mech):
        f = np.zeros((3, 2))
        f[:, 1] = -self.K * mech.positions()["b"][0, 1] / 3
        return LoadStep({"b": f}, None, {})

    def state_dict(self):
        return {}

    def load_state_dict(self, state):
        pass


def test_iterated_coupling_is_stable_where_plain_staggering_is_not():
    """Spring feedback with ω·dt_em = 0.31: forces lagging one EM step pump energy in (amplitude
    grows > 10×); iterating each EM step on its end geometry converges in a few iterations and the
    amplitude never grows (initial amplitude 1 m/s / ω)."""
    from pulseform.orchestrator.coupling.loop import LoopOptions

    omega = 2 * math.pi * 10.0
    amps = {}
    for iterate in (False, True):
        body = RigidAxialBody("b", NODES, 1.0, dt=1e-4, velocity=1.0)
        opts = LoopOptions(n=50, n_min=50, n_max=50, iterate=iterate, iterate_tol=1e-6, iterate_max=30)
        loop = StaggeredLoop(Spring(omega ** 2), body, opts)
        loop.run_until(1.0)
        amps[iterate] = math.hypot(body.y * omega, body.v)
        if iterate:
            assert loop.counters.unconverged == 0 and 2 <= loop.counters.iterations_max <= 30
    assert amps[False] > 10.0
    assert amps[True] <= 1.0
