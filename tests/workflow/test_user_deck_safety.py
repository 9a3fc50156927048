"""A user's deck is code (issue 13): its parameters are checked names and numbers, a deck that runs
programs is refused when the case is loaded (before gmsh or getdp ever run), gmsh on a .geo runs
under a time limit, and ``pulseform check`` leaves no temporary folder behind, pass or fail.

The checks run ``pulseform.orchestrator.cli.main`` in-process on a copy of the example
``cases/user_deck_sheet_bulge`` and compare real effects: exit codes, the one error line, a marker
file that a ``SystemCall`` would create, the temporary folders left, the time taken."""

from __future__ import annotations

import re
import shutil
import subprocess
import time
import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import tomli_w

from pulseform.orchestrator import cli
from pulseform.orchestrator.em import user_deck
from pulseform.orchestrator.em.user_deck import DeckContractError, find_program_call, mesh_file
from pulseform.solvers.getdp import solver as getdp_solver
from pulseform.solvers.getdp.contract import runner_number_names

from wf_helpers import REPO

CASE = REPO / "cases/user_deck_sheet_bulge"
#: a .geo whose parameter N sets the number of points: N = 1e9 keeps gmsh busy for hours
POINTS_GEO = """DefineConstant[ N = 10 ];
For i In {1:N}
  Point(i) = {i * 1e-3, 0, 0, 1e-3};
EndFor
"""


@pytest.fixture
def case(tmp_path, monkeypatch):
    """A copy of the example deck; temporary folders of ``check`` go to ``tmp_path/tmp``."""
    folder = tmp_path / "case"
    shutil.copytree(CASE, folder, ignore=shutil.ignore_patterns("reference", "with_die.toml"))
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    monkeypatch.setenv("PULSEFORM_TRACEBACK", "1")  # an internal error fails the test with its traceback
    return folder


def main(argv: list[str]) -> int:
    """``cli.main`` in-process, without keeping the console handler it adds to the root logger
    (bound to this test's captured stderr)."""
    import logging

    root = logging.getLogger()
    before = list(root.handlers)
    try:
        return cli.main(argv)
    finally:
        for h in root.handlers[:]:
            if h not in before:
                root.removeHandler(h)


def check(folder: Path, *sets: str, capsys) -> tuple[int, str]:
    """``pulseform check folder --set ...`` in-process: (exit code, the error line or "")."""
    capsys.readouterr()
    code = main(["check", str(folder), *[a for s in sets for a in ("--set", s)]])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.startswith("pulseform: error:")]
    assert len(lines) == (code != 0), err[-2000:]
    return code, lines[0] if lines else ""


def set_parameters(folder: Path, params: dict) -> None:
    data = tomllib.loads((folder / "case.toml").read_text())
    data["geometry"]["parameters"] = params
    (folder / "case.toml").write_text(tomli_w.dumps(data))


