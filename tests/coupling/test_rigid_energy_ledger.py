"""The energy ledger of a rigid body under an AC force (issue 32, item 6).

A levitated plate (m = 50 g) under gravity and the Lorentz force of a 50 Hz coil current, F = 2 m g sin²(ωt),
ω = 2π·50 Hz: its mean holds the weight, a = −g cos(2ωt), and from rest the motion is periodic at once:
v = −g sin(2ωt)/(2ω). The work of the force and gravity is then exactly the kinetic energy,
W(t) = ½ m v(t)². 85 periods of the current (170 force cycles, the issue's 1.7 s), 40 / 80 / 160 EM steps per
period, n = 1: the real rigid-body participant (:class:`RigidMechanics` over ``RigidBody``) and the loop under the
analytic force fake (:class:`AnalyticForce`, evaluated at the centre of each step's impulse window). Seconds.

The ledger before (Σ F·Δu of the held force, no term where the force changes: the explicit solver books that
switch, the rigid body did not) drifted at first order over the cycles: W = 1.03 mJ against the exact 6.09 µJ,
``energy_error_rel`` 0.994 (the issue's 0.99). With the switch booked, the balance closes to round-off and W is
the scheme's second-order work.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.coupling.fakes import AnalyticForce
from pulseform.orchestrator.coupling.loop import LoopOptions, StaggeredLoop
from pulseform.orchestrator.mech.rigid import RigidMechanics
from pulseform.orchestrator.run.driver import mech_metrics
from pulseform.orchestrator.run.history import History
from pulseform.orchestrator.run.summary import headline
from pulseform.solvers.dolfinx.rigid import RigidBody

REPO = Path(__file__).resolve().parents[2]
M, G, F_HZ = 0.05, 9.81, 50.0
W = 2 * math.pi * F_HZ
NODES = np.array([[0.0, 0.0], [0.02, 0.0], [0.02, 0.002]])


def _levitate(steps_per_period: int, periods: float = 85.125):
    """Run the plate to ``periods`` periods of the current (85 + 1/8: sin(2ωt) = 1 at the end, the kinetic
    energy at its largest). Returns the history (as the driver records it), the ledger at the end, the work of
    the old rule and the end time."""
    dt = 1.0 / F_HZ / steps_per_period
    body = RigidBody("plate", NODES, M, gravity=(0.0, -G))
    mech = RigidMechanics([body], dt)
    loop = StaggeredLoop(AnalyticForce("plate", len(NODES), lambda t: 2 * M * G * math.sin(W * t) ** 2), mech,
                         LoopOptions(n=1))
    history = History(Path("unused"))
    old = [0.0]

    def record(row=None):
        e = mech.energies()
        history.record({"time_s": mech.time, "energy_kinetic_J": e["kinetic_J"],
                        "energy_external_work_J": e["external_work_J"]})

    record()
    end = periods / F_HZ
    while mech.time < end * (1 - 1e-12):
        u = body.u[1]
        row = loop.em_step(end)
        old[0] += (row["force_y_N"] - M * G) * (body.u[1] - u)   # the old rule: f·Δu of the held force only
        record(row)
    e = mech.energies()
    e["balance_error_J"] = e["kinetic_J"] + e["stop_dissipated_J"] - e["external_work_J"]
    return history, e, old[0], mech.time


def _exact_work(t: float) -> float:
    return 0.5 * M * (G / (2 * W) * math.sin(2 * W * t)) ** 2


def test_ledger_closes_and_its_work_converges_at_second_order():
    err_new, err_old = [], []
    for spp in (40, 80, 160):
        history, e, old, t = _levitate(spp)
        exact = _exact_work(t)
        err_new.append(abs(e["external_work_J"] - exact) / exact)
        err_old.append(abs(old - exact) / exact)
        m = mech_metrics(None, None, history, e)
        old_e = dict(e, external_work_J=old, balance_error_J=e["kinetic_J"] - old)
        old_rel = abs(old_e["balance_error_J"]) / max(abs(old), history.column("energy_kinetic_J")[0])
        print(f"\n{spp} steps/period: W {e['external_work_J']:.6g} J (old {old:.6g}), exact {exact:.6g} J; "
              f"energy_error_rel {m['energy_error_rel']:.3g} (old rule, old scale: {old_rel:.3g})")
        assert m["energy_error_rel"] < 1e-9          # measured 5e-15 .. 1.2e-14: round-off
        assert old_rel > 0.95                        # what the issue read (0.99): the drift, not the physics
    new_order = [math.log2(a / b) for a, b in zip(err_new, err_new[1:])]
    old_order = [math.log2(a / b) for a, b in zip(err_old, err_old[1:])]
    print(f"work error new {err_new} (orders {new_order}), old {err_old} (orders {old_order})")
    assert all(1.9 < p < 2.1 for p in new_order)    # measured 2.00, 2.00 (8.2 %, 2.1 %, 0.51 %)
    assert all(0.9 < p < 1.1 for p in old_order)    # measured 1.00, 1.00 (16800 %, 8400 %, 4200 %)
    assert err_new[0] < 0.1 and err_old[-1] > 10.0


def test_energy_error_is_relative_to_the_largest_work_not_the_net_work_at_the_end():
    """Ending where the plate is at rest (a whole number of force cycles), the net work is ~0: the metric is
    relative to the largest work of the run, so round-off reads as round-off."""
    history, e, _, t = _levitate(40, periods=85.0)
    assert abs(e["external_work_J"]) < 1e-3 * history.column("energy_external_work_J").max()
    assert mech_metrics(None, None, history, e)["energy_error_rel"] < 1e-9


def test_summary_of_an_ac_levitation_says_what_the_loads_did():
    """"peak kinetic energy 38 % of the external work" compared the peak with the net work at the end; under
    an AC force the summary gives the peak kinetic energy in J, when, and how far the loads' work swung."""
    case, _ = load_case(REPO / "cases" / "jumping_ring")
    history, e, _, t = _levitate(40)
    lines = {h.label: h for h in headline(case, {}, history)}
    ke = lines["peak kinetic energy"]
    peak = history.column("energy_kinetic_J").max()
    assert ke.unit == "µJ" and ke.value == pytest.approx(peak * 1e6)
    assert "%" not in ke.text() and "the loads put in and took back work (up to" in ke.text()
    assert "plastic work" not in lines
