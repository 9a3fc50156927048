"""Cell force density -> consistent nodal forces: conservation and exact volumes/pressures."""

import numpy as np
import pytest

from pulseform.orchestrator.coupling import transfer as tr

from .meshes import rect_mesh


@pytest.mark.parametrize("axisymmetric", [False, True])
def test_ledger_is_round_off(axisymmetric):
    """Σ nodal F equals Σ f_e V_e to round-off (the issue asks <= 1e-10 on shared nodes)."""
    x, cells = rect_mesh(17, 5, 0.05, 0.06, 0.0, 0.001, jitter=0.3)
    f = np.random.default_rng(1).normal(size=(len(cells), 2)) * 1e9
    F = tr.cell_to_nodal_forces(x, cells, f, axisymmetric=axisymmetric, thickness=0.3)
    ref = tr.cell_force_integral(x, cells, f, axisymmetric=axisymmetric, thickness=0.3)
    assert tr.ledger_error(F, ref) < 1e-12


def test_axisymmetric_volume_is_exact_ring():
    """Pappus: a rectangle a <= r <= b, 0 <= z <= h revolves into π (b² − a²) h."""
    a, b, h = 0.0105, 0.0125, 0.03
    x, cells = rect_mesh(4, 9, a, b, 0.0, h, jitter=0.25)
    v = tr.cell_volumes(x, cells, axisymmetric=True).sum()
    assert v == pytest.approx(np.pi * (b * b - a * a) * h, rel=1e-13)


def test_axisymmetric_consistent_weights_integrate_r():
    """Σ_i W_i r_i = ∫ r dV = 2π ∫ r² dA = 2π h (b³ − a³)/3 for P1 (exact: r·N_i integrand is quadratic)."""
    a, b, h = 0.01, 0.02, 0.005
    x, cells = rect_mesh(6, 3, a, b, 0.0, h)
    w = tr.nodal_volume_weights(x, cells, axisymmetric=True)
    # W_i = ∫ N_i 2πr dA, so Σ_i W_i r_i = ∫ (Σ_i N_i r_i) 2πr dA = 2π ∫ r² dA (P1 interpolates r exactly).
    got = (w * x[cells, 0]).sum()
    assert got == pytest.approx(2 * np.pi * h * (b ** 3 - a ** 3) / 3, rel=1e-12)


def test_pressure_inside_a_tube_pushes_outward():
    """p on the inner face r = a of a ring of height h: Σ F_r = p 2π a h, Σ F_z = 0."""
    a, b, h, p = 0.0105, 0.0125, 0.02, 350e6
    x, cells = rect_mesh(3, 8, a, b, 0.0, h)
    facets = tr.boundary_facets(cells, x)
    inner = facets[np.isclose(x[facets[:, 0], 0], a) & np.isclose(x[facets[:, 1], 0], a)]
    F = tr.pressure_to_nodal_forces(x, inner, p, axisymmetric=True)
    assert F[:, 0].sum() == pytest.approx(p * 2 * np.pi * a * h, rel=1e-13)
    assert abs(F[:, 1].sum()) < 1e-9 * p * a * h


def test_pressure_on_top_of_plate_planar():
    """p on the top y = t of a plate w wide, depth d: Σ F_y = −p w d."""
    x, cells = rect_mesh(10, 2, 0.0, 0.28, 0.0, 0.001)
    facets = tr.boundary_facets(cells, x)
    top = facets[np.isclose(x[facets, 1], 0.001).all(axis=1)]
    F = tr.pressure_to_nodal_forces(x, top, 30e6, axisymmetric=False, thickness=0.5)
    assert F[:, 1].sum() == pytest.approx(-30e6 * 0.28 * 0.5, rel=1e-13)
    assert abs(F[:, 0].sum()) < 1e-6


def test_projection_identity_and_convergence():
    """Same mesh: identity. Non-matching meshes: the ledger error of a smooth field converges at
    least at first order in h (sampling a piecewise-constant field at the target's quadrature
    points is first-order accurate; the fit over four refinements must show it)."""
    x, cells = rect_mesh(8, 4, 0.0, 1.0, 0.0, 0.5, jitter=0.2)
    f = np.random.default_rng(2).normal(size=(len(cells), 2))
    assert np.allclose(tr.project_cell_field(x, cells, f, x, cells), f, rtol=1e-14, atol=0)
    errs = []
    for n in (8, 16, 32, 64):
        xs, cs = rect_mesh(n, n // 2, 0.0, 1.0, 0.0, 0.5, jitter=0.2, seed=n)
        fs = np.stack([np.sin(3 * xs[cs].mean(1)[:, 0]), np.cos(2 * xs[cs].mean(1)[:, 1])], axis=1)
        xd, cd = rect_mesh(n + 3, n // 2 + 1, 0.0, 1.0, 0.0, 0.5)
        fd = tr.project_cell_field(xs, cs, fs, xd, cd)
        ref = tr.cell_force_integral(xs, cs, fs, axisymmetric=False)
        got = tr.cell_to_nodal_forces(xd, cd, fd, axisymmetric=False)
        errs.append(tr.ledger_error(got, ref))
    rate = np.polyfit(np.log([1 / 8, 1 / 16, 1 / 32, 1 / 64]), np.log(errs), 1)[0]
    assert rate >= 1.0, (errs, rate)