# ----------------------------------------------------------------------------- 1. parameters
def test_runner_number_names_cover_every_name_a_getdp_step_defines(tmp_path, monkeypatch):
    """Against a real GetDPSolver.step (getdp itself replaced by a recorder): every -setnumber /
    -setstring name and every list run.pro defines is in runner_number_names()."""
    from pulseform.solvers.getdp import Circuit, Coil, Conductor, CurrentTable, EMMesh, EMModel, GetDPSolver

    seen: list[tuple[dict, dict, str]] = []

    class Recorded(Exception):
        pass

    def fake_run_getdp(deck, mesh, run_dir, *, numbers, strings, **kw):
        seen.append((numbers, strings, Path(deck).read_text()))
        raise Recorded

    monkeypatch.setattr(getdp_solver, "run_getdp", fake_run_getdp)
    mesh = EMMesh([(0.1, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)], [[0, 1, 2], [0, 2, 3]], [101, 201],
                  [[0, 3], [1, 2]], [11, 12])
    models = [EMModel(True, [Coil(3)], [Conductor(1e7)], circuit=Circuit(1e-4, 1e3), shell=(1.0, 2.0),
                      probes=[(0.5, 0.5)]),
              EMModel(True, [Coil(3, waveform=CurrentTable([0.0, 1e-6], [0.0, 1.0]))], [Conductor(1e7)])]
    for k, model in enumerate(models):
        solver = GetDPSolver(model, tmp_path / f"s{k}")
        state = solver.initial_state()
        with pytest.raises(Recorded):
            solver.step(mesh, state, 1e-7)
        # the Init path (state carried to a new mesh) defines InitA_List and Flag_InitA
        state.res_path, state.mesh_signature = str(tmp_path / "none.res"), "other"
        state.a_points, state.a_triangles = mesh.points.tolist(), mesh.triangles.tolist()
        state.a_values = np.zeros(len(mesh.points)).tolist()
        with pytest.raises(Recorded):
            solver.step(mesh, state, 1e-7)
    reserved = set(runner_number_names())
    defined = set()
    for numbers, strings, wrapper in seen:
        defined |= set(numbers) | set(strings)
        defined |= set(re.findall(r"^(\w+)\(\) =", wrapper, flags=re.M))
    assert {"C_bank", "TimeInit", "NbSteps", "Flag_InitA", "OutDir", "InitA_List", "Coil_Table_1"} <= defined
    missing = {n for n in defined if re.sub(r"_\d+$", "_<k>", n) not in reserved}
    assert not missing, missing


@pytest.mark.parametrize("name", ["a b", "-o", "x;y", 'q"', "1abc", "Lc-Sheet", "é", "x" * 65])
def test_parameter_names_must_be_identifiers(case, capsys, name):
    set_parameters(case, {"NbTurns": 5, name: 1.0})
    code, line = check(case, capsys=capsys)
    assert code == 2
    assert "case.toml" in line and "geometry.parameters." in line and "identifier" in line


@pytest.mark.parametrize("name", ["C_bank", "Phys_Coil_1", "Phys_Air", "Coil_Ns_1", "Coil_sigma_3", "Cond_sigma_2",
                                  "TimeInit", "NbSteps", "Flag_ElemOut", "Init_Vc", "OutDir", "PulseformLib",
                                  "InitA_List", "Probe_X_1"])
def test_parameters_may_not_shadow_a_number_the_runner_sets(case, capsys, name):
    set_parameters(case, {"NbTurns": 5, name: 1.0})
    code, line = check(case, capsys=capsys)
    assert code == 2
    assert f"geometry.parameters.{name}:" in line and "case.toml" in line
    assert "Reserved: Phys_*, Pulseform{Lib,HarmonicLib,MagneticLib,NewtonLib,PersistentLib}, C_bank" in line
    assert len(line) <= 320


@pytest.mark.parametrize("value", [float("inf"), float("nan"), "5", True, 10 ** 400, [1, 2]])
def test_parameter_values_must_be_finite_numbers(case, capsys, value):
    set_parameters(case, {"NbTurns": value})
    code, line = check(case, capsys=capsys)
    assert code == 2
    assert "geometry.parameters.NbTurns:" in line and "finite number" in line and len(line) <= 320


def test_the_docs_list_every_reserved_name():
    docs = (REPO / "docs/workflow.md").read_text()
    for item in user_deck.reserved_listing().split(", "):
        assert f"`{item}`" in docs or item == "Phys_*", item
    for name in user_deck.ROLE_NUMBERS.values():
        assert f"`{name}`" in docs, name


def test_names_that_only_look_like_runner_numbers_pass():
    for ok in ("Coil_Gap", "Coil_Ns", "C_bank2", "Phys_Coil_x", "Coil_Split", "TimeEnd", "Lc_Sheet"):
        assert not user_deck.is_reserved_parameter(ok), ok
    for bad in ("Coil_Ns_12", "Cond_sigma_1", "Val_Rint", "Phys_Coil_9",  # Phys_Coil_<k>: coil k's id
                "Cond_MuR_2", "Cond_BH_1", "NL_tol_rel", "NbCores", "PulseformMagneticLib"):  # the magnetic block's
        assert user_deck.is_reserved_parameter(bad), bad


