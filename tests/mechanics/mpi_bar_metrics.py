"""Run the coarse bar impact (plane stress, two bodies + soft contact, and the rigid-wall variant)
and a kinetically damped step load on a thick cylinder, and print their metrics as JSON on rank 0.
Used by test_mpi.py serially and under mpirun."""
import json
import sys

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, ExplicitSolver, Material
from pulseform.solvers.dolfinx.verification import bar_impact


def kinetic_damping_cylinder() -> dict:
    """500 steps of a 100 MPa step pressure on an elastic axisymmetric cylinder (a = 0.1 m, b = 0.2 m)
    under kinetic damping (tests/mechanics/test_kinetic_damping.py): its energy ledger."""
    msh = dmesh.create_rectangle(MPI.COMM_WORLD, [np.array([0.1, 0.0]), np.array([0.2, 0.02])], [20, 4])
    ends = lambda x: (np.isclose(x[1], 0.0) | np.isclose(x[1], 0.02))  # noqa: E731
    s = ExplicitSolver([BodySpec("tube", msh, Material(2800.0, 26.5e9, 65.1e9, 1e12, 0.0), fixed=((ends, (1,)),))],
                       formulation="axisymmetric", comm=msh.comm)
    s.kinetic_damping = True
    dt = 0.9 * s.stable_time_step()
    for _ in range(50):
        s.advance(dt, 10, external_forces={"tube": s.pressure_nodal_forces("tube", lambda x: x[0] < 0.101, 100e6)})
    e = s.energies()
    return {k: e[k] for k in ("kinetic_J", "elastic_J", "external_work_J", "kinetic_damping_J")}


out = {}
for name, kw in (("two_body", {}), ("wall", {"rigid_wall": True, "wall_sliding": True})):
    r = bar_impact(nx=40, ny=20, **kw)
    m = dict(r["metrics"])
    e = r["energies"][-1]
    m["kinetic_J"] = e["kinetic_J"]
    m["elastic_J"] = e["elastic_J"]
    m["n_steps"] = r["solver"].step_count
    out[name] = m
out["kinetic_damping"] = kinetic_damping_cylinder()
if MPI.COMM_WORLD.rank == 0:
    json.dump(out, sys.stdout)
