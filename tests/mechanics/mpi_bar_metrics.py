"""Run the coarse bar impact (plane stress, two bodies + soft contact, and the rigid-wall variant)
and a kinetically damped step load on a thick cylinder, and print their metrics as JSON on rank 0.
Used by test_mpi.py serially and under mpirun."""
import json
import sys

from mpi4py import MPI
from test_kinetic_damping import cylinder, step_load  # this folder (the script's own) is on sys.path

from pulseform.solvers.dolfinx.verification import bar_impact


def kinetic_damping_cylinder() -> dict:
    """500 steps of the kinetically damped step load of test_kinetic_damping.py on all ranks: the
    energy ledger."""
    s = cylinder(MPI.COMM_WORLD)
    s.kinetic_damping = True
    step_load(s, 500)
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