# ----------------------------------------------------------------------------- 2. decks that run programs
def _marker_geo(folder: Path, marker: Path, command: str = "SystemCall") -> int:
    """Append ``command "touch marker"`` to the example .geo; return its line number."""
    geo = folder / "sheet_bulge.geo"
    text = geo.read_text().rstrip("\n") + "\n"
    geo.write_text(text + f'{command} "touch {marker}";\n')
    return text.count("\n") + 1


@pytest.mark.parametrize("command", ["SystemCall", "System", "NonBlockingSystemCall"])
def test_a_geo_that_runs_a_program_is_refused_before_gmsh_runs(case, capsys, tmp_path, command):
    marker = tmp_path / f"marker_{command}"
    line_no = _marker_geo(case, marker, command)
    code, line = check(case, capsys=capsys)
    assert code == 2
    assert f"geometry.mesh: sheet_bulge.geo:{line_no}: {command} runs a program" in line
    assert "refused unless geometry.allow_system_calls = true" in line
    time.sleep(0.5 if command == "NonBlockingSystemCall" else 0)
    assert not marker.exists()
    assert not any((tmp_path / "tmp").iterdir())  # nothing was meshed


def test_allow_system_calls_runs_the_deck(case, capsys, tmp_path):
    """The control: the same deck with allow_system_calls = true does create the marker (and
    still honours the contract)."""
    marker = tmp_path / "marker"
    _marker_geo(case, marker)
    code, line = check(case, "geometry.allow_system_calls=true", capsys=capsys)
    assert code == 0, line
    assert marker.exists()


def test_run_refuses_it_too(case, tmp_path):
    marker = tmp_path / "marker"
    _marker_geo(case, marker)
    out = tmp_path / "out"
    code = main(["run", str(case), "--out", str(out), "--quiet", "--set", "time.end=1e-6"])
    assert code == 2 and not marker.exists() and not (out / "em_mesh").exists()


def test_program_calls_are_found_through_includes(case, capsys, tmp_path):
    """.geo -> sub/a.geo -> ../b.geo (relative to the including file; b includes a again: a cycle)
    -> SystemCall; .pro -> evil.pro -> SystemCommand. Missing includes are skipped."""
    marker = tmp_path / "marker"
    (case / "sub").mkdir()
    (case / "sub/a.geo").write_text('Include "missing.geo";\nInclude "../b.geo";\n')
    (case / "b.geo").write_text(f'Include "sub/a.geo";\n\n// System\nSystemCall "touch {marker}";\n')
    geo = case / "sheet_bulge.geo"
    geo.write_text(geo.read_text() + '\nInclude "sub/a.geo";\n')
    code, line = check(case, capsys=capsys)
    assert code == 2 and ": b.geo:4: SystemCall runs a program" in line
    assert not marker.exists()

    geo.write_text((CASE / "sheet_bulge.geo").read_text())
    (case / "evil.pro").write_text('/* SystemCommand */\nResolution { { Name X;\n'
                                   f'  Operation {{ SystemCommand["touch {marker}"]; }} }} }}\n')
    pro = case / "sheet_bulge.pro"
    pro.write_text(pro.read_text().replace('Include "sheet_bulge_common.pro";',
                                           'Include "sheet_bulge_common.pro";\nInclude "evil.pro";'))
    code, line = check(case, capsys=capsys)
    assert code == 2 and "geometry.pro: evil.pro:3: SystemCommand runs a program" in line


