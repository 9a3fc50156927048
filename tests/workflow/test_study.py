"""Issue 36: studies that resume and extend (members named by the hash of their resolved case), a failed member
re-run only when asked, the answer (study.json, report.md, pictures), and the Dask backend giving the local
backend's table. Members: the bar impact on 0.25 m elements for 20 µs (~0.5 s each)."""

from __future__ import annotations

import csv
import json
import os
import re

import pytest

from warm_cli import pulseform_cli
from wf_helpers import REPO

CASE = str(REPO / "cases/bar_impact")
SMALL = ["--set", "bodies.left.mesh_size=0.25", "--set", "bodies.right.mesh_size=0.25", "--set", "time.end=2e-5",
         "--set", "output.field_interval=1e-5"]
SOBOL = ["--design", "sobol", "--seed", "3", "--param", "time.cfl=0.3:0.9", "--param",
         "materials.paper_al.density=2000:3000"]
#: wall times and the member's worker differ from run to run; everything else of the table must not
VARYING = re.compile(r".*(_time_s|_transfer_s|_mesh_motion_s|_getdp_process_s|_getdp_io_s)$|worker")


def _table(out) -> list[dict]:
    return [{k: v for k, v in row.items() if not VARYING.fullmatch(k)} for row in csv.DictReader(open(out / "sweep.csv"))]


def _records(out) -> dict[str, bytes]:
    return {p.parent.name: p.read_bytes() for p in out.glob("*/member.json")}


def test_a_study_resumes_and_extends_running_only_the_members_it_lacks(tmp_path):
    out = tmp_path / "st"
    r = pulseform_cli(["sweep", CASE, "--out", out, "--sample", "4", *SOBOL, *SMALL, "--jobs", "2"])
    assert r.returncode == 0, r.stderr[-3000:]
    first, table4 = _records(out), _table(out)
    assert len(first) == 4 and len(table4) == 4
    # a study killed while a member ran: that member has no record yet (nor its results); another one ended just
    # as the study died: its run's metrics.json says ok, but the study did not record it
    folders = [m["folder"] for m in json.loads((out / "design.json").read_text())["members"]]
    lost, ended = folders[1], folders[2]
    for name in ("member.json", "metrics.json"):
        (out / lost / name).unlink()
    (out / ended / "member.json").unlink()
    mtime = (out / ended / "metrics.json").stat().st_mtime_ns
    r = pulseform_cli(["sweep", CASE, "--out", out, "--resume", "--sample", "4", *SOBOL, *SMALL])
    assert r.returncode == 0, r.stderr[-3000:]
    assert "3 of 4 members need not run" in r.stderr
    again = _records(out)
    same = set(first) - {lost, ended}
    assert {k: again[k] for k in same} == {k: first[k] for k in same}
    assert json.loads(again[ended])["returncode"] == 0 and (out / ended / "metrics.json").stat().st_mtime_ns == mtime
    assert _table(out) == table4  # the table rebuilt from the folders: the uninterrupted study's
    # extended: a Sobol design of 6 starts with the 4 points of the design of 4
    r = pulseform_cli(["sweep", CASE, "--out", out, "--resume", "--sample", "6", *SOBOL, *SMALL])
    assert r.returncode == 0, r.stderr[-3000:]
    assert "4 of 6 members need not run" in r.stderr
    table6 = _table(out)
    assert table6[:4] == table4 and len(table6) == 6
    assert {k: v for k, v in _records(out).items() if k in again} == again  # the first four did not run again
    # the answer: each metric's sensitivities and surface, the pictures
    study = json.loads((out / "study.json").read_text())
    stress = study["answer"]["metrics"]["left_max_von_mises_MPa"]
    assert stress["n"] == 6 and stress["ranking"][0] == "materials.paper_al.density"  # the wave's ρc: density
    assert stress["surface"]["loo_rmse"] > 0 and set(stress["sobol_total"]) == {"time.cfl", "materials.paper_al.density"}
    assert "| 1 | materials.paper_al.density |" in (out / "report.md").read_text()
    for name in ("study_scatter.png", "study_sensitivity.png", "study_surface_left_max_von_mises_MPa.png"):
        assert (out / "plots" / name).is_file()


