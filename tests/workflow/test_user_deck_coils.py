"""Users' own decks with several coil roles (``[[geometry.coils]]``: name, physical group, turns), on
cases/user_deck_sheet_bulge/two_coils.toml (the demo's coil split into an inner coil of 2 turns and an
outer one of 3, sheet_bulge_two_coils.pro).

References:
- the split deck with both coils in series on the bank (sign +1) is the one-coil deck of case.toml:
  the same .geo meshed with the same nodes and elements in the same order (only the coil's physical
  group differs), the same turns carrying the same current at the same current density N I / S per
  coil region; GetDP's circuit has two coil branches in series instead of one, so the linear systems
  differ in their network rows only and the results agree to round-off;
- with two prescribed sources the coil currents GetDP reports are the sources' formulas
  I0 e^(-beta (t - t_on)) sin(2 pi f (t - t_on) + phi) (after t_on) times the coil's sign, to the 10
  significant digits history.csv keeps (as tests/coupling/test_case_sources.py for coaxial_coils).
"""

from __future__ import annotations

import json
import math
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from pulseform.orchestrator.cli import main
from pulseform.orchestrator.run.history import History

from wf_helpers import REPO, one_line_error, pulseform

FOLDER = REPO / "cases/user_deck_sheet_bulge"
TWO = FOLDER / "two_coils.toml"
#: no pictures: the tests read metrics, history.csv and the mesh (a picture group that fails is only logged, so
#: drawing them here tested nothing; tests/workflow/test_results_pictures.py tests them)
SHORT = ["--quiet", "--set", "time.end=6e-6", "--set", "output.field_interval=3e-6", "--set", "output.plots=false"]


def _copy_with(tmp_path: Path, edit) -> Path:
    """The example folder copied to ``tmp_path/case`` with two_coils.toml edited by ``edit(data)``."""
    folder = tmp_path / "case"
    shutil.copytree(FOLDER, folder, ignore=shutil.ignore_patterns("reference"))
    data = tomllib.loads(TWO.read_text())
    edit(data)
    (folder / "two_coils.toml").write_text(tomli_w.dumps(data))
    return folder / "two_coils.toml"


@pytest.mark.getdp
def test_two_coils_in_series_on_the_bank_equal_the_one_coil_deck(tmp_path):
    """Impulse, peak current, speed and the coil currents of the split deck vs case.toml (see the module
    docstring); measured 6e-15 relative (impulse, peak current) at 6 us with a factorisation per EM step
    (em.factor_reuse_tol = 0: the two decks assemble the same system in another order, and round-off is
    what the comparison resolves; with kept factors each solve is exact to its 1e-10 residual only:
    1.7e-9 measured). It also sees the mesh motion
    keep coil 2's nodes fixed like coil 1's: smoothed with the air instead they changed the impulse by
    1.5e-4 (tried by dropping EMGeometry.more_coils in user_deck.build_user_geometry)."""
    one, two = tmp_path / "one", tmp_path / "two"
    fresh = ["--set", "em.factor_reuse_tol=0"]
    assert main(["run", str(FOLDER / "case.toml"), "--out", str(one), *SHORT, *fresh]) == 0
    assert main(["run", str(TWO), "--out", str(two), *SHORT, *fresh]) == 0
    m1 = json.loads((one / "metrics.json").read_text())
    m2 = json.loads((two / "metrics.json").read_text())
    for key in ("force_impulse_Ns", "coil_current_peak_kA", "sheet_max_speed_m_s", "kinetic_energy_final_J"):
        rel = abs(m2[key] / m1[key] - 1.0)
        print(f"{key}: one coil {m1[key]:.15g}, two coils in series {m2[key]:.15g} ({rel:.1e} relative)")
        assert rel <= 1e-9, key
    assert m2["em_steps"] == m1["em_steps"] and m2["conservation_error_rel"] < 1e-10
    assert m2["inner_current_peak_kA"] == m2["outer_current_peak_kA"] == pytest.approx(m1["coil_current_peak_kA"],
                                                                                         rel=1e-9)
    h1, h2 = History.read(one / "history.csv"), History.read(two / "history.csv")
    i1 = h1.column("coil_current_A")
    assert np.abs(i1).max() > 1e4  # the bank's current has risen: a real comparison
    for col in ("inner_current_A", "outer_current_A"):  # the same series current, to the CSV's 10 digits
        assert np.abs(h2.column(col) - i1).max() <= 1e-9 * np.abs(i1).max(), col
    # the runner renumbered the groups in the order of [[geometry.coils]]: inner 101 (2 of the 5 turns of
    # 4 mm x 3 mm), outer 102 (3 turns); the areas are those of the turns' rectangles
    from pulseform.orchestrator.case.io import load_case
    from pulseform.orchestrator.em import user_deck as ud
    from pulseform.solvers.getdp import coil_tag
    from pulseform.solvers.getdp.files import element_volumes

    g = load_case(TWO)[0].geometry
    mesh = ud.read_deck_mesh(two / "em_mesh/sheet_bulge.msh", g.regions, coils=g.coils)
    areas = [element_volumes(mesh, np.flatnonzero(mesh.tri_tags == coil_tag(k)), False).sum() for k in (1, 2, 3)]
    assert areas == pytest.approx([2 * 12e-6, 3 * 12e-6, 0.0], rel=1e-9, abs=1e-15)


