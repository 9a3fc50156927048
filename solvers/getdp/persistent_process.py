"""One persistent getdp process and its message protocol (used by :mod:`.persistent` in 2D and by
:mod:`.persistent3d` in 3D: ``EM_Persistent3D``, a 3-component U, the unknowns of system A seeded by
:meth:`PersistentProcess.seed`).

Protocol of one EM step (the Resolution ``EM_Persistent`` of ``decks/Lib_Persistent.pro``):

* Python -> getdp: one binary GetDP ``.res`` message written into the FIFO ``in.fifo`` (getdp's
  ``-res`` file); ``ReadSolution[U]`` blocks on it.  Its ``$Solution`` header carries t_n (Time),
  the flags (TimeImag, :data:`FLAG_ELEM` ...) and the step number (TimeStep); the vector is the
  node displacement *increment* (x_new - x_getdp) in the dof order of the displacement system U,
  read once per process from getdp's ``.pre`` (DofData #1).  ``DeformMesh`` moves the nodes.
* getdp -> Python: text lines on the FIFO ``out.fifo`` (held open read-write here, so getdp's
  appending opens never block and a read never sees end-of-file): ``C k I U P Fx Fy`` per coil,
  ``K k P Fx Fy`` per conductor, ``G W Vc Ic``, ``S factorised corrections residual`` (the step's
  solve: :class:`FactorReuse`), then ``D k t dt`` when the step is done; the
  per-element force table ``elem_F.txt`` (and ``elem_P.txt``, ``elem_b.txt``, ``field_b.txt``,
  ``field_a.txt``, ``nodes_a.txt``, ``nodes_a_prev.txt`` on request) in the process's ``out/``.
* Failure: the wait selects on the FIFO and on a pidfd of getdp: a getdp that dies is reported at
  once with its exit status and log tail, one that hangs is killed after the time limit; getdp runs
  with :func:`~.runner.child_preexec` (SIGKILL when pulseform dies, SIGINT ignored).
"""
from __future__ import annotations

import os
import select
import shutil
import signal
import subprocess
import tempfile
import time
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from .mesh import EMMesh, write_msh22
from .mesh3d import Mesh3D
from .persistent_data import exact_increment, read_pre_dofs
from .runner import FAST_MPI_ENV, GetDPError, child_preexec, find_getdp, log_tail, scan_log
from .solver import DECK_DIR, DEFAULT_PETSC_ARGS

RESOLUTION = "EM_Persistent"
#: the library holding it, included by Lib_PulsedForming.pro when ``PulseformPersistentLib`` names it
PERSISTENT_LIB = (DECK_DIR / "Lib_Persistent.pro").resolve()
#: message flags (the ``TimeImag`` of a message; Lib_Persistent.pro): per-element force, Joule
#: power and B on the conductors, nodal state of x_n and x_{n-1}, stop, no globals (profiling),
#: query (no step), redo (the last step again on a new geometry), whole-domain fields, factorise
#: (this step factorises its own matrix: :class:`FactorReuse`), prime (3D: move, and factorise the
#: matrix of a given geometry and time step without a step: :meth:`PersistentProcess.prime`)
FLAG_ELEM, FLAG_COND_FIELDS, FLAG_STATE, FLAG_STOP = 1, 2, 4, 8
FLAG_NO_GLOBALS, FLAG_QUERY, FLAG_REDO, FLAG_FIELDS = 16, 32, 64, 128
FLAG_FACTORISE, FLAG_PRIME = 512, 1024
#: ``PF_GlobalsSet``: coil I, U and circuit (1) + conductor Joule power (4) + energy from the sources (32)
LEAN_GLOBALS = 37
_ENXIO = 6