def test_a_failed_member_is_run_again_only_when_asked(tmp_path):
    """3 km/s into the contact layer stops the solver (exit 1); cfl 2 is refused by validation (exit 2, no folder);
    each has its line in the table; --resume leaves the failure, --resume --retry-failed runs it again."""
    out = tmp_path / "st"
    grid = ["--param", "bodies.left.initial_velocity=[10.0, 0.0],[3000.0, 0.0]", "--param", "time.cfl=0.5,2.0"]
    r = pulseform_cli(["sweep", CASE, "--out", out, *grid, *SMALL])
    assert r.returncode == 1, r.stderr[-3000:]
    rows = {(row["bodies.left.initial_velocity"], row["time.cfl"]): row["returncode"]
            for row in csv.DictReader(open(out / "sweep.csv"))}
    assert rows == {("[10.0, 0.0]", "0.5"): "0", ("[3000.0, 0.0]", "0.5"): "1",
                    ("[10.0, 0.0]", "2.0"): "2", ("[3000.0, 0.0]", "2.0"): "2"}
    before = _records(out)
    assert len(before) == 2  # the refused members have no folder
    r = pulseform_cli(["sweep", CASE, "--out", out, "--resume", *grid, *SMALL])
    assert r.returncode == 1 and "4 of 4 members need not run (done, failed or rejected)" in r.stderr, r.stderr[-2000:]
    assert _records(out) == before
    r = pulseform_cli(["sweep", CASE, "--out", out, "--resume", "--retry-failed", *grid, *SMALL])
    assert r.returncode == 1 and "runs again (it failed)" in r.stderr, r.stderr[-2000:]
    after = _records(out)
    failed = next(k for k in before if k.startswith("initial_velocity-3000"))
    assert after[failed] != before[failed]  # run again (a new worker)
    assert {k: v for k, v in after.items() if k != failed} == {k: v for k, v in before.items() if k != failed}


def test_study_arguments_are_bad_input(tmp_path):
    """One line, exit 2, nothing run: a range without --sample, --retry-failed without --resume, a bad objective."""
    cases = [(["--param", "time.cfl=0.3:0.9"], "--sample"),
             (["--param", "time.cfl=0.5", "--retry-failed"], "--retry-failed"),
             (["--param", "time.cfl=0.3:0.9", "--sample", "4", "--objective", "most:x"], "--objective")]
    for extra, word in cases:
        r = pulseform_cli(["sweep", CASE, "--out", tmp_path / "x", *extra])
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and word in lines[0], r.stderr
    assert not (tmp_path / "x").exists()


@pytest.mark.slow  # ~13 s (a LocalCluster's start and cold members); tests/workflow/test_study_demo.py: 32 members
@pytest.mark.parametrize("backend", ["dask"])
def test_the_dask_backend_gives_the_local_table(tmp_path, backend):
    """The same study through dask.distributed (a LocalCluster of 2 workers) and through local processes."""
    pytest.importorskip("distributed")
    tables = []
    for executor in ("local", backend):
        out = tmp_path / executor
        r = pulseform_cli(["sweep", CASE, "--out", out, "--sample", "4", *SOBOL, *SMALL, "--jobs", "2",
                           "--executor", executor])
        assert r.returncode == 0, r.stderr[-3000:]
        tables.append(_table(out))
    assert tables[0] == tables[1] and len(tables[0]) == 4
    assert "dask.distributed: 2 worker threads" in r.stderr


def test_a_members_hash_is_its_resolved_case_and_the_files_it_names(tmp_path):
    """The same resolved case, the same member (a comment or a --set of the file's own value change nothing); a value
    or a deck's content that changes makes another member."""
    import shutil

    from pulseform.orchestrator.workflows.study_store import member_hash

    bar = tmp_path / "bar"
    shutil.copytree(REPO / "cases/bar_impact", bar)
    h = member_hash(bar, ["time.cfl=0.4"])
    assert member_hash(bar, ["time.cfl=0.4", "time.end=2.2e-3"]) == h  # the file's own end time
    (bar / "case.toml").write_text("# a comment\n" + (bar / "case.toml").read_text())
    assert member_hash(bar, ["time.cfl=0.4"]) == h
    assert member_hash(bar, ["time.cfl=0.41"]) != h
    deck = tmp_path / "deck"
    shutil.copytree(REPO / "cases/user_deck_sheet_bulge", deck)
    d = member_hash(deck, [])
    pro = deck / "sheet_bulge.pro"
    pro.write_text(pro.read_text() + "\n// edited\n")
    assert member_hash(deck, []) != d


