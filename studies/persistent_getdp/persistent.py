"""Prototype driver (issue 15, study): ONE getdp process advances many EM steps on a moving mesh.

Protocol (per EM step; see decks/Lib_Persistent.pro and docs/persistent_getdp.md):

* Python -> getdp: one binary GetDP ``.res`` message written into the FIFO ``in.fifo`` (getdp's
  ``-res`` file).  ``ReadSolution[U]`` blocks on it; its ``$Solution`` header carries t_n (Time),
  the flags (TimeImag: 1 element force, 2 fields, 4 state, 8 stop) and the step number (TimeStep);
  the vector is the node displacement *increment* (x_new - x_current) in U's dof order, which is
  read once per process from getdp's ``.pre`` (DofData #1: ``NumType Entity Harmonic Type NumDof``).
* getdp -> Python: text lines on the FIFO ``out.fifo`` (opened O_RDWR here, so getdp's ``fopen(.., "a")``
  never blocks and a read never sees EOF): ``C k I U P Fx Fy`` per coil, ``K k P Fx Fy`` per conductor,
  ``G W Vc Ic``, then ``D k t dt`` when the step is done; the per-element force table ``elem_F.txt``
  (and ``elem_P.txt``, ``elem_b.txt``, ``nodes_a.txt``, ``nodes_a_prev.txt`` on request) in the run folder.
* Failure: the wait selects on the FIFO and on a pidfd of getdp: a getdp that dies is reported at
  once with its exit status and log tail, one that hangs is killed after ``step_time_limit`` s; getdp
  runs with the product's ``child_preexec`` (SIGKILL on parent death, SIGINT ignored).

This is study code: it reuses the product's model/mesh helpers read-only and is not imported by
the product.
"""
from __future__ import annotations

import os
import select
import shutil
import signal
import stat
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp import EMMesh, EMModel, GetDPError, write_msh22
from pulseform.solvers.getdp.runner import FAST_MPI_ENV, child_preexec, find_getdp, log_tail, scan_log
from pulseform.solvers.getdp.solver import DEFAULT_PETSC_ARGS, GetDPSolver, _element_table, _element_volumes

HERE = Path(__file__).resolve().parent
#: study copies of the product decks: em_case.pro unchanged, Lib_PulsedForming.pro with the two-valued
#: Init constraints and ``Include "Lib_Persistent.pro"`` at its end (see decks/)
STUDY_CASE_DECK = HERE / "decks" / "em_case.pro"
STUDY_LIB = HERE / "decks" / "Lib_PulsedForming.pro"
RESOLUTION = "EM_Persistent"
FLAG_ELEM, FLAG_FIELDS, FLAG_STATE, FLAG_STOP, FLAG_QUERY, FLAG_REDO = 1, 2, 4, 8, 32, 64


def read_pre_dofs(path: Path, system: int) -> np.ndarray:
    """Rows (NumType, Entity, Harmonic, Type, NumDof) of DofData #``system`` in a getdp ``.pre`` file."""
    text = Path(path).read_text()
    head = f"$DofData /* #{system} */"
    i = text.find(head)
    if i < 0:
        raise RuntimeError(f"{path}: no {head}")
    lines = text[i:text.find("$EndDofData", i)].splitlines()
    n_any = int(lines[5].split()[0])
    rows = np.array([ln.split()[:5] for ln in lines[6:6 + n_any]], dtype=np.int64)
    return rows


@dataclass
class StepOut:
    """What one persistent EM step returned (end-of-step values, as GetDPSolver's last sub-step)."""

    k: int
    t: float
    dt_gamma: float
    coil: np.ndarray          # (n_coils, 5): I, U, P, Fx, Fy
    cond: np.ndarray          # (n_cond, 3): P, Fx, Fy
    glob: np.ndarray          # W, Vc, Ic
    elements: np.ndarray | None = None       # rows of mesh.triangles (conductors)
    force_density: np.ndarray | None = None  # (n_el, 2) N/m^3: element integral / element volume
    joule_density: np.ndarray | None = None
    flux_density: np.ndarray | None = None
    nodes_a: np.ndarray | None = None        # (n, 2): node id, r a_phi of x_n
    nodes_a_prev: np.ndarray | None = None   # of x_{n-1}
    timing: dict = field(default_factory=dict)


