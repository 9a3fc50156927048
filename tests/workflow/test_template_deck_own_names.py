"""Decks on GetDP's template that set the runner's names themselves, and the messages of badly grouped
template decks (issue 32, items 1 and 3).

The deck of every test is tests/workflow/template_decks/current_template.pro (a GetDP user's deck on
``Lib_Magnetodynamics2D_av_Cir.pro``: the flat coil's current prescribed by the template's ``Current_2D``,
the sheet a massive conductor) on the mesh of cases/user_deck_sheet_bulge, edited in one place.

* A deck that sets its own time window with plain assignments (``TimeInit = 0; TimeFinal = 10e-6;
  DeltaTime = 1e-6;``, as GetDP's examples do; such an assignment beats getdp's ``-setnumber``) runs
  unchanged: pulseform's ``run.pro`` saves the runner's window before the deck and assigns it again after
  it (solvers/getdp/template.py, ``runner_guard_lines``). Reference: the same deck run by plain getdp
  (``getdp deck.pro -solve Magnetodynamics2D_av``, GetDP's own Resolution: implicit Euler over the deck's
  window, no pulseform line) on the same mesh file.
* A deck's own assignment of a runner number it reads while parsed (a shell radius, a
  ``[geometry.parameters]`` name) cannot be undone: one line names the file, line and the fix.
* Item 3's bad decks: each message, exact.
"""

from __future__ import annotations

import shutil
import subprocess
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from pulseform.orchestrator.case.io import load_case

from wf_helpers import REPO, four_steps, one_line_error, pulseform, worst_vs_plain_getdp

LIBRARY = REPO / "cases/user_deck_sheet_bulge"
DECK = Path(__file__).with_name("template_decks") / "current_template.pro"
INCLUDE = 'Include "/usr/share/doc/getdp/examples/templates/Lib_Magnetodynamics2D_av_Cir.pro";'
#: the decks' own pulse (current_template.pro): I0 e^(-Decay t) sin(Omega_I t)
PULSE = {"amplitude": 20e3, "beta": 1e4, "omega": 1e5}


def _case(tmp_path: Path, old: str = "", new: str = "", edit=None) -> Path:
    """A case folder: cases/user_deck_sheet_bulge's mesh and case.toml on current_template.pro
    (library = 'getdp_template', em.current = the deck's pulse, implicit Euler), the deck's ``old``
    replaced by ``new`` (once), the case file's data edited by ``edit(data)``."""
    folder = tmp_path / "case"
    shutil.copytree(LIBRARY, folder, ignore=shutil.ignore_patterns("reference"))
    text = DECK.read_text()
    if old:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    (folder / "current_template.pro").write_text(text)
    data = tomllib.loads((folder / "case.toml").read_text())
    del data["em"]["circuit"]
    data["em"].update(current=dict(PULSE), time_scheme="euler")
    data["geometry"].update(library="getdp_template", pro="current_template.pro")
    if edit is not None:
        edit(data)
    (folder / "case.toml").write_text(tomli_w.dumps(data))
    return folder


def _refused(folder: Path) -> str:
    r = pulseform("check", str(folder))
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    return one_line_error(r)


def _line_of(folder: Path, text: str) -> int:
    """The 1-based line of the deck that holds ``text``."""
    return next(i for i, ln in enumerate((folder / "current_template.pro").read_text().splitlines(), 1) if text in ln)


