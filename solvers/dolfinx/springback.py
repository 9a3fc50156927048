"""Springback (issue 34, item 3, first piece): the static equilibrium a formed part reaches when the loads
are taken off, from the state of any solver of this package (explicit or implicit; positions, stress,
plastic strain), by the implicit solver's static steps.

The part keeps its supports (``supports="kept"``: the ``fixed`` components of its :class:`~.body.BodySpec`)
or is released onto a statically determinate set of supports that stops its rigid motions without
loading it (``supports="minimal"``: one node held in every component, a second one across the line
between them, in 3D a third one across their plane — the 3-2-1 rule; :func:`minimal_supports`). The
unbalanced internal forces of the stressed state are released over ``steps`` static steps (the external
force (1 − k/steps) (f_int^0 − f_c^0) at step k, f_c^0 the contact forces of the start state), so that reverse
yielding is followed in increments.

Contact pairs between released bodies and rigid walls are kept (``contact="kept"``, ``walls="kept"``: a press
fit's parts stay in contact and the residual contact pressure is that of the released equilibrium; a part stays
in its die) or removed (the default: the shape out of the die). A kept pair keeps the elastic law of eq. (5) and
loses its friction and viscosity (velocity-dependent: a static release has no velocity). Under MPI the minimal
supports are chosen on the whole body (every rank's owned nodes gathered: the same nodes on every rank) and the
static steps are the implicit solver's distributed ones (kept contact pairs included). Not done yet: friction in a
kept contact.
"""
from __future__ import annotations

import logging
from dataclasses import replace
from typing import Dict, Optional, Sequence

import numpy as np

from .implicit import ImplicitSolver, ImplicitSolver3D
from .implicit_options import ImplicitOptions
from .tet_kernel import MODE_SOLID

__all__ = ["springback", "minimal_supports", "SUPPORTS", "KEEP"]

log = logging.getLogger(__name__)

#: how a part is held during springback
SUPPORTS = ("kept", "minimal")
#: what happens to contact pairs and rigid walls during springback
KEEP = ("kept", "removed")


def minimal_supports(x: np.ndarray) -> tuple:
    """Statically determinate supports of a body with nodes at ``x`` (N, dim), m: ``fixed`` entries
    ``(marker, components)`` of :class:`~.body.BodySpec` that stop every rigid motion and nothing else.

    2D: the node nearest the centroid held in x and y, the node farthest from it held across the line
    between them (the component of the larger normal part). 3D: the first node in x, y, z, the farthest
    one in the two components most across their line, a third node, farthest from that line, in the
    component most normal to the plane of the three.
    """
    dim = x.shape[1]
    c = x.mean(axis=0)
    a = int(np.argmin(np.linalg.norm(x - c, axis=1)))
    b = int(np.argmax(np.linalg.norm(x - x[a], axis=1)))
    t = (x[b] - x[a]) / np.linalg.norm(x[b] - x[a])
    fixed = [(_node_marker(x[a]), tuple(range(dim)))]
    if dim == 2:
        fixed.append((_node_marker(x[b]), (int(np.argmin(np.abs(t))),)))
        return tuple(fixed)
    across = tuple(int(i) for i in np.argsort(np.abs(t))[:2])
    fixed.append((_node_marker(x[b]), across))
    d = x - x[a]
    off = d - np.outer(d @ t, t)
    k = int(np.argmax(np.linalg.norm(off, axis=1)))
    n = np.cross(t, off[k])
    fixed.append((_node_marker(x[k]), (int(np.argmax(np.abs(n))),)))
    return tuple(fixed)


def _kept_pairs(source, names: Sequence[str]) -> tuple:
    """``source``'s contact pairs between bodies of ``names``, with the elastic law only (friction and viscosity
    0: a static release has no velocity)."""
    out = []
    for i, cp in enumerate(source.contact_pairs):
        if not {cp.slave, cp.master} <= set(names):
            log.info("springback: contact pair %d (%s -> %s) removed: a body of it is not released", i, cp.slave,
                     cp.master)
            continue
        if cp.friction > 0 or cp.viscosity > 0:
            log.info("springback: contact pair %d keeps the elastic law of eq. (5); its friction and viscosity "
                     "are dropped", i)
        out.append(replace(cp, friction=0.0, viscosity=0.0))
    return tuple(out)


def _kept_walls(source, names: Sequence[str]) -> tuple:
    """``source``'s rigid walls restricted to the bodies of ``names`` (a wall acting on none of them is dropped)."""
    out = []
    for w in source.rigid_walls:
        on = list(names) if w.bodies is None else [n for n in w.bodies if n in names]
        if on:
            out.append(replace(w, bodies=tuple(on)))
    return tuple(out)


def _whole_body(body, comm) -> np.ndarray:
    """The reference positions (m) of all of ``body``'s nodes, each once (the owned rows of every rank, in rank
    order): the same array on every rank."""
    own = body.X0[: body.n_owned]
    return np.concatenate(comm.allgather(own)) if comm.size > 1 else own


