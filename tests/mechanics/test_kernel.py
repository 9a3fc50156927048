"""Element-kernel checks: compiled vs numpy twin, patch test, objectivity under 90 deg rotation."""
import math
import subprocess
import sys

import numpy as np
import pytest

from pulseform.solvers.dolfinx import BodySpec, ExplicitSolver, Material
from pulseform.solvers.dolfinx.kernels import WORK_SIZE, element_step, pack_parameters
from pulseform.solvers.dolfinx.kernels import (MODE_AXISYMMETRIC, MODE_PLANE_STRAIN,
                                               MODE_PLANE_STRESS)
from pulseform.solvers.dolfinx.reference_kernel import element_step_numpy

from mech_helpers import distorted_square

STEEL = Material(7800.0, 80e9, 170e9, 300e6, 1e9)
ALL = lambda x: np.full(x.shape[1], True)  # noqa: E731


def _body(formulation, **kw):
    msh = distorted_square(origin=(0.5, 0.0) if formulation == "axisymmetric" else (0.0, 0.0))
    return ExplicitSolver([BodySpec("b", msh, STEEL, **kw)], formulation=formulation,
                          comm=msh.comm)


@pytest.mark.parametrize("mode", [MODE_PLANE_STRESS, MODE_PLANE_STRAIN, MODE_AXISYMMETRIC])
def test_compiled_kernel_matches_numpy_twin(mode):
    """Same algorithm, two implementations: agreement to round-off, in the plastic range."""
    formulation = {0: "plane_stress", 1: "plane_strain", 2: "axisymmetric"}[mode]
    s = _body(formulation)
    b = s.bodies["b"]
    rng = np.random.default_rng(0)
    v = rng.normal(scale=20.0, size=b.v.shape)
    dt = 0.2 * s.stable_time_step()
    x = b.x + dt * v
    stress0 = rng.normal(scale=200e6, size=b.cell_stress.shape)
    if mode == MODE_PLANE_STRESS:
        stress0[:, 2] = 0.0
    prm = pack_parameters(STEEL, mode, 1.0, 0.06, 1.2, True)
    out = []
    for kern in (lambda *a: element_step(*a, np.empty(WORK_SIZE), np.empty(0)), element_step_numpy):
        st, ep, f, acc = stress0.copy(), np.full(len(stress0), 0.01), np.zeros_like(v), np.zeros(3)
        d = kern(b.cells, x, v, dt, prm, st, ep, f, acc)
        out.append((st, ep, f, acc, d))
    (s1, e1, f1, a1, d1), (s2, e2, f2, a2, d2) = out
    assert (e1 > 0.01).sum() > 10          # the check exercises the radial return
    scale = np.abs(s1).max()
    assert np.abs(s1 - s2).max() <= 1e-10 * scale
    assert np.abs(e1 - e2).max() <= 1e-12
    assert np.abs(f1 - f2).max() <= 1e-10 * np.abs(f1).max()
    assert a1[0] == pytest.approx(a2[0], rel=1e-10) and a1[1] == pytest.approx(a2[1], rel=1e-10)
    assert d1 == pytest.approx(d2, rel=1e-12)
    if mode == MODE_PLANE_STRESS:
        assert np.all(s1[:, 2] == 0.0)


@pytest.mark.parametrize("formulation", ["plane_strain", "plane_stress", "axisymmetric"])
def test_patch_test_homogeneous_motion(formulation):
    """Linear velocity field on a distorted mesh (all nodes prescribed): every cell gets the same
    stress, and a uniform stress gives zero internal force on interior nodes (planar), to
    round-off. Reference: exactness of P1 for linear fields (patch test)."""
    Gd = np.array([[2.0, 0.7], [-0.4, -1.1]])      # 1/s
    if formulation == "axisymmetric":
        Gd[0, 1] = 0.0     # homogeneous in 3D needs u_r proportional to r (uniform hoop strain)

    def motion(X, t):
        F = np.eye(2) + t * Gd
        return X @ F.T

    s = _body(formulation, motion=((ALL, motion),))
    b = s.bodies["b"]
    dt = 0.5 * s.stable_time_step()
    s.advance(dt, 40)
    st = b.cell_stress
    scale = np.abs(st).max()
    assert scale > 1e6
    assert np.abs(st - st.mean(axis=0)).max() <= 1e-9 * scale
    if formulation != "axisymmetric":
        f = np.zeros_like(b.v)
        prm = pack_parameters(STEEL, s.mode, 1.0, 0.06, 1.2, False)
        element_step(b.cells, b.x, np.zeros_like(b.v), 0.0, prm, st.copy(), b.eps_p.copy(), f,
                     np.zeros(3), np.empty(WORK_SIZE), np.empty(0))
        bnd = np.unique(b.segments)
        interior = np.setdiff1d(np.arange(b.n_local), bnd)
        assert interior.size > 10
        fscale = np.abs(f).max()
        assert np.abs(f[interior]).max() <= 1e-10 * fscale


