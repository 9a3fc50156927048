"""Hand the state of one solver of this package over to another on the same meshes (issue 34, item 5: the stages
of a chained run — an implicit static preform, an explicit pulse, a springback — each with its own solver).

What is carried: the node positions, the Cauchy stress and plastic strain of every cell, its temperature (a
material that carries one), the time and the step count; the velocities too, or the bodies are set to rest. The
destination then restarts from that state as a solver does from its initial one: its internal and contact forces,
accelerations, critical step (explicit) and energy ledger are those of the carried state, its accumulated energies
start at zero (the caller keeps the earlier stages' totals). Exactly the same arrays: the state at the start of the
next stage is, bit for bit, the state the previous one left (the velocities aside, see :func:`carry_state`).
"""
from __future__ import annotations

import logging

import numpy as np

__all__ = ["carry_state", "restart", "VELOCITIES"]

log = logging.getLogger(__name__)

#: what happens to the velocities at a hand-over
VELOCITIES = ("kept", "zeroed")


def restart(solver) -> None:
    """Recompute ``solver``'s forces, accelerations and ledger start from its bodies' present state (positions,
    stress, plastic strain, velocities): the implicit solver's own restart, the explicit solver's start (critical
    step of the present mesh, forces and accelerations, stored energy)."""
    again = getattr(solver, "_restart_from_state", None)
    if again is not None:
        again()
    else:
        solver._init_start()


def carry_state(source, dest, velocities: str = "kept", bodies=None, clock: bool = True) -> None:
    """Copy ``source``'s state into ``dest`` (a solver built on the same bodies' meshes, e.g. by
    :func:`pulseform.orchestrator.mech.model.rebuild_solver`) and restart ``dest`` from it.

    Parameters
    ----------
    source, dest : ExplicitSolver, ExplicitSolver3D, ImplicitSolver, ImplicitSolver3D or a springback solver
        Every body of ``dest`` must be a body of ``source`` with the same nodes and cells.
    velocities : {"kept", "zeroed"}
        Keep the node velocities (m/s) or set the bodies to rest. An explicit solver's velocity is the last
        half-step value and an implicit solver's the full-step one: between the two integrators a kept velocity
        is half a step off (the accelerations are recomputed either way); a static implicit ``dest`` has none.
    bodies : sequence of str, optional
        The bodies to copy (default: every body of ``dest``; the others keep ``dest``'s state).
    clock : bool
        Copy the time (s) and step count too (False: ``dest`` keeps its own, e.g. from a springback solver, whose
        steps are static release steps).

    Raises
    ------
    ValueError
        ``velocities`` unknown, or a body that differs (name, nodes, reference positions).
    """
    if velocities not in VELOCITIES:
        raise ValueError(f"velocities must be one of {VELOCITIES}, got {velocities!r}")
    for n in (dest.bodies if bodies is None else bodies):
        dst, src = dest.bodies[n], source.bodies.get(n)
        if src is None or src.x.shape != dst.x.shape or src.cells.shape != dst.cells.shape \
                or not np.array_equal(src.X0, dst.X0):
            raise ValueError(f"body {n!r}: the destination solver's mesh is not the source's")
        dst.x[...] = src.x
        dst.cell_stress[...] = src.cell_stress
        dst.eps_p[...] = src.eps_p
        dst.temperature[...] = src.temperature
        dst.v[...] = src.v if velocities == "kept" else 0.0
        dst.a[...] = 0.0
    if clock:
        dest.time = float(source.time)
        dest.step_count = int(source.step_count)
    restart(dest)
    log.debug("state handed over at t = %.6g s (step %d), velocities %s", dest.time, dest.step_count, velocities)
