"""Decks on GetDP's template (``geometry.library = "getdp_template"``) beyond the one coil on a bank
(issue 18): two coils in series on the bank, a die beside the workpiece (the worked example
cases/template_sheet_bulge/with_die.toml), a coil current prescribed by the deck's own ``Current_2D``,
and a planar deck (``geometry.planar = true``).

Reference of each: the same configuration on pulseform's library ``Lib_PulsedForming.pro`` (the decks of
cases/user_deck_sheet_bulge) on the identical mesh (the same .geo with the same parameters: asserted
node for node). Both decks discretise the same equations (the template's massive conductor with
``Voltage_2D`` 0 is j = -sigma dA/dt; its stranded coil js = Ns/Sc I e_z), so every EM output of eight
implicit-Euler steps of 0.25 us (coil currents and voltages, Joule powers, forces per conductor, the
force density of every conductor element, the magnetic energy, the capacitor voltage) agrees to the
round-off of two linear systems: measured <= 4e-15 relative (printed by the test); asserted 1e-9.
The decks of the first, third and fourth are test data (tests/workflow/template_decks/), written as a
GetDP user writes them (no pulseform-specific line); they run on copies of cases/user_deck_sheet_bulge.
"""

from __future__ import annotations

import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from pulseform.orchestrator.case.io import load_case

from wf_helpers import REPO, one_line_error, pulseform

LIBRARY = REPO / "cases/user_deck_sheet_bulge"
DECKS = Path(__file__).with_name("template_decks")
DIE_EXAMPLE = REPO / "cases/template_sheet_bulge/with_die.toml"
#: the decks' own pulse (current_template.pro): I0 e^(-Decay t) sin(Omega_I t)
PULSE = {"amplitude": 20e3, "beta": 1e4, "omega": 1e5}
STEPS, DT = 8, 0.25e-6


def _folder(tmp_path: Path) -> Path:
    """cases/user_deck_sheet_bulge (mesh, library decks, case files) plus the template decks."""
    folder = tmp_path / "case"
    shutil.copytree(LIBRARY, folder, ignore=shutil.ignore_patterns("reference"))
    for deck in [*DECKS.glob("*.pro"), *DIE_EXAMPLE.parent.glob("sheet_bulge*template.pro")]:
        shutil.copy(deck, folder)
    shutil.copy(DIE_EXAMPLE, folder / "with_die_template.toml")
    return folder


def _pair(folder: Path, base: str, pro: str, edit=None, scheme: str = "euler") -> tuple[Path, Path]:
    """(library case, template case): ``base`` of the library folder stepped with ``scheme``, edited by
    ``edit(data)``; the template case is the same with ``pro`` on GetDP's template."""
    data = tomllib.loads((folder / base).read_text())
    data["em"]["time_scheme"] = scheme
    if edit is not None:
        edit(data)
    lib = folder / f"lib_{pro[:-4]}.toml"
    lib.write_text(tomli_w.dumps(data))
    data["geometry"].update(library="getdp_template", pro=pro)
    tpl = folder / f"tpl_{pro[:-4]}.toml"
    tpl.write_text(tomli_w.dumps(data))
    return lib, tpl


def _prescribed(data: dict) -> None:
    del data["em"]["circuit"]
    data["em"]["current"] = dict(PULSE)


def _planar(data: dict) -> None:
    _prescribed(data)
    data["geometry"]["planar"] = True
    data["mechanics"]["formulation"] = "plane_strain"


def _em_run(toml: Path, work: Path, steps=(DT,) * STEPS):
    """The case's EM geometry (built as a run builds it: mesh, deck check, value check), then EM steps
    of ``steps`` (s) on the run's solver (one getdp run per step: the library deck's carry is the Init
    path under BDF2, the template deck's always -restart)."""
    from pulseform.orchestrator.em import user_deck as ud

    case, _ = load_case(toml)
    geometry = ud.build_user_geometry(case, work / "em_mesh", work / "em")
    model = ud.user_em_model(case)
    solver = ud.make_solver(case, model, work / "em", deck_ids=getattr(geometry, "deck_ids", None))
    state = solver.initial_state(0.0)
    results = []
    for t in np.cumsum(steps):
        result, state = solver.step(geometry.mesh, state, float(t))
        results.append(result)
    return geometry, results


QUANTITIES = ("coil_current", "coil_voltage", "coil_power", "conductor_force", "conductor_power", "magnetic_energy",
              "force_density", "capacitor_voltage")


