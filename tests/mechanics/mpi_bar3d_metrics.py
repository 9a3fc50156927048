"""Run the coarse 3D bar impact (quarter bar on a sliding wall, 24 000 tetrahedra) and a plastic
variant (100 m/s), the bar on a soft plane (eq. 5) and two bars in node-to-face contact, and print their metrics and end state as JSON on rank 0 (serial and under
mpirun, for test_3d_mpi.py)."""
import json
import sys

import numpy as np
from mpi4py import MPI

from pulseform.solvers.dolfinx.verification import bar_impact_3d

comm = MPI.COMM_WORLD


def end_state(s) -> dict:
    """Energies and the displacement / stress fields reduced over the ranks (owned rows only)."""
    out = {k: v for k, v in s.energies().items()}
    for n, b in s.bodies.items():
        no = b.n_owned
        u = b.x[:no] - b.X0[:no]
        out[f"{n}_u_sum_m"] = comm.allreduce(float(np.abs(u).sum()))
        out[f"{n}_u_max_m"] = comm.allreduce(float(np.abs(u).max()), op=MPI.MAX)
        out[f"{n}_von_mises_max_Pa"] = comm.allreduce(float(b.von_mises.max()), op=MPI.MAX)
        out[f"{n}_eps_p_max"] = comm.allreduce(float(b.eps_p.max()), op=MPI.MAX)
    out["n_steps"] = s.step_count
    return out


res = {}
r = bar_impact_3d(nx=40, ny=10, quarter=True)
res["elastic"] = {**r["metrics"], **end_state(r["solver"])}
r = bar_impact_3d(nx=40, ny=10, quarter=True, soft_plane=True)
res["soft_plane"] = {**r["metrics"], **end_state(r["solver"])}
r = bar_impact_3d(nx=20, ny=5, quarter=True, two_body=True, t_end=1.0e-3)
res["two_body"] = end_state(r["solver"])
res["two_body"]["contact_mid_Pa"] = r["stress"][-1]
r = bar_impact_3d(nx=20, ny=5, quarter=True, speed=100.0, t_end=1.5e-3)
res["plastic"] = end_state(r["solver"])
if comm.rank == 0:
    json.dump(res, sys.stdout)