@dataclass(frozen=True)
class FactorReuse:
    """Kept LU factors across the EM steps of a persistent process (``decks/Lib_PersistentStep.pro``).

    Each step assembles its own system A x = b and solves it by GCR (a Krylov method: the iterates of
    GMRES) right-preconditioned with the LU factors of an earlier step's matrix, from the linear
    extrapolation of the last two states, until ``|b - A x| <= tol |b|`` (2-norms, the true residual
    checked at the end): the converged x solves this step's system to that relative residual, not an
    approximation of the physics. A step factorises its own matrix when there are no factors yet,
    when the previous step needed more than 3/4 of ``max_corrections`` iterations, when
    ``max_corrections`` did not converge, or when asked (:data:`FLAG_FACTORISE`).

    Parameters
    ----------
    tol : float
        Relative residual of a step solved with kept factors (-); 0: every step factorises (GetDP's
        own Generate + Solve).
    max_corrections : int
        GCR iterations before a step factorises its own matrix (each keeps two vectors of the system's
        size in getdp).
    history : int
        History directions searched before the first solve with the factors (0, 1 or 2): the second and
        third differences of the last states (a product with A each, no triangular solve; Fischer's
        projection for successive right-hand sides).
    """

    tol: float = 0.0
    max_corrections: int = 20
    history: int = 2

    def __post_init__(self) -> None:
        if not 0.0 <= self.tol < 1.0:
            raise ValueError(f"factor reuse tolerance must be in [0, 1), got {self.tol!r}")
        if self.max_corrections < 1:
            raise ValueError(f"factor reuse max_corrections must be >= 1, got {self.max_corrections!r}")
        if self.history not in (0, 1, 2):
            raise ValueError(f"factor reuse history must be 0, 1 or 2, got {self.history!r}")

    def solver_args(self, petsc_args: Sequence[str]) -> tuple[str, ...]:
        """``petsc_args`` for a process that keeps factors: UMFPACK without its iterative refinement (the
        kept factors only precondition GCR, which checks the true residual; measured on the 3D bench's system:
        a solve 5.3 ms instead of 6.9 ms, its default 2 refinement steps each a product and a solve)."""
        args = tuple(petsc_args)
        if self.tol > 0 and "umfpack" in args and "-mat_umfpack_irstep" not in args:
            args += ("-mat_umfpack_irstep", "0")
        return args

    def numbers(self) -> dict[str, float]:
        """The deck's ``-setnumber`` values."""
        return {"PF_ReuseTol": float(self.tol), "PF_ReuseMaxIt": float(self.max_corrections),
                "PF_ReuseHist": float(self.history)}


@dataclass
class StepAnswer:
    """What getdp answered to one message (end-of-step values).

    ``coil`` (n_coils, 5): I (A), U (V, getdp's sign), P (W), Fx, Fy (N); ``cond`` (n_conductors, 3):
    P (W), Fx, Fy (N); ``glob``: magnetic energy (J), capacitor voltage (V), capacitor current (A),
    inductor current (A: the circuit state; equal to the capacitor's to round-off)
    (totals per radian in axisymmetry, per metre in planar, as getdp prints them, except where
    :class:`PersistentGetDPSolver` fills them in).  ``wall`` (s): Python's wait for the answer.
    The solve of a step (``Lib_PersistentStep.pro``, kept factors): ``factorised`` (the step factorised
    its own matrix), ``corrections`` (GCR iterations with kept factors), ``residual`` (their final
    relative residual |b - A x| / |b|; 0 after a factorisation), ``refactor_next`` (the next step factorises its
    own matrix: this one needed more than 3/4 of the iterations allowed); a query answers 0, 0, 0, False.
    ``dtime`` (s): the step's implicit-Euler time step gamma dt (what its matrix was assembled with). ``cpu`` (s): getdp's
    own CPU time of the step's parts -- moving the mesh, assembling the system (Generate), solving it, the
    outputs -- (0, 0, 0, 0) for a query: where an EM step's time goes, unaffected by other processes on
    the machine.
    """

    k: int
    t: float
    coil: np.ndarray
    cond: np.ndarray
    glob: np.ndarray
    has_globals: bool
    wall: float
    factorised: bool = False
    corrections: int = 0
    residual: float = 0.0
    refactor_next: bool = False
    dtime: float = 0.0
    cpu: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)


