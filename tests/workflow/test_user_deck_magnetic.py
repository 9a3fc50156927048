"""Magnetic materials on a user's deck (issue 35): the example deck (cases/user_deck_sheet_bulge) includes the
runner's magnetic block ``PulseformMagneticLib`` (decks/em_magnetic.pro) in place of its own nu[], so a case's
relative permeability or B-H curve on the workpiece or die reaches it. Checked here: the block gives the deck
exactly the reluctivity a hand-written nu[] gives (same mesh, same system: round-off); the user deck with a steel
die equals the built-in geometry's case with the same material (slow; within 1 % as tests/workflow/test_user_deck.py:
the two meshes differ); and every way a deck could run the material in vacuum, or run Newton's iterations the
runner does not read, is refused in one line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from pulseform.orchestrator.case.io import load_case
from pulseform.solvers.getdp.files import read_element_table
from pulseform.orchestrator.em.deck_check import DeckContractError, _newton_table
from pulseform.orchestrator.em.user_deck import (check_contract, deck_names, make_solver, mesh_file, read_deck_mesh,
                                                 user_em_model)

from wf_helpers import REPO, one_line_error, pulseform

CASE = REPO / "cases/user_deck_sheet_bulge"
BLOCK = "Include PulseformMagneticLib;"
MU_R = 50.0
#: a coarse 1010 steel curve (points of cases/emf_sheet_die_steel's FEMM table; H A/m, B T)
CURVE = ["materials.steel.bh_curve.field_strength=[238.7, 636.6, 1591.5, 7957.7, 79577.5, 318310.0]",
         "materials.steel.bh_curve.flux_density=[0.2003, 0.7908, 1.302, 1.73, 2.095, 2.4]"]


def _copy(tmp_path, edit=None):
    """A copy of the example (its deck edited by ``edit``, which must change it); returns its folder."""
    case = tmp_path / "case"
    shutil.copytree(CASE, case, ignore=shutil.ignore_patterns("reference"))
    if edit is not None:
        pro = case / "sheet_bulge.pro"
        text = pro.read_text()
        assert BLOCK in text
        pro.write_text(edit(text))
        assert pro.read_text() != text
    return case


def _first_step(case_file, overrides, work):
    """The deck check of ``case_file`` (with ``overrides``) in ``work``: its report and first step's force rows."""
    case, _ = load_case(case_file, overrides)
    mesh = read_deck_mesh(mesh_file(case.geometry, work / "mesh"), case.geometry.regions, coils=case.geometry.coils)
    solver = make_solver(case, user_em_model(case), work / "em")
    report = check_contract(solver, mesh, work / "em/check", names=deck_names(case))
    ids, values = read_element_table(work / "em/check/out/elem_f.txt", 3, 1)
    return report, np.asarray(values)[0][np.argsort(ids)]


@pytest.mark.getdp
def test_the_block_gives_the_deck_the_cases_permeability(tmp_path):
    """The die's mu_r = 50 through the block (case material) against the same deck with the block replaced by a
    hand-written nu[] (nu = 1/(mu0 mu_r) on Cond_2, the case's die in vacuum): one step of the deck check gives
    the same energy, coil current and force on every element to round-off (the same system; measured: identical);
    with the die in vacuum they differ (the test sees the permeability)."""
    own_nu = ("Function {\n  nu[Region[{Air, Shell, Coil_1, Cond_1}]] = 1 / mu0;\n"
              f"  nu[Cond_2] = 1 / (mu0 * {MU_R!r});\n}}")
    hand = _copy(tmp_path / "hand", lambda t: t.replace(BLOCK, own_nu))
    block, f_block = _first_step(CASE / "with_die.toml", [f"materials.steel.relative_permeability={MU_R!r}"],
                                 tmp_path / "block")
    own, f_own = _first_step(hand / "with_die.toml", [], tmp_path / "own")
    vacuum, f_vac = _first_step(CASE / "with_die.toml", [], tmp_path / "vacuum")
    print(f"W: block {block.magnetic_energy:.12g}, hand-written {own.magnetic_energy:.12g}, vacuum "
          f"{vacuum.magnetic_energy:.12g} J")
    assert block.magnetic_energy == pytest.approx(own.magnetic_energy, rel=1e-12)
    assert block.coil_current == pytest.approx(own.coil_current, rel=1e-12)
    assert np.abs(f_block - f_own).max() <= 1e-10 * np.abs(f_own).max()
    # the die in vacuum: one 0.1 us step barely reaches into the die (measured 1.1e-6 in W, 3.6e-4 in the force)
    assert abs(vacuum.magnetic_energy / block.magnetic_energy - 1) > 1e-7
    assert np.abs(f_block - f_vac).max() > 1e-4 * np.abs(f_vac).max()


def _refused(case_file, *sets) -> str:
    """``pulseform check`` refuses: exit 2 and its one error line. Run in the case's folder on the file's name: the
    line names the case file as given, and a long temporary path would take the line's middle (one_line elides
    past 280 characters)."""
    case_file = Path(case_file)
    r = pulseform("check", case_file.name, *[a for s in sets for a in ("--set", s)], cwd=case_file.parent)
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    return one_line_error(r)


