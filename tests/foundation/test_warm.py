"""Issue 31, item 3: a study's members in children forked from one warm process (orchestrator/run/warm.py).

- the members of a coupled sweep give metrics.json bitwise equal to `pulseform run` alone with the same --set
  values (the timers aside), and draw no pictures of their own;
- a member that fails (the solver stops) is reported with its log tail, a member that crashes (SIGKILL) is
  reported as killed with its run.log's tail, and the others finish;
- a stop signal to the study (SIGTERM to the sweep, or Ctrl-C: SIGINT to its process group) starts no further
  member, the running one stops at its next safe point with a checkpoint, sweep.csv holds what they reached;
- without a usable warm process the members run as processes of their own.
(A killed sweep's members stop with a checkpoint: test_signals.py::test_sweep_killed_its_members_stop_with_a_checkpoint.)
"""

from __future__ import annotations

import csv
import json
import os
import re
import signal
import subprocess
import time

import pytest

from signals_common import CORNER, EXE, REPO, _stepping, _wait_for, member_dir

#: metrics that are wall times (the rest must be equal bitwise)
TIMERS = re.compile(r".*(_time_s|_transfer_s|_mesh_motion_s|_getdp_process_s|_getdp_io_s)$")
SHORT = ["--set", "time.end=4e-6", "--set", "output.field_interval=2e-6"]


def _physics(path) -> dict:
    m = json.loads(path.read_text())
    return {k: v for k, v in m.items() if not TIMERS.match(k) or k == "end_time_s"}


