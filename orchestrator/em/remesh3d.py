"""A 3D GetDP load that meshes its air again when the moved air mesh breaks, carrying the EM state.

:class:`RemeshingGetDPLoad3D` is :class:`~.frozen3d.FreezingGetDPLoad3D` (the same history, flags and
fall-back) whose :meth:`~RemeshingGetDPLoad3D.follow` answers a
:class:`~pulseform.orchestrator.mesh.motion.MeshQualityError` of the harmonic air motion with a remesh,
"as in 2D" (:meth:`pulseform.orchestrator.em.participant.GetDPLoad.follow`):

1. the air is re-tetrahedralised around the bodies' current shapes
   (:func:`~pulseform.orchestrator.mesh.remesh3d.remesh_air3d`): every conductor, coil and shell
   tetrahedron is kept node for node, the symmetry planes' air is re-triangulated, the physical groups
   the deck needs (planes, outer boundary, skins, electrodes) are kept;
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

Checkpoints after a remesh are not supported (the resumed run would rebuild the fresh mesh):
:meth:`state_dict` raises then.
"""
from __future__ import annotations

import logging
import time
from dataclasses import replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from pulseform.solvers.getdp.mesh import AIR
from pulseform.solvers.getdp.mesh3d import Mesh3D
from pulseform.solvers.getdp.persistent3d import PERSISTENT_LIB3D, RESOLUTION_PERSISTENT3D, PersistentEM3DStepper
from pulseform.solvers.getdp.solver3d import RESOLUTION3D
from pulseform.solvers.getdp.state_carry3d import EdgeDofs, carry_vector, edge_dofs
from pulseform.solvers.getdp.stepper3d import read_res_vector, write_res_vector

from ..mesh.motion import MeshQualityError
from ..mesh.motion3d import MeshMover3D, tet_quality
from ..mesh.remesh3d import remesh_air3d
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
    per remesh (time s, wall s, tetrahedra, worst quality after).
    """

    def __init__(self, *args, make_mover: Callable[[Mesh3D], MeshMover3D],
                 planes: Sequence[tuple[np.ndarray, np.ndarray]], remesh: bool = True,
                 air_tags: Sequence[int] = (AIR,), max_remeshes: int = 50, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.columns = tuple(self.columns) + ("em_remeshes",)
        self.make_mover, self.planes, self.remesh = make_mover, list(planes), bool(remesh)
        self.air_tags, self.max_remeshes = tuple(air_tags), int(max_remeshes)
        self.threshold = float(self.mover.min_quality)   # the fresh mesh's: every remesh is held to it
        self.remeshes = 0
        self.remesh_log: list[dict] = []
        self._dofs: tuple[Path, EdgeDofs] | None = None   # the edge unknowns of the current mesh

    # ------------------------------------------------------------------ the loop's calls
    def follow(self, t0: float, mechanics) -> None:
        """As :meth:`GetDPLoad3D.follow`; a broken air mesh is meshed again (module docstring), or the
        EM mesh freezes / the run stops when that fails (t0 in s)."""
        if self.frozen_at is None and self.remesh:
            try:
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
            x[b.body_to_em] = positions[b.name][:, :3]
        try:
            new, old_to_new = remesh_air3d(self.mesh, x, folder / "mesh.msh", self.planes, air_tags=self.air_tags)
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
            state = replace(state, res_path=res, x_prev=x_prev)
        self.stepper.close()   # the persistent getdp of the old mesh ends; the next step starts one on the new
        for b in self.bodies:
            b.body_to_em = old_to_new[b.body_to_em]
            b.sub = conductor_submesh3d(new, b.tag)
        self.mesh, self.state = new, state
        self.mover = self.make_mover(new)
        self.mover.min_quality = self.threshold
        self._last_valid = new.points.copy()
        self._dofs = (new.path, new_dofs)
        sub = self.bodies[0].sub
        self._sheet_pos = np.full(len(new.tets), -1, dtype=np.int64)
        self._sheet_pos[sub.rows] = np.arange(len(sub.rows))
        self.remeshes = k
        wall = time.perf_counter() - c0
        self.remesh_log.append({"time_s": float(t0), "wall_s": wall, "tets": int(new.n_tets),
                                "nodes": int(new.n_nodes), "min_quality": q})
        self.timers["remesh_s"] = self.timers.get("remesh_s", 0.0) + wall
        log.info("t = %.4g s: 3D air remesh %d: %d tetrahedra, worst quality %.3g (threshold %.3g), %.1f s", t0, k,
                 new.n_tets, q, self.threshold, wall)
        return new

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

    def state_dict(self) -> dict[str, np.ndarray]:
        """:meth:`GetDPLoad3D.state_dict`; refused after a remesh (a resume would rebuild the fresh mesh)."""
        if self.remeshes:
            raise RuntimeError("a checkpoint after a 3D air remesh is not supported: the resumed run would start "
                               "from the fresh EM mesh")
        return super().state_dict()
