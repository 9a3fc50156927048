"""Run the ``getdp`` executable: argv (no shell), absolute paths, one log per run, checks.

Everything that touches the process lives here; :mod:`.solver` builds the
arguments and reads the outputs.
"""
from __future__ import annotations

import os
import pickle
import re
import select
import shutil
import signal
import subprocess
import time
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

#: Open MPI / hwloc settings of an isolated singleton (one process, no launcher) that cut a getdp
#: start from ~0.4 s to ~0.1 s without changing results (measured, see SOLVER_NOTES.md and
#: docs/getdp.md "Performance").  The last two (no hwloc I/O discovery; only the collective components
#: a singleton uses instead of dlopen-ing all ten) cut its CPU time at start by ~10-15 % more (74-82 ->
#: 60-68 ms, ``perf stat -r 20`` of a getdp on an empty deck, loaded machine).  Restricting Open MPI's
#: ``schizo`` framework breaks MPI_Init (tried).  Set in the child's env only (and by ``pulseform`` for
#: itself when not under ``mpirun``).
FAST_MPI_ENV = {
    "OMPI_MCA_ess_singleton_isolated": "1",
    "OMPI_MCA_pml": "ob1",
    "OMPI_MCA_btl": "self",
    "OMPI_MCA_mtl": "^ofi,psm,psm2",
    "OMPI_MCA_osc": "sm",
    "HWLOC_COMPONENTS": "-pci,-opencl,-gl,-cuda,-nvml,-linuxio",
    "OMPI_MCA_coll": "self,basic,libnbc",
}

#: ``prctl`` option that sends the child a signal when the thread that started it dies
_PR_SET_PDEATHSIG = 1


def die_with_parent(death_signal: int = signal.SIGKILL) -> None:
    """In a child between fork and exec: have the kernel send ``death_signal`` when the parent dies
    (``PR_SET_PDEATHSIG``, kept across exec), and exit at once if the parent is already gone."""
    import ctypes

    parent = os.getppid()
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(_PR_SET_PDEATHSIG, int(death_signal), 0, 0, 0)
    if os.getppid() != parent:  # the parent died before the death signal was armed
        os._exit(1)