# ----------------------------------------------------------------------------- item 1: the deck's own window
@pytest.mark.getdp
def test_a_deck_with_its_own_time_window_runs_unchanged(tmp_path):
    """The deck assigns ``TimeInit = 0; TimeFinal = 10e-6; DeltaTime = 1e-6;`` (plain assignments, byte for
    byte kept: run.pro includes the deck file itself). It passes the deck check (which refused it before:
    its step ended at 10 us instead of the runner's 0.1 us), and ten EM steps of 1 us on pulseform's solver
    give, after every step, the whole solution vector (nodal a, the coil's and sheet's global unknowns) of
    the plain getdp run of the same deck over its own window at that time: measured <= 4e-15 relative
    (the same linear systems); asserted 1e-9."""
    from pulseform.orchestrator.em import user_deck as ud
    from pulseform.solvers.getdp.template import read_solutions

    window = "TimeInit = 0; TimeFinal = 10e-6; DeltaTime = 1e-6;"
    folder = _case(tmp_path, INCLUDE, window + "\n" + INCLUDE)
    deck_bytes = (folder / "current_template.pro").read_bytes()
    case, _ = load_case(folder / "case.toml")
    work = tmp_path / "run"
    geometry = ud.build_user_geometry(case, work / "em_mesh", work / "em")  # the deck check passes
    solver = ud.make_solver(case, ud.user_em_model(case), work / "em", deck_ids=geometry.deck_ids)
    state, results = solver.initial_state(0.0), []
    for k in range(1, 11):
        result, state = solver.step(geometry.mesh, state, k * 1e-6)
        results.append(result)
    assert (folder / "current_template.pro").read_bytes() == deck_bytes
    run_pro = (Path(results[0].path) / "run.pro").read_text()
    assert f'Include "{folder / "current_template.pro"}";' in run_pro

    plain = tmp_path / "plain"
    plain.mkdir()
    argv = [shutil.which("getdp"), str(folder / "current_template.pro"), "-msh", str(Path(results[0].path) / "mesh.msh"),
            "-name", str(plain / "plain"), "-solve", "Magnetodynamics2D_av", "-v", "2"]
    r = subprocess.run(argv, cwd=plain, capture_output=True, text=True, timeout=300, check=False)
    assert r.returncode == 0 and "Error" not in r.stdout, r.stdout[-2000:]
    reference = read_solutions(plain / "plain.res")
    assert len(reference) == 10
    worst = 0.0
    for result, (t_ref, x_ref) in zip(results, reference):
        t, x = read_solutions(Path(result.path) / "em.res")[-1]
        assert t == pytest.approx(t_ref, rel=1e-12) and x.shape == x_ref.shape
        worst = max(worst, float(np.abs(x - x_ref).max() / np.abs(x_ref).max()))
    print(f"largest relative difference to the plain getdp run over 10 steps: {worst:.1e}")
    assert worst <= 1e-9
    # a real current flows: the deck's pulse at 10 us (20 kA e^-0.1 sin 1 = 15.2 kA)
    want = PULSE["amplitude"] * np.exp(-PULSE["beta"] * 1e-5) * np.sin(PULSE["omega"] * 1e-5)
    assert results[-1].coil_current[-1, 0] == pytest.approx(want, rel=1e-9)


@pytest.mark.getdp
def test_a_deck_that_overrides_a_number_it_reads_names_the_line(tmp_path):
    """A plain ``Val_Rint = 0.14;`` (the template's shell radius, read while the deck is parsed: the
    runner cannot assign it again in time) against geometry.shell_inner_radius = 0.15: the file, line
    and the one-line fix."""
    folder = _case(tmp_path, INCLUDE, "Val_Rint = 0.14;\n" + INCLUDE)
    n = _line_of(folder, "Val_Rint = 0.14;")
    assert _refused(folder) == (
        f"pulseform: error: deck current_template.pro:{n} assigns Val_Rint = 0.14; the runner's -setnumber "
        "Val_Rint = 0.15 (geometry.shell_inner_radius) loses to a plain assignment: write DefineConstant[ "
        "Val_Rint = 0.14 ]; instead (the case's value then reaches the deck)")


@pytest.mark.getdp
def test_a_geometry_parameter_the_deck_assigns_in_an_included_file_names_that_file(tmp_path):
    """``NbTurns = 4;`` in sheet_bulge_common.pro (an Include of the deck) against
    geometry.parameters.NbTurns = 5: the included file is named."""
    folder = _case(tmp_path)
    common = folder / "sheet_bulge_common.pro"
    common.write_text(common.read_text() + "NbTurns = 4;\n")
    n = len(common.read_text().splitlines())
    assert _refused(folder) == (
        f"pulseform: error: deck current_template.pro: sheet_bulge_common.pro:{n} assigns NbTurns = 4; the "
        "runner's -setnumber NbTurns = 5 (geometry.parameters.NbTurns) loses to a plain assignment: write "
        "DefineConstant[ NbTurns = 4 ]; instead (the case's value then reaches the deck)")


