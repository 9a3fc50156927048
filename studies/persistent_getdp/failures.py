"""Failure handling of the persistent getdp: each case must end in a GetDPError (or a clean exit)
that names what happened and carries getdp's log tail, within the step time limit, and getdp must
never outlive its parent.

  1. getdp killed mid-run (SIGKILL, as the out-of-memory killer would)  -> error names the signal
  2. getdp hangs (SIGSTOP: it never answers)                             -> killed at the step time
                                                                            limit, error names the limit
  3. an error inside getdp (a message with a wrong step number)          -> exit code 1, getdp's error line
  4. the Python parent is SIGKILLed while getdp waits on the FIFO        -> getdp is gone (PR_SET_PDEATHSIG
                                                                            of the product's child_preexec)
  5. SIGINT to the process group while getdp waits                       -> getdp ignores it (child_preexec),
                                                                            the next step and the stop message work

Usage: .venv/bin/python studies/persistent_getdp/failures.py
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import MODEL, make_mesh  # noqa: E402
from persistent import PersistentGetDP  # noqa: E402

from pulseform.solvers.getdp import GetDPError  # noqa: E402


def expect_error(label, fn, must_contain):
    t0 = time.perf_counter()
    try:
        fn()
    except GetDPError as err:
        msg = str(err)
        ok = must_contain in err.summary and "--- log tail ---" in msg
        print(f"{label}: {'OK' if ok else 'UNEXPECTED'} after {time.perf_counter() - t0:.2f} s: {err.summary!r}; "
              f"log tail of {len(err.log_tail.splitlines())} lines")
        return ok
    print(f"{label}: UNEXPECTED: no error")
    return False


CHILD = """
import sys, time
sys.path.insert(0, {here!r})
from common import MODEL, make_mesh
from persistent import PersistentGetDP
p = PersistentGetDP(MODEL, {run!r})
p.start(make_mesh(1e3))
print(p.proc.pid, flush=True)
time.sleep(600)
"""


def main():
    mesh = make_mesh(1e3)
    results = []
    with tempfile.TemporaryDirectory(prefix="pgdp_fail_") as tmp:
        w = Path(tmp)
        # 1. killed mid-run
        p = PersistentGetDP(MODEL, w / "killed", step_time_limit=60)
        p.start(mesh)
        p.step(mesh.points, 0.5e-6)

        def kill_then_step():
            os.kill(p.proc.pid, signal.SIGKILL)
            p.step(mesh.points, 1.0e-6)
        results.append(expect_error("1 getdp SIGKILLed", kill_then_step, "SIGKILL"))
        p.close()
        # 2. hang
        p = PersistentGetDP(MODEL, w / "hang", step_time_limit=3.0)
        p.start(mesh)
        p.step(mesh.points, 0.5e-6)

        def hang():
            os.kill(p.proc.pid, signal.SIGSTOP)
            p.step(mesh.points, 1.0e-6)
        results.append(expect_error("2 getdp hangs (limit 3 s)", hang, "time limit of 3 s"))
        p.close()
        # 3. error inside getdp
        p = PersistentGetDP(MODEL, w / "error", step_time_limit=60)
        p.start(mesh)
        p.step(mesh.points, 0.5e-6)

        def bad_message():
            p.k += 5          # Python and getdp out of step: getdp's Error[] ends the run
            p.step(mesh.points, 1.0e-6)
        results.append(expect_error("3 error inside getdp", bad_message, "out of sequence"))
        p.close()
        # 4. parent SIGKILLed
        child = subprocess.Popen([sys.executable, "-c", CHILD.format(here=str(Path(__file__).resolve().parent),
                                                                       run=str(w / "orphan"))],
                                 stdout=subprocess.PIPE, text=True)
        pid = int(child.stdout.readline())
        child.kill()
        child.wait()
        time.sleep(0.5)
        gone = not Path(f"/proc/{pid}").exists() or "zombie" in open(f"/proc/{pid}/status").read().lower()
        print(f"4 parent SIGKILLed: getdp {pid} {'gone: OK' if gone else 'STILL RUNNING: UNEXPECTED'}")
        results.append(gone)
        # 5. SIGINT while waiting
        p = PersistentGetDP(MODEL, w / "sigint", step_time_limit=60)
        p.start(mesh)
        p.step(mesh.points, 0.5e-6)
        os.kill(p.proc.pid, signal.SIGINT)
        time.sleep(0.2)
        alive = p.proc.poll() is None
        o = p.step(mesh.points, 1.0e-6)
        rc = p.close()
        ok = alive and o.k == 2 and rc == 0
        print(f"5 SIGINT to getdp: {'ignored, next step and stop fine: OK' if ok else 'UNEXPECTED'} (exit {rc})")
        results.append(ok)
    print(f"failures: {sum(results)}/{len(results)} cases as expected")


if __name__ == "__main__":
    main()