@pytest.mark.getdp
def test_warm_members_equal_runs_alone_bitwise(tmp_path):
    case = str(REPO / "cases/emf_sheet_bulge")
    out = tmp_path / "sw"
    r = subprocess.run([EXE, "sweep", case, "--out", str(out), "--jobs", "2", "--param", "coupling.n=10,20", *SHORT],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    log = (out / "warm.log").read_text()
    assert "imports" in log and len(re.findall(r"member \d: process \d+ ended: exit 0", log)) == 2, log
    for n, member in (("10", member_dir(out, 0)), ("20", member_dir(out, 1))):
        assert member.name.startswith(f"n-{n}_")
        alone = tmp_path / f"alone_{n}"
        a = subprocess.run([EXE, "run", case, "--out", str(alone), "--quiet", "--set", "output.plots=false", *SHORT,
                            "--set", f"coupling.n={n}"], capture_output=True, text=True, timeout=600)
        assert a.returncode == 0, a.stderr[-3000:]
        got, want = _physics(member / "metrics.json"), _physics(alone / "metrics.json")
        assert got == want, {k: (got.get(k), want.get(k)) for k in set(got) | set(want) if got.get(k) != want.get(k)}
        assert (member / "history.csv").read_bytes() == (alone / "history.csv").read_bytes()
        assert not list((member / "plots").iterdir())  # no pictures of its own: `pulseform plot` draws them
    assert (out / "plots" / "sweep_coupling_n.png").is_file()  # the study's own


def test_failed_and_crashed_members_are_reported_the_others_finish(tmp_path):
    """Three members, two at a time: 3 km/s into the contact layer stops the solver (exit 1: its error line
    and run.log's tail on the terminal); the member at 1.7e-4 s is killed (SIGKILL: a crash) while it steps;
    the third finishes."""
    out = tmp_path / "sw"
    sweep = subprocess.Popen([EXE, "sweep", *CORNER[2:3], *CORNER[4:], "--out", str(out), "--jobs", "2",
                              "--param", "time.end=1.6e-4,1.7e-4", "--param",
                              "bodies.blank.initial_velocity=[0.0, 0.0],[0.0, -3000.0]"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # members: 000 (1.6e-4, rest), 001 (1.6e-4, 3 km/s), 002 (1.7e-4, rest), 003 (1.7e-4, 3 km/s)
    victim = lambda: member_dir(out, 2)  # noqa: E731
    _wait_for(lambda: victim() is not None and _stepping(victim()), sweep, what="member 2's first step")
    pid = int(re.search(r"member 2: process (\d+):", (out / "warm.log").read_text()).group(1))
    os.kill(pid, signal.SIGKILL)
    stdout, stderr = sweep.communicate(timeout=600)
    assert sweep.returncode == 1, stderr[-3000:]
    rows = {(row["time.end"], row["bodies.blank.initial_velocity"]): row for row in csv.DictReader(open(out / "sweep.csv"))}
    assert rows[("1.6e-4", "[0.0, 0.0]")]["returncode"] == "0"
    assert float(rows[("1.6e-4", "[0.0, 0.0]")]["end_time_s"]) == pytest.approx(1.6e-4)
    assert rows[("1.7e-4", "[0.0, 0.0]")]["returncode"] == str(-signal.SIGKILL)
    assert rows[("1.7e-4", "[0.0, 0.0]")]["error"] == "killed by SIGKILL"
    assert rows[("1.6e-4", "[0.0, -3000.0]")]["returncode"] == "1"
    assert rows[("1.6e-4", "[0.0, -3000.0]")]["error"].startswith("pulseform: error: corner_fill")
    # the terminal: each failure with its log tail (run.log's last lines, indented: the killed member's last steps,
    # the failed member's traceback), then the summary lines
    killed, failed = _reported(stderr, "WARNING: member 2 ("), _reported(stderr, "WARNING: member 1 (")
    assert "failed: killed by SIGKILL" in killed[0] and killed[1:] and "INFO" in killed[-1], killed
    assert "failed: pulseform: error: corner_fill" in failed[0] and "ContactPenetrationError" in failed[-2], failed
    assert "FAILED(-9)" in stdout and "Traceback" not in stderr


def _reported(stderr: str, start: str) -> list[str]:
    """The line of stderr that starts with ``start`` and the indented lines under it (the log tail)."""
    lines = stderr.splitlines()
    i = next(i for i, ln in enumerate(lines) if ln.startswith(start))
    j = next((j for j in range(i + 1, len(lines)) if not lines[j].startswith("  ")), len(lines))
    return lines[i:j]


@pytest.mark.parametrize("how", ["SIGTERM to the sweep", "SIGINT to its process group"])
def test_a_stopped_sweep_stops_its_members_at_a_safe_point(tmp_path, how):
    out = tmp_path / "sw"
    sweep = subprocess.Popen([EXE, "sweep", *CORNER[2:3], *CORNER[4:], "--out", str(out), "--jobs", "1",
                              "--param", "time.end=3.0e-4,3.1e-4,3.2e-4"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    first = lambda: member_dir(out, 0)  # noqa: E731
    _wait_for(lambda: first() is not None and _stepping(first()), sweep, what="the first member's first step")
    time.sleep(1.0)  # into its steps
    if how.startswith("SIGTERM"):
        sweep.send_signal(signal.SIGTERM)
        sig = signal.SIGTERM
    else:  # a Ctrl-C in the terminal: the sweep, the warm process and the member each get SIGINT
        os.killpg(sweep.pid, signal.SIGINT)
        sig = signal.SIGINT
    _, stderr = sweep.communicate(timeout=300)
    assert sweep.returncode == 128 + sig, stderr[-3000:]
    lines = [ln for ln in stderr.splitlines() if ln.startswith("pulseform: ")]
    assert lines and lines[-1].startswith(f"pulseform: sweep interrupted by {signal.Signals(sig).name}: no further "
                                          "member started"), stderr[-3000:]
    m = json.loads((first() / "metrics.json").read_text())
    assert m["status"] == "interrupted" and 0 < m["end_time_s"] < 3.0e-4, m
    assert (first() / "checkpoint.npz").is_file()
    rows = list(csv.DictReader(open(out / "sweep.csv")))
    assert [row["returncode"] for row in rows] == [str(128 + sig), "", ""], rows
    assert member_dir(out, 1) is None and member_dir(out, 2) is None  # never started
    if sig != signal.SIGTERM:
        return
    # issue 36: `--resume` continues the stopped member from its checkpoint (the design narrowed to that member, to
    # keep the test short: the same resolved case, the same folder; tests/workflow/test_study_demo.py resumes a
    # whole study)
    r = subprocess.run([EXE, "sweep", *CORNER[2:3], *CORNER[4:], "--out", str(out), "--resume",
                        "--param", "time.end=3.0e-4"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "member 0 (" in r.stderr and "continues from its checkpoint" in r.stderr, r.stderr[-3000:]
    rows = list(csv.DictReader(open(out / "sweep.csv")))
    assert [row["returncode"] for row in rows] == ["0"], rows
    m = json.loads((first() / "metrics.json").read_text())
    assert m["status"] == "ok" and m["end_time_s"] == pytest.approx(3.0e-4)
    assert "resumed at t" in (first() / "run.log").read_text()


def test_without_a_warm_process_members_run_on_their_own(tmp_path, monkeypatch):
    from pulseform.orchestrator.run import warm

    case = str(REPO / "cases/bar_impact")
    pool = warm.WarmPool(tmp_path / "warm.log")
    try:
        r = pool.run(["check", case])
        assert r.returncode == 0 and "valid" in r.stdout and pool.ready_s is not None
        bad = pool.run(["check", str(tmp_path / "nothing")])
        assert bad.returncode == 2 and bad.stderr.startswith("pulseform: error:")
    finally:
        pool.close()
    assert "ended: exit 2" in (tmp_path / "warm.log").read_text()

    monkeypatch.setattr(warm, "SERVER_MODULE", "pulseform.orchestrator.no_such_module")  # it dies at once
    broken = warm.WarmPool(tmp_path / "broken.log")
    try:
        r = broken.run(["check", case])
        assert r.returncode == 0 and "valid" in r.stdout, r.stderr  # run as `pulseform check` of its own
    finally:
        broken.close()
    assert "No module named" in (tmp_path / "broken.log").read_text()


def test_a_member_runs_in_its_folder_and_is_killed_past_its_time_limit(tmp_path):
    """``WarmPool.run(argv, cwd=, timeout=)`` (what tests/warm_cli.py gives the tests' runs): a relative ``--out`` is
    taken in ``cwd``; a member still running at its time limit is killed (SIGKILL) and TimeoutExpired raised, as
    ``subprocess.run(timeout=)`` does (one whose limit passed before the warm process started it: as soon as it
    starts), and the pool serves the next member."""
    from pulseform.orchestrator.run.warm import WarmPool

    coarse = ["--quiet", "--set", "bodies.left.mesh_size=0.25", "--set", "bodies.right.mesh_size=0.25",
              "--set", "output.plots=false"]
    pool = WarmPool()
    try:
        with pytest.raises(subprocess.TimeoutExpired):  # its limit passes while the warm process still imports
            pool.run(["run", str(REPO / "cases/bar_impact"), "--out", "early", *coarse], cwd=tmp_path, timeout=0.01)
        assert pool.ready.wait(180)
        t0 = time.perf_counter()
        with pytest.raises(subprocess.TimeoutExpired):  # the whole bar impact: seconds, not 0.2 s
            pool.run(["run", str(REPO / "cases/bar_impact"), "--out", "killed", *coarse], cwd=tmp_path, timeout=0.2)
        assert time.perf_counter() - t0 < 5
        time.sleep(1.0)
        assert not (tmp_path / "killed" / "metrics.json").exists()  # it did not finish after the limit either
        assert not (tmp_path / "early" / "metrics.json").exists()   # killed as soon as it started
        r = pool.run(["run", str(REPO / "cases/bar_impact"), "--out", "rel", *coarse, "--set", "time.end=1e-4",
                      "--set", "output.field_interval=5e-5"], cwd=tmp_path, timeout=300)
        assert r.returncode == 0, r.stderr[-2000:]
        assert (tmp_path / "rel" / "metrics.json").is_file()
    finally:
        pool.close()