def _sine(t, amplitude, frequency, phase=0.0, decay=0.0, t_on=0.0):
    s = np.asarray(t, float) - t_on
    return np.where(s >= 0.0, amplitude * np.exp(-decay * s) * np.sin(2 * math.pi * frequency * s + phase), 0.0)


@pytest.mark.getdp
def test_two_prescribed_sources_drive_their_own_coils(tmp_path):
    """Coil currents in history.csv = the source formulas times the coil's sign (module docstring)."""
    a = {"name": "a", "type": "sine", "amplitude": 15e3, "frequency": 20e3, "decay": 2e4}
    b = {"name": "b", "type": "sine", "amplitude": 9e3, "frequency": 35e3, "phase": 0.3, "decay": 4e4, "t_on": 2e-6}

    def edit(d):
        d["em"]["sources"] = [a, b]
        d["em"]["coils"] = [{"name": "inner", "source": "a"}, {"name": "outer", "source": "b", "sign": -1}]

    toml = _copy_with(tmp_path, edit)
    out = tmp_path / "out"
    assert main(["run", str(toml), "--out", str(out), *SHORT]) == 0
    h = History.read(out / "history.csv")
    formulas = {"inner_current_A": lambda t: _sine(t, **{k: v for k, v in a.items() if k not in ("name", "type")}),
                "outer_current_A": lambda t: -_sine(t, **{k: v for k, v in b.items() if k not in ("name", "type")})}
    t = h.column("time_s")[1:]  # row 0: the state at rest before the first step
    assert (t < b["t_on"]).any() and (t > b["t_on"]).any()  # before and after coil b's switch-on
    for col, formula in formulas.items():
        got, want = h.column(col)[1:], formula(t)
        # history.csv keeps 10 significant digits of the current and of the time: rounding budget
        slope = np.abs(formula(t + 1e-12) - formula(t - 1e-12)) / 2e-12
        budget = 5e-10 * (np.abs(want) + t * slope) + 1e-12 * np.abs(want).max()
        err = np.abs(got - want)
        print(f"{col}: {len(t)} EM steps, max |I - formula| = {err.max() / np.abs(want).max():.1e} of max|I|, "
              f"at most {(err / budget).max():.2f} of the CSV rounding budget")
        assert np.abs(want).max() > 1e3 and np.all(err <= budget), col
    assert "capacitor_voltage_V" not in h.columns or not np.any(h.column("capacitor_voltage_V"))