def _node_marker(p: np.ndarray):
    """Marker of the node at ``p`` (m) in coordinates given as (3, N)."""
    p = np.asarray(p, float)
    tol = 1e-9 * max(float(np.abs(p).max()), 1e-3)

    def marker(X: np.ndarray) -> np.ndarray:
        return np.all(np.abs(X[: p.size] - p[:, None]) <= tol, axis=0)

    return marker


def springback(source, supports: str = "kept", steps: int = 1, newton_tol: float = 1e-8,
               newton_max: int = 25, max_cuts: int = 6, bodies: Optional[Sequence[str]] = None,
               contact: str = "removed", walls: str = "removed"):
    """The springback of ``source``'s bodies: a static implicit solver started from their state, released.

    Parameters
    ----------
    source : ExplicitSolver, ExplicitSolver3D, ImplicitSolver or ImplicitSolver3D
        The solver at the end of forming (serial or under MPI).
    supports : {"kept", "minimal"}
        The bodies' own fixed components, or statically determinate supports (:func:`minimal_supports`)
        applied in the reference configuration's node positions.
    steps : int
        Static steps over which the unbalanced internal forces are released.
    newton_tol, newton_max, max_cuts : float, int, int
        Newton settings of the static steps (:class:`~.implicit_options.ImplicitOptions`).
    bodies : sequence of str, optional
        The bodies to release (default: all).
    contact : {"removed", "kept"}
        Keep ``source``'s contact pairs between released bodies (elastic law of eq. (5), friction and viscosity
        dropped) or remove every pair.
    walls : {"removed", "kept"}
        Keep ``source``'s rigid walls (on the released bodies they act on) or remove them.

    Returns
    -------
    ImplicitSolver or ImplicitSolver3D
        The static solver after springback: its bodies hold the final shape (``x``), the residual stresses
        and plastic strain; ``springback_displacement[name]`` (N, dim), m, is the motion of springback;
        ``contact_pressure(i)`` the residual contact of kept pair ``i``, ``source_pairs[i]`` its index in
        ``source.contact_pairs``.

    Raises
    ------
    SingularSystemError
        ``supports = "kept"`` and a body's supports leave it free to move rigidly.
    ImplicitConvergenceError
        Newton did not converge on the smallest step.
    """
    if supports not in SUPPORTS:
        raise ValueError(f"supports must be one of {SUPPORTS}, got {supports!r}")
    for key, val in (("contact", contact), ("walls", walls)):
        if val not in KEEP:
            raise ValueError(f"{key} must be one of {KEEP}, got {val!r}")
    if int(steps) != steps or steps < 1:
        raise ValueError(f"steps must be a positive integer, got {steps!r}")
    names = list(source.bodies) if bodies is None else list(bodies)
    unknown = set(names) - set(source.bodies)
    if unknown:
        raise ValueError(f"unknown bodies {sorted(unknown)}")
    specs = []
    for n in names:
        b = source.bodies[n]
        spec = b.spec
        fixed = spec.fixed if supports == "kept" else minimal_supports(_whole_body(b, source.comm))
        zero = (0.0,) * b.gdim
        specs.append(replace(spec, fixed=fixed, motion=(), initial_velocity=zero, sliding=()))
    options = ImplicitOptions(dt=1.0, scheme="static", newton_tol=newton_tol, newton_max=newton_max,
                              max_cuts=max_cuts)
    pairs = _kept_pairs(source, names) if contact == "kept" else ()
    kept_walls = _kept_walls(source, names) if walls == "kept" else ()
    if source.mode == MODE_SOLID:
        sb = ImplicitSolver3D(specs, options, comm=source.comm, contact_pairs=pairs, rigid_walls=kept_walls)
    else:
        sb = ImplicitSolver(specs, options, formulation=source.formulation,
                            thickness=float(next(iter(source.bodies.values())).thickness), comm=source.comm,
                            contact_pairs=pairs, rigid_walls=kept_walls)
    #: the source's index of each kept pair (the springback solver's pair i is the source's source_pairs[i])
    sb.source_pairs = [i for i, cp in enumerate(source.contact_pairs) if {cp.slave, cp.master} <= set(names)] \
        if pairs else []
    for n in names:
        src, dst = source.bodies[n], sb.bodies[n]
        dst.x[...] = src.x
        dst.cell_stress[...] = src.cell_stress
        dst.eps_p[...] = src.eps_p
        dst.temperature[...] = src.temperature
    sb.time = float(source.time)
    sb._restart_from_state()
    start = {n: sb.bodies[n].x.copy() for n in names}
    # the present state is in equilibrium with its internal and contact forces: the removed loads (and the inertia
    # of a dynamic state) are f_int - f_c; cut steps ramp from them
    f0 = {n: sb._fint[n] - sb._fcon[n] for n in names}
    for n in names:
        sb._f_from[n][...] = f0[n]
    for k in range(1, int(steps) + 1):
        frac = 1.0 - k / steps
        sb.advance(1.0 / steps, 1, {n: frac * f0[n] for n in names})
    sb.springback_displacement: Dict[str, np.ndarray] = {n: sb.bodies[n].x - start[n] for n in names}
    for n in names:
        d = np.linalg.norm(sb.springback_displacement[n], axis=1)
        log.info("springback of %s: largest displacement %.4g m", n, float(d.max()) if d.size else 0.0)
    return sb