@pytest.mark.parametrize("text, found", [
    ('// SystemCall "x";\n/* System "y";\n SystemCall */\nPrintf("SystemCall \\" System");\n', None),
    ('Point(1) = {0, 0, 0};\nMySystemCall = 1; System_x = 2;\n', None),
    ('Merge "mesh.msh";\nMerge "part.STEP";\n', None),
    ('x = 1;\n\n  SystemCall StrCat["to", "uch"];\n', "3: SystemCall runs a program"),
    ('Merge "x.py";\n', "1: Merge of 'x.py'"),
    ('Merge StrCat["x", ".py"];\n', "1: Merge of a computed file name"),
    ('Include StrCat["a", ".geo"];\n', "1: Include of a computed file name"),
    ('OnelabRun("x", "y");\n', "1: OnelabRun runs a program"),
])
def test_the_scan_skips_comments_and_strings(tmp_path, text, found):
    deck = tmp_path / "d.geo"
    deck.write_text(text)
    result = find_program_call(deck, "geo")
    if found is None:
        assert result is None
    else:
        assert result is not None and f"{result[0].rsplit(':', 1)[1]}: {result[1]}".startswith(found)


def test_the_pro_scan_knows_getdp(tmp_path):
    deck = tmp_path / "d.pro"
    deck.write_text('Resolution { { Name R; System { { Name A; NameOfFormulation F; } }\n'
                    '  Operation { Generate[A]; Solve[A]; } } }\nInclude PulseformLib;\n')
    assert find_program_call(deck, "pro") is None  # System is a GetDP keyword, not a call
    deck.write_text('Function { f[] = Python[]{"import os"}; }\n')
    assert find_program_call(deck, "pro")[1] == "Python runs a program"


