"""Users' own decks (cases/user_deck_sheet_bulge): the example runs end to end and matches the
built-in equivalent case (cases/emf_sheet_bulge: same geometry, bank and loop) within 1 %, a deck
that breaks the contract fails with one line naming what is missing, deck paths stay inside the
case folder. The deck check (issue 18): a hollow deck, a deck that ignores the state carry and a deck
with its own time window are each refused in one line; every shipped deck passes the chained-carry
check with a run's numbers."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from pulseform.orchestrator.case.io import load_case

from wf_helpers import REPO, one_line_error, pulseform

CASE = REPO / "cases/user_deck_sheet_bulge"
#: no pictures: these tests read metrics, logs and tables, never a picture (a picture group that fails is only
#: logged, so drawing them here tested nothing; tests/workflow/test_results_pictures.py tests them)
SHORT = ["--quiet", "--set", "time.end=4e-6", "--set", "output.field_interval=2e-6", "--set", "output.plots=false"]
MATCH = ["--quiet", "--set", "time.end=6e-6", "--set", "output.field_interval=3e-6", "--set", "output.plots=false"]


def _match_builtin(tmp_path, deck_case, builtin_case) -> dict:
    """Run a user-deck case and its built-in equivalent with the same loop settings; compare the
    force impulse (the main metric), the peak current and the sheet's speed within 1 % (issue 7)."""
    builtin, _ = load_case(builtin_case)
    loop = ["--set", f"coupling.n={builtin.coupling.n}", "--set", f"coupling.em_substeps={builtin.coupling.em_substeps}",
            "--set", f"em.time_scheme='{builtin.em.time_scheme}'"]
    ru = pulseform("run", str(deck_case), "--out", str(tmp_path / "user"), *MATCH, *loop)
    assert ru.returncode == 0, ru.stderr[-3000:]
    rb = pulseform("run", str(builtin_case), "--out", str(tmp_path / "builtin"), *MATCH)
    assert rb.returncode == 0, rb.stderr[-3000:]
    mu = json.loads((tmp_path / "user/metrics.json").read_text())
    mb = json.loads((tmp_path / "builtin/metrics.json").read_text())
    for key in ("force_impulse_Ns", "coil_current_peak_kA", "sheet_max_speed_m_s"):
        print(f"{key}: user deck {mu[key]:.6g}, built-in {mb[key]:.6g} ({100 * (mu[key] / mb[key] - 1):+.3f} %)")
        assert mu[key] == pytest.approx(mb[key], rel=0.01), key
    assert mu["conservation_error_rel"] < 1e-10 and mu["em_steps"] == mb["em_steps"]
    return mu


@pytest.mark.getdp
def test_user_deck_matches_the_builtin_case(tmp_path):
    """Reference: the built-in case run by the same command (cases/emf_sheet_bulge)."""
    _match_builtin(tmp_path, CASE, REPO / "cases/emf_sheet_bulge")
    # the runner meshed the user's .geo and checked the contract before the run
    assert (tmp_path / "user/em_mesh/sheet_bulge.msh").is_file()
    assert (tmp_path / "user/em/contract_check/out/elem_f.txt").is_file()


@pytest.mark.slow
@pytest.mark.getdp
def test_user_deck_with_a_die_matches_the_builtin_case(tmp_path):
    """(Slow, ~11 s: the second run pair of _match_builtin, whose default-tier run is
    test_user_deck_matches_the_builtin_case; the die case on a user deck runs coupled in
    tests/workflow/test_user_remesh.py::test_template_and_library_decks_carry_a_remesh_alike)
    The deck's optional die mapped to the role die (massive conductor 2, a mechanical body)
    against cases/emf_sheet_die; the contract check saw the die's tables."""
    _match_builtin(tmp_path, CASE / "with_die.toml", REPO / "cases/emf_sheet_die")
    assert (tmp_path / "user/em/contract_check/out/cond_F_2.txt").is_file()


def _broken_copy(tmp_path, edit_lib):
    """A copy of the example whose deck includes its own (edited) copy of the library."""
    case = tmp_path / "case"
    shutil.copytree(CASE, case, ignore=shutil.ignore_patterns("reference"))
    lib = (REPO / "solvers/getdp/decks/Lib_PulsedForming.pro").read_text()
    (case / "Lib_local.pro").write_text(edit_lib(lib))
    pro = case / "sheet_bulge.pro"
    text = pro.read_text()
    assert "Include PulseformLib;" in text
    pro.write_text(text.replace("Include PulseformLib;", 'Include "Lib_local.pro";'))
    return case


