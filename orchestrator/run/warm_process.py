"""The warm process of a study (:mod:`.warm`): :func:`serve` imports the libraries once (:data:`PRELOAD`), answers
``{"ready": s}``, then forks one child per member request and runs the CLI's ``main(argv)`` in it (:func:`_member`),
answering ``started`` and the member's exit code and output (its end: :data:`MAX_OUTPUT`). The protocol and the
lifetime rules are :mod:`.warm`'s docstring; ``python -m pulseform.orchestrator.warm_server`` runs it."""

from __future__ import annotations

import json
import logging
import os
import signal
import sys
import time
from typing import Callable, Sequence

__all__ = ["serve", "PRELOAD", "MAX_OUTPUT"]

log = logging.getLogger("pulseform.orchestrator.run.warm")  # warm.log names the study's warm machinery

#: what the warm process imports before it forks members (what a run without pictures imports; a member that
#: draws, ``--set output.plots=true``, imports matplotlib itself)
PRELOAD = ("pulseform.orchestrator.case.io", "pulseform.orchestrator.em.skin_depth",
           "pulseform.orchestrator.run.runner", "pulseform.orchestrator.run.driver",
           "pulseform.solvers.getdp.persistent", "pulseform.solvers.getdp.replay", "h5py", "cffi", "meshio._cxml", "gmsh")
#: the most of a member's standard output / error that comes back (its end)
MAX_OUTPUT = 1 << 20
_NAME, _SERVER_NAME, _PR_SET_NAME = b"pulseform", b"pulseform-warm", 15  # process names (ps, /proc/PID/comm)


# =============================================================================== the warm process
def _set_name(name: bytes) -> None:
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_NAME, ctypes.c_char_p(name), 0, 0, 0)
    except (OSError, AttributeError):
        pass


def _tail(path: str) -> str:
    with open(path, "rb") as fh:
        size = fh.seek(0, os.SEEK_END)
        fh.seek(max(0, size - MAX_OUTPUT))
        return fh.read().decode("utf-8", errors="replace")


def _member(main: Callable[[list[str]], int], req: dict, out_path: str, err_path: str, close_fds: Sequence[int]) -> None:
    """In the forked child: become a member (``main(argv)``: the CLI's) and leave with its exit code, without the
    warm process's exit handlers (MPI_Finalize belongs to the warm process)."""
    code = 1
    try:
        for fd in close_fds:
            os.close(fd)
        from pulseform.solvers.getdp.runner import die_with_parent

        die_with_parent(signal.SIGTERM)   # the warm process ends: the member stops at its next safe point
        _set_name(_NAME)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        os.chdir(req.get("cwd") or ".")
        for fd, path, flags in ((0, os.devnull, os.O_RDONLY), (1, out_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC),
                                (2, err_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)):
            new = os.open(path, flags, 0o600)
            os.dup2(new, fd)
            os.close(new)
        code = main(list(req["argv"]))
    except SystemExit as exc:  # argparse: usage errors
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except BaseException:  # noqa: BLE001 - whatever happens, the child leaves here
        import traceback

        traceback.print_exc()
        code = 1
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # noqa: BLE001
                pass
        os._exit(code & 0xFF if code >= 0 else 1)


