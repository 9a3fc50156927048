"""The EM participant: one EM step = one getdp run (model, state and results in :mod:`.model`)."""
from __future__ import annotations

import shutil
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np

from .applied_field import applied_start
from .bh_curve import model_magnetic, read_newton
from .bdf2 import bdf2_coefficients, match_rows, trapezoid_mean
from .deck_numbers import model_deck_numbers
from .conductivity import check_deck, checked_temperatures, coil_mass_cp, start_power, step_inputs
from .files import discard_folder, element_volumes, init_list_line, read_element_table, read_table
from .mesh import EMMesh, coil_tag, conductor_tag, physical_numbers, write_msh22
from .model import (Circuit, Coil, Conductor, CurrentTable, DampedSine, EMModel, EMState, EMStepResult,  # noqa: F401
                    mesh_signature, table_lines)
from .runner import GetDPError, run_getdp

DECK_DIR = Path(__file__).resolve().parent / "decks"
#: PETSc options on getdp's command line: LU with UMFPACK (as MUMPS to round-off, ~30 % less wall time per run here)
DEFAULT_PETSC_ARGS = ("-ksp_type", "preonly", "-pc_type", "lu", "-pc_factor_mat_solver_type", "umfpack")
CASE_DECK = DECK_DIR / "em_case.pro"
#: the ``run.pro`` line that names the magnetic block (``decks/em_magnetic.pro``: nu[] of every region from the
#: model's materials) for a deck other than the built-in one, which then does ``Include PulseformMagneticLib;``
MAGNETIC_BLOCK_LINE = f'PulseformMagneticLib = "{(DECK_DIR / "em_magnetic.pro").resolve()}";'
RESOLUTION = "EM_Transient"
#: time schemes of :class:`GetDPSolver`: GetDP's theta-scheme loop (theta from the ``TimeTheta``
#: number, 1 = implicit Euler), or BDF2 as one shifted implicit-Euler step per run (:mod:`.bdf2`)
TIME_SCHEMES = ("euler", "bdf2")