@pytest.mark.getdp
def test_deck_without_an_output_table_names_it(tmp_path):
    def drop_elem_b(lib):
        lines = [ln for ln in lib.splitlines() if '"elem_b.txt"' not in ln]
        assert len(lines) == len(lib.splitlines()) - 1
        return "\n".join(lines)

    case = _broken_copy(tmp_path, drop_elem_b)
    for argv in (["check", str(case)], ["run", str(case), "--out", str(tmp_path / "out"), *SHORT]):
        r = pulseform(*argv)
        assert r.returncode == 2, argv  # bad input, found before the first step (check: without running)
        line = one_line_error(r)
        assert "breaks the deck contract" in line and "elem_b.txt" in line and "EM_Elem" in line
        assert "elem_f.txt" not in line  # only what is missing is named


@pytest.mark.getdp
def test_deck_without_the_resolution_names_it(tmp_path):
    case = _broken_copy(tmp_path, lambda lib: lib.replace("{ Name EM_Transient;", "{ Name MyTransient;"))
    r = pulseform("check", str(case))
    assert r.returncode == 2
    line = one_line_error(r)
    assert "EM_Transient" in line and "sheet_bulge.pro" in line


def test_unknown_group_name_is_named(tmp_path):
    r = pulseform("run", str(CASE), "--out", str(tmp_path / "out"), *SHORT, "--set", "geometry.regions.coil=COILS")
    assert r.returncode == 2
    line = one_line_error(r)
    assert "geometry.regions.coil" in line and "'COILS'" in line and "COIL" in line


def test_deck_paths_stay_inside_the_case_folder(tmp_path):
    r = pulseform("check", str(CASE), "--set", "geometry.pro=../emf_sheet_bulge/case.pro")
    assert r.returncode == 2 and "outside the case folder" in one_line_error(r) and "geometry.pro" in r.stderr
    outside = tmp_path / "mine.pro"  # a working deck elsewhere (check runs its contract step)
    outside.write_text((CASE / "sheet_bulge.pro").read_text())
    shutil.copy(CASE / "sheet_bulge_common.pro", tmp_path)
    r = pulseform("check", str(CASE), "--set", f"geometry.pro={outside}")
    assert r.returncode == 2 and "allow_outside" in one_line_error(r)
    r = pulseform("check", str(CASE), "--set", f"geometry.pro={outside}", "--set", "geometry.allow_outside=true")
    assert r.returncode == 0, r.stderr
    r = pulseform("check", str(CASE), "--set", "geometry.mesh=missing.geo")
    assert r.returncode == 2 and "file not found" in one_line_error(r)


def test_paths_resolve_from_the_case_folder_not_the_cwd(tmp_path):
    r = pulseform("check", str(CASE), cwd=tmp_path)
    assert r.returncode == 0
    assert f'pro = "{CASE / "sheet_bulge.pro"}"' in r.stdout


@pytest.mark.slow
@pytest.mark.getdp
def test_user_deck_on_both_getdp_paths_gives_the_same_results(tmp_path):
    """(Slow, ~11 s: two more runs of the example. The default tier's companions: the two getdp paths equal on
    the same steps, tests/getdp/test_persistent.py::test_same_results_as_one_process_per_step; the user deck
    on 'auto' (BDF2: the persistent getdp) end to end, test_user_deck_matches_the_builtin_case; the per-step
    path chosen and logged, test_user_deck_without_the_persistent_resolution_runs_per_step.)
    Issue 15: a user deck on PulseformLib runs on the persistent getdp (em.getdp_process = 'auto'
    with BDF2 selects it after a probe) and on a getdp process per EM step with the same results
    (round-off: the two paths solve the same systems; tests/getdp/test_persistent.py gives 8e-14 on
    one step; the persistent path factorises every step here, em.factor_reuse_tol = 0: kept factors solve to
    a 1e-10 residual, not to round-off)."""
    metrics, logs = {}, {}
    for mode in ("auto", "per_step"):
        r = pulseform("run", str(CASE), "--out", str(tmp_path / mode), *SHORT, "--set", f"em.getdp_process='{mode}'",
                      "--set", "em.factor_reuse_tol=0")
        assert r.returncode == 0, r.stderr[-3000:]
        metrics[mode] = json.loads((tmp_path / mode / "metrics.json").read_text())
        logs[mode] = (tmp_path / mode / "run.log").read_text()
    assert "user deck: one persistent getdp process" in logs["auto"]
    assert "user deck: a getdp process per EM step" in logs["per_step"]
    assert (tmp_path / "auto/em/persistent_001/getdp.log").is_file()
    assert not [f for f in (tmp_path / "auto").rglob("*") if f.is_fifo()]  # a FIFO would block a reader
    # measured: at most 3.3e-13 relative (kinetic energy), 2e-14 on the peak current
    keys = ("force_impulse_Ns", "coil_current_peak_kA", "coil_joule_heat_J", "kinetic_energy_final_J",
            "sheet_max_von_mises_MPa")
    for key in keys:
        assert metrics["auto"][key] == pytest.approx(metrics["per_step"][key], rel=1e-11), key


