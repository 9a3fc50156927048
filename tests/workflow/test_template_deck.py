"""Users' decks on GetDP's standard template (issue 18, ``geometry.library = "getdp_template"``):
cases/template_sheet_bulge (the demo written as a GetDP user writes it, on its own physical ids,
including /usr/share/doc/getdp/examples/templates/Lib_Magnetodynamics2D_av_Cir.pro unchanged) runs
through pulseform's wrapper and equals the same demo on pulseform's own library on the same mesh;
bad input and clashes between the deck's values and the case's are one line, exit 2."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from pulseform.orchestrator.case.io import load_case

from wf_helpers import REPO, one_line_error, pulseform

CASE = REPO / "cases/template_sheet_bulge"
LIBRARY_CASE = REPO / "cases/user_deck_sheet_bulge"
#: the loop of the template case (implicit Euler, one getdp run per EM step), for both runs
LOOP = ["--set", "coupling.n=4", "--set", "coupling.em_substeps=1", "--set", "em.time_scheme='euler'"]
SHORT = ["--quiet", "--set", "time.end=3e-6", "--set", "output.field_interval=1.5e-6"]
#: the example deck's own bank (sheet_bulge_template.pro: Cap, V0, Res, Ind), as an em.circuit inline table
BANK = "capacitance = 50e-6, voltage = 6e3, resistance = 0.01, inductance = 2e-6"


def _refused(case, *sets) -> str:
    """``pulseform check`` of a case: exit 2 and its one error line."""
    r = pulseform("check", str(case), *[a for s in sets for a in ("--set", s)])
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    return one_line_error(r)


@pytest.mark.slow
@pytest.mark.getdp
def test_template_deck_equals_the_library_deck_on_the_same_mesh(tmp_path):
    """(Slow, ~30 s: two coupled runs. The default tier's companions: the template deck's EM steps against the library
    deck's on the same mesh in
    tests/workflow/test_template_deck_variants.py::test_bdf2_by_restart_equals_the_library_decks_bdf2, the deck's
    physical ids and contract in test_template_deck_passes_the_deck_check, a coupled template-deck run against a
    library-deck run in tests/workflow/test_user_remesh.py::test_template_and_library_decks_carry_a_remesh_alike.)
    Reference: cases/user_deck_sheet_bulge (the same demo on pulseform's library
    Lib_PulsedForming.pro) on the identical mesh (the same .geo and parameters) with the same loop.
    Both decks discretise the same equations (the template's massive conductor with U = 0 is
    j = -sigma dA/dt), so the runs agree to the round-off of two linear systems: measured 2.4e-15
    relative in the impulse, peak current and speed, every history.csv column equal to its 10
    printed digits; asserted 1e-8."""
    rt = pulseform("run", str(CASE), "--out", str(tmp_path / "template"), *SHORT, *LOOP)
    assert rt.returncode == 0, rt.stderr[-3000:]
    rl = pulseform("run", str(LIBRARY_CASE), "--out", str(tmp_path / "library"), *SHORT, *LOOP)
    assert rl.returncode == 0, rl.stderr[-3000:]
    mt = json.loads((tmp_path / "template/metrics.json").read_text())
    ml = json.loads((tmp_path / "library/metrics.json").read_text())
    for key in ("force_impulse_Ns", "coil_current_peak_kA", "sheet_max_speed_m_s"):
        print(f"{key}: template {mt[key]:.12g}, library {ml[key]:.12g} ({mt[key] / ml[key] - 1:+.2e})")
        assert mt[key] == pytest.approx(ml[key], rel=1e-8), key
    assert mt["em_steps"] == ml["em_steps"] > 30 and mt["conservation_error_rel"] < 1e-10
    ht = np.genfromtxt(tmp_path / "template/history.csv", delimiter=",", names=True)
    hl = np.genfromtxt(tmp_path / "library/history.csv", delimiter=",", names=True)
    assert ht.dtype.names == hl.dtype.names and len(ht) == len(hl)
    for name in ht.dtype.names:  # the error measures are round-off themselves: on the energy's scale
        scale = float(np.abs(hl["energy_external_work_J"] if name.endswith("error_J") else hl[name]).max())
        if name == "conservation_error_rel":
            assert ht[name].max() < 1e-10
        else:
            assert np.abs(ht[name] - hl[name]).max() <= 1e-8 * scale, name
    # the getdp runs read the deck's own physical ids (1200 the sheet, 1100 the coil), not the runner's
    msh = (tmp_path / "template/em/contract_check/mesh.msh").read_text()
    elements = msh.split("$Elements\n", 1)[1].splitlines()[1:]
    tags = {int(line.split()[3]) for line in elements if line.startswith(tuple("0123456789"))}
    assert {1000, 1001, 1100, 1200, 1010, 1011} == tags
    run_pro = (tmp_path / "template/em/contract_check/run.pro").read_text()
    assert 'sheet_bulge_template.pro";' in run_pro and "NameOfFormulation Magnetodynamics2D_av" in run_pro
    assert "PF_Cond_1 = Region[{1200}]" in run_pro and "PF_Coil_1 = Region[{1100}]" in run_pro


@pytest.mark.slow
@pytest.mark.getdp
def test_template_deck_bdf2_run_equals_the_library_deck(tmp_path):
    """A coupled run of the example with em.time_scheme = 'bdf2' and the loop of
    cases/user_deck_sheet_bulge (coupling.n = 20, em_substeps = 1) against that case as shipped (BDF2 on
    pulseform's library, the persistent getdp), same mesh: the template deck's BDF2 restarts every getdp
    run from x_tilde written as a .res (tests/workflow/test_template_deck_variants.py compares the EM
    steps). Measured at 3 us (8 EM steps): 2.0e-15 relative in the impulse, 8.9e-16 in the peak current
    (2.5e-13 against the library's per-step BDF2, whose x_tilde travels as printed digits); asserted 1e-9. The
    library run factorises every EM step (em.factor_reuse_tol = 0), as the template's process per step does:
    kept factors solve to a 1e-10 residual only (6.9e-9 measured here; docs/getdp.md, Kept factors)."""
    bdf2 = ["--set", "em.time_scheme='bdf2'", "--set", "coupling.n=20", "--set", "coupling.em_substeps=1"]
    rt = pulseform("run", str(CASE), "--out", str(tmp_path / "template"), *SHORT, *bdf2)
    assert rt.returncode == 0, rt.stderr[-3000:]
    rl = pulseform("run", str(LIBRARY_CASE), "--out", str(tmp_path / "library"), *SHORT,
                   "--set", "em.factor_reuse_tol=0")
    assert rl.returncode == 0, rl.stderr[-3000:]
    assert "one persistent getdp process" in (tmp_path / "library/run.log").read_text()
    mt = json.loads((tmp_path / "template/metrics.json").read_text())
    ml = json.loads((tmp_path / "library/metrics.json").read_text())
    for key in ("force_impulse_Ns", "coil_current_peak_kA", "sheet_max_speed_m_s", "coil_joule_heat_J"):
        print(f"{key}: template {mt[key]:.15g}, library {ml[key]:.15g} ({mt[key] / ml[key] - 1:+.1e})")
        assert mt[key] == pytest.approx(ml[key], rel=1e-9), key
    assert mt["em_steps"] == ml["em_steps"] > 5


@pytest.mark.getdp
def test_template_deck_passes_the_deck_check(tmp_path):
    """The deck check on the example: it solves the model (one force row per sheet element, the
    field state on every coil and sheet node), a step chained by -restart equals one two-step run
    (measured 5.3e-16), and the deck's own values equal the case's."""
    from pulseform.orchestrator.em import template_deck as td
    from pulseform.orchestrator.em import user_deck as ud
    from pulseform.solvers.getdp import conductor_tag

    case, _ = load_case(CASE / "case.toml")
    g = case.geometry
    msh = ud.mesh_file(g, tmp_path / "mesh")
    mesh = ud.read_deck_mesh(msh, g.regions, coils=g.coils)
    ids = td.deck_physical_ids(msh, ud.group_map(g.regions, g.coils))
    assert ids == {1: 1000, 2: 1001, 101: 1100, 201: 1200, 11: 1010, 12: 1011}
    model = ud.user_em_model(case, bank=True)  # the example leaves its bank to the deck: the check reads it
    solver = ud.make_solver(case, model, tmp_path / "em", deck_ids=ids)
    report = ud.check_contract(solver, mesh, tmp_path / "em/contract_check")
    assert report.force_rows == np.sum(mesh.tri_tags == conductor_tag(1)) > 0
    assert report.magnetic_energy > 0 and report.coil_current > 0
    assert set(report.carry_difference) == {"restart"} and report.carry_difference["restart"] < 1e-12
    vals = td.check_deck_values(case, model, tmp_path / "em/contract_check/out")
    assert vals["sigma_1"] == pytest.approx(2.5e7, rel=1e-12) and vals["turns_1"] == pytest.approx(5, rel=1e-12)
    assert (vals["C"], vals["R"], vals["L"], vals["V0"]) == pytest.approx((50e-6, 0.01, 2e-6, 6e3), rel=1e-12)
    # a step that would need the Init path (a new connectivity) is refused: the deck's own Init of the
    # bank would win over the carried capacitor voltage (module docstring of solvers/getdp/template.py)
    from pulseform.solvers.getdp.template import TemplateDeckError

    state = solver.initial_state(0.0)
    _, state = solver.step(mesh, state, 1e-7)
    with pytest.raises(TemplateDeckError, match="Init path"):
        solver.step(mesh, state, 2e-7, force_init_path=True)


@pytest.mark.getdp
@pytest.mark.parametrize("setting, words", [
    ("materials.al_blank.electrical_conductivity=3e7",
     ["materials.al_blank.electrical_conductivity = 3e+07 S/m", "sigma[] on SHEET = 2.5e+07 S/m"]),
    ("geometry.turns=4", ["geometry.turns = 4 turns", "js0[] over COIL = 5 turns"]),
    (f"em.circuit={{{BANK.replace('voltage = 6e3', 'voltage = 5e3')}}}",
     ["em.circuit.voltage = 5000 V", "capacitor's voltage = 6000 V"]),
    (f"em.circuit={{{BANK.replace('capacitance = 50e-6', 'capacitance = 40e-6')}}}",
     ["em.circuit.capacitance = 4e-05 F", "Capacitance[] = 5e-05 F"]),
])
def test_case_values_that_differ_from_the_deck_are_refused(setting, words):
    """The deck owns its conductivity, turns and bank: a case that says otherwise is refused, both named.
    (The example leaves its bank to the deck: the bank cases state one, the deck's but for one value.)"""
    line = _refused(CASE, setting)
    assert "sheet_bulge_template.pro and the case differ" in line
    for w in words:
        assert w in line


@pytest.mark.parametrize("setting, words", [
    ("geometry.template.formulation='Magnetodynamics2D_a'",
     ["geometry.template.formulation: got 'Magnetodynamics2D_a'", "no such Formulation", "Magnetodynamics2D_av"]),
    ("geometry.template.system='Sys_Mag'", ["geometry.template.system: got 'Sys_Mag'", "systems on it: A"]),
    ("geometry.library='pulseform'", ["geometry.library", "set geometry.library = 'getdp_template'"]),
])
def test_bad_template_input_is_one_line(setting, words):
    """Refused when the case is loaded, before gmsh or getdp run."""
    line = _refused(CASE, setting)
    for w in words:
        assert w in line, line


def test_the_persistent_getdp_is_refused_for_a_template_deck():
    """BDF2 is allowed (by restart, a getdp run per step); the persistent getdp is not (its Init
    constraints would lose against the deck's own circuit Init: docs/workflow.md)."""
    line = _refused(CASE, "em.time_scheme='bdf2'", "em.getdp_process='persistent'", "coupling.em_substeps=1")
    assert "em.getdp_process: got 'persistent'; a deck on GetDP's template runs a getdp process per EM step" in line


def test_template_table_needs_the_template_library():
    line = _refused(LIBRARY_CASE, "geometry.template.system='A'")
    assert "geometry.template: [geometry.template] is for library = 'getdp_template'" in line


def _edited(tmp_path, old: str, new: str):
    case = tmp_path / "case"
    shutil.copytree(CASE, case)
    pro = case / "sheet_bulge_template.pro"
    text = pro.read_text()
    assert text.count(old) == 1
    pro.write_text(text.replace(old, new))
    return case


@pytest.mark.getdp
def test_template_deck_with_its_own_time_window_passes_the_check(tmp_path):
    """The deck's own ``TimeFinal = 10e-6;`` (a plain assignment, which beats the runner's -setnumber; this
    deck used to be refused: its check step ended at 10 µs instead of 0.1 µs) passes: run.pro assigns the
    runner's window again after the deck. Its run against plain getdp on the deck:
    tests/workflow/test_template_deck_own_names.py."""
    inc = 'Include "/usr/share/doc/getdp/examples/templates/'
    r = pulseform("check", str(_edited(tmp_path, inc, "TimeFinal = 10e-6;\n" + inc)))
    assert r.returncode == 0, r.stderr[-2000:]
    assert "sheet_bulge_template.pro: honours the deck contract" in r.stdout


@pytest.mark.getdp
def test_template_deck_on_ids_the_mesh_lacks_is_refused(tmp_path):
    """The sheet's group on an id that is not the mesh's: its elements (physical 1200 in the mesh)
    have no conductivity in the deck, getdp stops, the check quotes it in one line."""
    line = _refused(_edited(tmp_path, "Sheet = Region[SHEET];", "Sheet = Region[9999];"))
    assert "getdp failed on the contract check" in line and "Region 1200" in line


def test_template_deck_defining_a_wrapper_name_is_refused(tmp_path):
    inc = 'Include "/usr/share/doc/getdp/examples/templates/'
    case = _edited(tmp_path, inc, "PostOperation { { Name EM_Step; NameOfPostProcessing Magnetodynamics2D_av; "
                                  "Operation { } } }\n" + inc)
    line = _refused(case)
    assert "defines EM_Step, a name of pulseform's wrapper" in line