class PersistentGetDP:
    """One getdp process for a whole run on one mesh connectivity (until a remesh).

    Parameters mirror :class:`GetDPSolver` (model, deck, extra_numbers, preamble, petsc_args);
    ``step_time_limit`` bounds each EM step and the start-up (s); ``verbosity`` is getdp's ``-v``.
    ``lean``: getdp evaluates only the integrals the loop needs each step (PF_GlobalsSet = 37: coil
    I, U, circuit; the magnetic energy as 1/2 (j, a) over coils and conductors (Wj, equal to the
    whole-domain integral to round-off); the conductor Joule power); the conductor force is the sum
    of the per-element table (the same element integrals) and the coil Joule power (Ns I / Sc)^2 /
    sigma times the coil volume (uniform current density); the coil force is not computed (NaN).
    """

    def __init__(self, model: EMModel, run_dir: str | Path, *, deck: str | Path = STUDY_CASE_DECK,
                 executable: str = "getdp", petsc_args=DEFAULT_PETSC_ARGS, step_time_limit: float = 600.0,
                 extra_numbers: dict | None = None, preamble=(), verbosity: int = 3, lean: bool = False):
        self.model = model
        self.run_dir = Path(run_dir).resolve()
        self.deck = Path(deck).resolve()
        self.exe = find_getdp(executable)
        self.petsc_args = list(petsc_args)
        self.step_time_limit = step_time_limit
        self.extra_numbers = dict(extra_numbers or {})
        self.preamble = list(preamble)
        self.verbosity = verbosity
        self.lean = lean
        if lean:
            self.extra_numbers["PF_GlobalsSet"] = 37
        self.proc: subprocess.Popen | None = None
        self._in_fd: int | None = None
        self._helper = object.__new__(GetDPSolver)   # only for _numbers / _table_lines (read-only use)
        self._helper.model = model

    # ------------------------------------------------------------------ start
    def prepare(self, mesh: EMMesh, *, t1: float = 0.0, dt_prev: float = 0.0, step0: int = 0,
                init: dict | None = None, init2: dict | None = None, t2: float = 0.0,
                extra: dict | None = None, out_path: Path | None = None) -> list[str]:
        """Write the run folder (mesh, run.pro, FIFOs) and return getdp's argv (see :meth:`start`).
        ``extra`` numbers and a regular ``out_path`` serve the self-clocked baseline (PF_SelfSteps)."""
        """Start getdp on ``mesh`` (its current node positions) from the state at ``t1``.

        ``init``: None (fresh start: capacitor at V0, no field) or {"ids", "values", "vc", "i"} of x_{n-1}
        (1-based node ids and r a_phi on the coil/conductor nodes, circuit values); ``init2`` the same
        for x_{n-2} at ``t2`` (needs the two-valued Init constraints of decks/Lib_PulsedForming_init2.pro).
        """
        rd = self.run_dir
        if rd.exists():
            shutil.rmtree(rd)
        (rd / "out").mkdir(parents=True)
        self.mesh = mesh
        self.points = mesh.points.copy()           # what getdp's nodes are at now
        msh = write_msh22(mesh, rd / "mesh.msh")
        numbers = self._helper._numbers(mesh)
        numbers.update(self.extra_numbers)
        numbers.update(Flag_ElemOut=0, PF_T1=t1, PF_T2=t2, PF_DtPrev=dt_prev, PF_Step0=step0,
                       PF_Seed=2 if init2 is not None else 1)
        numbers.update(extra or {})
        lines = self.preamble + self._helper._table_lines()
        m = self.model
        if m.circuit is not None:
            numbers["Init_Vc"] = m.circuit.V0 if init is None else init["vc"]
            numbers["Init_I"] = 0.0 if init is None else init["i"]
        if init is not None:
            numbers["Flag_InitA"] = 1 if init2 is None else 2
            lines.append(_list_line("InitA_List", init["ids"], init["values"]))
            if init2 is not None:
                lines.append(_list_line("InitA2_List", init2["ids"], init2["values"]))
                if m.circuit is not None:
                    numbers["Init2_Vc"], numbers["Init2_I"] = init2["vc"], init2["i"]
        wrapper = rd / "run.pro"
        wrapper.write_text("// generated by studies/persistent_getdp/persistent.py\n" + "\n".join(lines)
                           + f'\nInclude "{self.deck}";\n')
        self.fifo_in, self.fifo_out = rd / "in.fifo", rd / "out.fifo"
        for p in (self.fifo_in, self.fifo_out):
            os.mkfifo(p, 0o600)
        argv = [self.exe, str(wrapper), "-msh", str(msh), "-name", str(rd / "em"), "-res", str(self.fifo_in)]
        for k, v in numbers.items():
            argv += ["-setnumber", k, repr(float(v))]
        argv += ["-setstring", "OutDir", str(rd / "out") + "/", "-setstring", "PF_Out", str(out_path or self.fifo_out)]
        argv += self.petsc_args + ["-solve", RESOLUTION, "-v", str(self.verbosity)]
        self.argv = argv
        return argv

    def start(self, mesh: EMMesh, **kw) -> float:
        """Start getdp on ``mesh`` (its current node positions) from the state at ``t1``.

        ``init``: None (fresh start: capacitor at V0, no field) or {"ids", "values", "vc", "i"} of x_{n-1}
        (1-based node ids and r a_phi on the coil/conductor nodes, circuit values); ``init2`` the same
        for x_{n-2} at ``t2`` (two-valued Init constraints of the study's Lib_PulsedForming.pro);
        ``dt_prev`` the step before t1, ``step0`` the number of the step ending at t1.
        Returns the start-up wall time (s) up to the point where getdp waits for the first step.
        """
        t0 = time.perf_counter()
        argv = self.prepare(mesh, **kw)
        rd = self.run_dir
        t1, step0 = kw.get("t1", 0.0), kw.get("step0", 0)
        # read end of the output FIFO held O_RDWR: getdp's opens never block, reads never see EOF
        self.out_fd = os.open(self.fifo_out, os.O_RDWR | os.O_NONBLOCK)
        self._buf = b""
        env = dict(os.environ)
        env.update(FAST_MPI_ENV)
        self.log_path = rd / "getdp.log"
        self._log = open(self.log_path, "w")
        self._log.write("# argv: " + " ".join(argv) + "\n")
        self._log.flush()
        self.proc = subprocess.Popen(argv, cwd=rd, stdout=self._log, stderr=subprocess.STDOUT, env=env,
                                     preexec_fn=child_preexec)
        self.pidfd = os.pidfd_open(self.proc.pid)
        self.k = step0
        self.t = t1
        # getdp opens in.fifo for reading once pre-processing is done and the loop waits:
        # then the .pre holds U's dof numbering
        self._open_in(time.monotonic() + self.step_time_limit, "start-up")   # kept for the first message
        rows = read_pre_dofs(rd / "em.pre", 1)
        ntypes = np.unique(rows[:, 0])
        if len(ntypes) != 2:
            raise RuntimeError(f"U system: expected 2 basis functions, found {ntypes}")
        self.n_u = int(rows[:, 4].max())
        self.u_index = np.full((mesh.n_nodes, 2), -1, np.int64)
        for comp, nt in enumerate(ntypes):           # X (defined first: smaller number), then Y
            sel = rows[:, 0] == nt
            self.u_index[rows[sel, 1] - 1, comp] = rows[sel, 4] - 1
        return time.perf_counter() - t0

    # ------------------------------------------------------------------ one step
    def step(self, points: np.ndarray, t_end: float, flags: int = FLAG_ELEM, redo: bool = False) -> StepOut:
        """Move the nodes to ``points`` and advance to ``t_end`` (one BDF2 step); ``redo``: the last
        step again, from its start state, on the geometry ``points`` (coupling.iterate)."""
        c0 = time.perf_counter()
        du = np.asarray(points, float) - self.points
        vec = np.zeros(self.n_u)
        ok = self.u_index >= 0
        vec[self.u_index[ok]] = du[ok]
        if np.any(du[~ok] != 0):
            raise ValueError("a node without a displacement dof moved")
        if redo:
            self.k -= 1
        self._send(vec, float(t_end), flags | (FLAG_REDO if redo else 0), self.k + 1)
        c1 = time.perf_counter()
        lines = self._wait_done()
        c2 = time.perf_counter()
        self.points = np.asarray(points, float).copy()   # getdp's nodes: x + (x_new - x) (1 ulp)
        self.k += 1
        self.t = float(t_end)
        out = self._parse(lines, flags)
        c3 = time.perf_counter()
        out.timing = {"send_s": c1 - c0, "getdp_s": c2 - c1, "read_s": c3 - c2}
        return out

    def query(self, flags: int) -> StepOut:
        """Outputs of the current solution without a step (``flags``: FLAG_FIELDS, FLAG_STATE, FLAG_ELEM)."""
        c0 = time.perf_counter()
        self._send(np.zeros(self.n_u), self.t, flags | FLAG_QUERY, self.k)
        lines = self._wait_done()
        out = self._parse(lines, flags)
        out.timing = {"query_s": time.perf_counter() - c0}
        return out

    def close(self, timeout: float = 30.0) -> int:
        """Send the stop message and wait for getdp to exit (kill it after ``timeout``)."""
        if self.proc is None:
            return 0
        try:
            if self.proc.poll() is None:
                self._send(np.zeros(self.n_u), self.t, FLAG_STOP, self.k + 1)
                self.proc.wait(timeout)
        except (subprocess.TimeoutExpired, GetDPError, OSError):
            self.proc.kill()
            self.proc.wait()
        finally:
            for fd in (self.out_fd, self.pidfd):
                try:
                    os.close(fd)
                except OSError:
                    pass
            self._log.close()
        rc = self.proc.returncode
        self.proc = None
        return rc

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()

    # ------------------------------------------------------------------ protocol
    def _fail(self, what: str, time_limit: float | None = None) -> GetDPError:
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

    def _open_in(self, deadline: float, what: str) -> None:
        """Open the input FIFO for writing once getdp reads it (O_NONBLOCK open fails with ENXIO before)."""
        delay = 2e-5
        while True:
            try:
                self._in_fd = os.open(self.fifo_in, os.O_WRONLY | os.O_NONBLOCK)
                return
            except OSError as err:
                if err.errno != 6:   # ENXIO: no reader yet
                    raise
            if self._dead():
                raise self._fail(f"getdp stopped before the {what}")
            if time.monotonic() > deadline:
                self.kill()
                raise self._fail(f"getdp exceeded its time limit of {self.step_time_limit:g} s ({what}) "
                                 "and was stopped", self.step_time_limit)
            time.sleep(delay)
            delay = min(delay * 2, 2e-3)

    def _send(self, vec: np.ndarray, t: float, flags: int, k: int) -> None:
        head = (b"$ResFormat /* pulseform */\n1.1 1\n$EndResFormat\n$Solution  /* DofData #1 */\n"
                + f"1 {t!r} {float(flags)!r} {k}\n".encode())
        msg = head + np.ascontiguousarray(vec, "<f8").tobytes() + b"\n$EndSolution\n"
        if self._in_fd is None:
            self._open_in(time.monotonic() + self.step_time_limit, f"step {k}")
        fd, self._in_fd = self._in_fd, None
        try:
            os.set_blocking(fd, True)
            view = memoryview(msg)
            while view:
                n = os.write(fd, view)   # BrokenPipeError if getdp dies while reading
                view = view[n:]
        except BrokenPipeError:
            raise self._fail(f"getdp stopped while reading step {k}") from None
        finally:
            os.close(fd)                 # EOF for getdp's ReadSolution

    def _wait_done(self) -> list[str]:
        deadline = time.monotonic() + self.step_time_limit
        lines: list[str] = []
        while True:
            nl = self._buf.find(b"\n")
            while nl >= 0:
                line = self._buf[:nl].decode()
                self._buf = self._buf[nl + 1:]
                lines.append(line)
                if line.startswith("D "):
                    return lines
                nl = self._buf.find(b"\n")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                self.kill()
                raise self._fail(f"getdp exceeded its time limit of {self.step_time_limit:g} s in step "
                                 f"{self.k + 1} and was stopped", self.step_time_limit)
            r, _, _ = select.select([self.out_fd, self.pidfd], [], [], remaining)
            if self.out_fd in r:
                self._buf += os.read(self.out_fd, 1 << 16)
            elif self.pidfd in r:
                try:   # lines written just before it died
                    self._buf += os.read(self.out_fd, 1 << 16)
                except BlockingIOError:
                    pass
                if b"D " not in self._buf:
                    self.proc.wait()
                    raise self._fail(f"getdp stopped during step {self.k + 1}")

    def _parse(self, lines: list[str], flags: int) -> StepOut:
        m = self.model
        coil = np.zeros((len(m.coils), 5))
        cond = np.zeros((len(m.conductors), 3))
        glob = np.zeros(3)
        k = t = dtg = None
        for ln in lines:
            f = ln.split()
            if f[0] == "C":
                coil[int(f[1]) - 1] = [float(x) for x in f[2:7]]
            elif f[0] == "K":
                cond[int(f[1]) - 1] = [float(x) for x in f[2:5]]
            elif f[0] == "G":
                glob[:] = [float(x) for x in f[1:4]]
            elif f[0] == "D":
                k, t, dtg = int(f[1]), float(f[2]), float(f[3])
        if k != self.k:
            raise RuntimeError(f"getdp answered step {k}, expected {self.k}")
        out = StepOut(k, t, dtg, coil, cond, glob)
        if any(ln.startswith("G ") for ln in lines):
            self.last_glob = glob.copy()
        d = self.run_dir / "out"
        if flags & FLAG_ELEM and m.conductors:
            ids, eF = _element_table(d / "elem_F.txt", 3, 1)
            out.elements = ids - 1
            vol = _element_volumes(self.mesh.with_points(self.points), out.elements, m.axisymmetric)
            out.force_density = eF[0, :, :2] / vol[:, None]
            if self.lean and any(ln.startswith("G ") for ln in lines):
                tags = self.mesh.tri_tags[out.elements]
                for j in range(len(m.conductors)):
                    out.cond[j, 1:3] = eF[0, tags == 201 + j, :2].sum(axis=0)
        if self.lean and any(ln.startswith("G ") for ln in lines):
            if not hasattr(self, "_coil_vol"):
                self._coil_vol = [float(_element_volumes(self.mesh, np.flatnonzero(self.mesh.tri_tags == 101 + j),
                                                         m.axisymmetric).sum()) for j in range(len(m.coils))]
                self._coil_sc = [float(_element_volumes(self.mesh, np.flatnonzero(self.mesh.tri_tags == 101 + j),
                                                        False).sum()) for j in range(len(m.coils))]
            for j, c in enumerate(m.coils):
                out.coil[j, 2] = (c.turns * out.coil[j, 0] / self._coil_sc[j]) ** 2 / c.sigma * self._coil_vol[j]
                out.coil[j, 3:5] = np.nan
        if flags & FLAG_FIELDS and m.conductors:
            ids, eP = _element_table(d / "elem_P.txt", 1, 1)
            vol = _element_volumes(self.mesh.with_points(self.points), ids - 1, m.axisymmetric)
            out.joule_density = eP[0, :, 0] / vol
            out.flux_density = _element_table(d / "elem_b.txt", 3, 1)[1][0, :, :2]
        if flags & FLAG_STATE:
            out.nodes_a = np.loadtxt(d / "nodes_a.txt", skiprows=1, ndmin=2)
            out.nodes_a_prev = np.loadtxt(d / "nodes_a_prev.txt", skiprows=1, ndmin=2)
        return out


