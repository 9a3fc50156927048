"""Point probes: values at a material point of a body, recorded into history.csv.

A probe is attached at the start of the run to the node (or, for cell quantities, the cell)
nearest to its point in the initial configuration, and follows that material point afterwards.
In a parallel run only the owning rank has the value; the others contribute nothing to a sum
reduction, so every rank ends up with the same number.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from ..case.model import Probe


@dataclass
class AttachedProbe:
    """A probe bound to a node or cell index of its body on the owning rank."""

    probe: Probe
    index: int  # local node or cell index, -1 where this rank does not own it
    columns: tuple[str, ...]
    pair: int = -1  # contact pair whose slave surface holds a contact_pressure probe


def nearest_global(points: np.ndarray, target: tuple[float, ...], n_owned: int,
                    comm: MPI.Comm) -> int:
    """Local index of the owned point nearest ``target`` (2 or 3 coordinates, m) on the rank holding
    the global nearest, else -1."""
    if len(target) == 3:
        d = np.linalg.norm(points[:n_owned, :3] - np.asarray(target, float), axis=1)
    else:
        d = np.hypot(points[:n_owned, 0] - target[0], points[:n_owned, 1] - target[1])
    local_best = (float(d.min()) if d.size else np.inf, comm.rank)
    best = comm.allreduce(local_best, op=MPI.MINLOC)
    return int(np.argmin(d)) if best[1] == comm.rank and d.size else -1


def attach(solver, probes: tuple[Probe, ...], comm: MPI.Comm) -> list[AttachedProbe]:
    """Bind each probe to its nearest node (or cell centroid for von Mises), in the initial configuration.

    A contact-pressure probe reads the first pair whose slave is the probe's body, at the slave
    surface node nearest the point.
    """
    out = []
    for p in probes:
        body = solver.bodies[p.body]
        if p.quantity == "contact_pressure":
            pairs = [i for i, cp in enumerate(solver.contact_pairs) if cp.slave == p.body]
            if not pairs:
                raise ValueError(f"probe {p.name!r}: body {p.body!r} is the slave of no contact pair")
            out.append(AttachedProbe(p, -1, (f"{p.name}_contact_pressure_Pa",), pairs[0]))
            continue
        if p.quantity == "von_mises":
            pts = body.X0[body.cells].mean(axis=1)
            n_owned = len(body.cells)
        else:
            pts = body.X0
            n_owned = body.n_owned
        idx = nearest_global(pts, p.point, n_owned, comm)
        if p.quantity == "wall_pressure" and not solver.rigid_walls:
            raise ValueError(f"probe {p.name!r}: wall_pressure needs a [[walls]] entry")
        if p.quantity in ("velocity", "displacement"):
            unit = "m_s" if p.quantity == "velocity" else "m"
            cols = tuple(f"{p.name}_{p.quantity}_{c}_{unit}" for c in "xyz"[:body.gdim])
        else:
            cols = (f"{p.name}_{p.quantity}_Pa",)
        out.append(AttachedProbe(p, idx, cols))
    return out


def sample(solver, attached: list[AttachedProbe], comm: MPI.Comm) -> dict[str, float]:
    """Current values of all probes, one column each (SI units in the names)."""
    local: list[float] = []
    for a in attached:
        body = solver.bodies[a.probe.body]
        q = a.probe.quantity
        if q == "contact_pressure":  # the same on every rank: count it once
            value = solver.contact_pressure_at(a.pair, a.probe.point)
            local.append(value if comm.rank == 0 else 0.0)
        elif a.index < 0:
            local.extend([0.0] * len(a.columns))
        elif q == "velocity":
            local.extend(float(v) for v in body.v[a.index, :len(a.columns)])
        elif q == "displacement":
            local.extend(float(v) for v in body.u[a.index, :len(a.columns)])
        elif q == "von_mises":
            vm = body.cell_means(body.von_mises) if hasattr(body, "cell_means") else body.von_mises
            local.append(float(vm[a.index]))   # a ten-node cell: the mean over its Gauss points
        elif q == "wall_pressure":
            rows, _, p = solver.wall_pressure(0, a.probe.body)
            hit = np.flatnonzero(np.asarray(rows) == a.index)
            local.append(float(p[hit[0]]) if hit.size else 0.0)
    values = comm.allreduce(np.array(local), op=MPI.SUM) if local else np.zeros(0)
    cols = [c for a in attached for c in a.columns]
    return dict(zip(cols, (float(v) for v in values)))
