"""The grid convergence index arithmetic (orchestrator/workflows/gci.py) against

- the worked example of Celik et al., "Procedure for Estimation and Reporting of Uncertainty Due to
  Discretization in CFD Applications", J. Fluids Eng. 130 (2008) 078001, Table 1, first column (three
  grids of 18,000 / 8,000 / 4,500 cells, h = N^(-1/2); φ = 6.063, 5.972, 5.863): p = 1.53,
  φ_ext = 6.1685, e_a = 1.5 %, e_ext = 1.7 %, GCI_fine = 2.2 % (to the table's printed digits);
- manufactured solutions φ(h) = φ0 + c h^p with unequal ratios (the order and φ0 exactly), and the
  oscillatory φ_k = φ0 + c (−1)^k h_k^p (the order exactly, flagged oscillatory);
- a zero difference (undefined) and bad input.
"""
from __future__ import annotations

import math

import pytest

from pulseform.orchestrator.workflows.gci import grid_convergence

CELIK_H = [(1 / 18000) ** 0.5, (1 / 8000) ** 0.5, (1 / 4500) ** 0.5]


def test_celik_2008_table_1():
    r = grid_convergence(CELIK_H, [6.063, 5.972, 5.863])
    assert r.r21 == pytest.approx(1.5) and r.r32 == pytest.approx(4 / 3)
    assert round(r.order, 2) == 1.53
    assert r.extrapolated == pytest.approx(6.1685, abs=5e-4)
    assert round(100 * r.error_approx, 1) == 1.5
    assert round(100 * r.error_extrapolated, 1) == 1.7
    assert round(100 * r.gci_fine, 1) == 2.2
    assert r.convergence == "monotone"


@pytest.mark.parametrize("p", [1.0, 2.0, 2.7])
def test_manufactured_monotone_recovers_order_and_limit(p):
    h = [0.1, 0.15, 0.2]  # r21 = 1.5, r32 = 4/3
    phi = [3.0 + 0.7 * x ** p for x in h]
    r = grid_convergence(h, phi)
    assert r.order == pytest.approx(p, rel=1e-9)
    assert r.extrapolated == pytest.approx(3.0, rel=1e-12)
    assert r.gci_fine == pytest.approx(1.25 * abs(phi[0] - 3.0) / phi[0], rel=1e-9)  # Fs times the true error
    assert r.convergence == "monotone"


def test_manufactured_oscillatory_recovers_order():
    h = [0.1, 0.2, 0.4]
    phi = [3.0 + 0.7 * (-1) ** k * x ** 2 for k, x in enumerate(h)]
    r = grid_convergence(h, phi)
    assert r.convergence == "oscillatory"
    assert r.order == pytest.approx(2.0, rel=1e-12)


def test_zero_difference_is_undefined():
    r = grid_convergence([1.0, 2.0, 4.0], [5.0, 5.0, 5.2])
    assert r.convergence == "undefined" and math.isnan(r.order) and math.isnan(r.gci_fine)


@pytest.mark.parametrize("h,phi", [([1, 2], [1, 2]), ([2, 1, 3], [1, 2, 3]), ([1, 2, 3], [1, float("nan"), 3])])
def test_bad_input(h, phi):
    with pytest.raises(ValueError):
        grid_convergence(h, phi)


def test_grid_independent_quantity_is_constant():
    r = grid_convergence([1.0, 2.0, 4.0], [17.1744, 17.1744, 17.1744])
    assert r.convergence == "constant" and r.gci_fine == 0.0 and r.extrapolated == 17.1744