def _same_run(tmp_path: Path, lib: Path, tpl: Path, n_coils: int, n_conductors: int, steps=(DT,) * STEPS,
              rtol: float = 1e-9) -> list:
    """The template case's EM steps equal the library case's on the same mesh (module docstring);
    returns the template's results."""
    gl, rl = _em_run(lib, tmp_path / "lib", steps)
    gt, rt = _em_run(tpl, tmp_path / "tpl", steps)
    assert np.array_equal(gl.mesh.points, gt.mesh.points) and np.array_equal(gl.mesh.triangles, gt.mesh.triangles)
    assert np.array_equal(gl.mesh.tri_tags, gt.mesh.tri_tags)
    assert rl[-1].coil_current.shape[1] == n_coils and rl[-1].conductor_force.shape[1] == n_conductors
    for name in QUANTITIES:
        a = [getattr(r, name) for r in rl]
        b = [getattr(r, name) for r in rt]
        if a[0] is None:
            assert b[0] is None, name
            continue
        a, b = np.concatenate([np.ravel(x) for x in a]), np.concatenate([np.ravel(x) for x in b])
        scale = float(np.abs(a).max())
        diff = float(np.abs(a - b).max()) / scale
        print(f"{name}: max |template - library| = {diff:.1e} of max |library| = {scale:.4g}")
        assert scale > 0 and diff <= rtol, name
    assert float(np.abs(rl[-1].coil_current).max()) > 1e3  # a real current flows: a real comparison
    return rt


@pytest.mark.slow
@pytest.mark.getdp
def test_two_coils_in_series_on_the_bank_equal_the_library_deck(tmp_path):
    """(Slow: a variant of the comparison _same_run, whose default-tier run is
    test_bdf2_by_restart_equals_the_library_decks_bdf2; two coils in series on a user deck's bank:
    tests/workflow/test_user_deck_coils.py)
    two_coils_template.pro (the circuit C -> R -> L -> inner coil -> outer coil -> C, 2 + 3 turns)
    against cases/user_deck_sheet_bulge/two_coils.toml."""
    lib, tpl = _pair(_folder(tmp_path), "two_coils.toml", "two_coils_template.pro")
    _same_run(tmp_path, lib, tpl, 2, 1)


@pytest.mark.slow
@pytest.mark.getdp
def test_the_die_example_equals_the_library_deck(tmp_path):
    """(Slow: a variant of the comparison _same_run, whose default-tier run is
    test_bdf2_by_restart_equals_the_library_decks_bdf2; the die example's template deck against the library's, coupled:
    tests/workflow/test_user_remesh.py::test_template_and_library_decks_carry_a_remesh_alike)
    The worked example cases/template_sheet_bulge/with_die.toml as shipped (the sheet and the steel
    die two massive conductors) against cases/user_deck_sheet_bulge/with_die.toml stepped implicit Euler."""
    folder = _folder(tmp_path)
    lib, _ = _pair(folder, "with_die.toml", "sheet_bulge_die_template.pro")
    _same_run(tmp_path, lib, folder / "with_die_template.toml", 1, 2)


@pytest.mark.slow
@pytest.mark.getdp
def test_a_prescribed_current_equals_the_library_deck(tmp_path):
    """(Slow: a variant of the comparison _same_run, whose default-tier run is
    test_bdf2_by_restart_equals_the_library_decks_bdf2; the deck's Current_2D stepped by the run's guard:
    test_a_current_that_drifts_after_the_check_stops_the_run)
    current_template.pro (the template's Current_2D on the coil, no circuit) against case.toml with
    em.current = the same pulse; the coil current is the pulse's formula (to 1e-12 of its amplitude)."""
    lib, tpl = _pair(_folder(tmp_path), "case.toml", "current_template.pro", _prescribed)
    _same_run(tmp_path, lib, tpl, 1, 1)
    _, rt = _em_run(tpl, tmp_path / "again")
    t = np.concatenate([r.times for r in rt])
    i = np.concatenate([r.coil_current[:, 0] for r in rt])
    want = PULSE["amplitude"] * np.exp(-PULSE["beta"] * t) * np.sin(PULSE["omega"] * t)
    assert np.abs(i - want).max() <= 1e-12 * PULSE["amplitude"]


@pytest.mark.slow
@pytest.mark.getdp
def test_a_planar_deck_equals_the_library_deck_in_plane_mode(tmp_path):
    """(Slow: a variant of the comparison _same_run, whose default-tier run is
    test_bdf2_by_restart_equals_the_library_decks_bdf2; the planar deck's check:
    test_a_deck_that_contradicts_the_case_is_refused)
    current_template.pro with Flag_Axi = 0 (the runner's -setnumber reaches its DefineConstant;
    CoefGeos = 1) against case.toml with geometry.planar = true: the half model x >= 0 per metre of
    depth, a = 0 on the symmetry plane x = 0 (the mesh's AXIS)."""
    lib, tpl = _pair(_folder(tmp_path), "case.toml", "current_template.pro", _planar)
    _same_run(tmp_path, lib, tpl, 1, 1)