def test_a_deck_with_its_own_nu_is_refused_a_magnetic_material(tmp_path):
    """The deck of before issue 35 (its own nu[] = 1/mu0, no block): the die's mu_r would run in vacuum."""
    case = _copy(tmp_path, lambda t: t.replace(BLOCK, "Function { nu[] = 1 / mu0; }"))
    line = _refused(case / "with_die.toml", "materials.steel.relative_permeability=50")
    assert "materials.steel.relative_permeability" in line and "sheet_bulge.pro has no Include PulseformMagneticLib" in line
    assert "its nu[] at sheet_bulge.pro:" in line and "in vacuum" in line
    line = _refused(case / "with_die.toml", *CURVE)
    assert "materials.steel.bh_curve" in line and "PulseformMagneticLib" in line


def test_a_deck_with_the_block_and_its_own_nu_is_refused(tmp_path):
    case = _copy(tmp_path, lambda t: t.replace(BLOCK, BLOCK + "\nFunction { nu[Cond_1] = 1 / mu0; }"))
    line = _refused(case / "with_die.toml")   # with or without a magnetic material: the block defines nu[]
    assert "geometry.pro" in line and "defines nu[] and the deck includes PulseformMagneticLib" in line
    assert "sheet_bulge.pro:" in line and "remove the deck's own nu[]" in line


def test_a_deck_with_its_own_nonlinear_regions_is_refused(tmp_path):
    """A deck's own Vol_NL_Mag would run Newton's iterations whose convergence the runner never reads."""
    case = _copy(tmp_path, lambda t: t.replace(BLOCK, BLOCK + "\nGroup { Vol_NL_Mag += Region[{Cond_1}]; }"))
    line = _refused(case / "case.toml")
    assert "geometry.pro" in line and "assigns Vol_NL_Mag" in line and "bh_curve" in line


def test_a_deck_that_assigns_the_blocks_numbers_is_refused(tmp_path):
    case = _copy(tmp_path, lambda t: t.replace(BLOCK, "Cond_MuR_2 = 1;\n" + BLOCK))
    line = _refused(case / "with_die.toml", "materials.steel.relative_permeability=50")
    assert "geometry.pro" in line and "assigns Cond_MuR_2" in line and "beats -setnumber" in line


def test_a_template_deck_keeps_its_own_materials():
    line = _refused(REPO / "cases/template_sheet_bulge", "materials.al_blank.relative_permeability=2")
    assert "materials.al_blank.relative_permeability" in line and "GetDP's template" in line


def test_the_check_reads_newtons_table(tmp_path):
    """After the check's first step: a newton.txt without a B-H curve in the case (Newton's iterations of the deck's
    own), or a curve without newton.txt (it never reached the deck), is one line; either consistent pair passes."""
    deck = tmp_path / "deck.pro"
    for nonlinear, table, refused in ((False, True, "runs Newton's iterations"), (True, False, "does not run the "
                                                                                  "case's B-H curve"),
                                      (False, False, None), (True, True, None)):
        out = tmp_path / f"{nonlinear}{table}"
        out.mkdir()
        if table:
            (out / "newton.txt").write_text("1e-07 2 1e-12 1\n")
        solver = SimpleNamespace(model=SimpleNamespace(is_nonlinear=nonlinear))
        if refused is None:
            _newton_table(solver, out, deck)
            continue
        with pytest.raises(DeckContractError, match=refused):
            _newton_table(solver, out, deck)


@pytest.mark.slow
@pytest.mark.getdp
def test_user_deck_with_a_steel_die_matches_the_builtin_case(tmp_path):
    """(Slow, ~30 s: two coupled runs with Newton's iterations in every EM step.) The example's die (with_die.toml)
    with a 1010 steel B-H curve against the built-in cases/emf_sheet_die with the same curve: the force impulse,
    peak current and sheet speed within 1 % (the meshes differ; the vacuum pair agrees as closely:
    test_user_deck.py::test_user_deck_with_a_die_matches_the_builtin_case), Newton's counts in both histories, the
    ledger closed."""
    builtin, _ = load_case(REPO / "cases/emf_sheet_die")
    sets = [a for s in CURVE for a in ("--set", s)]
    run = ["--quiet", "--set", "time.end=6e-6", "--set", "output.field_interval=3e-6", "--set", "output.plots=false"]
    loop = ["--set", f"coupling.n={builtin.coupling.n}", "--set", f"coupling.em_substeps={builtin.coupling.em_substeps}",
            "--set", f"em.time_scheme='{builtin.em.time_scheme}'"]
    metrics = {}
    for name, case, extra in (("user", CASE / "with_die.toml", loop), ("builtin", REPO / "cases/emf_sheet_die", [])):
        r = pulseform("run", str(case), "--out", str(tmp_path / name), *run, *sets, *extra)
        assert r.returncode == 0, r.stderr[-3000:]
        metrics[name] = json.loads((tmp_path / name / "metrics.json").read_text())
    mu, mb = metrics["user"], metrics["builtin"]
    for key in ("force_impulse_Ns", "coil_current_peak_kA", "sheet_max_speed_m_s"):
        print(f"{key}: user deck {mu[key]:.6g}, built-in {mb[key]:.6g} ({100 * (mu[key] / mb[key] - 1):+.3f} %)")
        assert mu[key] == pytest.approx(mb[key], rel=0.01), key
    assert mu["conservation_error_rel"] < 1e-10 and mu["em_steps"] == mb["em_steps"]
    assert (tmp_path / "user/em/contract_check/out/newton.txt").is_file()
