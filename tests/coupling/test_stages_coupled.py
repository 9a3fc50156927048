"""``[[stages]]`` on a GetDP-coupled case (issue 34, item 5): the demo (cases/emf_sheet_bulge, its forming-limit
check included) as pulse 3 us, springback, pulse 3 us (a new discharge of the bank at half its voltage),
springback, in one run.

What is checked, and against what: each pulse is a fresh discharge of the bank (the coil current is zero where the
second pulse starts); the circuit is linear and the sheet, elastic over 3 us (1.7e-7 m), springs back to within
1e-12 m, so the second discharge at 3 kV carries half the first's current at the same time after its start: to 1e-5 (the
circuit is linear on a fixed mesh; the sheet moves 1.7e-7 m in the first pulse and a quarter of that in the second,
the force going as V², which changes the coupling at the 1e-6 level: measured 1.3e-6; a charge or a time carried
over from the first pulse would be off by order one); one history with its stage column.
Slow (~6 s): the mechanics-only chain is the default tier's (tests/mechanics/test_stages.py)."""
from __future__ import annotations

import csv
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from warm_cli import pulseform_cli

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
@pytest.mark.getdp
def test_two_discharges_each_followed_by_springback(tmp_path):
    case = tomllib.loads((REPO / "cases/emf_sheet_bulge/case.toml").read_text())
    case["time"]["end"] = 6e-6
    case["output"] = {**case.get("output", {}), "plots": False, "field_interval": 1e-6}
    case["stages"] = [{"name": "pulse1", "kind": "pulse", "end": 3e-6}, {"name": "release1", "kind": "springback"},
                      {"name": "pulse2", "kind": "pulse", "end": 6e-6, "voltage": 3000.0},
                      {"name": "release2", "kind": "springback"}]
    assert case["em"]["circuit"]["voltage"] == 6000.0   # the demo's bank: the second pulse at half of it
    (tmp_path / "case.toml").write_text(tomli_w.dumps(case))
    out = tmp_path / "out"
    r = pulseform_cli(["run", str(tmp_path / "case.toml"), "--out", str(out), "--quiet"])
    assert r.returncode == 0, r.stderr[-3000:]
    rows = list(csv.DictReader((out / "history.csv").open()))
    stage = np.array([float(x["stage"]) for x in rows])
    t = np.array([float(x["time_s"]) for x in rows])
    i = np.array([float(x["coil_current_A"]) for x in rows])
    assert list(np.unique(stage)) == [1.0, 2.0, 3.0, 4.0] and np.all(np.diff(stage) >= 0)
    first, second = np.flatnonzero(stage == 1), np.flatnonzero(stage == 3)
    assert i[second[0]] == 0.0 and t[second[0]] == pytest.approx(3e-6, rel=1e-12)
    assert np.allclose(t[second] - 3e-6, t[first], rtol=0, atol=1e-15)
    print("pulse 1 current (A):", i[first[-3:]], "pulse 2:", i[second[-3:]])
    assert np.max(np.abs(i[second] - 0.5 * i[first])) <= 1e-5 * np.max(np.abs(i[first]))
    m = json.loads((out / "metrics.json").read_text())
    assert m["status_ok"] == 1.0 and m["stages"] == 4.0
    assert m["stage_release1_sheet_springback_max_m"] > 0 and m["stage_release2_sheet_springback_max_m"] > 0
