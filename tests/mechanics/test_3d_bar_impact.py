"""Paper section 4 bar impact in 3D (issue 20): a 4 m bar with a 2 m x 2 m section at 5 m/s
against a frictionless rigid wall (the symmetry plane of the two-body impact at 10 m/s), quarter
model with roller symmetry planes, linear tetrahedra.

References: eq. (6) sigma = rho c v / 2 with the 1D bar speed c = sqrt(E / rho) = 5000 m/s and the
relative speed 10 m/s -> 70 MPa; contact duration 2 L / c = 1.6 ms (paper section 4). Tolerances as
in 2D (tests/mechanics/test_bar_impact.py): 3 % and 4 %; energy balance within 1 %.
"""
import pytest

from pulseform.solvers.dolfinx.verification import PAPER_BAR_MATERIAL as MAT
from pulseform.solvers.dolfinx.verification import bar_impact_3d

RHO_C_V_2 = MAT.density * MAT.bar_wave_speed * 10.0 / 2.0      # 70.0 MPa
DURATION = 2 * 4.0 / MAT.bar_wave_speed                         # 1.6 ms


def _check(r, label):
    m = r["metrics"]
    rate = r["steps"] * r["cells"] / r["loop_s"] / 1e6
    print(f"\n3D bar impact {label}: plateau {m['contact_stress_plateau_MPa']:.2f} MPa "
          f"(std {m['contact_stress_std_MPa']:.2f}) vs {RHO_C_V_2 / 1e6:.2f}, duration "
          f"{m['contact_duration_ms']:.4f} ms vs {DURATION * 1e3:.3f}, energy error "
          f"{m['energy_error_rel']:.2e}; {r['cells']} tets, {r['steps']} steps in {r['loop_s']:.2f} s "
          f"({rate:.1f} M element-updates/s)")
    assert m["contact_stress_plateau_MPa"] == pytest.approx(RHO_C_V_2 / 1e6, rel=0.03)
    assert m["contact_duration_ms"] == pytest.approx(DURATION * 1e3, rel=0.04)
    assert m["energy_error_rel"] < 0.01
    assert r["energies"][-1]["plastic_J"] == 0.0      # 70 MPa is below the 240 MPa yield


def test_reference_values():
    assert RHO_C_V_2 == pytest.approx(70e6, rel=2e-3)
    assert DURATION == pytest.approx(1.6e-3, rel=2e-3)


def test_bar_impact_3d_coarse_quarter():
    """dx = 0.1 m: 40 x 10 x 10 bricks, 24 000 tetrahedra (a few seconds)."""
    _check(bar_impact_3d(nx=40, ny=10, quarter=True), "quarter, dx 0.1 m")


@pytest.mark.slow
def test_bar_impact_3d_fine_quarter():
    """dx = 0.05 m: 80 x 20 x 20 bricks, 192 000 tetrahedra."""
    _check(bar_impact_3d(nx=80, ny=20, quarter=True), "quarter, dx 0.05 m")


@pytest.mark.slow
def test_bar_impact_3d_full_section_equals_quarter():
    """The full 2 m x 2 m section (no symmetry conditions, probe at the face centre) gives the
    quarter model's plateau: the roller planes are symmetry planes."""
    full = bar_impact_3d(nx=40, ny=20, quarter=False)
    _check(full, "full section, dx 0.1 m")
    quarter = bar_impact_3d(nx=40, ny=10, quarter=True)["metrics"]
    assert full["metrics"]["contact_stress_plateau_MPa"] == pytest.approx(
        quarter["contact_stress_plateau_MPa"], rel=0.02)
