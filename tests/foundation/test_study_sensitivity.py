"""Issue 36: the arithmetic of a study's answer and its designs (orchestrator/workflows/sensitivity.py, designs.py,
study_answer.py), on functions whose answers are known in closed form."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pulseform.orchestrator.workflows.designs import DesignError, design_points, parse_params
from pulseform.orchestrator.workflows.sensitivity import QuadraticSurface, sobol_indices, standardised_regression
from pulseform.orchestrator.workflows.study_answer import AnswerError, best_member, parse_constraint, parse_objective
from pulseform.orchestrator.workflows.sweep import Member


def test_sobol_indices_of_the_ishigami_function_within_2_percent():
    """Ishigami f = sin x1 + a sin² x2 + b x3⁴ sin x1 on [-π, π]³, a = 7, b = 0.1: V = a²/8 + bπ⁴/5 + b²π⁸/18 + 1/2,
    V1 = (1 + bπ⁴/5)²/2, V2 = a²/8, V3 = 0, V13 = 8b²π⁸/225 (Ishigami & Homma 1990; Sobol' & Levitan 1999):
    S = (0.3139, 0.4424, 0), S_T = (0.5576, 0.4424, 0.2437). Each estimate within 2 % (0.02 absolute for S3 = 0)."""
    a, b = 7.0, 0.1
    f = lambda x: np.sin(x[:, 0]) + a * np.sin(x[:, 1]) ** 2 + b * x[:, 2] ** 4 * np.sin(x[:, 0])  # noqa: E731
    v = a ** 2 / 8 + b * np.pi ** 4 / 5 + b ** 2 * np.pi ** 8 / 18 + 0.5
    v1, v2, v13 = 0.5 * (1 + b * np.pi ** 4 / 5) ** 2, a ** 2 / 8, 8 * b ** 2 * np.pi ** 8 / 225
    s_exact, st_exact = np.array([v1, v2, 0.0]) / v, np.array([v1 + v13, v2, v13]) / v
    s, st = sobol_indices(f, [-np.pi] * 3, [np.pi] * 3, n=2 ** 14)
    assert abs(s[0] / s_exact[0] - 1) < 0.02 and abs(s[1] / s_exact[1] - 1) < 0.02, s
    assert abs(s[2]) < 0.02, s
    assert np.all(np.abs(st / st_exact - 1) < 0.02), (st, st_exact)


def test_standardised_regression_coefficients_of_a_linear_function():
    """y = 3 x1 - x2 + 0.5 x3 + 0 x4: SRC_i = b_i σ_i / σ_y exactly and R² = 1 (no noise)."""
    x = np.random.default_rng(0).uniform(size=(40, 4)) * [1.0, 2.0, 3.0, 1.0]
    coef = np.array([3.0, -1.0, 0.5, 0.0])
    y = 2.0 + x @ coef
    src, r2 = standardised_regression(x, y)
    np.testing.assert_allclose(src, coef * x.std(axis=0) / y.std(), rtol=1e-10, atol=1e-12)
    assert r2 == pytest.approx(1.0, abs=1e-12)
    noisy = y + np.random.default_rng(1).normal(scale=2.0, size=len(y))
    assert standardised_regression(x, noisy)[1] < 0.9  # noise lowers the fit's R²


def test_quadratic_surface_leave_one_out_equals_refitting_without_each_member():
    """The PRESS residuals are the leave-one-out errors: compared with n refits, each without one sample."""
    rng = np.random.default_rng(3)
    x = rng.uniform(-1, 2, size=(25, 3))
    y = 1 + x[:, 0] ** 2 - 2 * x[:, 0] * x[:, 1] + 0.3 * x[:, 2] + rng.normal(scale=0.1, size=25)
    surf = QuadraticSurface.fit(x, y, lo=[-1] * 3, hi=[2] * 3)
    assert surf.degree == 2
    errs = [y[i] - QuadraticSurface.fit(np.delete(x, i, 0), np.delete(y, i), lo=[-1] * 3, hi=[2] * 3)(x[i:i + 1])[0]
            for i in range(len(y))]
    assert surf.loo_rmse == pytest.approx(math.sqrt(np.mean(np.square(errs))), rel=1e-9)
    assert surf.loo_max == pytest.approx(max(abs(e) for e in errs), rel=1e-9)
    exact = QuadraticSurface.fit(x, 1 + x[:, 0] ** 2 - 2 * x[:, 0] * x[:, 1] + 0.3 * x[:, 2])
    assert exact.loo_rmse < 1e-9  # a quadratic is reproduced exactly
    few = QuadraticSurface.fit(x[:8], y[:8])
    assert few.degree == 1  # 10 quadratic terms need at least 12 samples


def test_latin_hypercube_and_sobol_designs():
    params = parse_params(["em.circuit.voltage=4000:8000", "geometry.coil_gap=1e-3:3e-3", "geometry.turns=3:6"])
    lhs = design_points(params, sample=16, design="lhs", seed=4)
    assert lhs == design_points(params, sample=16, design="lhs", seed=4)  # the same seed, the same members
    assert lhs != design_points(params, sample=16, design="lhs", seed=5)
    volts = sorted(float(p["em.circuit.voltage"]) for p in lhs)
    # a Latin hypercube: exactly one point in each of the 16 equal strata of every range
    assert [int((v - 4000) / 250) for v in volts] == list(range(16))
    assert {p["geometry.turns"] for p in lhs} <= {"3", "4", "5", "6"}  # whole-number range: whole numbers
    sobol8, sobol16 = (design_points(params, sample=n, design="sobol", seed=2) for n in (8, 16))
    assert sobol16[:8] == sobol8  # doubling a Sobol study keeps its members
    grid = design_points(parse_params(["time.cfl=0.2,0.4", "bodies.left.initial_velocity=[1,0],[2,0],[3,0]"]))
    assert len(grid) == 6 and grid[1] == {"time.cfl": "0.2", "bodies.left.initial_velocity": "[2,0]"}
    with pytest.raises(DesignError, match="--sample"):
        design_points(params)  # a range has no values of its own
    with pytest.raises(DesignError, match="lo < hi"):
        parse_params(["time.cfl=0.9:0.3"])
    with pytest.raises(DesignError, match="allowed: lhs, sobol"):
        design_points(params, sample=4, design="grid")


def test_best_member_under_constraints():
    ms = [Member(i, {"k": str(i)}, Path(f"m{i}"), returncode=rc, metrics=met) for i, (rc, met) in enumerate([
        (0, {"defl": 5.0, "stress": 100.0}), (0, {"defl": 9.0, "stress": 400.0}), (0, {"defl": 7.0, "stress": 250.0}),
        (1, {"defl": 99.0, "stress": 1.0}), (0, {"defl": 8.0})])]
    best = best_member(ms, parse_objective("max:defl"), [parse_constraint("stress<300")])
    assert best["index"] == 2 and best["value"] == 7.0 and best["feasible"] == 2 and best["candidates"] == 4
    assert best_member(ms, ("min", "defl"))["index"] == 0
    assert "meets the constraints" in best_member(ms, ("max", "defl"), [("stress", "<", 1.0)])["error"]
    with pytest.raises(AnswerError):
        parse_objective("biggest:defl")
    with pytest.raises(AnswerError):
        parse_constraint("stress<<3")


def test_study_progress_counts_and_time_left(caplog, monkeypatch):
    """Counts done / failed / running and the time left: the members left over the rate of this session's ends."""
    import logging
    import time

    from pulseform.orchestrator.run import progress

    clock = iter([0.0, 10.0, 20.0])
    monkeypatch.setattr(time, "perf_counter", lambda: next(clock))
    p = progress.StudyProgress(6, already=(1, 1), quiet=True)  # a resumed study: 2 of 6 ended before
    p.started()
    p.started()
    with caplog.at_level(logging.INFO, logger="pulseform.orchestrator.run.progress"):
        p.ended(True, "member 2 ok")      # t = 10 s: 1 end in 10 s, 3 left -> 30 s
        assert (p.done, p.failed, p.running) == (2, 1, 1) and p.eta_s == pytest.approx(30.0)
        p.ended(False, "member 3 FAILED(1)")  # t = 20 s: 2 ends in 20 s, 2 left -> 20 s
    assert (p.done, p.failed, p.running) == (2, 2, 0) and p.eta_s == pytest.approx(20.0)
    assert caplog.messages[-1] == "member 3 FAILED(1): 4/6 ended (done 2, failed 2, running 0; ~20 s left)"
    p.close()
