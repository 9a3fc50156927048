"""The Joule heat of an EM step handed to the mechanics (issue 33), 2D and 3D alike.

GetDP computes the Joule power density q = |j|^2 / sigma per conductor element (W/m^3) at the end of every
sub-step of an EM step. The heat an element receives over the step [t0, t1] is taken as the mean of those
values times t1 - t0 (J/m^3; the rectangle rule of the implicit-Euler sub-steps, as the held force density),
and it goes to the mechanical cell on the same nodes (a body whose mesh is cut from the EM mesh: shared
nodes, the same cells in another order). The mechanics adds it to the cell's temperature adiabatically
(``ExplicitSolver.add_heat``) at the end of the step.

A mechanical cell without a matching EM element (meshes that do not share their nodes) gets no Joule heat:
:func:`cell_of_elements` reports how many.
"""

from __future__ import annotations

import logging

import numpy as np

from ..mesh.shared import cell_of_elements

__all__ = ["cell_of_elements", "joule_heat", "JouleHeat", "element_temperatures"]

log = logging.getLogger(__name__)


def joule_heat(joule_density: np.ndarray, duration: float, match: np.ndarray) -> np.ndarray:
    """Heat per unit volume (J/m^3) of the mechanical cells over an EM step.

    Parameters
    ----------
    joule_density : (n_sub, m) array
        GetDP's Joule power density of the body's EM elements at the end of each sub-step, W/m^3.
    duration : float
        The EM step t1 - t0, s.
    match : (nc,) int array
        :func:`cell_of_elements`: the EM element of each cell, -1 for none (no heat).
    """
    e = np.maximum(np.asarray(joule_density, dtype=float), 0.0).mean(axis=0) * duration
    out = np.zeros(len(match))
    on = match >= 0
    out[on] = e[match[on]]
    return out


def element_temperatures(mechanics, bodies, em_cells: np.ndarray, tri_tags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The temperature (K) of the EM elements of the bodies that carry one: (EM element rows, temperatures), each
    element at the temperature of the mechanical cell on the same nodes (:func:`cell_of_elements`; an element
    without such a cell is left out: GetDP's σ(T) then takes the conductor's initial temperature there).

    Parameters
    ----------
    mechanics
        The loop's mechanics (``heated_cells()``, ``cell_temperatures()``).
    bodies : list
        The participant's conductor bodies (``name``, ``tag``, ``body_to_em``).
    em_cells : int array
        The EM mesh's cells (EM node indices).
    tri_tags : int array
        The EM cells' physical ids.
    """
    cells = getattr(mechanics, "heated_cells", dict)()
    temps = getattr(mechanics, "cell_temperatures", dict)()
    rows, values = [], []
    for b in bodies:
        if b.name not in cells:
            continue
        elements = np.flatnonzero(tri_tags == b.tag)
        match = cell_of_elements(em_cells[elements], b.body_to_em, cells[b.name])
        on = match >= 0
        rows.append(elements[match[on]])
        values.append(np.asarray(temps[b.name], float)[on])
    if not rows:
        return np.zeros(0, np.int64), np.zeros(0)
    return np.concatenate(rows), np.concatenate(values)


class JouleHeat:
    """The Joule heat of every EM step for the mechanics' bodies that carry a temperature (an EM participant
    holds one): the element-to-cell matches, made once per set of EM elements (again after a remesh)."""

    def __init__(self) -> None:
        self._match: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def heat(self, mechanics, bodies, result, em_cells: np.ndarray, duration: float) -> dict[str, np.ndarray]:
        """Body name -> heat per unit volume of its mechanical cells over the step (J/m^3); empty when no body
        carries a temperature (no Joule power is then asked of GetDP).

        Parameters
        ----------
        mechanics
            The loop's mechanics (``heated_cells()``: the cells of the bodies with a temperature).
        bodies : list
            The participant's conductor bodies (``name``, ``tag``, ``body_to_em``).
        result
            GetDP's step result (``elements``, ``element_tags``, ``joule_density`` (n_sub, n_el) W/m^3).
        em_cells : int array
            The EM mesh's triangles (2D) or tetrahedra (3D), EM node indices.
        duration : float
            The EM step, s.
        """
        cells = getattr(mechanics, "heated_cells", dict)()
        if not cells:
            return {}
        q = result.joule_density
        if q is None:
            raise RuntimeError("GetDP gave no Joule power density per element: the temperature per cell needs it")
        out = {}
        for b in bodies:
            if b.name not in cells:
                continue
            mine = np.flatnonzero(result.element_tags == b.tag)
            elements = result.elements[mine]
            known = self._match.get(b.name)
            if known is None or not np.array_equal(known[0], elements):
                match = cell_of_elements(em_cells[elements], b.body_to_em, cells[b.name])
                missing = int((match < 0).sum())
                if missing:
                    log.warning("body %s: %d of %d cells share no EM element (meshes that do not share their "
                                "nodes): they get no Joule heat", b.name, missing, len(match))
                known = (elements.copy(), match)
                self._match[b.name] = known
            out[b.name] = joule_heat(np.asarray(q)[:, mine], duration, known[1])
        return out
