"""Metrics helper on synthetic histories with known answers."""
import numpy as np
import pytest

from pulseform.solvers.dolfinx import bar_impact_metrics, contact_stress_metrics, energy_error_rel


def test_plateau_std_duration_of_a_known_signal():
    t = np.linspace(0.0, 3e-3, 3001)
    on = (t > 0.5e-3) & (t < 2.1e-3)                 # 1.6 ms of contact
    s = np.where(on, 70e6 + 2e6 * np.sin(2 * np.pi * t / 1e-4), 0.0)
    m = contact_stress_metrics(t, s)
    assert m["contact_duration_ms"] == pytest.approx(1.6, abs=2e-3)   # crossing within a sample
    assert m["contact_start_ms"] == pytest.approx(0.5, abs=1e-3)
    assert m["contact_stress_plateau_MPa"] == pytest.approx(70.0, abs=0.05)
    assert m["contact_stress_std_MPa"] == pytest.approx(2.0 / np.sqrt(2), rel=0.02)


def test_metrics_validation_and_energy_error():
    t = np.linspace(0, 1, 11)
    with pytest.raises(ValueError):
        contact_stress_metrics(t, np.zeros(11))            # never in contact
    with pytest.raises(ValueError):
        contact_stress_metrics(t, np.r_[0.0, np.ones(10)])   # never ends
    e = [{"balance_error_J": 1.0}, {"balance_error_J": -3.0}]
    assert energy_error_rel(e[1], 100.0) == 0.03
    s = np.r_[0.0, np.ones(8), 0.0, 0.0] * 1e6
    assert bar_impact_metrics(t, s, e, 100.0)["energy_error_rel"] == 0.03


def test_contact_shorter_than_the_sampling_has_no_plateau():
    """One sample in contact (crossings at 0.2 and 1.8 us): a window of 90-95 % of the contact
    (1.64-1.72 us) holds no sample, so the plateau is NaN, without numpy's "Mean of empty slice"
    warnings on the console (found by the issue-13 fuzz: bars that barely touch)."""
    import warnings

    t = [0.0, 1e-6, 2e-6, 3e-6]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = contact_stress_metrics(t, [0.0, 5e6, 0.0, 0.0], window=(0.9, 0.95), threshold=1e6)
    assert np.isnan(m["contact_stress_plateau_MPa"]) and np.isnan(m["contact_stress_std_MPa"])
    assert m["contact_duration_ms"] == pytest.approx(1.6e-3)