# ----------------------------------------------------------------------------- item 3: messages with their cause
@pytest.mark.getdp
def test_a_workpiece_left_out_of_the_conductor_group(tmp_path):
    """The sheet left out of Vol_C_Mag (still in Vol_Mag): the deck is not hollow for want of ids."""
    folder = _case(tmp_path, "Vol_C_Mag = Region[{Sheet}];", "Vol_C_Mag = Region[{}];")
    assert _refused(folder) == (
        "pulseform: error: deck current_template.pro: SHEET (physical 1200, geometry.regions.workpiece) is not in "
        "the deck's Vol_C_Mag (the template's massive conductors): add it to Vol_C_Mag")


@pytest.mark.getdp
def test_a_region_without_a_conductivity(tmp_path):
    folder = _case(tmp_path, "sigma[Sheet] = Sigma_Sheet;", "")
    assert _refused(folder) == (
        "pulseform: error: deck current_template.pro: getdp failed on the contract check: Error: Function 'sigma' "
        "undefined in Region 1200; SHEET (physical 1200, geometry.regions.workpiece) has no sigma[]: define sigma[] "
        "on its group in the deck, its conductivity (S/m)")


@pytest.mark.getdp
def test_a_bank_on_a_deck_without_a_circuit(tmp_path):
    """The case's capacitor bank on the deck's Current_2D (Flag_CircuitCoupling = 0): getdp used to stop at
    ``Unknown Group: Capacitance_Cir`` in a line of the generated run.pro (in `check`, a deleted folder)."""
    def bank(data):
        del data["em"]["current"]
        data["em"]["circuit"] = {"capacitance": 50e-6, "voltage": 6e3, "resistance": 0.01, "inductance": 2e-6}

    assert _refused(_case(tmp_path, edit=bank)) == (
        "pulseform: error: deck current_template.pro has no circuit for the case's capacitor bank "
        "(Flag_CircuitCoupling = 0): add the template's circuit (Flag_CircuitCoupling = 1, Capacitance_Cir, "
        "Resistance_Cir, Inductance_Cir, ElectricalCircuit: cases/template_sheet_bulge) or use em.current")


@pytest.mark.getdp
def test_a_workpiece_in_the_stranded_group_too(tmp_path):
    """The sheet in Vol_S_Mag as well as Vol_C_Mag: getdp's own error (no js0 on the sheet) is the symptom."""
    folder = _case(tmp_path, "Vol_S_Mag = Region[{Coil}];", "Vol_S_Mag = Region[{Coil, Sheet}];")
    assert _refused(folder) == (
        "pulseform: error: deck current_template.pro: getdp failed on the contract check (Error: Function 'js0' "
        "undefined in Region 1200): SHEET (physical 1200, geometry.regions.workpiece) is in both Vol_C_Mag and "
        "Vol_S_Mag: a group has one role; remove it from Vol_S_Mag")


@pytest.mark.getdp
def test_a_coil_in_the_massive_group_too(tmp_path):
    """The coil in Vol_C_Mag as well as Vol_S_Mag: getdp solves it without complaint (eddy currents in a
    stranded coil), so the first run's group table is the only witness."""
    folder = _case(tmp_path, "Vol_C_Mag = Region[{Sheet}];", "Vol_C_Mag = Region[{Sheet, Coil}];")
    assert _refused(folder) == (
        "pulseform: error: deck current_template.pro: COIL (physical 1100, geometry.regions.coil) is in both "
        "Vol_S_Mag and Vol_C_Mag: a group has one role; remove it from Vol_C_Mag")


def test_one_group_given_two_roles_in_the_case(tmp_path):
    """regions.coil and regions.workpiece both SHEET: refused when the case is loaded (it used to say that
    the triangles of COIL have no role)."""
    def two_roles(data):
        data["geometry"]["regions"]["coil"] = "SHEET"

    folder = _case(tmp_path, edit=two_roles)
    assert _refused(folder) == (
        f"pulseform: error: {folder / 'case.toml'}: geometry.regions.workpiece: got 'SHEET', which is already "
        "geometry.regions.coil; a physical group has one role")