# ----------------------------------------------------------------------------- solver
class GetDPSolver:
    """Drives getdp for the staggered coupling; see the package docstring for the API.

    ``work_dir`` receives one folder per run (``run_name`` or ``step_<index>``) with the mesh,
    the generated ``run.pro``, ``getdp.log``, ``em.res`` and the output tables.  ``keep_runs``
    (default: keep all) deletes older run folders made by this object, keeping the last N.
    ``petsc_args`` go on getdp's command line (default: LU with UMFPACK).  ``reuse_pre``:
    restarts on the same connectivity copy the previous run's ``.pre`` (dof numbering) and
    run ``getdp -cal``, skipping pre-processing (same results, checked in the tests).
    ``extra_numbers`` are passed with ``-setnumber`` on top of the model's (a user deck's own
    parameters and physical ids); ``preamble`` lines go into ``run.pro`` before the deck is
    included (e.g. a string constant naming the library file).  ``time_scheme``: ``"euler"``
    (GetDP's theta loop, implicit Euler unless ``extra_numbers`` sets ``TimeTheta``) or
    ``"bdf2"`` (second order, one sub-step per run, always the Init path; see :mod:`.bdf2`).
    """

    def __init__(self, model: EMModel, work_dir: str | Path, *, executable: str = "getdp",
                 petsc_args: Sequence[str] = DEFAULT_PETSC_ARGS, timeout: float | None = None,
                 deck: str | Path = CASE_DECK, keep_runs: int | None = None, reuse_pre: bool = True,
                 extra_numbers: dict[str, float] | None = None, preamble: Sequence[str] = (),
                 time_scheme: str = "euler"):
        self.model = model
        self.extra_numbers = {k: float(v) for k, v in (extra_numbers or {}).items()}
        if time_scheme not in TIME_SCHEMES:
            raise ValueError(f"time_scheme must be one of {TIME_SCHEMES}, got {time_scheme!r}")
        if time_scheme == "bdf2" and self.extra_numbers.get("TimeTheta", 1.0) != 1.0:
            raise ValueError("time_scheme='bdf2' runs implicit-Euler steps: TimeTheta must be 1")
        self.time_scheme = time_scheme
        self.preamble = list(preamble)
        self.work_dir = Path(work_dir).resolve()
        self.work_dir.mkdir(parents=True, exist_ok=True)
        self.executable = executable
        self.petsc_args = list(petsc_args)
        self.timeout = timeout
        self.deck = Path(deck).resolve()
        #: the physical ids the built-in deck receives (a user's deck gets its role ids in ``extra_numbers``)
        self.deck_numbers = physical_numbers() if self.deck == CASE_DECK.resolve() else {}
        if keep_runs is not None and keep_runs < 1:
            raise ValueError("keep_runs must be >= 1 (the last run holds the restart .res)")
        self.keep_runs = keep_runs
        self.reuse_pre = reuse_pre
        self._runs: list[Path] = []
        check_deck(model, self.deck, CASE_DECK)   # σ(T) needs the built-in deck
        if model.is_magnetic and self.deck != CASE_DECK.resolve() and MAGNETIC_BLOCK_LINE not in self.preamble:
            raise ValueError("a magnetic material (mu_r or a B-H curve) needs the built-in deck (em_case.pro) or a "
                             f"deck that includes PulseformMagneticLib (preamble {MAGNETIC_BLOCK_LINE!r}): "
                             f"{self.deck.name} does not read them")
        self._elem_temperature: tuple[np.ndarray, np.ndarray] | None = None   # (EM triangle rows, K) for σ(T)

    # -- state
    def initial_state(self, t0: float = 0.0) -> EMState:
        v0 = self.model.circuit.V0 if self.model.circuit else 0.0
        return EMState(t=float(t0), capacitor_voltage=v0, current=0.0,
                       coil_heat=[0.0] * len(self.model.coils))

    def set_element_temperatures(self, elements: np.ndarray, temperature: np.ndarray) -> None:
        """Temperatures (K) of EM elements (rows of the mesh's triangles) for the conductors' σ(T) laws at the
        next steps (:func:`.conductivity.step_inputs`; an element not listed is at its ``initial_temperature``)."""
        self._elem_temperature = checked_temperatures(elements, temperature)

    # -- one step
    def step(self, mesh: EMMesh, state: EMState, t_end: float, n_sub: int = 1, *,
             material_points: np.ndarray | None = None, run_name: str | None = None,
             force_init_path: bool = False, element_output: str = "all",
             field_output: bool = False) -> tuple[EMStepResult, EMState]:
        """Advance from ``state.t`` to ``t_end`` with ``n_sub`` implicit Euler sub-steps (BDF2: one step).

        ``mesh`` holds the current node positions.  If its connectivity equals that of
        the previous step (and, when ``material_points`` is given, the coil/conductor nodes
        are the same material points as before), the field continues with
        ``-restart -res <previous .res>``: values travel with the nodes, right for
        Lagrangian conductor nodes.  Otherwise (or with ``force_init_path``) the previous
        nodal r a_phi is interpolated at ``material_points`` (reference coordinates of the
        new nodes; default ``mesh.points``, i.e. spatial) and fed through an Init
        constraint.  Pass ``material_points`` at every step or at none: they are stored
        in the state as the frame of the next interpolation.

        ``element_output``: per-element tables at ``"all"`` sub-steps (default), only the
        ``"last"`` one (the element arrays then have one row), or ``"none"`` (zero
        elements) -- they cost about as much as the solve on long runs.

        ``field_output``: also B on every triangle and the nodal unknown on every node at the
        step's end (``result.b_cells``, ``result.a_nodes``; PostOperation ``EM_Field``, for
        snapshots: ask for them only on the steps whose fields are written).  A deck without
        ``EM_Field`` leaves them None.
        """
        n_elem_rows = {"all": int(n_sub), "last": 1, "none": 0}.get(element_output)
        if n_elem_rows is None:
            raise ValueError("element_output must be 'all', 'last' or 'none'")
        if not t_end > state.t:
            raise ValueError(f"t_end={t_end} must be after state.t={state.t}")
        if int(n_sub) != n_sub or n_sub < 1:
            raise ValueError("n_sub must be a positive integer")
        bdf2 = self.time_scheme == "bdf2"
        if bdf2 and n_sub != 1:
            raise ValueError("time_scheme='bdf2' takes one step per getdp run: n_sub (em_substeps) must be 1")
        t_init = state.t
        model = self.model
        run_dir = self.work_dir / (run_name or f"step_{state.step_index:05d}")
        if state.res_path is not None and Path(state.res_path).resolve().parent == run_dir.resolve():
            raise ValueError(f"run folder {run_dir} holds the previous step's restart data: use another run_name")
        if run_dir.exists():
            shutil.rmtree(run_dir)
        run_dir.mkdir(parents=True)
        out_dir = run_dir / "out"
        out_dir.mkdir()
        msh = self._write_mesh(mesh, run_dir / "mesh.msh")
        sig = mesh_signature(mesh)
        numbers = self.run_numbers(mesh)
        numbers.update(Flag_ElemOut={"all": 1, "last": 2, "none": 0}[element_output],
                       Flag_FieldOut=int(bool(field_output)))
        data_lines = self.preamble + self._table_lines()
        if model.has_conductivity_laws:
            sig_numbers, sig_lines = step_inputs(model, mesh, state, float(t_end) - state.t, self._elem_temperature)
            numbers.update(sig_numbers)
            data_lines += sig_lines
        extra: list[str] = []
        has_field = state.res_path is not None
        pts = mesh.points if material_points is None else np.asarray(material_points, float)
        if pts.shape != mesh.points.shape:
            raise ValueError(f"material_points shape {pts.shape} != mesh points {mesh.points.shape}")
        restart = (has_field and not force_init_path and (not bdf2 or self.bdf2_by_restart)
                   and state.mesh_signature == sig
                   and Path(state.res_path).exists()
                   and (material_points is None or self._nodes_are_material(mesh, pts, state)))
        reuse_pre = False
        init_vc, init_i, a_prev = state.capacitor_voltage, state.current, None
        if restart:
            res = state.res_path
            if bdf2:  # a subclass's BDF2 by restart: one implicit-Euler step of gamma*dt from x_tilde
                t_init, res = self._bdf2_restart(run_dir, state, float(t_end))
            extra += ["-restart", "-res", str(Path(res).resolve())]
            if self.reuse_pre and state.pre_path and Path(state.pre_path).exists():
                shutil.copyfile(state.pre_path, run_dir / "em.pre")   # same dofs: skip pre-processing
                reuse_pre = True
        elif has_field:
            if state.a_values is None:
                raise ValueError("state has a field but no nodal values to carry to a new mesh")
            if numbers.get("TimeTheta", 1.0) != 1.0:
                raise ValueError("TimeTheta < 1 needs the whole previous solution (air field, every circuit "
                                 "unknown); the Init path carries only coil/conductor nodes: use BDF2")
            ids, vals = self._interpolate_a(mesh, pts, state, state.a_values)
            a_prev = vals
            if bdf2:  # one implicit-Euler step of gamma*dt from x_tilde ends at t_end (see .bdf2)
                hist = state.a_prev_values is not None and state.dt_prev
                gamma, c1, c2 = bdf2_coefficients(float(t_end) - state.t, state.dt_prev if hist else None)
                t_init = float(t_end) - gamma * (float(t_end) - state.t)
                if hist:
                    vals = c1 * vals - c2 * self._interpolate_a(mesh, pts, state, state.a_prev_values)[1]
                    init_vc = c1 * state.capacitor_voltage - c2 * state.capacitor_voltage_prev
                    init_i = c1 * state.current - c2 * state.current_prev
            numbers["Flag_InitA"] = 1
            data_lines.append(init_list_line("InitA_List", ids, vals))
        numbers.update(TimeInit=t_init, TimeFinal=float(t_end), NbSteps=int(n_sub))
        if model.applied_field is not None:
            bdf2_restart = self.time_scheme == "bdf2" and bool(state.dt_prev and state.res_path is not None)
            numbers["Field_F1"] = applied_start(state.applied_f, state.applied_f_prev, state.t, state.dt_prev,
                                              float(t_end), bdf2_restart)
        if model.circuit is not None:
            numbers["Init_Vc"] = init_vc
            numbers["Init_I"] = init_i
        wrapper = run_dir / "run.pro"
        wrapper.write_text(self._run_pro_text(data_lines))
        info = run_getdp(wrapper, msh, run_dir, resolution=RESOLUTION, numbers=numbers,
                         strings={"OutDir": str(out_dir) + "/"}, extra_args=extra + self.petsc_args,
                         executable=self.executable, timeout=self.timeout, reuse_pre=reuse_pre)
        for w in info.warnings:
            warnings.warn(f"getdp ({run_dir.name}): {w}", RuntimeWarning, stacklevel=2)
        coil_sigma = [float(numbers.get(f"Coil_sigma_{k}", c.sigma)) for k, c in enumerate(model.coils, start=1)]
        power_start = start_power(state, coil_sigma) if bdf2 else None
        result = self._read(mesh, out_dir, state, float(t_end), int(n_sub), n_elem_rows, power_start)
        result.run = info
        result.path = str(run_dir)
        if model.is_nonlinear:   # Newton's iterations of every sub-step; a step above the tolerance stops here
            result.newton_iterations = read_newton(out_dir, model.newton_tolerance, 0.0, model.newton_max_iterations,
                                                   log_path=info.log_path)
        if field_output:
            self._read_fields(mesh, out_dir, result)
        new_state = self._next_state(mesh, material_points, out_dir, run_dir, state, result, sig, float(t_end))
        if bdf2:
            self._bdf2_history(mesh, pts, state, result, new_state, a_prev)
        if model.has_conductivity_laws:   # this step's σ and end power: the next step's σ(T) and start power
            new_state.coil_sigma, new_state.coil_power = coil_sigma, result.coil_power[-1].tolist()
        # the .pre of a run without the Init list is reusable by later restarts on this connectivity
        new_state.pre_path = str(run_dir / "em.pre") if "Flag_InitA" not in numbers else None
        if model.applied_field is not None:
            new_state.applied_f = float(model.applied_field.unit_f(float(t_end)))
            new_state.applied_f_prev = float(state.applied_f)
        if self.keep_runs is not None:  # bound the disk use of long runs; never the newest runs
            if run_dir in self._runs:
                self._runs.remove(run_dir)
            self._runs.append(run_dir)
            while len(self._runs) > self.keep_runs:
                discard_folder(self._runs.pop(0))
        return result, new_state

    #: BDF2 by restart from a synthetic x_tilde (a subclass's ``_bdf2_restart``), not the Init path
    bdf2_by_restart = False

    #: a step's whole-domain fields (:meth:`post_fields`) stay available after later steps (its run
    #: folder holds the solution); the persistent solver's expire at its next step
    fields_expire = False

    def close(self) -> None:
        """Release what the solver holds between steps (nothing here: every step is its own getdp
        run; the persistent solver ends its process)."""

    def complete_state(self, state: EMState) -> EMState:
        """``state`` with everything a restart needs: here ``state`` itself (it names its ``.res``)."""
        return state

    def checkpoint_state(self, state: EMState) -> EMState:
        """The state a checkpoint stores, from which :meth:`step` continues: ``state`` itself (each
        step is a new getdp process started from the previous ``.res``, as after a resume)."""
        return state

    def post_fields(self, result: EMStepResult, mesh: EMMesh) -> bool:
        """Fill ``result.b_cells`` and ``result.a_nodes`` afterwards, from the run's saved solution.

        Runs ``getdp run.pro -msh mesh.msh -res em.res -pos EM_Field`` in ``<run folder>/fields``
        (same numbers as the run; no solve, ~0.1 s here), so the run folder must still exist.
        ``mesh``: the mesh of that run.  Returns False (and leaves them None) when the deck has
        no PostOperation ``EM_Field`` or wrote nothing; other getdp failures raise
        :class:`GetDPError`.
        """
        if result.b_cells is not None and result.a_nodes is not None:
            return True
        if result.run is None or not result.path:
            raise ValueError("post_fields needs the result of a GetDPSolver.step (its run folder and argv)")
        run_dir = Path(result.path)
        argv = list(result.run.argv)
        numbers, strings = {}, {}
        for i, tok in enumerate(argv[:-2]):
            if tok == "-setnumber":
                numbers[argv[i + 1]] = float(argv[i + 2])
            elif tok == "-setstring":
                strings[argv[i + 1]] = argv[i + 2]
        out = run_dir / "fields"
        if out.exists():
            shutil.rmtree(out)
        out.mkdir()
        strings["OutDir"] = str(out) + "/"
        numbers["Flag_FieldOut"] = 1.0
        extra = ["-res", str(run_dir / "em.res")]
        if (run_dir / "em.pre").is_file():   # -pos reads the run's dof numbering from <name>.pre
            shutil.copyfile(run_dir / "em.pre", out / "em.pre")
        else:
            extra = ["-pre", RESOLUTION] + extra
        try:
            run_getdp(Path(argv[1]), Path(argv[3]), out, resolution=RESOLUTION, post_operation="EM_Field",
                      numbers=numbers, strings=strings, extra_args=extra,
                      executable=self.executable, timeout=self.timeout)
        except GetDPError as exc:
            if "EM_Field" in str(exc):   # a user deck without the PostOperation
                return False
            raise
        self._read_fields(mesh, out, result)
        return result.b_cells is not None and result.a_nodes is not None

    # -- helpers
    def _write_mesh(self, mesh: EMMesh, path: Path) -> Path:
        """Write the run's MSH 2.2 mesh (a template deck's solver writes its own physical ids)."""
        return write_msh22(mesh, path)

    def _run_pro_text(self, data_lines: list[str]) -> str:
        """``run.pro``: the data lines, then the deck (a template deck's solver appends its wrapper)."""
        return ("// generated by pulseform.solvers.getdp for one run\n" + "\n".join(data_lines)
                + f'\nInclude "{self.deck}";\n')

    def _read_fields(self, mesh: EMMesh, out: Path, result: EMStepResult) -> None:
        """``field_b.txt`` / ``field_a.txt`` of ``out`` (if written) into ``result.b_cells`` / ``a_nodes``."""
        fb, fa = out / "field_b.txt", out / "field_a.txt"
        if not (fb.is_file() and fa.is_file()):
            return
        ids, vals = read_element_table(fb, 3, 1)
        if len(ids) and (ids.min() < 1 or ids.max() > len(mesh.triangles)):
            raise RuntimeError(f"{fb}: element ids outside the mesh's triangles")
        b = np.full((len(mesh.triangles), 2), np.nan)
        b[ids - 1] = vals[0, :, :2]
        d = np.loadtxt(fa, skiprows=1, ndmin=2)
        a = np.zeros(mesh.n_nodes)   # r = 0: r a_phi = 0 (getdp may print nan on the axis)
        if d.size:
            a[d[:, 0].astype(np.int64) - 1] = np.nan_to_num(d[:, 1], nan=0.0)
        result.b_cells, result.a_nodes = b, a

    def _bdf2_history(self, mesh: EMMesh, pts: np.ndarray, state: EMState, result: EMStepResult,
                      new_state: EMState, a_prev: np.ndarray | None) -> None:
        """Fill the BDF2 history of ``new_state`` and the start value of ``result``'s force mean."""
        new_state.dt_prev = float(result.times[-1] - state.t)
        new_state.a_prev_values = (np.zeros(len(new_state.a_values)) if a_prev is None else a_prev).tolist()
        new_state.capacitor_voltage_prev, new_state.current_prev = state.capacitor_voltage, state.current
        new_state.coil_power = result.coil_power[-1].tolist()
        if len(result.elements) == 0:
            return
        centroids = pts[mesh.triangles[result.elements]].mean(axis=1)
        new_state.force_density = result.force_density[-1].tolist()
        new_state.force_points = centroids.tolist()
        if state.res_path is None:   # from rest: no current, no force at the start
            result.force_density_start = np.zeros_like(result.force_density[-1])
        elif state.force_density is not None:
            scale = max(float(np.abs(centroids).max()), 1e-30)
            idx = match_rows(centroids, np.asarray(state.force_points, float), 1e-9 * scale)
            if idx is not None:
                result.force_density_start = np.asarray(state.force_density, float)[idx]
        if result.force_density_start is None:
            warnings.warn("BDF2: no force density at the step's start on these elements; "
                          "force_density_mean falls back to the end value", RuntimeWarning, stacklevel=3)

    def run_numbers(self, mesh: EMMesh) -> dict[str, float]:
        """The ``-setnumber`` inputs every getdp run of this model on ``mesh`` gets: the model's
        numbers, the built-in deck's physical ids, then the caller's ``extra_numbers`` (last: they win)."""
        numbers = self._numbers(mesh)
        numbers.update(self.deck_numbers)
        numbers.update(self.extra_numbers)
        return numbers

    def _numbers(self, mesh: EMMesh) -> dict[str, float]:
        """The model's numbers for the library deck (:func:`.deck_numbers.model_deck_numbers`)."""
        return model_deck_numbers(self.model, mesh, self.extra_numbers)

    def _table_lines(self) -> list[str]:
        """The run deck's table lines (:func:`.model.table_lines`) and the B–H curves' lists
        (:func:`.bh_curve.model_magnetic`)."""
        return table_lines(self.model.coils, self.model.applied_field) + model_magnetic(self.model)[1]

    def conductor_nodes(self, mesh: EMMesh) -> tuple[np.ndarray, np.ndarray]:
        """(triangles, sorted unique nodes) of the coil and conductor regions.

        Cached for the last connectivity (moved meshes share their triangle arrays).
        """
        cached = getattr(self, "_cs_cache", None)
        if cached is not None and cached[0] is mesh.triangles and cached[1] is mesh.tri_tags:
            return cached[2], cached[3]
        m = self.model
        sel = np.isin(mesh.tri_tags, [coil_tag(k) for k in range(1, len(m.coils) + 1)]
                      + [conductor_tag(k) for k in range(1, len(m.conductors) + 1)])
        tri = mesh.triangles[sel]
        nodes = np.unique(tri)
        self._cs_cache = (mesh.triangles, mesh.tri_tags, tri, nodes)
        return tri, nodes

    def _nodes_are_material(self, mesh: EMMesh, material_points: np.ndarray, state: EMState) -> bool:
        """True if the coil/conductor nodes keep their material identity since the last step
        (restart carries values by node, which is right only for Lagrangian nodes)."""
        if state.a_points is None:
            return True
        _, nodes = self.conductor_nodes(mesh)
        old = np.asarray(state.a_points, float)
        if old.shape != (len(nodes), 2):
            return False
        scale = max(float(np.abs(old).max()), 1e-30)
        return bool(np.abs(material_points[nodes] - old).max() <= 1e-12 * scale)

    def _interpolate_a(self, mesh: EMMesh, material_points: np.ndarray, state: EMState, values):
        """Nodal ``values`` (on ``state.a_points``) at the new coil/conductor nodes, in material coordinates."""
        import matplotlib.tri as mtri

        old_p = np.asarray(state.a_points, float)
        old_t = np.asarray(state.a_triangles, np.int64)
        old_v = np.asarray(values, float)
        _, nodes = self.conductor_nodes(mesh)
        if self._nodes_are_material(mesh, material_points, state):   # same material nodes: no interpolation
            return nodes + 1, old_v.copy()
        q = material_points[nodes]
        tri = mtri.Triangulation(old_p[:, 0], old_p[:, 1], old_t)
        vals = np.asarray(mtri.LinearTriInterpolator(tri, old_v)(q[:, 0], q[:, 1]).filled(np.nan))
        miss = np.isnan(vals)
        if miss.any():  # outside the old conductors (remeshed boundary): nearest old node
            d2 = ((q[miss, None, :] - old_p[None, :, :]) ** 2).sum(-1)
            vals[miss] = old_v[np.argmin(d2, axis=1)]
        return nodes + 1, vals

    def _read(self, mesh: EMMesh, out: Path, state: EMState, t_end: float, n: int,
              n_rows: int, power_start: np.ndarray | None = None) -> EMStepResult:
        m = self.model
        nc, nk = len(m.coils), len(m.conductors)
        dt = (t_end - state.t) / n
        w = read_table(out / "W.txt")
        times = w[:, 0]
        if len(times) != n:
            raise RuntimeError(f"expected {n} sub-steps in {out}, found {len(times)}")
        if abs(times[-1] - t_end) > 1e-6 * dt:
            raise RuntimeError(f"last sub-step at t = {times[-1]!r}, expected {t_end!r}")
        cur = np.column_stack([read_table(out / f"coil_I_{k}.txt")[:, 1] for k in range(1, nc + 1)]) \
            if nc else np.zeros((n, 0))
        us = np.column_stack([read_table(out / f"coil_U_{k}.txt")[:, 1] for k in range(1, nc + 1)]) \
            if nc else np.zeros((n, 0))
        cp = np.column_stack([read_table(out / f"coil_P_{k}.txt")[:, 1] for k in range(1, nc + 1)]) \
            if nc else np.zeros((n, 0))
        cf = np.stack([read_table(out / f"coil_F_{k}.txt")[:, 1:3] for k in range(1, nc + 1)], axis=1) \
            if nc else np.zeros((n, 0, 2))
        kf = np.stack([read_table(out / f"cond_F_{k}.txt")[:, 1:3] for k in range(1, nk + 1)], axis=1) \
            if nk else np.zeros((n, 0, 2))
        kp = np.column_stack([read_table(out / f"cond_P_{k}.txt")[:, 1] for k in range(1, nk + 1)]) \
            if nk else np.zeros((n, 0))
        if nk and n_rows:
            ids, ef = read_element_table(out / "elem_f.txt", 3, n_rows)
            ids_F, eF = read_element_table(out / "elem_F.txt", 3, n_rows)
            ids_P, eP = read_element_table(out / "elem_P.txt", 1, n_rows)
            ids_b, eb = read_element_table(out / "elem_b.txt", 3, n_rows)
            if not (np.array_equal(ids, ids_F) and np.array_equal(ids, ids_P) and np.array_equal(ids, ids_b)):
                raise RuntimeError("per-element tables list elements in different orders")
            elements = ids - 1
            if elements.max() >= len(mesh.triangles):
                raise RuntimeError("per-element output refers to a non-triangle element")
            vol = element_volumes(mesh, elements, m.axisymmetric)
            centroid = ef[:, :, :2]
            force = eF[:, :, :2] / vol[None, :, None]
            joule = eP[:, :, 0] / vol[None, :]
            bfield = eb[:, :, :2]
            tags = mesh.tri_tags[elements]
        else:
            elements = np.zeros(0, np.int64)
            tags = np.zeros(0, np.int64)
            force = np.zeros((n_rows, 0, 2))
            centroid = np.zeros((n_rows, 0, 2))
            joule = np.zeros((n_rows, 0))
            bfield = np.zeros((n_rows, 0, 2))
        probe_b = np.stack([read_table(out / f"probe_b_{i}.txt")[:, -3:-1]
                            for i in range(1, len(m.probes) + 1)], axis=1) if m.probes else np.zeros((n, 0, 2))
        vc = ic = None
        if m.circuit is not None:
            vc = read_table(out / "cir_U.txt")[:, 1]
            ic = read_table(out / "cir_I.txt")[:, 1]
        # Joule heat over the step: rectangle rule (implicit Euler) or trapezoid (BDF2, from power_start)
        q = cp.sum(axis=0) * dt if power_start is None else trapezoid_mean(power_start, cp) * n * dt
        heat = np.asarray(state.coil_heat or [0.0] * nc, float) + q
        mass_cp = coil_mass_cp(m, mesh)
        for name, arr in (("force density", force), ("coil current", cur), ("energy", w[:, 1])):
            if not np.all(np.isfinite(arr)):
                raise RuntimeError(f"non-finite {name} in {out}")
        return EMStepResult(times=times, dt=dt, elements=elements, element_tags=tags, force_density=force,
                            force_density_centroid=centroid,
                            joule_density=joule, flux_density=bfield, coil_current=cur, coil_voltage=-us, coil_power=cp,
                            coil_force=cf, conductor_force=kf, conductor_power=kp, magnetic_energy=w[:, 1],
                            capacitor_voltage=vc, circuit_current=ic, coil_heat=heat, probe_b=probe_b,
                            coil_temperature_rise=heat / mass_cp if nc else heat)

    def _next_state(self, mesh, material_points, out, run_dir, state, result, sig, t_end) -> EMState:
        d = np.loadtxt(out / "nodes_a.txt", skiprows=1, ndmin=2)
        pts = mesh.points if material_points is None else np.asarray(material_points, float)
        tri, used = self.conductor_nodes(mesh)
        remap = np.full(mesh.n_nodes, -1, np.int64)
        remap[used] = np.arange(len(used))
        vals = np.zeros(mesh.n_nodes)
        vals[d[:, 0].astype(np.int64) - 1] = np.nan_to_num(d[:, 1], nan=0.0)  # r = 0: r a_phi = 0
        return EMState(
            t=t_end, step_index=state.step_index + 1,
            capacitor_voltage=float(result.capacitor_voltage[-1]) if result.capacitor_voltage is not None else 0.0,
            current=float(result.circuit_current[-1]) if result.circuit_current is not None else 0.0,
            coil_heat=result.coil_heat.tolist(), res_path=str(run_dir / "em.res"), mesh_signature=sig,
            a_points=pts[used].tolist(), a_triangles=remap[tri].tolist(), a_values=vals[used].tolist())