# ----------------------------------------------------------------------------- bad input: one line, exit 2
def _refused(toml: Path, tmp_path: Path, *sets: str) -> list[str]:
    """``check`` and ``run`` of ``toml`` with ``--set`` overrides: both exit 2 with one error line."""
    args = [a for s in sets for a in ("--set", s)]
    lines = []
    for argv in (["check", str(toml), *args], ["run", str(toml), "--out", str(tmp_path / "run"), *SHORT, *args]):
        r = pulseform(*argv)
        assert r.returncode == 2, (argv, r.stderr[-2000:])
        lines.append(one_line_error(r))
    assert not (tmp_path / "run" / "history.csv").exists()
    return lines


def test_a_coil_group_missing_in_the_mesh_is_named(tmp_path):
    check, run = _refused(TWO, tmp_path, "geometry.coils[1].group=COIL_MIDDLE")
    for line in (check, run):
        assert "geometry.coils[1].group: no physical group named 'COIL_MIDDLE'" in line
    assert "COIL_INNER, COIL_OUTER" in check  # what the mesh has (run's longer line is shortened in the middle)


def test_an_em_coil_that_is_not_a_coil_role_is_named(tmp_path):
    for line in _refused(TWO, tmp_path, "em.coils[1].name='middle'"):
        assert "em.coils[1].name: got 'middle'; the coils of geometry.coils are 'inner', 'outer'" in line


def test_a_coil_role_without_an_em_coils_entry_is_named(tmp_path):
    toml = _copy_with(tmp_path, lambda d: d["em"].update(coils=d["em"]["coils"][:1]))
    for line in _refused(toml, tmp_path):
        assert "em.coils: geometry coil 'outer' has no [[em.coils]] entry" in line


def test_coil_turns_missing_or_below_one_are_named(tmp_path):
    def drop_turns(d):
        del d["geometry"]["coils"][1]["turns"]

    toml = _copy_with(tmp_path, drop_turns)
    for line in _refused(toml, tmp_path):
        assert "geometry.coils[1].turns" in line and "missing" in line
    for line in _refused(TWO, tmp_path, "geometry.coils[0].turns=0"):
        assert "geometry.coils[0].turns: got 0; must be >= 1" in line
    one = FOLDER / "case.toml"  # the one coil of regions.coil: geometry.turns
    for line in _refused(one, tmp_path, "geometry.turns=0"):
        assert "geometry.turns: got 0; must be >= 1" in line
    lines = [ln for ln in one.read_text().splitlines() if not ln.startswith("turns = ")]
    (tmp_path / "case").mkdir(exist_ok=True)
    for f in FOLDER.glob("sheet_bulge*"):
        shutil.copy(f, tmp_path / "case")
    (tmp_path / "case/one.toml").write_text("\n".join(lines) + "\n")
    for line in _refused(tmp_path / "case/one.toml", tmp_path):
        assert "geometry.turns: missing" in line


def test_regions_coil_and_geometry_coils_together_are_refused(tmp_path):
    for line in _refused(TWO, tmp_path, "geometry.regions.coil='COIL_INNER'"):
        assert "geometry.regions.coil: give either regions.coil" in line
    for line in _refused(TWO, tmp_path, "geometry.coils[1].group='SHEET'"):
        assert "geometry.coils[1].group: got 'SHEET', which is already geometry.regions.workpiece" in line


@pytest.mark.getdp
def test_a_deck_without_a_group_for_every_coil_role_is_named(tmp_path):
    """Two coil roles on the one-coil deck sheet_bulge.pro (it defines Coil_1 only): getdp's error and
    what the deck must define, in one line."""
    r = pulseform("check", str(TWO), "--set", "geometry.pro='sheet_bulge.pro'")
    assert r.returncode == 2
    line = one_line_error(r)
    assert "Unknown Group: Coil_2" in line and "define Coil_2 = Region[{Phys_Coil_2}]" in line
