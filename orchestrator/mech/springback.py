"""The case's ``[springback]``: after the run, release the deformable bodies from the solver's final state
(:func:`pulseform.solvers.dolfinx.springback.springback`: static implicit steps, loads off, supports kept or
minimal, contact pairs and walls kept or removed) and report what came out of the die: the springback fields, the
largest springback displacement per body and at the displacement probes, the residual stresses and, with contact
kept, the residual contact pressure of every kept pair (a press fit's quality)."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Sequence

import numpy as np
from mpi4py import MPI

from pulseform.solvers import dolfinx as mech
from pulseform.solvers.dolfinx.springback import springback

from ..case.model import Case
from .probes import nearest_global

log = logging.getLogger(__name__)

__all__ = ["run_springback", "spring_back", "contact_metrics"]


def run_springback(case: Case, solver, fields_prefix: str, analyses: Sequence = ()) -> dict[str, float]:
    """Spring the case's bodies back from ``solver``'s state and write ``fields/springback/<name>_<body>.xdmf``
    (one output: the final shape, residual stress and plastic strain at the run's end time; a folder of its own,
    so that the run's field series, ``fields/*.h5``, stays the forming run's).

    Parameters
    ----------
    case : Case
        The case (its ``springback`` table and probes).
    solver : ExplicitSolver, ExplicitSolver3D, ImplicitSolver or ImplicitSolver3D
        The run's deformable bodies at the end of the run (one process, or every rank of a partitioned run).
    fields_prefix : str
        Path prefix of the run's field files (``fields/<case name>[_partN]``): its folder holds ``springback/``.
    analyses : sequence
        The run's analyses: their ``springback_metrics(sb)`` join the metrics.

    Returns
    -------
    dict
        Metrics: ``<body>_springback_max_m`` (largest springback displacement, m), ``<body>_springback_max_<c>_m``
        (largest |component|, m), ``<body>_residual_von_mises_max_Pa``, ``<body>_residual_plastic_strain_max``,
        ``<probe>_springback_<c>_m`` for the displacement probes on those bodies (m), ``springback_newton_iterations``;
        with ``contact = "kept"``, per kept pair (``i``: its index in ``[[contact]]``)
        ``springback_contact<i>_pressure_mean_Pa`` (mean over the slave nodes in contact, 0 if none),
        ``springback_contact<i>_pressure_max_Pa`` and ``springback_contact<i>_closed_nodes``.
    """
    return spring_back(case, solver, Path(fields_prefix).parent / "springback", case.case.name, case.springback,
                       analyses)[1]


def spring_back(case: Case, solver, folder: Path, name: str, cfg, analyses: Sequence = ()) -> tuple:
    """Spring ``solver``'s bodies back as ``cfg`` (a :class:`~..case.springback.SpringbackTable`: the case's
    ``[springback]``, or a springback stage's) says, write ``folder/<name>_<body>.xdmf`` and report.

    Returns
    -------
    (springback solver, dict)
        The static solver after springback (its bodies hold the released state) and the metrics of
        :func:`run_springback`.
    """
    names = list(cfg.bodies) or list(solver.bodies)
    sb = springback(solver, supports=cfg.supports, steps=cfg.steps, bodies=names, contact=cfg.contact,
                    walls=cfg.walls)
    folder = Path(folder)
    folder.mkdir(exist_ok=True)
    writer = mech.FieldWriter(sb, str(folder / name))
    try:
        writer.write(solver.time)
    finally:
        writer.close()
    out: dict[str, float] = {"springback_newton_iterations": float(sb.newton_iterations)}
    comps = "xyz"
    comm = sb.comm

    def largest(a: np.ndarray) -> float:
        """The largest value of ``a`` over every rank (0 where none has any)."""
        local = float(a.max()) if len(a) else 0.0
        return float(comm.allreduce(local, op=MPI.MAX)) if comm.size > 1 else local

    for n in names:
        b = sb.bodies[n]
        d = sb.springback_displacement[n][: b.n_owned]
        out[f"{n}_springback_max_m"] = largest(np.linalg.norm(d, axis=1))
        for c in range(b.gdim):
            out[f"{n}_springback_max_{comps[c]}_m"] = largest(np.abs(d[:, c]))
        out[f"{n}_residual_von_mises_max_Pa"] = largest(b.von_mises)
        out[f"{n}_residual_plastic_strain_max"] = largest(b.eps_p)
        log.info("springback of %s: largest displacement %.4g m, largest residual von Mises stress %.4g Pa",
                 n, out[f"{n}_springback_max_m"], out[f"{n}_residual_von_mises_max_Pa"])
    out.update(contact_metrics(sb))
    for a in analyses:
        out.update(a.springback_metrics(sb))
    for p in case.probes:
        if p.quantity != "displacement" or p.body not in names:
            continue
        b = sb.bodies[p.body]
        i = nearest_global(b.X0, tuple(p.point[: b.gdim]), b.n_owned, comm)
        u = np.zeros(b.gdim)
        if i >= 0:
            u[:] = sb.springback_displacement[p.body][i]
        if comm.size > 1:      # only the rank holding the nearest node has it: the others add zeros
            u = comm.allreduce(u, op=MPI.SUM)
        for c in range(b.gdim):
            out[f"{p.name}_springback_{comps[c]}_m"] = float(u[c])
    return sb, out




def contact_metrics(sb) -> dict[str, float]:
    """The residual contact pressure of the springback solver ``sb``'s kept pairs (named by their index in the
    source's pairs, ``sb.source_pairs``): ``springback_contact<i>_pressure_mean_Pa`` (mean over the slave nodes in
    contact; 0 if none), ``..._pressure_max_Pa`` and ``..._closed_nodes``."""
    out: dict[str, float] = {}
    for k, i in enumerate(sb.source_pairs):
        _, _, p, _ = sb.contact_pressure(k)
        key = f"springback_contact{i}"
        out[f"{key}_pressure_mean_Pa"] = float(p.mean()) if len(p) else 0.0
        out[f"{key}_pressure_max_Pa"] = float(p.max()) if len(p) else 0.0
        out[f"{key}_closed_nodes"] = float(len(p))
        log.info("springback: contact pair %d keeps a mean pressure %.4g Pa on %d nodes", i,
                 out[f"{key}_pressure_mean_Pa"], len(p))
    return out
