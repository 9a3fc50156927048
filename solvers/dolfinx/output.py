"""XDMF field output (one file per body) through dolfinx.io.XDMFFile."""
from __future__ import annotations

import logging
from pathlib import Path

from dolfinx import fem
from dolfinx.io import XDMFFile

__all__ = ["FieldWriter"]

log = logging.getLogger(__name__)


class FieldWriter:
    """Write displacement, velocity (P1) and stress, von Mises, eps_p (DG0) of every body.

    The mesh is written in the reference configuration; warp it by ``displacement`` to see the
    deformed shape.

    Parameters
    ----------
    solver : ExplicitSolver
        The solver whose bodies are written.
    path_prefix : str or Path
        Files are ``<path_prefix>_<body>.xdmf`` (+ .h5).
    """

    def __init__(self, solver, path_prefix):
        self.solver = solver
        self._files = {}
        self._fun = {}
        prefix = Path(path_prefix)
        for n, b in solver.bodies.items():
            path = prefix.parent / f"{prefix.name}_{n}.xdmf"
            xf = XDMFFile(b.mesh.comm, str(path), "w")
            xf.write_mesh(b.mesh)
            W4 = fem.VectorFunctionSpace(b.mesh, ("DG", 0), dim=4)
            W1 = fem.FunctionSpace(b.mesh, ("DG", 0))
            funs = {"displacement": fem.Function(b.V), "velocity": fem.Function(b.V),
                    "stress": fem.Function(W4), "von_mises": fem.Function(W1),
                    "eps_p": fem.Function(W1)}
            for name, f in funs.items():
                f.name = name
            nco = b.cells.shape[0]
            c4 = W4.dofmap.list.array.reshape(-1, 1)[:nco, 0]
            c1 = W1.dofmap.list.array.reshape(-1, 1)[:nco, 0]
            self._files[n] = xf
            self._fun[n] = (funs, c4, c1)

    def write(self, t: float) -> None:
        """Write all fields at time ``t`` (s)."""
        for n, b in self.solver.bodies.items():
            funs, c4, c1 = self._fun[n]
            funs["displacement"].x.array[:] = b.u.ravel()
            funs["velocity"].x.array[:] = b.v.ravel()
            s = funs["stress"].x.array.reshape(-1, 4)
            s[c4] = b.cell_stress
            funs["von_mises"].x.array[c1] = b.von_mises
            funs["eps_p"].x.array[c1] = b.eps_p
            for f in funs.values():
                f.x.scatter_forward()
                self._files[n].write_function(f, t)

    def close(self) -> None:
        """Close the files."""
        for xf in self._files.values():
            xf.close()
        self._files = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
