"""A 3D GetDP load that meshes its air again when the moved air mesh breaks, carrying the EM state.

:class:`RemeshingGetDPLoad3D` is :class:`~.frozen3d.FreezingGetDPLoad3D` (the same history, flags and
fall-back) whose :meth:`~RemeshingGetDPLoad3D.follow` answers a
:class:`~pulseform.orchestrator.mesh.motion.MeshQualityError` of the harmonic air motion with a remesh,
"as in 2D" (:meth:`pulseform.orchestrator.em.participant.GetDPLoad.follow`):

1. the air is re-tetrahedralised around the bodies' current shapes
   (:func:`~pulseform.orchestrator.mesh.remesh3d.remesh_air3d`): every conductor, coil and shell
   tetrahedron is kept node for node, the symmetry planes' air is re-triangulated at the sizes of the
   *fresh* mesh's air faces on them (:func:`~pulseform.orchestrator.mesh.remesh3d.plane_air`, taken
   when the load is built: repeated remeshes do not drift), the physical groups the deck needs (planes,
   outer boundary, skins, electrodes) are kept;
2. the new mesh must be valid and better than the threshold of the fresh mesh (``mover.min_quality``,
   the same absolute number for every remesh: no drift); if it is not (a gap thinner than the kept
   triangles allow, gmsh failing), the EM mesh freezes at the last valid one (``freeze=True``, the
   flag ``em_mesh_frozen``) or the run stops (``freeze=False``);
3. the EM state is carried (:mod:`pulseform.solvers.getdp.state_carry3d`): the complete state (x_n and
   x_{n-1}, asked from the persistent getdp) is mapped edge by edge (conductors and coils; the air's
   unknowns are zero: sigma = 0 there, no time derivative reads them), the circuit's globals by key,
   the circuit scalars, the BDF2 step ratio and the trapezoid's start force density as they are (the
   conductors' tetrahedra keep their order); the persistent getdp ends and a new one starts from the
   carried state at the next step.

Vanishing gaps: the contact layer of the mechanics (eq. (5), ``h0``) keeps the sheet's nodes off the die's
faces (it stops them near 0.4 h0), so the air there does not close; the new air fills what is left between
the kept boundary triangles. Kept skins that intersect (the one-sided node-to-face contact lets a die edge
enter the sheet: the racetrack at 36.4 us, docs/coupling.md) or a gap too thin for a valid tetrahedron fail
step 2 and the mesh freezes there (reported), never a broken mesh handed to GetDP.

Checkpoints (:meth:`RemeshingGetDPLoad3D.state_dict`): after a remesh, those of
:class:`~.frozen3d.FreezingGetDPLoad3D` with the current EM mesh (``remesh/*``: nodes, tetrahedra, their
ids and physical ids, the surface elements), each body's EM nodes, the edge unknowns' map, the remesh
count, log and threshold, and the fresh mesh's plane faces (the size reference, ``remesh/plane_air/*``). A resume writes the mesh back (``resume_<step>/mesh.msh``, the same file), builds
its air motion anew with ``make_mover`` held to the stored threshold and seeds a new persistent getdp with
the stored x_n, x_{n-1} at the checkpoint's step, as a resume without a remesh does: the run continues
bit for bit (tests/coupling/test_case_racetrack_remesh.py).

``remesh_before_steps`` (EM step numbers, 1-based; empty by default) forces a remesh before those steps
whatever the air's quality: the tests' way to remesh a short run (and a study's, of the remesh itself).
"""
from __future__ import annotations

import logging
import time
from dataclasses import replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from pulseform.solvers.getdp.mesh import AIR
from pulseform.solvers.getdp.mesh3d import Mesh3D, read_msh22_tets
from pulseform.solvers.getdp.persistent3d import PERSISTENT_LIB3D, RESOLUTION_PERSISTENT3D, PersistentEM3DStepper
from pulseform.solvers.getdp.solver3d import RESOLUTION3D
from pulseform.solvers.getdp.state_carry3d import EdgeDofs, carry_vector, edge_dofs
from pulseform.solvers.getdp.stepper3d import read_res_vector, write_res_vector

from ..mesh.motion import MeshQualityError
from ..mesh.motion3d import MeshMover3D, tet_quality
from ..mesh.remesh3d import PlaneAir, plane_air, read_msh22_triangles, remesh_air3d, write_msh22_3d
from ..mesh.shared3d import conductor_submesh3d
from .frozen3d import FreezingGetDPLoad3D
from .participant3d import GetDPLoad3D

log = logging.getLogger(__name__)

__all__ = ["RemeshingGetDPLoad3D", "RemeshFailed"]


class RemeshFailed(RuntimeError):
    """The air could not be meshed again into a valid mesh above the threshold (one line)."""