def test_without_dask_the_dask_backend_is_refused_in_one_line(tmp_path, monkeypatch, capsys):
    import builtins

    from pulseform.orchestrator.cli import main

    real = builtins.__import__

    def no_distributed(name, *args, **kwargs):
        if name == "distributed" or name.startswith("distributed."):
            raise ImportError(f"No module named {name!r}")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_distributed)
    code = main(["sweep", CASE, "--out", str(tmp_path / "x"), "--executor", "dask", "--param", "time.cfl=0.5"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and not (tmp_path / "x").exists()
    assert len(err) == 1 and "dask.distributed is not installed" in err[0] and "python3-distributed" in err[0], err


@pytest.mark.parametrize("record, status, checkpoint, state", [
    (None, None, False, "new"),                       # never started (or killed before it wrote anything)
    (None, "interrupted", True, "stopped"),           # stopped at a checkpoint, its study killed before recording
    (None, "ok", False, "done"),                      # ended well, its study killed before recording it
    (0, "ok", False, "done"),
    (1, "failed", False, "failed"),
    (-9, "interrupted", False, "failed"),             # killed without a checkpoint
    (130, None, False, "new"),                        # Ctrl-C before it wrote anything: runs again, not a failure
    (143, "interrupted", False, "new"),               # SIGTERM before its first checkpoint: runs again from the start
    (143, "interrupted", True, "stopped"),            # SIGTERM: continues from its checkpoint
    (-2, "ok", False, "done"),                        # SIGINT after its run ended
    (0, "ok", False, "new"),                          # ... but the record of another case (hash): runs again
])
def test_what_a_member_folder_says(tmp_path, record, status, checkpoint, state):
    from pulseform.orchestrator.workflows.study_store import member_state
    from pulseform.orchestrator.workflows.sweep import Member

    m = Member(0, {"time.cfl": "0.5"}, tmp_path / "m", digest="abc")
    m.out.mkdir()
    if record is not None:
        other = state == "new" and record not in (130, 143)
        (m.out / "member.json").write_text(json.dumps({"hash": "xyz" if other else "abc", "returncode": record}))
        if other:
            status = None
    if status is not None:
        (m.out / "metrics.json").write_text(json.dumps({"status": status, "end_time_s": 1e-4}))
    if checkpoint:
        (m.out / "checkpoint.npz").write_bytes(b"")
    assert member_state(m) == state
    if state == "done":
        assert m.returncode == 0 and json.loads((m.out / "member.json").read_text())["returncode"] == 0
        assert m.metrics == {"end_time_s": 1e-4}


@pytest.mark.getdp
def test_a_member_whose_getdp_fails_fails_alone(tmp_path):
    """A getdp on PATH that fails for one bank (C_bank = 44 µF: 'Error : ...', exit 1) and runs the real one
    otherwise: that member fails with getdp's error in its line of the table, the other succeeds."""
    import shutil

    real = shutil.which("getdp")
    if real is None:
        pytest.skip("getdp not found")
    fake = tmp_path / "bin" / "getdp"
    fake.parent.mkdir()
    fake.write_text('#!/bin/sh\ncase "$*" in *"C_bank 4.4e-05 "*) echo "Error   : fake getdp failure" >&2; exit 1;; '
                    f'esac\nexec {real} "$@"\n')
    fake.chmod(0o755)
    out = tmp_path / "st"
    r = pulseform_cli(["sweep", str(REPO / "cases/emf_sheet_bulge"), "--out", out, "--quiet",
                       "--param", "em.circuit.capacitance=5e-5,4.4e-5", "--set", "geometry.mesh_size_sheet=1e-3",
                       "--set", "geometry.mesh_size_coil=2e-3", "--set", "time.end=4e-6",
                       "--set", "output.field_interval=2e-6"],
                      env={"PATH": f"{fake.parent}:{os.environ['PATH']}"})
    assert r.returncode == 1, r.stderr[-3000:]
    rows = {row["em.circuit.capacitance"]: row for row in csv.DictReader(open(out / "sweep.csv"))}
    assert rows["5e-5"]["returncode"] == "0" and float(rows["5e-5"]["max_deflection_mm"]) > 0
    assert rows["4.4e-5"]["returncode"] == "1" and "getdp" in rows["4.4e-5"]["error"], rows["4.4e-5"]
    assert "Traceback" not in r.stderr


def test_a_lone_record_is_cleared_before_its_member_runs_again(tmp_path):
    """A member stopped (Ctrl-C) before its run made its results folder leaves only the study's member.json there;
    run again from the start, the folder must be empty for `pulseform run --force` (which replaces only folders
    it made). Anything else in the folder stays (a user's folder is never deleted)."""
    from pulseform.orchestrator.run.results import MARKER_NAME
    from pulseform.orchestrator.workflows.study_store import RECORD, clear_lone_record
    from pulseform.orchestrator.workflows.sweep import Member

    lone, other, made = (Member(i, {"time.cfl": "0.5"}, tmp_path / n, digest="abc") for i, n in
                         enumerate(("lone", "other", "made")))
    for m, extra in ((lone, None), (other, "notes.txt"), (made, MARKER_NAME)):
        m.out.mkdir()
        (m.out / RECORD).write_text("{}")
        if extra:
            (m.out / extra).write_text("x")
        clear_lone_record(m)
    assert list(lone.out.iterdir()) == []
    assert sorted(p.name for p in other.out.iterdir()) == sorted([RECORD, "notes.txt"])
    assert sorted(p.name for p in made.out.iterdir()) == sorted([RECORD, MARKER_NAME])