class PersistentProcess:
    """One ``getdp -solve EM_Persistent`` process on one mesh connectivity (see the module docstring).

    Parameters
    ----------
    run_dir : Path
        The process's folder (mesh, ``run.pro``, FIFOs, ``getdp.log``, ``out/``); made anew.
    argv_numbers : dict
        Numbers passed with ``-setnumber`` (the model's, the deck's, the seed's).
    lines : list of str
        Lines of ``run.pro`` before the deck is included (lists: Init values, current tables).
    deck : Path
        The case deck (it includes the library, which includes ``Lib_Persistent.pro``).
    time_limit : float or None
        Wall-time limit (s) of the start-up and of each message's answer; None: 600 s.
    resolution : str
        The Resolution to solve (``EM_Persistent``; ``EM_Persistent3D`` of :mod:`.persistent3d`).
    u_system : int
        DofData number of the displacement system U (its systems' order in the Resolution).

    A 2D :class:`~.mesh.EMMesh` (U has 2 components) or a :class:`~.mesh3d.Mesh3D` (3 components,
    written with its node positions by ``Mesh3D.moved``).
    """

    def __init__(self, run_dir: Path, mesh: EMMesh | Mesh3D, argv_numbers: dict[str, float], lines: list[str],
                 deck: Path, *, executable: str = "getdp", petsc_args: Sequence[str] = DEFAULT_PETSC_ARGS,
                 time_limit: float | None = None, verbosity: int = 2, resolution: str = RESOLUTION,
                 u_system: int = 1, element_values: bool = False) -> None:
        self.run_dir = Path(run_dir).resolve()
        self.element_values = bool(element_values)  # U also holds one value per element (PF_SigmaElem)
        self.s_index: dict[int, int] = {}
        self.time_limit = float(time_limit) if time_limit else 600.0
        rd = self.run_dir
        if rd.exists():
            shutil.rmtree(rd)
        (rd / "out").mkdir(parents=True)
        self.out_dir = rd / "out"
        self.mesh = mesh
        self.points = np.array(mesh.points, float)  # getdp's node coordinates, as getdp computes them
        self.u_system = int(u_system)
        if isinstance(mesh, Mesh3D):
            msh = mesh.moved(self.points, rd / "mesh.msh").path
        else:
            msh = write_msh22(mesh, rd / "mesh.msh")
        wrapper = rd / "run.pro"
        wrapper.write_text("// generated by pulseform.solvers.getdp.persistent\n" + "\n".join(lines)
                           + f'\nInclude "{Path(deck).resolve()}";\n')
        # the FIFOs live in a private folder of the temporary directory, not in the results folder:
        # some file systems (SMB, FAT, some FUSE mounts) cannot hold a FIFO
        self.fifo_dir = Path(tempfile.mkdtemp(prefix="pulseform_getdp_"))
        self.fifo_in, self.fifo_out = self.fifo_dir / "in.fifo", self.fifo_dir / "out.fifo"
        self._remove_fifos = weakref.finalize(self, shutil.rmtree, str(self.fifo_dir), True)
        for p in (self.fifo_in, self.fifo_out):
            os.mkfifo(p, 0o600)
        argv = [find_getdp(executable), str(wrapper), "-msh", str(msh), "-name", str(rd / "em"),
                "-res", str(self.fifo_in)]
        for k, v in argv_numbers.items():
            argv += ["-setnumber", k, repr(float(v))]
        argv += ["-setstring", "OutDir", str(self.out_dir) + "/", "-setstring", "PF_Out", str(self.fifo_out)]
        # -bin (after the PETSc options: before them getdp stopped without solving): SaveSolution writes
        # the exact unknowns
        self.argv = argv + list(petsc_args) + ["-bin", "-solve", resolution, "-v", str(int(verbosity))]
        self.proc: subprocess.Popen | None = None
        self._in_fd: int | None = None
        self._buf = b""

    # ------------------------------------------------------------------ life cycle
    def start(self, step0: int, t1: float) -> float:
        """Start getdp; return once it waits for the first message, with the start-up wall time (s)."""
        c0 = time.perf_counter()
        self.out_fd = os.open(self.fifo_out, os.O_RDWR | os.O_NONBLOCK)
        env = dict(os.environ)
        env.update(FAST_MPI_ENV)
        self.log_path = self.run_dir / "getdp.log"
        self._log = open(self.log_path, "w")
        self._log.write("# argv: " + " ".join(self.argv) + "\n")
        self._log.flush()
        try:
            self.proc = subprocess.Popen(self.argv, cwd=self.run_dir, stdout=self._log, stderr=subprocess.STDOUT,
                                         env=env, preexec_fn=child_preexec)
        except OSError as exc:
            raise GetDPError(f"cannot start getdp: {exc}", log_path=self.log_path, run_dir=self.run_dir) from exc
        self._finalizer = weakref.finalize(self, _kill, self.proc)
        self.pidfd = os.pidfd_open(self.proc.pid)
        self.k, self.t = int(step0), float(t1)
        # getdp opens in.fifo for reading once pre-processing is done and its loop waits: then the
        # .pre holds U's dof numbering
        self._open_in(time.monotonic() + self.time_limit, "start-up")
        rows = read_pre_dofs(self.run_dir / "em.pre", self.u_system)
        ntypes = np.unique(rows[:, 0])
        dim = self.points.shape[1]
        if len(ntypes) != dim + int(self.element_values):
            raise RuntimeError(f"displacement system U: expected {dim} basis functions"
                               f"{' and one per element' if self.element_values else ''}, found {ntypes}")
        self.n_u = int(rows[:, 4].max())
        self.u_index = np.full((self.mesh.n_nodes, dim), -1, np.int64)
        for comp, nt in enumerate(ntypes[:dim]):  # X (defined first: the smaller number), then Y (and Z)
            sel = rows[:, 0] == nt
            self.u_index[rows[sel, 1] - 1, comp] = rows[sel, 4] - 1
        if self.element_values:  # the per-element values (PF_H_s, defined after PF_H_u): element tag -> unknown
            sel = rows[:, 0] == ntypes[dim]
            self.s_index = dict(zip(rows[sel, 1].tolist(), (rows[sel, 4] - 1).tolist()))
        self._has_u = self.u_index >= 0
        self._vec = np.zeros(self.n_u)
        return time.perf_counter() - c0

    def close(self, timeout: float = 30.0) -> int:
        """Send the stop message and wait for getdp to exit (killed after ``timeout`` s); its exit code."""
        if self.proc is None:
            self._release()
            return 0
        try:
            if self.proc.poll() is None:
                self._send(np.zeros(self.n_u), self.t, FLAG_STOP, self.k + 1)
                self.proc.wait(timeout)
        except (subprocess.TimeoutExpired, GetDPError, OSError, AttributeError):
            self.kill()
        finally:
            self._release()
        return self.proc.returncode

    def kill(self) -> None:
        """End getdp at once (SIGKILL)."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()

    def _release(self) -> None:
        for name in ("out_fd", "pidfd", "_in_fd"):
            fd = getattr(self, name, None)
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
                setattr(self, name, None)
        if getattr(self, "_log", None) is not None and not self._log.closed:
            self._log.close()
        self._remove_fifos()

    @property
    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def died(self, what: str) -> GetDPError:
        """The error of a process that ended by itself (crash, signal), with its exit and log tail."""
        self.proc.wait()
        return self._fail(f"getdp stopped {what}")

    # ------------------------------------------------------------------ messages
    def step(self, points: np.ndarray, t_end: float, flags: int, redo: bool = False) -> StepAnswer:
        """Move getdp's nodes to ``points`` and advance to ``t_end`` (one BDF2 step); ``redo``: the
        last step again from its start state, on the geometry ``points``."""
        du = self._increment(points)
        k = self.k if redo else self.k + 1
        c0 = time.perf_counter()
        self._send(self._vec, float(t_end), flags | (FLAG_REDO if redo else 0), k)
        answer = self._answer(k, c0)
        self.points += du  # what getdp computed: x + du, the same IEEE operation (= points: exact_increment)
        self.k, self.t = k, float(t_end)
        return answer

    def _increment(self, points: np.ndarray) -> np.ndarray:
        """The displacement increment (n, dim) m that takes getdp's nodes to ``points`` exactly
        (:func:`exact_increment`), written into the message vector."""
        du = exact_increment(self.points, np.asarray(points, float))
        if np.any(du[~self._has_u] != 0.0):
            raise ValueError("a node without a displacement dof moved")
        self._vec[self.u_index[self._has_u]] = du[self._has_u]
        return du

    def set_element_values(self, tags: np.ndarray, values: np.ndarray) -> None:
        """The per-element values (e.g. σ, S/m) the next step messages carry (``decks/Lib_PersistentSigma.pro``,
        ``PF_SigmaElem``): one per element tag of the regions that have them, each of those tags once."""
        tags = np.asarray(tags, np.int64)
        if len(tags) != len(self.s_index) or len(np.unique(tags)) != len(tags):
            raise ValueError(f"per-element values: got {len(tags)} element tags, getdp has {len(self.s_index)}")
        try:
            idx = np.fromiter((self.s_index[t] for t in tags.tolist()), np.int64, len(tags))
        except KeyError as exc:
            raise ValueError(f"per-element values: element {exc.args[0]} has no value in getdp") from None
        self._vec[idx] = np.asarray(values, float)

    def prime(self, points: np.ndarray, dtime: float) -> StepAnswer:
        """Move getdp's nodes to ``points`` and, with ``dtime`` > 0, factorise the system matrix of that
        geometry and implicit-Euler time step (s), without a step: the following steps' kept factors
        (``decks/Lib_Persistent3D.pro``; the solution and its history stay)."""
        du = self._increment(points)
        c0 = time.perf_counter()
        self._send(self._vec, float(dtime), FLAG_PRIME, self.k)
        answer = self._answer(self.k, c0)
        self.points += du  # what getdp computed
        return answer

    def query(self, flags: int) -> StepAnswer:
        """Outputs of the current solution without a step (``flags``: FLAG_COND_FIELDS, FLAG_FIELDS,
        FLAG_STATE, FLAG_ELEM)."""
        c0 = time.perf_counter()
        self._send(np.zeros(self.n_u), self.t, flags | FLAG_QUERY | FLAG_NO_GLOBALS, self.k)
        return self._answer(self.k, c0)

    def seed(self, blocks: Sequence[tuple[int, float, float, int, np.ndarray]]) -> None:
        """Send each block of :meth:`send_solutions` as a message of its own, waiting for getdp's
        acknowledgment (a ``D`` line of the current step) before the next: a ``ReadSolution`` per block
        before the loop (Lib_Persistent3D.pro's seed). A message sent before getdp closed the FIFO after
        the previous one could be lost."""
        for block in blocks:
            c0 = time.perf_counter()
            self.send_solutions([block], "the seed")
            self._answer(self.k, c0)

    def _answer(self, k: int, c0: float) -> StepAnswer:
        """getdp's answer to message ``k``; its wall time counts from ``c0``, before the message was sent
        (closing the FIFO's write end can hand the core to getdp at once: that time is getdp's)."""
        lines = self._wait_done(k)
        wall = time.perf_counter() - c0
        return self._parse(lines, k, wall)

    def _fail(self, what: str, time_limit: float | None = None) -> GetDPError:
        self.reported = True  # the error names the exit; closing need not warn again
        self._log.flush()
        rc = self.proc.poll()
        if rc is not None and rc < 0:
            what += f" (getdp killed by signal {signal.Signals(-rc).name})"
        elif rc is not None:
            what += f" (getdp exited with code {rc})"
        errors, _ = scan_log(self.log_path.read_text(errors="replace"))
        if errors:
            what += f": {errors[0]}"
        return GetDPError(what, log_path=self.log_path, run_dir=self.run_dir, returncode=rc,
                          log_tail=log_tail(self.log_path), time_limit=time_limit)

    def _dead(self) -> bool:
        return bool(select.select([self.pidfd], [], [], 0)[0])

    def _timeout(self, what: str) -> GetDPError:
        self.kill()
        return self._fail(f"getdp exceeded its time limit of {self.time_limit:g} s ({what}) and was stopped",
                          self.time_limit)

    def _open_in(self, deadline: float, what: str) -> None:
        """Open the input FIFO for writing once getdp reads it (an O_NONBLOCK open fails with ENXIO before)."""
        delay = 2e-5
        while True:
            try:
                self._in_fd = os.open(self.fifo_in, os.O_WRONLY | os.O_NONBLOCK)
                return
            except OSError as err:
                if err.errno != _ENXIO:
                    raise
            if self._dead():
                self.proc.wait()
                raise self._fail(f"getdp stopped before the {what}")
            if time.monotonic() > deadline:
                raise self._timeout(what)
            time.sleep(delay)
            delay = min(delay * 2, 2e-3)

    def _send(self, vec: np.ndarray, t: float, flags: int, k: int) -> None:
        self.send_solutions([(self.u_system, t, float(flags), k, vec)], f"step {k}")

    def send_solutions(self, blocks: Sequence[tuple[int, float, float, int, np.ndarray]], what: str) -> None:
        """Write one binary ``.res`` message of ``blocks`` (DofData number, Time, TimeImag, TimeStep,
        vector) into the input FIFO (what a ``ReadSolution`` reads; e.g. the seed of system A)."""
        msg = b"$ResFormat /* pulseform */\n1.1 1\n$EndResFormat\n"
        for num, t, t_imag, k, vec in blocks:
            msg += (f"$Solution  /* DofData #{num} */\n{num} {float(t)!r} {float(t_imag)!r} {k}\n".encode()
                    + np.ascontiguousarray(vec, "<f8").tobytes() + b"\n$EndSolution\n")
        if self._in_fd is None:
            self._open_in(time.monotonic() + self.time_limit, what)
        fd, self._in_fd = self._in_fd, None
        try:
            os.set_blocking(fd, True)
            view = memoryview(msg)
            while view:
                view = view[os.write(fd, view):]  # BrokenPipeError if getdp dies while reading
        except BrokenPipeError:
            self.proc.wait()
            raise self._fail(f"getdp stopped while reading {what}") from None
        finally:
            os.close(fd)  # end-of-file for getdp's ReadSolution

    def _wait_done(self, k: int) -> list[str]:
        deadline = time.monotonic() + self.time_limit
        lines: list[str] = []
        while True:
            nl = self._buf.find(b"\n")
            while nl >= 0:
                line = self._buf[:nl].decode(errors="replace")
                self._buf = self._buf[nl + 1:]
                lines.append(line)
                if line.startswith("D "):
                    return lines
                nl = self._buf.find(b"\n")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise self._timeout(f"EM step {k}")
            ready, _, _ = select.select([self.out_fd, self.pidfd], [], [], remaining)
            if self.out_fd in ready:
                self._buf += os.read(self.out_fd, 1 << 16)
            elif self.pidfd in ready:
                try:  # lines written just before it died
                    self._buf += os.read(self.out_fd, 1 << 16)
                except BlockingIOError:
                    pass
                if b"D " not in self._buf:
                    self.proc.wait()
                    raise self._fail(f"getdp stopped during EM step {k}")

    def _parse(self, lines: list[str], k_expected: int, wall: float) -> StepAnswer:
        coil, cond, glob = [], [], np.zeros(4)
        k = t = None
        has_globals = False
        solve = (False, 0, 0.0, False)
        cpu = (0.0, 0.0, 0.0, 0.0)
        dtime = 0.0
        for ln in lines:
            f = ln.split()
            if not f:
                continue
            if f[0] == "C":
                coil.append((int(f[1]), [float(x) for x in f[2:7]]))
            elif f[0] == "K":
                cond.append((int(f[1]), [float(x) for x in f[2:5]]))
            elif f[0] == "G":
                glob[:] = [float(x) for x in f[1:5]]
                has_globals = True
            elif f[0] == "S":
                solve = (float(f[1]) != 0.0, int(float(f[2])), float(f[3]), float(f[4]) != 0.0)
            elif f[0] == "T":
                cpu = tuple(float(x) for x in f[1:5])
            elif f[0] == "D":
                k, t, dtime = int(f[1]), float(f[2]), float(f[3])
        if k != k_expected:
            raise GetDPError(f"getdp answered step {k}, expected {k_expected}", log_path=self.log_path,
                             run_dir=self.run_dir, log_tail=log_tail(self.log_path))
        c = np.array([v for _, v in sorted(coil)]).reshape(-1, 5)
        kk = np.array([v for _, v in sorted(cond)]).reshape(-1, 3)
        return StepAnswer(k, t, c, kk, glob, has_globals, wall, *solve, dtime, cpu)


def _kill(proc: subprocess.Popen) -> None:
    """Finalizer: a process object dropped without :meth:`PersistentProcess.close` ends its getdp."""
    if proc.poll() is None:
        proc.kill()
        proc.wait()