# ----------------------------------------------------------------------------- 3. + 5. gmsh time limit
def _gmsh_children_of_us() -> list[str]:
    """Command lines of live gmsh processes whose parent is this test process."""
    import os

    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            cmd = (stat.parent / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if int(fields[1]) == os.getpid() and "gmsh" in cmd:
            found.append(cmd)
    return found


def test_mesh_file_stops_gmsh_at_its_time_limit_and_keeps_the_log(tmp_path):
    geo = tmp_path / "points.geo"
    geo.write_text(POINTS_GEO)
    g = SimpleNamespace(mesh=str(geo), parameters={"N": 1e9})
    t0 = time.monotonic()
    with pytest.raises(DeckContractError) as info:
        mesh_file(g, tmp_path / "work", time_limit=1.0)
    assert time.monotonic() - t0 < 15
    msg = str(info.value)
    assert "gmsh exceeded its time limit of 1 s" in msg and str(geo) in msg and "\n" not in msg
    log = tmp_path / "work/gmsh.log"
    assert info.value.log_path == log and log.is_file() and "points.geo" in log.read_text()
    assert _gmsh_children_of_us() == []
    # a sane N meshes well within the limit
    out = mesh_file(SimpleNamespace(mesh=str(geo), parameters={"N": 3}), tmp_path / "ok", time_limit=30)
    assert out.is_file()


@pytest.mark.parametrize("param", ["NbTurns=1e9", "Lc_Sheet=1e-9"])
def test_check_of_an_absurd_parameter_ends_at_the_gmsh_time_limit(case, capsys, tmp_path, param):
    """Issue 13: these made `pulseform check` run gmsh forever; now one line after the limit."""
    t0 = time.monotonic()
    code, line = check(case, f"geometry.parameters.{param}", "limits.gmsh_time_limit_s=2", capsys=capsys)
    wall = time.monotonic() - t0
    assert code == 2 and wall < 30, (code, wall)
    assert "sheet_bulge.geo: meshing with gmsh exceeded its time limit of 2 s (limits.gmsh_time_limit_s)" in line
    assert "(log:" not in line  # the log was in the removed temporary folder
    assert _gmsh_children_of_us() == []
    assert not any((tmp_path / "tmp").iterdir())


def test_a_tiny_geo_with_a_point_count_parameter(case, capsys, tmp_path):
    (case / "points.geo").write_text(POINTS_GEO)
    code, line = check(case, "geometry.mesh='points.geo'", "geometry.parameters.N=1e9",
                       "limits.gmsh_time_limit_s=2", capsys=capsys)
    assert code == 2 and "points.geo: meshing with gmsh exceeded its time limit of 2 s" in line
    assert not any((tmp_path / "tmp").iterdir())


def test_gmsh_dies_with_pulseform(tmp_path):
    """SIGKILL of a `pulseform check` meshing a never-ending .geo: its gmsh child ends too."""
    import os
    import signal
    import sys

    case = tmp_path / "case"
    shutil.copytree(CASE, case, ignore=shutil.ignore_patterns("reference", "with_die.toml"))
    exe = str(Path(sys.executable).with_name("pulseform"))
    tmp = tmp_path / "tmp"  # a SIGKILL leaves check's temporary folder: keep it in tmp_path
    tmp.mkdir()
    proc = subprocess.Popen([exe, "check", str(case), "--set", "geometry.parameters.NbTurns=1e9"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=dict(os.environ, TMPDIR=str(tmp)))
    try:
        gmsh_pid = None
        for _ in range(200):
            for stat in Path("/proc").glob("[0-9]*/stat"):
                try:
                    ppid = int(stat.read_text().rsplit(")", 1)[1].split()[1])
                    cmd = (stat.parent / "cmdline").read_bytes()
                except (OSError, ValueError, IndexError):
                    continue
                if ppid == proc.pid and b"gmsh" in cmd:
                    gmsh_pid = int(stat.parent.name)
            if gmsh_pid:
                break
            time.sleep(0.1)
        assert gmsh_pid is not None, "gmsh did not start"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
        for _ in range(100):
            try:
                state = Path(f"/proc/{gmsh_pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
            except OSError:
                break  # gone
            if state == "Z":
                break  # dead, not yet reaped
            time.sleep(0.1)
        else:
            os.kill(gmsh_pid, signal.SIGKILL)
            pytest.fail("gmsh outlived pulseform")
    finally:
        if proc.poll() is None:
            proc.kill()


# ----------------------------------------------------------------------------- 4. check's temporary folder
def test_a_failing_check_removes_its_folder_and_quotes_the_getdp_error(case, capsys, tmp_path):
    pro = case / "sheet_bulge.pro"
    pro.write_text(pro.read_text().replace("Include PulseformLib;", "Include PulseformLib;\nBogus[];"))
    code, line = check(case, capsys=capsys)
    assert code == 2
    assert "getdp failed on the contract check: Error" in line and "syntax error" in line
    assert "(log:" not in line
    assert not any((tmp_path / "tmp").iterdir())


def test_a_passing_check_removes_its_folder(case, capsys, tmp_path):
    code, _ = check(case, capsys=capsys)
    assert code == 0
    assert not any((tmp_path / "tmp").iterdir())


@pytest.mark.parametrize("name", ["PulseformLib", "PulseformPersistentLib"])
def test_deck_may_not_repoint_the_runners_library(tmp_path, capsys, name):
    """`Include PulseformLib;` is not scanned (it is the runner's own library), so a deck that sets
    the name itself would have getdp read an unchecked file: refused in one line; the library's own
    `DefineConstant[ PulseformPersistentLib = "" ]` default (a copied library) stays allowed."""
    from pulseform.orchestrator.em.user_deck import find_program_call

    lib = (REPO / "solvers/getdp/decks/Lib_PulsedForming.pro").read_text()
    (tmp_path / "Lib_local.pro").write_text(lib)
    deck = tmp_path / "deck.pro"
    deck.write_text('Include "Lib_local.pro";\n')
    assert find_program_call(deck, "pro") is None  # a copied library with its DefineConstant default
    (tmp_path / "evil.pro").write_text('SystemCommand["touch /tmp/pwned"];\n')
    deck.write_text(f'{name} = "evil.pro";\nInclude {name};\n')
    where, what = find_program_call(deck, "pro")
    assert where.endswith("deck.pro:1") and f"{name} is set" in what
