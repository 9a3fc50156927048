"""Validation entries judged on a GCI band (orchestrator/workflows/gci_band.py, issue 19).

The band arithmetic is Celik et al. 2008 (tested in test_gci.py against their Table 1); here the
judgement: the reference must lie within the finest level's value ± GCI ± the reference's own
uncertainty. The manufactured sequence φ(h) = 100 + 10 h² on h = 1, 2, 4 (values 110, 140, 260) has the
exact order 2, limit 100 and GCI = 1.25 · (30/110) / 3 = 0.11364, i.e. the band 110 ± 12.5: a reference
of 100 lies in it, one of 90 does not (by 7.5) unless its own uncertainty covers that.
"""
from __future__ import annotations

import json

import pytest

from pulseform.orchestrator.workflows.gci_band import GciBand, band_verdict
from pulseform.orchestrator.workflows.registry import REGISTRY, RUNS, Analytic, Entry, RunOutput, register

H = (1.0, 2.0, 4.0)
PHI = tuple(100.0 + 10.0 * h ** 2 for h in H)  # 110, 140, 260


def test_band_of_the_manufactured_sequence():
    v = band_verdict(H, PHI, 100.0, 0.0)
    assert v.order == pytest.approx(2.0, rel=1e-9) and v.extrapolated == pytest.approx(100.0, rel=1e-9)
    assert v.gci == pytest.approx(1.25 * (30.0 / 110.0) / 3.0, rel=1e-12)
    assert v.allowed == pytest.approx(12.5, rel=1e-9) and v.met and v.convergence == "monotone"


def test_a_band_that_excludes_the_reference_fails():
    v = band_verdict(H, PHI, 90.0, 0.0)
    assert not v.met and v.miss == pytest.approx(7.5, rel=1e-9)
    assert not band_verdict(H, PHI, 90.0, 0.08).met  # 8 % of 90 = 7.2 < 7.5: still outside
    assert band_verdict(H, PHI, 90.0, 0.09).met  # 8.1 > 7.5: the reference's own uncertainty covers it
    assert band_verdict(H, PHI, 90.0, 8.0, error="abs").met and not band_verdict(H, PHI, 90.0, 7.0, error="abs").met


def test_levels_in_any_order_and_only_the_three_finest():
    """A fourth, coarser level (h = 8, off the sequence) does not enter; the order of levels does not matter."""
    v = band_verdict((4.0, 8.0, 1.0, 2.0), (PHI[2], 1e6, PHI[0], PHI[1]), 100.0, 0.0)
    assert v.fine == 110.0 and v.order == pytest.approx(2.0, rel=1e-9)


def test_no_band_without_an_order():
    """Equal fine and medium values leave the order undefined: no band, the entry fails."""
    v = band_verdict(H, (110.0, 110.0, 260.0), 110.0, 0.5)
    assert not v.met and v.convergence == "undefined" and "no GCI band" in v.text()
    with pytest.raises(ValueError):
        band_verdict(H[:2], PHI[:2], 100.0, 0.0)


def _entry(name: str, reference: float, uncertainty: float) -> Entry:
    return Entry(name, "fake", "phi, GCI band", "-", "fake_levels", Analytic(f"{reference:g}", "test", value=reference),
                 0.0, computed=lambda r: r.curves["phi_levels"][1][0],
                 gci=GciBand("phi_levels", uncertainty, "test: a manufactured sequence"))


def test_validation_report_judges_on_the_band(tmp_path, monkeypatch):
    """Through pulseform validate's evaluation: the in-band reference passes although the error (10 %) is far
    above the entry's zero tolerance; the excluded one fails and the report says by how much."""
    from pulseform.orchestrator.workflows.validate import run_validation

    monkeypatch.setitem(RUNS, "fake_levels", lambda work: RunOutput(curves={"phi_levels": (list(H), list(PHI))}))
    inside, outside = _entry("fake.inside", 100.0, 0.0), _entry("fake.outside", 90.0, 0.0)
    out = run_validation([inside, outside], tmp_path / "v")
    assert [o.status for o in out] == ["pass", "FAIL"]
    assert out[0].error == pytest.approx(0.1) and out[0].band["allowed"] == pytest.approx(12.5)
    assert "outside by 7.5" in out[1].message
    rep = json.loads((tmp_path / "v" / "report.json").read_text())
    assert not rep["passed"] and rep["entries"][1]["criterion"] == "reference within computed ± GCI ± 0 %"


def test_registry_refuses_a_band_on_a_bound():
    e = Entry("fake.band_below", "fake", "x", "-", "converge_emf_fixed_disk", Analytic("1", "test", value=1.0), 0.0,
              computed=lambda r: 1.0, compare="below", gci=GciBand("x", 0.0, "test"))
    with pytest.raises(ValueError, match="scalar 'equal' entries only"):
        register(e)
    assert "fake.band_below" not in REGISTRY