def child_preexec() -> None:
    """``preexec_fn`` of every external program (getdp, gmsh): it must never outlive pulseform.

    SIGKILL when the parent dies (:func:`die_with_parent`), and SIGINT ignored, so that a Ctrl-C
    in the terminal (sent to the whole process group) lets the running step finish: pulseform
    itself then stops at its next safe point, and a SIGKILL of pulseform still ends the child.
    """
    die_with_parent(signal.SIGKILL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class TimeLimitExceeded(RuntimeError):
    """A child process (gmsh meshing, ...) ran longer than its time limit and was killed.
    ``what`` names the work, ``time_limit`` is the limit (s)."""

    def __init__(self, what: str, time_limit: float) -> None:
        self.what, self.time_limit = what, time_limit
        super().__init__(f"{what} exceeded its time limit of {time_limit:g} s and was stopped")


class ChildFailed(RuntimeError):
    """A child process died (a signal, e.g. the out-of-memory killer, or a C++ abort) before its answer."""


def call_in_child(fn: Callable[..., Any], *args: Any, time_limit: float | None, what: str, **kwargs: Any) -> Any:
    """``fn(*args, **kwargs)`` computed in a forked child process under a wall-time limit (s).

    For in-process libraries that cannot be interrupted (the gmsh API): the child dies with its
    parent (:func:`child_preexec`), a crash or an out-of-memory kill of the child is a
    :class:`ChildFailed` instead of the end of pulseform, and a run over ``time_limit`` is killed
    and raised as :class:`TimeLimitExceeded`. The result (or the exception) travels back pickled;
    ``fn`` must not log or use MPI (a forked child shares neither safely).
    """
    return ChildCall(fn, *args, time_limit=time_limit, what=what, **kwargs).result()


class ChildCall:
    """``fn(*args, **kwargs)`` started now in a forked child (:func:`call_in_child`), its answer
    collected later by :meth:`result`: the parent works on meanwhile (e.g. imports DOLFINx while
    gmsh meshes on the other core). The time limit (s) counts from the start; an answer complete
    before the parent asks is taken even if the parent asks after the limit. :meth:`cancel` (also
    on garbage collection) kills and reaps a child whose answer is no longer wanted."""

    def __init__(self, fn: Callable[..., Any], *args: Any, time_limit: float | None, what: str, **kwargs: Any) -> None:
        self.what, self.time_limit = what, time_limit
        self.deadline = None if time_limit is None else time.monotonic() + time_limit
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child: compute, send, leave without running the parent's exit handlers
            code = 0
            try:
                os.close(r)
                child_preexec()
                signal.signal(signal.SIGTERM, signal.SIG_DFL)
                try:
                    payload = pickle.dumps((True, fn(*args, **kwargs)))
                except BaseException as exc:  # noqa: BLE001 - every failure goes back to the parent
                    try:
                        payload = pickle.dumps((False, exc))
                    except Exception:  # noqa: BLE001 - an exception that cannot be pickled
                        payload = pickle.dumps((False, RuntimeError(f"{type(exc).__name__}: {exc}")))
                with os.fdopen(w, "wb") as fh:
                    fh.write(payload)
            except BaseException:  # noqa: BLE001
                code = 1
            finally:
                os._exit(code)
        os.close(w)
        self.pid: int | None = pid
        self._r = r
        self._finalizer = weakref.finalize(self, _reap, pid, r)

    def result(self) -> Any:
        """Wait for the child's answer (the value, or its exception raised here)."""
        if self.pid is None:
            raise RuntimeError(f"{self.what}: the answer was already taken or cancelled")
        pid, r = self.pid, self._r
        self.pid = None
        self._finalizer.detach()
        data = bytearray()
        try:
            while True:
                remaining = None if self.deadline is None else max(self.deadline - time.monotonic(), 0.0)
                if not select.select([r], [], [], remaining)[0]:
                    raise TimeLimitExceeded(self.what, self.time_limit)
                chunk = os.read(r, 1 << 20)
                if not chunk:
                    break
                data += chunk
        finally:
            os.close(r)
            if not data or self.deadline is not None and time.monotonic() >= self.deadline:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            _, status = os.waitpid(pid, 0)
        if not data:
            how = (f"killed by signal {signal.Signals(os.WTERMSIG(status)).name}" if os.WIFSIGNALED(status)
                   else f"exit code {os.WEXITSTATUS(status)}")
            sig = os.WTERMSIG(status) if os.WIFSIGNALED(status) else 0
            hint = {signal.SIGKILL: " (often the out-of-memory killer)",
                    signal.SIGABRT: " (an abort, e.g. std::bad_alloc when memory runs out; its message went to "
                                    "standard error)"}.get(sig, "")
            raise ChildFailed(f"{self.what} died before it finished: {how}{hint}")
        ok, value = pickle.loads(bytes(data))
        if not ok:
            raise value
        return value

    def cancel(self) -> None:
        """Kill and reap the child if its answer was not taken."""
        if self.pid is not None:
            self.pid = None
            self._finalizer()


def _reap(pid: int, r: int) -> None:
    """Finalizer of a :class:`ChildCall` whose answer nobody took: kill, reap, close."""
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    try:
        os.waitpid(pid, 0)
    except ChildProcessError:
        pass
    try:
        os.close(r)
    except OSError:
        pass


_ERROR_PATTERN = re.compile(
    r"^(?:Error|Critical)\s*:|diverg|did not converge|not converged|no convergence|Segmentation|MPI_ABORT"
    r"|\bAbort", re.M | re.I)
_WARNING_PATTERN = re.compile(r"^Warning\s*:.*$", re.M)


class GetDPError(RuntimeError):
    """getdp is missing, failed, was killed, or its log shows an error.

    The message ends with the tail of the log; ``log_path`` and ``run_dir`` point at
    what stays on disk (partial outputs are never deleted).
    """

    def __init__(self, message: str, *, log_path: Path | None = None, run_dir: Path | None = None,
                 returncode: int | None = None, log_tail: str = "", time_limit: float | None = None):
        self.summary = message  # the first line, without log path and tail
        self.time_limit = time_limit  # set when getdp was stopped for exceeding it (s)
        self.log_path = log_path
        self.run_dir = run_dir
        self.returncode = returncode
        self.log_tail = log_tail
        full = message
        if log_path is not None:
            full += f"\n  log: {log_path}"
        if log_tail:
            full += "\n  --- log tail ---\n" + log_tail
        super().__init__(full)


@dataclass
class RunInfo:
    """What one getdp run left behind. ``cpu_parts`` (s): of one step of a persistent process, getdp's own
    CPU time moving the mesh, assembling (Generate), solving, and computing the outputs
    (:class:`~.persistent_process.StepAnswer`); None for a process per run."""

    argv: list[str]
    run_dir: Path
    log_path: Path
    wall_time: float
    warnings: list[str] = field(default_factory=list)
    cpu_parts: tuple[float, float, float, float] | None = None


def run_logged(argv: list[str], cwd: Path, log_path: Path, time_limit: float | None) -> tuple[int, str]:
    """Run an external program (``argv``, in ``cwd``) with its output in ``log_path`` (first line: the argv),
    stopped after ``time_limit`` seconds and never outliving this process (:func:`child_preexec`).

    Returns (return code, the log's text after the argv line). Raises ``subprocess.TimeoutExpired`` past the
    limit and ``OSError`` when the program cannot start: the caller names the input in its own error."""
    with open(log_path, "w") as fh:
        fh.write("# argv: " + " ".join(argv) + "\n")
        fh.flush()
        r = subprocess.run(argv, cwd=cwd, stdout=fh, stderr=subprocess.STDOUT, timeout=time_limit, check=False,
                           preexec_fn=child_preexec)
    return r.returncode, Path(log_path).read_text(errors="replace").split("\n", 1)[-1]


def find_getdp(executable: str | os.PathLike = "getdp") -> str:
    """Absolute path of the getdp executable, or GetDPError."""
    exe = str(executable)
    path = shutil.which(exe)
    if path is None:
        raise GetDPError(f"getdp executable not found: {exe!r} (install the Debian package 'getdp')")
    return os.path.abspath(path)


def log_tail(path: Path, n_lines: int = 25) -> str:
    try:
        lines = Path(path).read_text(errors="replace").splitlines()
    except OSError:
        return ""
    return "\n".join(lines[-n_lines:])


def scan_log(text: str) -> tuple[list[str], list[str]]:
    """(errors, warnings) found in a getdp log."""
    errors = []
    for m in _ERROR_PATTERN.finditer(text):
        start = text.rfind("\n", 0, m.start()) + 1
        end = text.find("\n", m.end())
        line = text[start: end if end >= 0 else len(text)].strip()
        if not errors or errors[-1] != line:
            errors.append(line)
    warnings = [m.group(0).strip() for m in _WARNING_PATTERN.finditer(text)]
    return errors, warnings


def run_getdp(
    deck: Path,
    mesh: Path,
    run_dir: Path,
    *,
    resolution: str,
    name: str = "em",
    numbers: dict[str, float] | None = None,
    strings: dict[str, str] | None = None,
    extra_args: list[str] | tuple[str, ...] = (),
    executable: str | os.PathLike = "getdp",
    timeout: float | None = None,
    verbosity: int = 3,
    log_name: str = "getdp.log",
    allowed_warnings: tuple[str, ...] = (),
    reuse_pre: bool = False,
    post_operation: str | None = None,
    pre_only: bool = False,
) -> RunInfo:
    """Run ``getdp deck -msh mesh -name run_dir/name -setnumber ... -solve resolution``.

    With ``post_operation``, run ``-pos post_operation`` instead of ``-solve`` (post-processing of a
    saved solution, which ``extra_args`` name with ``-res FILE``).
    With ``pre_only``, run ``-pre resolution`` only: the dof numbering in ``run_dir/<name>.pre``.

    All paths are made absolute; the process runs in ``run_dir`` with stdout and
    stderr in one log file there.  Raises :class:`GetDPError` on a missing binary,
    a non-zero return code, a signal, a timeout or an error line in the log.
    Warnings not matching ``allowed_warnings`` are returned in ``RunInfo.warnings``.
    """
    run_dir = Path(run_dir).resolve()
    run_dir.mkdir(parents=True, exist_ok=True)
    log_path = run_dir / log_name
    exe = None
    try:
        exe = find_getdp(executable)
    except GetDPError as err:
        log_path.write_text(str(err) + "\n")
        raise GetDPError(str(err).splitlines()[0], log_path=log_path, run_dir=run_dir,
                         log_tail=log_tail(log_path)) from None
    argv = [exe, str(Path(deck).resolve()), "-msh", str(Path(mesh).resolve()), "-name", str(run_dir / name)]
    for key, val in (numbers or {}).items():
        argv += ["-setnumber", key, repr(float(val))]
    for key, val in (strings or {}).items():
        argv += ["-setstring", key, str(val)]
    argv += list(extra_args)
    # -cal: processing only, with the pre-processing data (dof numbering) already in
    # run_dir/<name>.pre (copied from a run on the same connectivity)
    if pre_only:
        argv += ["-pre", resolution]
    elif post_operation is not None:
        argv += ["-pos", post_operation]
    else:
        argv += ["-cal"] if reuse_pre else ["-solve", resolution]
    argv += ["-v", str(int(verbosity))]
    env = dict(os.environ)
    env.update(FAST_MPI_ENV)
    t0 = time.perf_counter()
    with open(log_path, "w") as log:
        log.write("# argv: " + " ".join(argv) + "\n")
        log.flush()
        try:
            proc = subprocess.run(argv, cwd=run_dir, stdout=log, stderr=subprocess.STDOUT, env=env,
                                  timeout=timeout, check=False, preexec_fn=child_preexec)
        except subprocess.TimeoutExpired:
            raise GetDPError(f"getdp exceeded its time limit of {timeout:g} s and was stopped", log_path=log_path,
                             run_dir=run_dir, log_tail=log_tail(log_path), time_limit=timeout) from None
        except OSError as err:
            raise GetDPError(f"could not start getdp: {err}", log_path=log_path, run_dir=run_dir) from None
    wall = time.perf_counter() - t0
    text = log_path.read_text(errors="replace")
    text = text[text.find("\n") + 1:]  # skip the argv line written above
    if proc.returncode < 0:
        try:
            sig = signal.Signals(-proc.returncode).name
        except ValueError:
            sig = str(-proc.returncode)
        raise GetDPError(f"getdp was killed by signal {sig}", log_path=log_path, run_dir=run_dir,
                         returncode=proc.returncode, log_tail=log_tail(log_path))
    errors, warnings = scan_log(text)
    if proc.returncode != 0 or errors:
        what = errors[0] if errors else "no error line in the log"
        raise GetDPError(f"getdp failed (return code {proc.returncode}): {what}", log_path=log_path,
                         run_dir=run_dir, returncode=proc.returncode, log_tail=log_tail(log_path))
    warnings = [w for w in warnings if not any(a in w for a in allowed_warnings)]
    return RunInfo(argv=argv, run_dir=run_dir, log_path=log_path, wall_time=wall, warnings=warnings)
