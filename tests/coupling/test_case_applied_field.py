"""``[em.applied_field]`` in a case file: validated with one clear line, and turned into the GetDP model's
``AppliedField`` by ``em_model`` (the field's physics is verified in tests/getdp/test_applied_field.py)."""
from __future__ import annotations

import math
import shutil
import tomllib
from pathlib import Path

import pytest
import tomli_w

from pulseform.orchestrator.case.io import load_case as _load

from pulseform.orchestrator.cli import main
from pulseform.orchestrator.em.solver import em_model
from pulseform.solvers.getdp import CurrentTable, DampedSine

def load_case(path: Path):
    """The case of a file (``load_case`` returns it with its path)."""
    return _load(path)[0]


REPO = Path(__file__).resolve().parents[2]
AXI = tomllib.loads((REPO / "cases/emf_sheet_bulge/case.toml").read_text())        # axisymmetric
PLANAR = tomllib.loads((REPO / "cases/emf_corner_fill/case.toml").read_text())    # planar (half model)
TEMPLATE = REPO / "cases/template_sheet_bulge/case.toml"


def _write(tmp_path: Path, base: dict, field: dict | None, name: str = "case.toml") -> Path:
    data = {**base, "em": {**base["em"]}}
    if field is not None:
        data["em"]["applied_field"] = field
    path = tmp_path / name
    path.write_text(tomli_w.dumps(data))
    return path


def _one_line(capsys, rc: int, must_contain: str) -> str:
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert must_contain in lines[0], lines[0]
    return lines[0]


def test_axisymmetric_dc_field_becomes_the_model_field(tmp_path):
    case = load_case(_write(tmp_path, AXI, {"type": "dc", "magnitude": 0.3, "direction": [0.0, -2.0], "t_on": 1e-6}))
    f = em_model(case, (0.15, 0.1875)).applied_field
    assert f.B0 == 0.3 and f.direction == (0.0, -2.0)
    assert isinstance(f.waveform, DampedSine)
    assert (f.waveform.I0, f.waveform.omega, f.waveform.phase, f.waveform.t_on) == (1.0, 0.0, 0.5 * math.pi, 1e-6)
    assert f([0.5e-6, 2e-6]).tolist() == [[0.0, -0.0], [0.0, -0.3]]
    assert em_model(load_case(_write(tmp_path, AXI, None, "none.toml")), None).applied_field is None


def test_planar_sine_and_table_fields(tmp_path):
    case = load_case(_write(tmp_path, PLANAR, {"type": "sine", "magnitude": 1.5, "direction": [0.0, 1.0],
                                               "frequency": 5e3, "decay": 2e3, "phase": 0.1}))
    f = em_model(case, None).applied_field
    assert (f.waveform.beta, f.waveform.omega, f.waveform.phase) == (2e3, 2 * math.pi * 5e3, 0.1)
    (tmp_path / "b.csv").write_text("time_s,factor\n0,0\n1e-5,1\n")
    case = load_case(_write(tmp_path, PLANAR, {"type": "table", "magnitude": 0.2, "direction": [0.0, 1.0],
                                               "file": "b.csv"}, "t.toml"))
    f = em_model(case, None).applied_field
    assert isinstance(f.waveform, CurrentTable) and f.waveform.values == [0.0, 1.0]
    assert f(5e-6).tolist() == pytest.approx([0.0, 0.1])


@pytest.mark.parametrize("base, field, message", [
    (AXI, {"type": "dc", "magnitude": 0.3, "direction": [1.0, 0.0]}, "em.applied_field.direction"),
    (PLANAR, {"type": "dc", "magnitude": 0.3, "direction": [1.0, 1.0]}, "symmetry plane x = 0"),
    (AXI, {"type": "dc", "magnitude": 0.3, "direction": [0.0, 0.0]}, "must not be zero"),
    (AXI, {"type": "dc", "magnitude": -0.3, "direction": [0.0, 1.0]}, "em.applied_field.magnitude"),
    (AXI, {"type": "dc", "magnitude": 1e9, "direction": [0.0, 1.0]}, "em.applied_field.magnitude"),
    (AXI, {"type": "dc", "magnitude": 0.3, "direction": [0.0, 1.0, 0.0]}, "em.applied_field.direction"),
    (AXI, {"type": "pulse", "magnitude": 0.3, "direction": [0.0, 1.0]}, "em.applied_field.type"),
    (AXI, {"type": "sine", "magnitude": 0.3, "direction": [0.0, 1.0]}, "em.applied_field.frequency"),
    (PLANAR, {"type": "table", "magnitude": 0.3, "direction": [0.0, 1.0], "file": "missing.csv"}, "file not found"),
])
def test_bad_applied_field_is_one_line(tmp_path, capsys, base, field, message):
    _one_line(capsys, main(["check", str(_write(tmp_path, base, field))]), message)


def test_table_with_bad_rows_and_template_deck_refused(tmp_path, capsys):
    (tmp_path / "b.csv").write_text("0,0\n1e-5,x\n")
    line = _one_line(capsys, main(["check", str(_write(tmp_path, PLANAR, {
        "type": "table", "magnitude": 0.3, "direction": [0.0, 1.0], "file": "b.csv"}))]), "em.applied_field.file")
    assert "factor -" in line
    folder = tmp_path / "template"   # a copy: its deck files resolve relative to its folder
    shutil.copytree(TEMPLATE.parent, folder)
    data = tomllib.loads(TEMPLATE.read_text())
    data["em"]["applied_field"] = {"type": "dc", "magnitude": 0.3, "direction": [0.0, 1.0]}
    (folder / "case.toml").write_text(tomli_w.dumps(data))
    _one_line(capsys, main(["check", str(folder / "case.toml")]), "getdp_template")
