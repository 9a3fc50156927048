"""Shared set-up of the study: the bench geometry (5-turn coil under a 1 mm Al disk), a capacitor
circuit like the demo's, and a prescribed sequence of moved meshes (the disk bulges, the air is
smoothed harmonically by the product's MeshMover, coil/shell/outer boundary fixed, axis nodes slide).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))

from em_step import mesh_with_about  # noqa: E402  (bench geometry: coil + disk, shell 0.15-0.1875)

from pulseform.orchestrator.mesh_motion import MeshMover  # noqa: E402
from pulseform.solvers.getdp import Circuit, Coil, Conductor, EMModel  # noqa: E402
from pulseform.solvers.getdp.mesh import AXIS, OUTER, SHELL  # noqa: E402

#: demo-like bank (cases/emf_sheet_bulge): 50 uF, 6 kV, 10 mOhm, 2 uH; 5-turn coil, Al disk
MODEL = EMModel(True, coils=[Coil(5)], conductors=[Conductor(2.5e7)],
                circuit=Circuit(C=50e-6, V0=6e3, R_ext=0.01, L_ext=2e-6), shell=(0.15, 0.1875))


def make_mesh(n_nodes: float):
    return mesh_with_about(n_nodes)


class Motion:
    """Disk nodes: u_z = A(t) (1 - (r/R)^2) for r < R = 50 mm (0 beyond: clamped), A(t) = a_max (t/T)^2;
    air: harmonic extension; the result is the sequence of node positions both paths see."""

    def __init__(self, mesh, a_max: float = 1.0e-3, t_ref: float = 30e-6, r_clamp: float = 0.05):
        self.mesh = mesh
        self.x0 = mesh.points.copy()
        tri = mesh.triangles
        disk = np.unique(tri[mesh.tri_tags == 201])
        fixed = np.unique(np.concatenate([tri[(mesh.tri_tags == 101) | (mesh.tri_tags == SHELL)].ravel(),
                                          mesh.lines[mesh.line_tags == OUTER].ravel(), disk]))
        axis = np.unique(mesh.lines[mesh.line_tags == AXIS].ravel())
        self.disk = disk
        self.mover = MeshMover(self.x0, tri, (np.union1d(fixed, axis), fixed))
        self.a_max, self.t_ref, self.r_clamp = a_max, t_ref, r_clamp

    def points(self, t: float) -> np.ndarray:
        u = np.zeros_like(self.x0)
        r = self.x0[self.disk, 0]
        u[self.disk, 1] = self.a_max * (t / self.t_ref) ** 2 * np.clip(1 - (r / self.r_clamp) ** 2, 0, None)
        return self.mover.moved(u)


def step_times(n_steps: int, dt: float = 0.5e-6) -> np.ndarray:
    """End times of ``n_steps`` EM steps of about ``dt``, with a few shorter and longer ones (variable
    BDF2 steps, as when the coupling lands on milestones)."""
    dts = np.full(n_steps, dt)
    dts[5::7] = 0.37 * dt
    dts[6::7] = 1.4 * dt
    return np.cumsum(dts)
