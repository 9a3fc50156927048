"""Run the coarse bar impact (plane stress, two bodies + soft contact, and the rigid-wall variant)
and print its metrics as JSON on rank 0. Used by test_mpi.py serially and under mpirun."""
import json
import sys

from mpi4py import MPI

from pulseform.solvers.dolfinx.verification import bar_impact

out = {}
for name, kw in (("two_body", {}), ("wall", {"rigid_wall": True, "wall_sliding": True})):
    r = bar_impact(nx=40, ny=20, **kw)
    m = dict(r["metrics"])
    e = r["energies"][-1]
    m["kinetic_J"] = e["kinetic_J"]
    m["elastic_J"] = e["elastic_J"]
    m["n_steps"] = r["solver"].step_count
    out[name] = m
if MPI.COMM_WORLD.rank == 0:
    json.dump(out, sys.stdout)