def test_a_line_of_the_generated_run_pro_is_quoted(tmp_path):
    """A getdp error located in the generated run.pro carries the line itself: `check` removes its folder
    before the message is read."""
    from pulseform.orchestrator.em.deck_check import _quote_run_pro

    run_pro = tmp_path / "run.pro"
    run_pro.write_text("// generated\nA = 1;\n  Print[ U, OnRegion Capacitance_Cir ];\n")
    error = f"Error   : '{run_pro}', line 3 : Unknown Group: Capacitance_Cir"
    assert _quote_run_pro(error, tmp_path) == ("Error   : pulseform's generated run.pro, line 3 (Print[ U, OnRegion "
                                               "Capacitance_Cir ];) : Unknown Group: Capacitance_Cir")


# ----------------------------------------------------------------------------- item 2: the deck's numbers, once
def _left_to_the_deck(data):
    """The case states neither the sheet's conductivity nor the coil's turns: the deck's own."""
    del data["geometry"]["turns"]
    del data["materials"]["al_blank"]["electrical_conductivity"]


@pytest.mark.getdp
def test_a_deck_constant_changed_through_set_reaches_both_sides(tmp_path):
    """The case leaves the sheet's conductivity and the coil's turns to the deck; ``pulseform check``
    shows the deck's constants (as getdp reads them) and the values the case takes from it; ``--set
    geometry.parameters.Sigma_Sheet=3e7`` changes the deck's Sigma_Sheet (-setnumber) and the case's
    conductivity at once (no refusal). Four EM steps of 0.5 us then equal plain getdp on the deck with
    ``-setnumber Sigma_Sheet 3e7 -setnumber TimeFinal 2e-6`` (its own DeltaTime 0.5 us) in every unknown
    after every step: measured ~1e-15; asserted 1e-9. The deck's own 2.5e7 differs by far more (the
    comparison sees the conductivity)."""
    from pulseform.orchestrator.em import user_deck as ud

    folder = _case(tmp_path, edit=_left_to_the_deck)
    r = pulseform("check", str(folder), "--set", "geometry.parameters.Sigma_Sheet=3e7")
    assert r.returncode == 0, r.stderr[-2000:]
    assert ("# current_template.pro: its constants as getdp reads them (--set geometry.parameters.<name>=... "
            "changes one): Flag_CircuitCoupling = 0, DeltaTime = 5e-07, Sigma_Sheet = 3e+07, Sigma_Coil = 5.8e+07, "
            "I0 = 20000, Decay = 10000, Omega_I = 100000, NbTurns = 5,") in r.stdout
    assert ("# the case takes from current_template.pro: materials.al_blank.electrical_conductivity = 3e+07 S/m "
            "(sigma[] on SHEET), geometry.turns = 5 (js0[] over COIL)") in r.stdout

    case, _ = load_case(folder / "case.toml", ["geometry.parameters.Sigma_Sheet=3e7"])
    work = tmp_path / "run"
    geometry = ud.build_user_geometry(case, work / "em_mesh", work / "em")
    model = ud.user_em_model(case, geometry.deck_values)
    assert model.conductors[0].sigma == pytest.approx(3e7, rel=1e-12) and model.coils[0].turns == pytest.approx(5)
    solver = ud.make_solver(case, model, work / "em", deck_ids=geometry.deck_ids)
    results = four_steps(solver, geometry.mesh)
    same = worst_vs_plain_getdp(tmp_path, folder / "current_template.pro", results, "set", "-setnumber", "Sigma_Sheet", "3e7")
    other = worst_vs_plain_getdp(tmp_path, folder / "current_template.pro", results, "own")
    print(f"against plain getdp -setnumber Sigma_Sheet 3e7: {same:.1e}; against the deck's own 2.5e7: {other:.1e}")
    assert same <= 1e-9 and other > 1e-4


@pytest.mark.getdp
def test_a_value_the_case_repeats_is_still_compared(tmp_path):
    """The case that states the conductivity keeps the deck check's comparison: changing the deck's
    Sigma_Sheet alone is refused, naming both values."""
    r = pulseform("check", str(_case(tmp_path)), "--set", "geometry.parameters.Sigma_Sheet=3e7")
    assert r.returncode == 2
    assert ("materials.al_blank.electrical_conductivity = 2.5e+07 S/m, the deck's sigma[] on SHEET = 3e+07 S/m"
            in one_line_error(r))
