"""The runs of a study (``sweep``, ``converge``, ``validate``, ``compare``) in processes forked from one warm process.

A cold ``pulseform run`` spends ~1.5 s on Python's start-up and the libraries' imports (DOLFINx ~0.9 s,
PETSc's initialisation) before its physics. A study instead starts one **warm process** (:func:`serve`, as ``python -m
pulseform.orchestrator.warm_server``: the CLI, the runner, DOLFINx, the compiled kernels and gmsh imported, MPI
initialised as a singleton) and runs each member as ``pulseform.orchestrator.cli.main(argv)`` in a child
**forked** from it:

- each member has its own process state (a copy of the warm one: no state leaks from member to member)
  and its own exit code; a crash (a signal, ``os._exit``) ends that child alone;
- the warm process is single-threaded when it forks, and a serial run's MPI is a singleton without
  transports (``FAST_MPI_ENV``: self only, isolated), so the fork after ``MPI_Init`` is safe here; a
  member's results are bitwise those of ``pulseform run`` with the same ``--set`` values
  (``tests/foundation/test_warm.py``);
- a member's standard output and error come back with its exit code (:class:`subprocess.CompletedProcess`);
- the members' own pictures are skipped (``output.plots = false`` before the study's own ``--set``
  values, which may turn them on again); the study draws its own figures at the end, and ``pulseform
  plot MEMBER_DIR`` draws a member's.

The protocol: JSON lines. The study writes ``{"id": k, "argv": [...], "cwd": "..."}`` (a member) or
``{"op": "term"}`` (SIGTERM to every running member); the warm process answers ``{"ready": s}`` once
its imports are done, ``{"id": k, "started": pid}`` when it forked the member and ``{"id": k,
"returncode": ..., "stdout": ..., "stderr": ...}`` when the member ended. Its own log (imports,
members started and ended) is ``warm.log`` in the study's folder.

Lifetime: the warm process dies with the study (parent-death signal SIGTERM), its members with it (SIGTERM:
they stop at their next safe point with a checkpoint, as a cold member whose sweep died). It ignores SIGINT:
a Ctrl-C reaches the members themselves (same process group). Its standard input closed with members still
running, it sends them SIGTERM and waits for them. Not ready within ``READY_TIMEOUT_S``, it is killed; the
members it had not started run cold (``children.run_pulseform``), those it had are reported failed.

:func:`run_all` runs a study's members ``jobs`` at a time; a stop signal to the study (SIGINT, SIGTERM)
starts no further member, asks the running ones to stop (SIGTERM through the warm process) and waits
for their answers, so the study's table holds what they reached.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from concurrent.futures import TimeoutError as FutureTimeout
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

from .children import failure_report, member_env, run_pulseform
from .interrupt import StudyInterrupted
from .warm_process import PRELOAD, _signal, serve  # noqa: F401 - the warm process's side

log = logging.getLogger(__name__)

__all__ = ["WarmPool", "warm_pool", "run_member_process", "run_all", "member_run_argv", "MEMBER_DEFAULTS",
           "StudyInterrupted", "READY_TIMEOUT_S", "failure_report", "import_in_background", "serve", "PRELOAD"]

#: ``--set`` values every member of a study gets before the study's own: no pictures per member (the
#: study draws its figures; ``pulseform plot MEMBER_DIR`` draws a member's)
MEMBER_DEFAULTS = ("output.plots=false",)
#: seconds the warm process may take for its imports before it is killed (members then run cold)
READY_TIMEOUT_S = 180.0
#: the module the warm process runs (:func:`serve` with the CLI's main)
SERVER_MODULE = "pulseform.orchestrator.warm_server"


def member_run_argv(case: str, out: Path | str, sets: Iterable[str] = ()) -> list[str]:
    """The ``pulseform`` arguments of a study's member: ``run CASE --out OUT --force --quiet`` with
    :data:`MEMBER_DEFAULTS` and then ``sets`` as ``--set`` values (a later value of a key wins)."""
    argv = ["run", str(case), "--out", str(out), "--force", "--quiet"]
    for s in (*MEMBER_DEFAULTS, *sets):
        argv += ["--set", s]
    return argv


# =============================================================================== the study's side
class WarmPool:
    """The study's handle on its warm process; :meth:`run` is thread-safe and runs members concurrently (the
    callers decide how many: ``jobs`` threads). ``log_path``: the warm process's log (``warm.log``)."""

    def __init__(self, log_path: Path | None = None, env: Mapping[str, str] | None = None) -> None:
        self.env = dict(member_env() if env is None else env)
        self.log_path = log_path
        self._lock = threading.Lock()
        self._futures: dict[int, Future] = {}
        self._started: dict[int, int] = {}   # id -> the member's pid, once the warm process forked it
        self._abandoned: set[int] = set()    # ids whose caller's time limit passed before the member started
        self._next = 0
        self._gone: str | None = None        # why the warm process is no longer usable
        self._stopping = False               # the study was stopped: no member starts any more
        self.ready_s: float | None = None    # its imports' duration, once it said so
        self.ready = threading.Event()       # set when its imports are done (or it is gone)
        self.proc: subprocess.Popen | None = None
        self._t0 = time.perf_counter()
        try:
            errors = open(log_path, "ab") if log_path is not None else subprocess.DEVNULL
            try:  # from the calling (main) thread: the parent-death signal follows this thread
                self.proc = subprocess.Popen([sys.executable, "-m", SERVER_MODULE], stdin=subprocess.PIPE,
                                             stdout=subprocess.PIPE, stderr=errors, env=self.env,
                                             preexec_fn=_server_preexec)
            finally:
                if errors is not subprocess.DEVNULL:
                    errors.close()
        except OSError as exc:
            self._gone = f"could not start the warm process: {exc}"
            self.ready.set()
            log.warning("%s; members run as processes of their own", self._gone)
            return
        self._reader = threading.Thread(target=self._read, name="warm-reader", daemon=True)
        self._reader.start()
        self._watchdog = threading.Timer(READY_TIMEOUT_S, self._not_ready)
        self._watchdog.daemon = True
        self._watchdog.start()

    # ------------------------------------------------------------------ members
    def run(self, argv: Sequence[str], cwd: Path | str | None = None,
            timeout: float | None = None) -> subprocess.CompletedProcess:
        """``pulseform ARGV`` in a child of the warm process, in ``cwd`` (default: the current working folder);
        its exit code and output. Falls back to a process of its own (:func:`.children.run_pulseform`) when the
        warm process is gone before it started the member. ``timeout`` (s): the member is killed (SIGKILL) after
        it and :class:`subprocess.TimeoutExpired` raised."""
        cwd = os.getcwd() if cwd is None else os.fspath(cwd)
        fut: Future = Future()
        with self._lock:  # the reader answers every future registered before it marks the process gone
            if self._stopping:
                return subprocess.CompletedProcess(list(argv), 128 + signal.SIGTERM, "",
                                                   "pulseform: error: not started: the study was stopped\n")
            if self._gone is None:
                k = self._next
                self._next += 1
                self._futures[k] = fut
                try:
                    self._send({"id": k, "argv": list(argv), "cwd": cwd})
                except OSError as exc:
                    self._futures.pop(k, None)
                    self._gone = f"the warm process does not read its requests ({exc})"
                    fut.set_result(None)
            else:
                fut.set_result(None)
        try:
            result = fut.result(timeout)
        except FutureTimeout:
            self._kill(k)
            raise subprocess.TimeoutExpired(list(argv), timeout) from None
        if result is not None:
            return result
        log.info("%s: pulseform %s as a process of its own", self._gone, " ".join(argv[:2]))
        return run_pulseform(argv, env=self.env, cwd=cwd, timeout=timeout)

    def _kill(self, k: int) -> None:
        """SIGKILL to member ``k`` (its answer then comes, unread); one the warm process has not started yet is
        killed as soon as it says it has."""
        with self._lock:
            pid = self._started.get(k)
            if pid is None:
                self._abandoned.add(k)
        if pid is not None:
            _signal(pid, signal.SIGKILL)

    def stop_members(self) -> None:
        """SIGTERM to every running member: each stops at its next safe point (a checkpoint) and answers; no
        member starts after it."""
        with self._lock:
            self._stopping = True
            if self._gone is None:
                try:
                    self._send({"op": "term"})
                except OSError:
                    pass

    def close(self, timeout: float = 60.0) -> None:
        """End the warm process (its standard input closes: it stops running members and exits)."""
        if self.proc is None:
            return
        with self._lock:
            self._gone = self._gone or "the warm process was closed"
            if self._next == 0:  # it never had a member: no need to wait for its imports
                self.proc.kill()
            try:
                self.proc.stdin.close()
            except OSError:
                pass
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            log.warning("the warm process did not end within %g s; killed", timeout)
            self.proc.kill()
            self.proc.wait()
        self._watchdog.cancel()
        self._reader.join(timeout=10)

    # ------------------------------------------------------------------ internals
    def _send(self, msg: dict) -> None:
        self.proc.stdin.write((json.dumps(msg) + "\n").encode())
        self.proc.stdin.flush()

    def _not_ready(self) -> None:
        if not self.ready.is_set() and self.proc is not None and self.proc.poll() is None:
            log.warning("the warm process was not ready within %g s; killed (see %s)", READY_TIMEOUT_S, self.log_path)
            self.proc.kill()

    def _read(self) -> None:
        """Dispatch the warm process's answers; at its end, answer what is left (:meth:`run` falls back for
        members it never started, reports those it did as failed)."""
        for line in self.proc.stdout:
            try:
                msg = json.loads(line)
            except ValueError:
                continue
            if "ready" in msg:
                self.ready_s = float(msg["ready"])
                self.ready.set()
                log.debug("warm process %d ready: imports %.2f s (%.2f s after the study started it)",
                          self.proc.pid, self.ready_s, time.perf_counter() - self._t0)
                continue
            k = msg.get("id")
            if "started" in msg:
                with self._lock:
                    self._started[k] = int(msg["started"])
                    late = k in self._abandoned
                if late:  # its caller's time limit passed before it started
                    _signal(int(msg["started"]), signal.SIGKILL)
                continue
            with self._lock:
                fut = self._futures.pop(k, None)
                self._started.pop(k, None)
            if fut is not None:
                fut.set_result(subprocess.CompletedProcess(msg.get("argv", []), int(msg["returncode"]),
                                                           msg.get("stdout", ""), msg.get("stderr", "")))
        code = self.proc.wait()
        self.ready.set()
        with self._lock:
            why = f"the warm process ended (exit {code}{'' if self.log_path is None else f'; {self.log_path}'})"
            self._gone = self._gone or why
            left, started = dict(self._futures), dict(self._started)
            self._futures.clear()
            self._started.clear()
        for k, fut in left.items():
            if k in started:  # it ran there and got SIGTERM with the warm process: failed, with the reason
                fut.set_result(subprocess.CompletedProcess([], 128 + signal.SIGTERM, "",
                                                           f"pulseform: error: {why} while the member ran "
                                                           f"(process {started[k]})\n"))
            else:
                fut.set_result(None)  # never started: run() starts it cold