@pytest.mark.getdp
def test_bdf2_by_restart_equals_the_library_decks_bdf2(tmp_path):
    """BDF2 on the template deck (cases/template_sheet_bulge's sheet_bulge_template.pro): every step one
    implicit-Euler step of gamma dt from x_tilde = c1 x_{n-1} - c2 x_{n-2}, written by pulseform as a .res
    of the whole solution and restarted from (solvers/getdp/template.py), against the library deck's BDF2
    (case.toml as shipped, one getdp run per step: x_tilde through its Init constraints) on the same mesh,
    with step ratios 1.5, 0.5, 1.67, 1.6, 0.25, 2 (variable-step BDF2). The library's x_tilde travels as
    printed digits (nodes_a.txt): measured <= 8.1e-13 relative; asserted 1e-9. The same steps in
    implicit Euler differ from BDF2 by ~1e-3: the comparison sees the scheme."""
    steps = (2e-7, 3e-7, 1.5e-7, 2.5e-7, 4e-7, 1e-7, 2e-7)
    folder = _folder(tmp_path)
    lib, tpl = _pair(folder, "case.toml", "sheet_bulge_template.pro", scheme="bdf2")
    bdf2 = _same_run(tmp_path, lib, tpl, 1, 1, steps)
    _, euler_lib = _pair(folder, "case.toml", "sheet_bulge_template.pro")
    _, euler = _em_run(euler_lib, tmp_path / "euler", steps)
    gap = abs(euler[-1].coil_current[-1, 0] / bdf2[-1].coil_current[-1, 0] - 1)
    print(f"implicit Euler vs BDF2, coil current at {sum(steps) * 1e6:.2g} us: {gap:.1e}")
    assert gap > 1e-5


# ----------------------------------------------------------------------------- the deck's values against the case's
def _edited_deck(folder: Path, old: str, new: str) -> None:
    pro = folder / "current_template.pro"
    text = pro.read_text()
    assert text.count(old) == 1
    pro.write_text(text.replace(old, new))


@pytest.mark.getdp
@pytest.mark.parametrize("planar, old, new, words", [
    (True, 'Include "sheet_bulge_common.pro";', 'Include "sheet_bulge_common.pro";\nFlag_Axi = 1;',
     ["geometry.planar = true (planar), the deck's Jacobian Vol on COIL is axisymmetric (Flag_Axi)"]),
    (True, "CoefGeos[] = 1; // per metre of depth", "CoefGeos[] = 0.1;",
     ["geometry.planar = true (CoefGeos[] = 1), the deck's CoefGeos[] on COIL = 0.1"]),
    (False, "CoefGeos[] = 2 * Pi;", "CoefGeos[] = 1;",
     ["geometry.planar = false (CoefGeos[] = 6.28319), the deck's CoefGeos[] on COIL = 1"]),
    (False, "I0 = 20e3,", "I0 = 25e3,",
     ["em.current gives 199.797 A at t = 1e-07 s, the deck's Current_2D on COIL = 249.746 A"]),
])
def test_a_deck_that_contradicts_the_case_is_refused(tmp_path, planar, old, new, words):
    """The deck's geometry (Jacobian Vol, CoefGeos[]) and its own Current_2D against the case's, in one
    line naming both (check's first step: t = 1e-7 s; I = 20 kA e^(-1e-3) sin(0.01) = 199.797 A, 25 kA: 249.746 A)."""
    folder = _folder(tmp_path)
    _, tpl = _pair(folder, "case.toml", "current_template.pro", _planar if planar else _prescribed)
    _edited_deck(folder, old, new)
    r = pulseform("check", str(tpl))
    assert r.returncode == 2, r.stderr[-2000:]
    line = one_line_error(r)
    assert "current_template.pro and the case differ" in line
    for w in words:
        assert w in line, line


@pytest.mark.getdp
def test_a_current_that_drifts_after_the_check_stops_the_run(tmp_path):
    """The case's decay 1.001e4 1/s against the deck's 1e4: at the check's step (0.1 us) the currents
    differ by 1e-6 relative (2e-4 A, within the tolerance of 1e-6 of the 20 kA amplitude), at 2 us by
    2e-5 relative (0.06 A): the run's step guard (TemplateDeckSolver.check_currents) stops it, one line."""
    from pulseform.solvers.getdp.template import TemplateDeckError

    def drift(data):
        _prescribed(data)
        data["em"]["current"]["beta"] = 1.001e4

    _, tpl = _pair(_folder(tmp_path), "case.toml", "current_template.pro", drift)
    with pytest.raises(TemplateDeckError, match=r"coil 1: the deck's Current_2D gives .* A at t = .* s, the case's "
                                                r"source .* A"):
        _em_run(tpl, tmp_path / "run")