class RemeshingGetDPLoad3D(FreezingGetDPLoad3D):
    """:class:`FreezingGetDPLoad3D` that remeshes its air instead of freezing (module docstring).

    Extra parameters (keywords): ``make_mover`` (Mesh3D -> MeshMover3D: the air motion of a new mesh,
    the same fixed and sliding sets as the first one's), ``planes`` ((point, unit normal) of the
    symmetry planes), ``remesh`` (False: behave as :class:`FreezingGetDPLoad3D`), ``air_tags``,
    ``max_remeshes`` (then freeze or stop). History column ``em_remeshes``; :attr:`remesh_log` one dict
    per remesh (time s, wall s, tetrahedra, nodes, worst quality after).
    """

    #: EM steps (1-based) before which the air is meshed again whatever its quality (module docstring)
    remesh_before_steps: frozenset[int] = frozenset()

    def __init__(self, *args, make_mover: Callable[[Mesh3D], MeshMover3D],
                 planes: Sequence[tuple[np.ndarray, np.ndarray]], remesh: bool = True,
                 air_tags: Sequence[int] = (AIR,), max_remeshes: int = 50, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        if remesh and self.model.order != 1:
            raise ValueError(f"3D EM remesh with order {self.model.order}: the state carry maps only the "
                             "Whitney edge unknowns (by node pair); use order 1, or remesh=False (freeze)")
        self.columns = tuple(self.columns) + ("em_remeshes",)
        self.make_mover, self.planes, self.remesh = make_mover, list(planes), bool(remesh)
        self.air_tags, self.max_remeshes = tuple(air_tags), int(max_remeshes)
        self.threshold = float(self.mover.min_quality)   # the fresh mesh's: every remesh is held to it
        # the fresh mesh's air faces on the planes: the sizes of every remesh's plane triangles (no drift)
        self.plane_air: list[PlaneAir | None] = plane_air(self.mesh, self.planes, air_tags=self.air_tags)
        self.remeshes = 0
        self.remesh_log: list[dict] = []
        self._dofs: tuple[Path, EdgeDofs] | None = None   # the edge unknowns of the current mesh
        self._surface: tuple[np.ndarray, np.ndarray] | None = None   # its surface elements (after a remesh)
        self._forced_step = 0

    # ------------------------------------------------------------------ the loop's calls
    def follow(self, t0: float, mechanics) -> None:
        """As :meth:`GetDPLoad3D.follow`; a broken air mesh is meshed again (module docstring), or the
        EM mesh freezes / the run stops when that fails (t0 in s)."""
        if self.frozen_at is None and self.remesh:
            try:
                if self.remesh_before_steps and self._forced_step != self.state.steps + 1 \
                        and self.state.steps + 1 in self.remesh_before_steps:
                    self._forced_step = self.state.steps + 1
                    raise MeshQualityError(f"a remesh forced before EM step {self._forced_step} (remesh_before_steps)")
                GetDPLoad3D.follow(self, t0, mechanics)
                self._last_valid = self._moved[1]
                return
            except MeshQualityError as err:
                if self.remeshes >= self.max_remeshes:
                    log.warning("t = %.4g s: %s; %d remeshes already", t0, err, self.remeshes)
                else:
                    log.info("t = %.4g s: %s: meshing the 3D air again", t0, err)
                    try:
                        self.remesh_now(t0, mechanics.positions())
                        GetDPLoad3D.follow(self, t0, mechanics)
                        self._last_valid = self._moved[1]
                        return
                    except (RemeshFailed, MeshQualityError) as exc:
                        log.warning("t = %.4g s: the 3D air remesh failed (%s)", t0, exc)
        super().follow(t0, mechanics)

    def load(self, t0: float, t1: float, t_mid: float, mechanics):
        """As :meth:`FreezingGetDPLoad3D.load`, with the history column ``em_remeshes``."""
        step = super().load(t0, t1, t_mid, mechanics)
        step.values["em_remeshes"] = float(self.remeshes)
        return step

    def run_metrics(self, history, counters) -> dict[str, float]:
        """:meth:`FreezingGetDPLoad3D.run_metrics` with ``em_remeshes`` (the count)."""
        return {**super().run_metrics(history, counters), "em_remeshes": float(self.remeshes)}

    # ------------------------------------------------------------------ the remesh
    def remesh_now(self, t0: float, positions: dict[str, np.ndarray]) -> Mesh3D:
        """Mesh the air again around the bodies at ``positions`` (name -> (n, >=3) m) and carry the EM
        state (its time must be ``t0``, s); returns the new mesh. Raises :class:`RemeshFailed` (nothing
        changed) when the new mesh is not valid above the threshold."""
        c0 = time.perf_counter()
        k = self.remeshes + 1
        folder = self.work_dir / f"remesh_{k:03d}"
        x = np.array(self._last_valid, float)
        for b in self.bodies:
            x[b.body_to_em] = b.vertices(positions[b.name])
        try:
            new, old_to_new = remesh_air3d(self.mesh, x, folder / "mesh.msh", self.planes, air_tags=self.air_tags,
                                           reference=self.plane_air)
        except Exception as exc:   # gmsh failing (a child process: any exception type) leaves the mesh as it was
            raise RemeshFailed(f"gmsh: {exc}") from exc
        q = float(tet_quality(new.points, new.tets).min())
        if not q > self.threshold:
            raise RemeshFailed(f"the new air mesh's worst quality {q:.3g} is not above the threshold {self.threshold:.3g}")
        state = self.stepper.complete_state(self.state)
        if abs(state.t - t0) > 1e-9 * max(abs(t0), 1e-300):
            raise RuntimeError(f"EM state at t = {state.t:.9g} s, remesh at {t0:.9g} s")
        old_dofs = self._current_dofs(folder / "dofs_old")
        new_dofs = self._edge_dofs(new, folder / "dofs_new")
        if state.res_path is not None:
            dofdata, t_res, x_n = read_res_vector(state.res_path)
            res = write_res_vector(folder / "x_n.res", dofdata, t_res, carry_vector(x_n, old_dofs, old_to_new, new_dofs))
            x_prev = None if state.x_prev is None else carry_vector(state.x_prev, old_dofs, old_to_new, new_dofs)
            state = replace(state, res_path=res, x_prev=x_prev, factors=None, x_older=())   # a new connectivity: new factors, no history
        self.stepper.close()   # the persistent getdp of the old mesh ends; the next step starts one on the new
        self._adopt(new, {b.name: old_to_new[b.body_to_em] for b in self.bodies}, read_msh22_triangles(new.path))
        self.state, self._dofs = state, (new.path, new_dofs)
        self.remeshes = k
        wall = time.perf_counter() - c0
        self.remesh_log.append({"time_s": float(t0), "wall_s": wall, "tets": int(new.n_tets),
                                "nodes": int(new.n_nodes), "min_quality": q})
        self.timers["remesh_s"] = self.timers.get("remesh_s", 0.0) + wall
        log.info("t = %.4g s: 3D air remesh %d: %d tetrahedra, worst quality %.3g (threshold %.3g), %.1f s", t0, k,
                 new.n_tets, q, self.threshold, wall)
        return new

    def _adopt(self, mesh: Mesh3D, body_to_em: dict[str, np.ndarray], surface: tuple[np.ndarray, np.ndarray]) -> None:
        """Make ``mesh`` (with its surface elements) the EM mesh: the bodies' EM nodes ``body_to_em`` (name ->
        rows) and regions, the air motion built anew and held to the fresh mesh's threshold."""
        for b in self.bodies:
            b.body_to_em = np.asarray(body_to_em[b.name], dtype=np.int64)
            b.sub = conductor_submesh3d(mesh, b.tag)
            b.match_cells()   # a ten-node body: its cells' EM tetrahedra (renumbered, node for node the same)
        self.mesh, self._surface = mesh, surface
        self.mover = self.make_mover(mesh)
        self.mover.min_quality = self.threshold
        self._last_valid = mesh.points.copy()
        sub = self.bodies[0].sub
        self._sheet_pos = np.full(len(mesh.tets), -1, dtype=np.int64)
        self._sheet_pos[sub.rows] = np.arange(len(sub.rows))

    def _edge_dofs(self, mesh: Mesh3D, folder: Path, **kw) -> EdgeDofs:
        """GetDP's edge unknowns of ``mesh`` for this load's stepper (its Resolution and systems)."""
        ek = any(c.direction == "electrokinetic" for c in self.model.coils)
        persistent = isinstance(self.stepper, PersistentEM3DStepper)
        return edge_dofs(self.model, mesh, folder, system=1 if ek else 0,
                         resolution=RESOLUTION_PERSISTENT3D if persistent else RESOLUTION3D,
                         lines_before=(f'PulseformPersistentLib = "{PERSISTENT_LIB3D}";',) if persistent else (), **kw)

    def _current_dofs(self, folder: Path) -> EdgeDofs:
        """The edge unknowns of the current mesh: the running process's own numbering (its ``.pre`` and
        mesh file) when there is one, else those of a ``-pre`` run."""
        if self._dofs is not None and self._dofs[0] == self.mesh.path:
            return self._dofs[1]
        proc = getattr(self.stepper, "proc", None)
        if proc is not None and (proc.run_dir / "em.pre").exists():
            return self._edge_dofs(self.mesh, folder, pre=proc.run_dir / "em.pre", msh=proc.run_dir / "mesh.msh")
        return self._edge_dofs(self.mesh, folder)

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict[str, np.ndarray]:
        """:meth:`FreezingGetDPLoad3D.state_dict`; after a remesh also the current EM mesh and what hangs on
        it (module docstring): ``remesh/*``."""
        out = super().state_dict()
        if not self.remeshes:
            return out
        m = self.mesh
        tris, tri_tags = self._surface if self._surface is not None else read_msh22_triangles(m.path)
        out.update({"remesh/count": np.int64(self.remeshes), "remesh/threshold": np.float64(self.threshold),
                    "remesh/log": np.array([[r[k] for k in _LOG_KEYS] for r in self.remesh_log], dtype=float),
                    "remesh/points": m.points.copy(), "remesh/tets": m.tets.copy(), "remesh/tet_ids": m.tet_ids.copy(),
                    "remesh/tet_tags": m.tet_tags.copy(), "remesh/tris": tris.copy(), "remesh/tri_tags": tri_tags.copy()})
        out.update({f"remesh/body_to_em/{b.name}": b.body_to_em.copy() for b in self.bodies})
        for k, ref in enumerate(self.plane_air):
            if ref is not None:
                out.update({f"remesh/plane_air/{k}/uv": ref.uv.copy(), f"remesh/plane_air/{k}/tris": ref.tris.copy()})
        if self._dofs is not None and self._dofs[0] == m.path:
            out.update({f"remesh/dofs/{k}": v for k, v in self._dofs[1].to_arrays().items()})
        return out

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`: after a remesh the stored mesh is written back to
        ``resume_<step>/mesh.msh`` (the same file) and becomes the EM mesh; the air motion is built anew on
        it (``make_mover``) and held to the stored threshold."""
        if "remesh/count" in state:
            self.timers.setdefault("remesh_s", 0.0)   # the stored timers hold it (GetDPLoad3D.load_state_dict)
            self._restore_mesh(state)
        super().load_state_dict({k: v for k, v in state.items() if not k.startswith("remesh/")})

    def _restore_mesh(self, state: dict[str, np.ndarray]) -> None:
        folder = self.work_dir / f"resume_{int(state['steps']):05d}"
        folder.mkdir(parents=True, exist_ok=True)
        tris, tri_tags = np.array(state["remesh/tris"]), np.array(state["remesh/tri_tags"])
        tets, tet_tags = np.array(state["remesh/tets"]), np.array(state["remesh/tet_tags"])
        ids = write_msh22_3d(folder / "mesh.msh.part", state["remesh/points"], tets, tet_tags, tris, tri_tags)
        path = (folder / "mesh.msh.part").replace(folder / "mesh.msh").resolve()
        points = read_msh22_tets(path)[0]
        if not (np.array_equal(ids, state["remesh/tet_ids"]) and np.array_equal(points, state["remesh/points"])):
            raise RuntimeError(f"{path}: the EM mesh written back differs from the checkpoint's")
        mesh = Mesh3D(points=points, tets=tets, tet_ids=ids, tet_tags=tet_tags, path=path,
                      sector_deg=self.mesh.sector_deg, electrode_area=self.mesh.electrode_area)
        self.stepper.close()
        self.threshold = float(state["remesh/threshold"])
        # _last_valid: the stored one follows (FreezingGetDPLoad3D.load_state_dict)
        self._adopt(mesh, {b.name: state[f"remesh/body_to_em/{b.name}"] for b in self.bodies}, (tris, tri_tags))
        dofs = {k[len("remesh/dofs/"):]: v for k, v in state.items() if k.startswith("remesh/dofs/")}
        self._dofs = (path, EdgeDofs.from_arrays(dofs)) if dofs else None
        self.remeshes = int(state["remesh/count"])
        for k in range(len(self.planes)):   # else (older checkpoints) those of the fresh mesh this load was built on
            if f"remesh/plane_air/{k}/uv" in state:
                self.plane_air[k] = PlaneAir(np.array(state[f"remesh/plane_air/{k}/uv"]),
                                             np.array(state[f"remesh/plane_air/{k}/tris"]))
        self.remesh_log = [{k: (int(v) if k in ("tets", "nodes") else float(v)) for k, v in zip(_LOG_KEYS, row)}
                           for row in np.asarray(state["remesh/log"], float).reshape(-1, len(_LOG_KEYS))]
        log.info("resume: the EM mesh of remesh %d (%d tetrahedra, %d nodes)", self.remeshes, mesh.n_tets, mesh.n_nodes)


#: the fields of a :attr:`RemeshingGetDPLoad3D.remesh_log` entry, in the checkpoint's columns
_LOG_KEYS = ("time_s", "wall_s", "tets", "nodes", "min_quality")