@pytest.mark.parametrize("kernel", ["numba", "numpy"])
def test_rigid_rotation_90deg_keeps_invariants(kernel):
    """A prestressed body rotated rigidly by 90 deg (positions prescribed exactly): the stress must
    rotate with it, invariants unchanged to 1e-6 (objectivity, Jaumann / Hughes-Winget)."""
    sig0 = (150e6, -60e6, 20e6, 45e6)
    T = 1e-3
    c = np.array([0.5, 0.5])

    def motion(X, t):
        th = 0.5 * math.pi * min(t / T, 1.0) ** 2
        R = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
        return c + (X - c) @ R.T

    msh = distorted_square()
    s = ExplicitSolver([BodySpec("b", msh, STEEL, motion=((ALL, motion),), initial_stress=sig0)],
                       formulation="plane_strain", comm=msh.comm, kernel=kernel)
    b = s.bodies["b"]
    n = 400
    s.advance(T / n, n)
    st = b.cell_stress
    sx, sy, sz, sxy = sig0
    # after +90 deg: sigma' = R sigma R^T -> xx' = yy, yy' = xx, xy' = -xy
    expect = np.array([sy, sx, sz, -sxy])
    assert np.abs(st - expect).max() <= 1e-6 * np.abs(sig0).max()
    tr = st[:, :3].sum(axis=1)
    det2 = st[:, 0] * st[:, 1] - st[:, 3] ** 2
    assert np.abs(tr - (sx + sy + sz)).max() <= 1e-6 * abs(sx + sy + sz)
    assert np.abs(det2 - (sx * sy - sxy ** 2)).max() <= 1e-6 * abs(sx * sy - sxy ** 2)
    assert np.abs(b.von_mises - b.von_mises[0]).max() <= 1e-6 * b.von_mises[0]
    assert np.all(b.eps_p == 0.0)


def test_numba_cache_works_from_another_directory(tmp_path):
    """The kernels import (cache=True) and run from an unrelated working directory."""
    code = ("import numpy as np\n"
            "from pulseform.solvers.dolfinx.kernels import element_critical_dt, pack_parameters\n"
            "from pulseform.solvers.dolfinx import Material\n"
            "m = Material(1.0, 1.0, 1.0, 1.0, 0.0)\n"
            "p = pack_parameters(m, 1, 1.0, 0.0, 0.0, False)\n"
            "x = np.array([[0., 0.], [1., 0.], [0., 1.]])\n"
            "c = np.array([[0, 1, 2]], dtype=np.int32)\n"
            "print(element_critical_dt(c, x, p))\n")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    # 2A / longest edge = 1 / sqrt(2); c = sqrt((1 + 4/3) / 1)
    assert float(r.stdout.strip()) == pytest.approx(1 / math.sqrt(2) / math.sqrt(7 / 3), rel=1e-12)


@pytest.mark.parametrize("mode", [MODE_PLANE_STRESS, MODE_PLANE_STRAIN, MODE_AXISYMMETRIC])
def test_return_lands_on_the_yield_surface(mode):
    """After a plastic step every yielding cell satisfies sigma_vm = sigma_0 + A eps_p (and
    sigma_zz = 0 in plane stress: the secant iteration on d_zz converged)."""
    formulation = {0: "plane_stress", 1: "plane_strain", 2: "axisymmetric"}[mode]
    s = _body(formulation)
    b = s.bodies["b"]
    rng = np.random.default_rng(1)
    v = rng.normal(scale=50.0, size=b.v.shape)
    dt = 0.3 * s.stable_time_step()
    st = np.zeros_like(b.cell_stress)
    st[:, :2] = rng.normal(scale=250e6, size=(len(st), 2))
    st[:, 3] = rng.normal(scale=100e6, size=len(st))
    ep = np.full(len(st), 0.02)
    prm = pack_parameters(STEEL, mode, 1.0, 0.06, 1.2, False)
    element_step(b.cells, b.x + dt * v, v, dt, prm, st, ep, np.zeros_like(v), np.zeros(3),
                 np.empty(WORK_SIZE), np.empty(0))
    p = st[:, :3].mean(axis=1)
    d = st[:, :3] - p[:, None]
    vm = np.sqrt(1.5 * ((d ** 2).sum(axis=1) + 2 * st[:, 3] ** 2))
    yielded = ep > 0.02
    assert yielded.sum() > 10
    sy = STEEL.yield_stress + STEEL.hardening_modulus * ep[yielded]
    assert np.allclose(vm[yielded], sy, rtol=1e-9)
    assert np.all(vm[~yielded] <= (STEEL.yield_stress + STEEL.hardening_modulus * 0.02) * (1 + 1e-12))
    if mode == MODE_PLANE_STRESS:
        assert np.all(st[:, 2] == 0.0)