def _list_line(name: str, ids, values) -> str:
    pairs = [f"{int(i)}, {float(v)!r}" for i, v in zip(ids, values)]
    body = ",\n  ".join(", ".join(pairs[j:j + 8]) for j in range(0, len(pairs), 8))
    return f"{name}() = {{{len(pairs)},\n  {body}}};"


# ---------------------------------------------------------------------------- restart (remesh / resume)
def state_from_query(p: PersistentGetDP, out: StepOut, material_points: np.ndarray, prev_circuit: tuple,
                     dt_prev: float):
    """The product's :class:`EMState` (BDF2 history in material coordinates) from a FLAG_STATE answer.

    ``prev_circuit`` = (capacitor voltage, current) of x_{n-1} (Python keeps it from the step before);
    the circuit values of x_n are the last step's globals.
    """
    from pulseform.solvers.getdp import EMState

    mesh = p.mesh
    tri, used = p._helper._cs_nodes(mesh)
    remap = np.full(mesh.n_nodes, -1, np.int64)
    remap[used] = np.arange(len(used))

    def nodal(table):
        v = np.zeros(mesh.n_nodes)
        v[table[:, 0].astype(np.int64) - 1] = np.nan_to_num(table[:, 1], nan=0.0)  # r = 0: r a_phi = 0
        return v[used].tolist()

    return EMState(t=p.t, step_index=p.k, capacitor_voltage=float(p.last_glob[1]), current=float(p.last_glob[2]),
                   a_points=np.asarray(material_points, float)[used].tolist(), a_triangles=remap[tri].tolist(),
                   a_values=nodal(out.nodes_a), a_prev_values=nodal(out.nodes_a_prev), dt_prev=dt_prev,
                   capacitor_voltage_prev=float(prev_circuit[0]), current_prev=float(prev_circuit[1]))


def seed_from_state(p_new: PersistentGetDP, mesh_new: EMMesh, material_new: np.ndarray, state) -> tuple[dict, dict]:
    """(init, init2) for :meth:`PersistentGetDP.start` on a new mesh: both BDF2 history states
    interpolated in material coordinates with the product's own routine (GetDPSolver._interpolate_a)."""
    h = p_new._helper
    ids, v1 = h._interpolate_a(mesh_new, material_new, state, state.a_values)
    _, v2 = h._interpolate_a(mesh_new, material_new, state, state.a_prev_values)
    init = {"ids": ids, "values": v1, "vc": state.capacitor_voltage, "i": state.current}
    init2 = {"ids": ids, "values": v2, "vc": state.capacitor_voltage_prev, "i": state.current_prev}
    return init, init2