@pytest.mark.getdp
def test_user_deck_without_the_persistent_resolution_runs_per_step(tmp_path):
    """A deck on its own copy of the library without Lib_Persistent.pro: 'auto' falls back to a getdp
    process per EM step (logged); an explicit 'persistent' is one line naming EM_Persistent, exit 2."""
    def drop_persistent(lib):
        assert "Include PulseformPersistentLib;" in lib
        return lib.replace("Include PulseformPersistentLib;", "")

    case = _broken_copy(tmp_path, drop_persistent)
    r = pulseform("run", str(case), "--out", str(tmp_path / "auto"), *SHORT)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "user deck: a getdp process per EM step" in (tmp_path / "auto/run.log").read_text()
    r = pulseform("run", str(case), "--out", str(tmp_path / "persistent"), *SHORT, "--set", "em.getdp_process='persistent'")
    assert r.returncode == 2
    line = one_line_error(r)
    assert "EM_Persistent" in line and "getdp_process" in line


# ----------------------------------------------------------------------------- the deck check (issue 18)
def _edited_deck(tmp_path, edit_pro, toml: str = "case.toml"):
    """A copy of the example whose own deck sheet_bulge.pro is edited by ``edit_pro`` (which must
    change it); returns the case file ``toml`` of the copy."""
    case = tmp_path / "case"
    shutil.copytree(CASE, case, ignore=shutil.ignore_patterns("reference"))
    pro = case / "sheet_bulge.pro"
    text = pro.read_text()
    edited = edit_pro(text)
    assert edited != text
    pro.write_text(edited)
    return case / toml


def _own_ids(text: str, roles=("Air", "Shell", "Coil_1", "Cond_1", "Axis", "Outer")) -> str:
    """The deck's regions on its own physical ids (AIR, COIL, ... of sheet_bulge_common.pro) instead
    of the ids the runner passes (Phys_*): the runner renumbered the mesh's groups, so they are empty."""
    own = {"Air": "AIR", "Shell": "INF", "Coil_1": "COIL", "Cond_1": "SHEET", "Cond_2": "DIE", "Axis": "AXIS",
           "Outer": "OUTER"}
    for role in roles:
        assert f"Region[{{Phys_{role}}}]" in text
        text = text.replace(f"Region[{{Phys_{role}}}]", f"Region[{{{own[role]}}}]")
    return text


def _refused(case, *sets) -> str:
    """``pulseform check`` of a broken deck: exit 2 and its one error line."""
    r = pulseform("check", str(case), *[a for s in sets for a in ("--set", s)])
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    return one_line_error(r)


@pytest.mark.getdp
def test_hollow_deck_is_refused(tmp_path):
    """The deck's groups on its own region numbers, which pulseform's renumbering leaves empty:
    getdp solves an empty model without complaint (the old contract check passed it: every table
    existed); the check names the zero energy, the missing force rows and the empty field state."""
    line = _refused(_edited_deck(tmp_path, _own_ids))
    assert "sheet_bulge.pro is hollow" in line
    assert "W = 0" in line and "force rows for 0 of 486 workpiece elements" in line
    assert "field state on 0 of" in line and "Phys_*" in line


@pytest.mark.getdp
def test_deck_with_a_hollow_workpiece_or_die_is_refused(tmp_path):
    """Only the workpiece on the deck's own id (the coil works: W and the current are not zero),
    then only the die of with_die.toml: one force row per workpiece and die element is required."""
    line = _refused(_edited_deck(tmp_path / "sheet", lambda t: _own_ids(t, ("Cond_1",))))
    assert "is hollow" in line and "force rows for 0 of 486 workpiece elements" in line and "W =" not in line
    line = _refused(_edited_deck(tmp_path / "die", lambda t: _own_ids(t, ("Cond_2",)), "with_die.toml"))
    assert "is hollow" in line and "force rows for 486 of 1582 workpiece and die elements" in line


@pytest.mark.getdp
def test_deck_that_ignores_the_state_carry_is_refused(tmp_path):
    """A library copy whose Init constraint never applies (Flag_InitA ignored): every step on the
    Init path (every BDF2 step) would restart from a zero field; one step alone looks right."""
    def ignore_init(lib):
        assert lib.count("If(Flag_InitA == 1)") == 1
        return lib.replace("If(Flag_InitA == 1)", "If(Flag_InitA == 99)")

    line = _refused(_broken_copy(tmp_path, ignore_init))
    assert "does not carry its state (Init path: Flag_InitA" in line and "two-step run" in line
    assert "in the force density" in line  # measured: 0.38