def _server_preexec() -> None:
    from pulseform.solvers.getdp.runner import die_with_parent

    die_with_parent(signal.SIGTERM)


@contextmanager
def warm_pool(folder: Path | None = None) -> Iterator[WarmPool]:
    """A :class:`WarmPool` for the block (its log ``folder/warm.log``), the one :func:`run_member_process`
    uses meanwhile; closed at the end. Call it from the main thread."""
    global _current
    pool = WarmPool(None if folder is None else Path(folder) / "warm.log")
    previous, _current = _current, pool
    try:
        yield pool
    finally:
        _current = previous
        pool.close()


_current: WarmPool | None = None


def run_member_process(argv: Sequence[str]) -> subprocess.CompletedProcess:
    """``pulseform ARGV`` through the study's warm process (:func:`warm_pool`), or as a process of its own
    outside one."""
    pool = _current
    return pool.run(argv) if pool is not None else run_pulseform(argv, env=member_env())


def import_in_background(*modules: str, after: WarmPool | None = None) -> threading.Thread:
    """Import ``modules`` in a thread of this process while it waits for its members (e.g. matplotlib for
    the study's figures at the end, ~0.3 s), once the warm process ``after`` is ready (not competing with its
    imports); join the thread before using them (``matplotlib.use`` on a half-imported pyplot fails)."""
    def target() -> None:
        import importlib

        if after is not None:
            after.ready.wait(READY_TIMEOUT_S)
        for name in modules:
            try:
                importlib.import_module(name)
            except Exception as exc:  # noqa: BLE001 - the figures' own import reports it later
                log.debug("background import of %s: %s", name, exc)

    thread = threading.Thread(target=target, name="study-imports", daemon=True)
    thread.start()
    return thread