@pytest.mark.parametrize("mode", [MODE_PLANE_STRESS, MODE_PLANE_STRAIN, MODE_AXISYMMETRIC])
@pytest.mark.parametrize("rate", [False, True])
def test_batched_kernel_equals_the_scalar_cell_update(mode, rate):
    """The vectorised batches (SoA scratch, selects instead of branches) give each cell what the
    scalar per-cell update gives, to round-off: several batches and a partial one, an inverted
    cell in the middle (first inverted index reported, its stress and plastic strain untouched,
    no force), plastic cells (and the plane-stress secant redo), a rate law (all scalar)."""
    from pulseform.solvers.dolfinx.element_math import BATCH, OUT_ROWS, cell_update
    from pulseform.solvers.dolfinx.material import CowperSymonds

    mat = Material(7800.0, 80e9, 170e9, 300e6, 1e9, rate_law=CowperSymonds(6500.0, 4.0)) if rate else STEEL
    rng = np.random.default_rng(3)
    nc = 2 * BATCH + 37
    x = np.zeros((3 * nc, 2))
    base = np.array([[0.0, 0.0], [1e-3, 0.0], [0.0, 1e-3]])
    for e in range(nc):
        x[3 * e:3 * e + 3] = base + rng.normal(scale=1e-4, size=(3, 2)) + [0.01 + 2e-3 * e, 0.0]
    cells = np.arange(3 * nc, dtype=np.int32).reshape(nc, 3)
    bad = BATCH + 5
    x[3 * bad + 1], x[3 * bad + 2] = x[3 * bad + 2].copy(), x[3 * bad + 1].copy()   # inverted
    v = rng.normal(scale=30.0, size=x.shape)
    dt = 2e-8
    stress0 = rng.normal(scale=800e6 if rate else 250e6, size=(nc, 4))
    if mode == MODE_PLANE_STRESS:
        stress0[:, 2] = 0.0
    prm = pack_parameters(mat, mode, 1e-3, 0.06, 1.2, True)
    st, ep, f, acc = stress0.copy(), np.full(nc, 0.01), np.zeros_like(x), np.zeros(3)
    d = element_step(cells, x, v, dt, prm, st, ep, f, acc, np.empty(WORK_SIZE), np.empty(0))
    assert acc[2] == bad
    assert np.array_equal(st[bad], stress0[bad]) and ep[bad] == 0.01 and not f[3 * bad:3 * bad + 3].any()
    assert (ep > 0.01).sum() > 20
    out = np.zeros(OUT_ROWS)
    dmin, wp, wv = np.inf, 0.0, 0.0
    for e in range(nc):
        if e == bad:
            continue
        p = x[cells[e]].ravel()
        q = v[cells[e]].ravel()
        cell_update(*p, *q, *stress0[e], 0.01, dt, prm, out, -1.0)  # T given: the compiled variant the kernels use
        scale = np.abs(out[:4]).max()
        assert np.abs(st[e] - out[:4]).max() <= 1e-12 * scale
        assert ep[e] == pytest.approx(out[4], rel=1e-12, abs=1e-15)
        fe = out[5:11].reshape(3, 2).copy()
        fe[:, 0] += out[11]
        assert np.abs(f[cells[e]] - fe).max() <= 1e-12 * np.abs(fe).max()
        dmin = min(dmin, out[12])
        wp += out[13]
        wv += out[14]
    assert d == pytest.approx(dmin, rel=1e-12)
    assert acc[0] == pytest.approx(wp, rel=1e-12) and acc[1] == pytest.approx(wv, rel=1e-12)