@pytest.mark.getdp
def test_deck_that_restarts_its_capacitor_is_refused(tmp_path):
    """The deck's own ``Init_Vc = 6e3;`` wins over the carried capacitor voltage: every step restarts
    the bank at full charge (the field itself is carried)."""
    case = _edited_deck(tmp_path, lambda t: t.replace("Include PulseformLib;", "Init_Vc = 6e3;\nInclude PulseformLib;"))
    line = _refused(case)
    assert "does not carry its state (Init path" in line and "Init_Vc" in line  # measured: 8.7e-05 in W


@pytest.mark.getdp
def test_deck_with_its_own_time_window_is_refused(tmp_path):
    """The deck's own ``TimeFinal = 10e-6;`` wins over the runner's -setnumber: the check's step
    ends at 10 µs instead of 0.1 µs."""
    case = _edited_deck(tmp_path, lambda t: t.replace("Include PulseformLib;", "TimeFinal = 10e-6;\nInclude PulseformLib;"))
    line = _refused(case)
    assert "overrides the time window" in line and "W.txt has 1 row(s) ending at t = 1e-05 s" in line
    assert "ending at 1e-07 s" in line
    n = next(i for i, ln in enumerate((case.parent / "sheet_bulge.pro").read_text().splitlines(), 1) if "TimeFinal = 10e-6;" in ln)
    assert line.endswith(f"(sheet_bulge.pro:{n} assigns it: write DefineConstant[ TimeFinal = 10e-6 ]; instead)"), line


def _shipped_user_decks() -> list:
    """Every case file under cases/ on a user deck written on pulseform's library."""
    found = []
    for toml in sorted((REPO / "cases").glob("*/*.toml")):
        text = toml.read_text()
        if '"user_deck"' in text and '"getdp_template"' not in text:  # template decks: test_template_deck.py
            found.append(toml)
    assert CASE / "case.toml" in found and CASE / "with_die.toml" in found
    return found


@pytest.mark.getdp
@pytest.mark.parametrize("toml", _shipped_user_decks(), ids=lambda p: f"{p.parent.name}/{p.name}")
@pytest.mark.parametrize("scheme", ["bdf2", "euler"])
def test_every_shipped_deck_passes_the_check_with_a_runs_numbers(tmp_path, toml, scheme):
    """The check on every shipped user deck: it solves the model (one force row per conductor
    element, the field state on every coil and conductor node), two chained one-step runs equal one
    two-step run to round-off through the Init path (measured 6.9e-13 / 9.1e-13 with the die: the
    nodal values travel as printed digits) and, for implicit Euler, the restart path (5e-16); its
    getdp numbers are exactly those of a run's first step (the role ids Phys_* and
    [geometry.parameters] included); its getdp runs take well under 2 s here (measured 0.55 s)."""
    from pulseform.orchestrator.em import user_deck as ud
    from pulseform.solvers.getdp import conductor_tag

    case, _ = load_case(toml, [f"em.time_scheme='{scheme}'"])
    g = case.geometry
    mesh = ud.read_deck_mesh(ud.mesh_file(g, tmp_path / "mesh"), g.regions, coils=g.coils)
    model = ud.user_em_model(case)
    report = ud.check_contract(ud.make_solver(case, model, tmp_path / "em"), mesh, tmp_path / "em/contract_check")
    tags = [conductor_tag(k) for k in range(1, len(model.conductors) + 1)]
    assert report.force_rows == np.isin(mesh.tri_tags, tags).sum() > 0
    assert report.magnetic_energy > 0 and report.coil_current > 0 and report.state_nodes > 0
    assert set(report.carry_difference) == ({"init"} if scheme == "bdf2" else {"init", "restart"})
    assert max(report.carry_difference.values()) < 1e-11
    assert report.wall_time_s < 10.0  # generous (shared CPUs); measured 0.55 s

    def numbers(argv):
        return {argv[i + 1]: float(argv[i + 2]) for i, a in enumerate(argv[:-2]) if a == "-setnumber"}

    checked = numbers(report.argv)
    for name in ud.ROLE_NUMBERS.values():
        assert (name in checked) == (name != "Phys_Cond_2" or len(tags) == 2), name
    n_coils = len(model.coils)  # two_coils.toml: [[geometry.coils]] inner, outer -> 101, 102
    assert checked["NbCoils"] == n_coils == max(len(g.coils), 1)
    assert [checked[f"Phys_Coil_{k}"] for k in range(1, n_coils + 1)] == [100 + k for k in range(1, n_coils + 1)]
    assert f"Phys_Coil_{n_coils + 1}" not in checked
    assert {k: float(v) for k, v in g.parameters.items()}.items() <= checked.items()
    run = ud.make_solver(case, model, tmp_path / "run")  # a run's first EM step, per-step getdp
    result, _ = run.step(mesh, run.initial_state(0.0), 1e-7)
    assert numbers(result.run.argv) == checked