def run_all(fn: Callable[[Any], Any], items: Sequence[Any], jobs: int = 1, pool: WarmPool | None = None) -> None:
    """``fn(item)`` for every item, ``jobs`` at a time (threads; ``fn`` runs a member and records its outcome).

    A stop signal (SIGINT, SIGTERM; main thread) starts no further item, sends the running members SIGTERM
    through ``pool`` (those that already had the terminal's SIGINT ignore it) and waits for them; then raises
    :class:`StudyInterrupted`. A second SIGINT stops the waiting at once (KeyboardInterrupt)."""
    from . import interrupt

    if not items:
        return
    with interrupt.signals_stop_run():
        ex = ThreadPoolExecutor(max_workers=max(1, jobs), thread_name_prefix="member")
        try:  # an item whose turn comes after a stop signal is left alone
            futures = [ex.submit(lambda item: None if interrupt.pending() else fn(item), item) for item in items]
            todo = set(futures)
            asked = False
            while todo:
                _, todo = wait(todo, timeout=0.1, return_when=FIRST_COMPLETED)
                if interrupt.pending() is not None and not asked:
                    asked = True
                    log.warning("stop requested (%s): no further member starts; the running ones stop at their "
                                "next safe point", signal.Signals(interrupt.pending()).name)
                    for f in futures:
                        f.cancel()
                    if pool is not None:
                        pool.stop_members()
                    todo = {f for f in todo if not f.cancelled()}
        finally:
            ex.shutdown(wait=True, cancel_futures=True)
        for f in futures:
            if not f.cancelled():
                f.result()  # an error of fn itself (not of a member) is the study's
        signum = interrupt.pending()
    if signum is not None:
        raise StudyInterrupted(signum, f"interrupted by {signal.Signals(signum).name}: no further member started, the "
                               "running ones stopped at their next safe point with a checkpoint (`pulseform run ... "
                               "--resume` continues one)")