def serve(main: Callable[[list[str]], int], setup: Callable[[], None]) -> int:
    """The warm process: imports, then members forked on request (each runs ``main(argv)``, the CLI's) until
    its standard input ends. ``setup()`` (the CLI's console log) runs before the imports."""
    import selectors
    import tempfile

    t0 = time.perf_counter()
    proto_in, proto_out = os.dup(0), os.dup(1)   # the protocol's pipes, away from 0 / 1 (libraries print)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    os.dup2(2, 1)
    _set_name(_SERVER_NAME)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from pulseform.solvers.getdp.runner import FAST_MPI_ENV

    launched = any(k in os.environ for k in ("OMPI_COMM_WORLD_SIZE", "PMI_RANK", "PMIX_RANK", "PMI_SIZE"))
    if not launched:  # as the console script's entry: a singleton's fast start
        for key, value in FAST_MPI_ENV.items():
            os.environ.setdefault(key, value)
    import importlib

    setup()  # before DOLFINx: FFCx's basicConfig() is then a no-op, as in the CLI
    for h in logging.getLogger().handlers:  # warm.log: with the time
        h.setFormatter(logging.Formatter("%(asctime)s %(levelname)s: %(message)s"))
    logging.getLogger("pulseform").setLevel(logging.INFO)
    for name in PRELOAD:
        importlib.import_module(name)
    from pulseform.solvers import warm_up_compiler

    compiler = warm_up_compiler()  # the compiled kernels' one-time target set-up: not once per member
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # gmsh resets SIGINT at import
    ready = time.perf_counter() - t0
    log.info("warm process %d: imports %.2f s (of which the compiler's set-up %.2f s)", os.getpid(), ready, compiler)
    out = os.fdopen(proto_out, "w", buffering=1)

    def answer(msg: dict) -> None:
        try:
            out.write(json.dumps(msg) + "\n")
        except (BrokenPipeError, OSError):  # the study is gone: the members stop with it (SIGTERM)
            pass

    answer({"ready": ready})
    work = tempfile.mkdtemp(prefix="pulseform_warm_")
    sel = selectors.DefaultSelector()
    sel.register(proto_in, selectors.EVENT_READ, None)
    running: dict[int, tuple] = {}   # pidfd -> (id, pid, out, err, start, argv)
    buffer = b""
    open_input = True
    try:
        while open_input or running:
            for key, _ in sel.select():
                if key.data is None:  # a request
                    chunk = os.read(proto_in, 1 << 16)
                    if not chunk:
                        open_input = False
                        sel.unregister(proto_in)
                        for _, pid, *_ in running.values():
                            _signal(pid, signal.SIGTERM)
                        if running:
                            log.info("the study closed the warm process: SIGTERM to %d running member(s)", len(running))
                        continue
                    buffer += chunk
                    *lines, buffer = buffer.split(b"\n")
                    for line in lines:
                        if not line.strip():
                            continue
                        req = json.loads(line)
                        if req.get("op") == "term":
                            log.info("SIGTERM to %d running member(s)", len(running))
                            for _, pid, *_ in running.values():
                                _signal(pid, signal.SIGTERM)
                            continue
                        k = req["id"]
                        paths = (os.path.join(work, f"{k}.out"), os.path.join(work, f"{k}.err"))
                        sys.stdout.flush()
                        sys.stderr.flush()
                        pid = os.fork()
                        if pid == 0:
                            _member(main, req, *paths, close_fds=[proto_in, proto_out, sel.fileno()]
                                    + [fd for fd in running])
                        pidfd = os.pidfd_open(pid)
                        running[pidfd] = (k, pid, *paths, time.perf_counter(), req["argv"])
                        sel.register(pidfd, selectors.EVENT_READ, "member")
                        log.info("member %d: process %d: pulseform %s", k, pid, " ".join(req["argv"]))
                        answer({"id": k, "started": pid})
                else:  # a member ended
                    pidfd = key.fd
                    sel.unregister(pidfd)
                    k, pid, out_path, err_path, start, argv = running.pop(pidfd)
                    os.close(pidfd)
                    _, status = os.waitpid(pid, 0)
                    code = os.waitstatus_to_exitcode(status)
                    log.info("member %d: process %d ended: exit %d after %.2f s", k, pid, code,
                             time.perf_counter() - start)
                    msg = {"id": k, "returncode": code, "argv": argv,
                           "stdout": _tail(out_path), "stderr": _tail(err_path)}
                    for p in (out_path, err_path):
                        os.unlink(p)
                    answer(msg)
    finally:
        import shutil

        shutil.rmtree(work, ignore_errors=True)
    log.info("warm process %d: done", os.getpid())
    logging.shutdown()
    os._exit(0)  # without the libraries' exit handlers (~0.5 s: nothing here needs them, no member is left)


def _signal(pid: int, sig: int) -> None:
    try:
        os.kill(pid, sig)
    except ProcessLookupError:
        pass
