"""Bad magnetic materials (issue 35): exit code 2, one line naming the file, the key and what is allowed."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
import tomli_w

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.cli import main

REPO = Path(__file__).resolve().parents[2]
BASE = tomllib.loads((REPO / "cases/emf_sheet_bulge/case.toml").read_text())
GOOD_H = [0.0, 100.0, 400.0, 3000.0, 1e5]
GOOD_B = [0.0, 0.8, 1.3, 1.6, 2.1]

# (id, bh_curve table or extra material keys, key named in the message, text of what is allowed)
BAD = [
    ("h_not_increasing", {"bh_curve": {"field_strength": [0.0, 400.0, 100.0, 3000.0],
                                       "flux_density": [0.0, 0.8, 1.3, 1.6]}}, "bh_curve.field_strength[2]",
     "strictly increasing"),
    ("b_not_increasing", {"bh_curve": {"field_strength": GOOD_H, "flux_density": [0.0, 0.8, 0.7, 1.6, 2.1]}},
     "bh_curve.flux_density[2]", "strictly increasing"),
    ("non_finite", {"bh_curve": {"field_strength": GOOD_H, "flux_density": [0.0, 0.8, float("inf"), 1.6, 2.1]}},
     "bh_curve.flux_density[2]", "finite"),
    ("nan", {"bh_curve": {"field_strength": [0.0, float("nan"), 400.0, 3000.0, 1e5], "flux_density": GOOD_B}},
     "bh_curve.field_strength[1]", "finite"),
    ("negative", {"bh_curve": {"field_strength": [-10.0, 100.0, 400.0], "flux_density": [0.1, 0.8, 1.3]}},
     "bh_curve.field_strength", ">= 0"),
    ("too_few", {"bh_curve": {"field_strength": [0.0, 100.0], "flux_density": [0.0, 0.8]}},
     "bh_curve.field_strength", "at least 2 points"),
    ("lengths_differ", {"bh_curve": {"field_strength": GOOD_H, "flux_density": GOOD_B[:-1]}},
     "bh_curve.flux_density", "one flux density"),
    ("below_vacuum_at_top", {"bh_curve": {"field_strength": [0.0, 100.0, 2e6], "flux_density": [0.0, 0.8, 1.0]}},
     "bh_curve.flux_density", "B >= mu0 H"),
    ("both", {"relative_permeability": 100.0, "bh_curve": {"field_strength": GOOD_H, "flux_density": GOOD_B}},
     "relative_permeability", "not both"),
    ("mu_r_zero", {"relative_permeability": 0.0}, "relative_permeability", "> 0"),
]


def _case(tmp_path: Path, material: dict, **em) -> Path:
    data = tomllib.loads(tomli_w.dumps(BASE))
    data["materials"]["al_blank"].update(material)
    data["em"].update(em)
    p = tmp_path / "case.toml"
    p.write_text(tomli_w.dumps(data))
    return p


@pytest.mark.parametrize("material,key,allowed", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_magnetic_material_is_one_line(tmp_path, capsys, material, key, allowed):
    file = _case(tmp_path, material)
    rc = main(["check", str(file)])
    _, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert str(file) in lines[0] and f"materials.al_blank.{key}" in lines[0] and allowed in lines[0], lines[0]


def test_a_bh_curve_runs_on_either_getdp(tmp_path, capsys):
    """A B–H curve runs on the persistent getdp (Newton's iterations in its loop) and per step: getdp_process
    'persistent', 'per_step' and 'auto' are all accepted (until issue 35's persistent Newton, 'persistent' was
    refused)."""
    mat = {"bh_curve": {"field_strength": GOOD_H, "flux_density": GOOD_B}}
    for process in ("persistent", "per_step", "auto"):
        rc = main(["check", str(_case(tmp_path, mat, getdp_process=process, time_scheme="bdf2"))])
        err = capsys.readouterr().err
        assert rc == 0 and "Traceback" not in err, (process, err)
    case, _ = load_case(_case(tmp_path, mat))
    curve = case.materials["al_blank"].bh_curve
    assert curve.field_strength == tuple(GOOD_H) and case.em.newton_tolerance == 1e-8


POT = tomllib.loads((REPO / "cases/emf_actuator_pot_core/case.toml").read_text())
POST, WALL = [0.0, -0.014, 0.010, 0.0], [0.030, -0.014, 0.034, 0.0]
# (id, change of the pot core case, key named in the message, text of what is allowed)
BAD_CORES = [
    ("unknown_material", lambda d: d["geometry"]["cores"][0].update(material="ferrite"),
     "geometry.cores[0].material", "one of the [materials] entries"),
    ("not_magnetic", lambda d: d["geometry"]["cores"][0].update(material="al"),
     "geometry.cores[0].material", "needs a magnetic material"),
    ("overlaps_the_coil", lambda d: d["geometry"]["cores"][0].update(boxes=[[0.0, -0.014, 0.012, -0.003]]),
     "geometry.cores[0].boxes[0]", "overlaps coils[0].windings[0]"),
    ("touches_the_workpiece", lambda d: d["geometry"]["cores"][0].update(boxes=[[0.0, -0.014, 0.011, 0.0]]),
     "geometry.cores[0].boxes[0]", "touches the workpiece"),
    ("boxes_overlap", lambda d: d["geometry"]["cores"][0].update(boxes=[POST, [0.005, -0.016, 0.034, -0.010]]),
     "geometry.cores[0].boxes[1]", "overlaps cores[0].boxes[0]"),
    ("empty", lambda d: d["geometry"]["cores"][0].update(boxes=[]), "geometry.cores[0].boxes", "at least one"),
    ("not_a_rectangle", lambda d: d["geometry"]["cores"][0].update(boxes=[[0.03, 0.0, 0.034, -0.014]]),
     "geometry.cores[0].boxes[0]", "z1 > z0"),
    ("same_name", lambda d: d["geometry"]["cores"].append({"name": "pot_core", "material": "iron_1010",
                                                           "boxes": [[0.040, -0.01, 0.045, 0.0]]}),
     "geometry.cores[1].name", "unique"),
    ("applied_field", lambda d: d["em"].update(applied_field={"type": "dc", "magnitude": 0.01,
                                                                    "direction": [0.0, 1.0]}),
     "materials.iron_1010.bh_curve", "applied_field"),
]


@pytest.mark.parametrize("change,key,allowed", [b[1:] for b in BAD_CORES], ids=[b[0] for b in BAD_CORES])
def test_bad_core_is_one_line(tmp_path, capsys, change, key, allowed):
    """[[geometry.cores]] of coaxial_coils: a bad box or material is one line naming the key (exit 2)."""
    data = tomllib.loads(tomli_w.dumps(POT))
    change(data)
    file = tmp_path / "case.toml"
    file.write_text(tomli_w.dumps(data))
    rc = main(["check", str(file)])
    _, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert str(file) in lines[0] and key in lines[0] and allowed in lines[0], lines[0]


def test_cores_reach_the_em_model():
    """Each box of a core is one GetDP core region with the material's curve; no cores: none."""
    from pulseform.orchestrator.em.solver import em_model

    case, _ = load_case(REPO / "cases/emf_actuator_pot_core/case.toml")
    model = em_model(case, shell=(0.15, 0.2))
    assert [c.name for c in model.cores] == ["pot_core"] * 3 and model.is_nonlinear
    assert model.cores[0].bh_curve.h[1:] == case.materials["iron_1010"].bh_curve.field_strength
    assert em_model(load_case(REPO / "cases/jumping_ring/case.toml")[0], shell=(0.25, 0.3125)).cores == []
