"""Selective mass scaling of ten-node bodies for quasi-static explicit runs (``ExplicitSolver3D(mass_scaling_dt=)``).

An explicit run's step is the smallest cell's critical step. A mesh crowded where the strain concentrates (the
root bricks of a cantilever whose plastic hinge forms there, far thinner than a layer) steps ten times shorter than
its regular cells, for nothing when the run is quasi-static: dynamic relaxation (kinetic damping) converges to the
static equilibrium, f_int(u) = f_ext, which does not depend on the mass matrix. Selective mass scaling (the idea of
LS-DYNA's DT2MS) adds mass only to the cells whose critical step dt_e is below a target dt_t: each such cell's
density is multiplied by s_e = (dt_t / dt_e)^2, so that its critical step (proportional to sqrt(rho)) is the target;
the other cells are untouched. Uniform scaling would not help: it lengthens every cell's step and every period of
the mesh alike, so the steps to rest stay the same.

The scaled density is the simulated system's: it enters the HRZ lumped mass (:func:`.tet10.hrz_lumped_mass`), hence
the kinetic energy of the ledger, and in the element kernel (:func:`.tet10_kernel.tet10_step`) the cell's wave speed
(its critical step) and its bulk viscosity; the stress update, the heating (rho c_p of the material) and the
thermal capacity are the material's. The dynamics are not the physical ones where mass was added: a transient
(a pulse) is not for this option.
"""
from __future__ import annotations

import logging

import numpy as np

from .tet10 import hrz_lumped_mass
from .tet10_kernel import tet10_cell_steps
from .tet_fields import tet_volumes

__all__ = ["selective_scale", "scaled_body_mass"]

log = logging.getLogger(__name__)


def selective_scale(cells10: np.ndarray, x: np.ndarray, prm: np.ndarray, factor: float, target_dt: float) -> np.ndarray:
    """The density factors of selective mass scaling: (target_dt / dt_e)^2 where a cell's critical step dt_e is
    below ``target_dt``, 1 elsewhere.

    Parameters
    ----------
    cells10 : int array (nc, 10)
        Ten-node cells.
    x : ndarray (N, 3)
        Node positions, m (the reference configuration: the scaling is fixed for the run).
    prm : ndarray
        The body's packed kernel parameters (:func:`.kernels.pack_parameters`): density kg/m^3, moduli Pa, bulk
        viscosity.
    factor : float
        The body's critical-step factor (:func:`.tet10.critical_step_factor`), dimensionless.
    target_dt : float
        The target critical step (CFL 1, at rest), s.

    Returns
    -------
    ndarray (nc,)
        Each cell's density factor, >= 1, dimensionless.
    """
    if not target_dt > 0.0:
        raise ValueError(f"mass_scaling_dt must be > 0 s, got {target_dt}")
    dts = np.empty(len(cells10))
    if not tet10_cell_steps(cells10, x, prm, float(factor), np.empty(0), dts):
        raise ValueError("inverted cell in the mesh: no critical step to scale")
    return np.where(dts < target_dt, (target_dt / dts) ** 2, 1.0)


def scaled_body_mass(name: str, cells10: np.ndarray, X0: np.ndarray, density: float, scale: np.ndarray,
                     n_nodes: int) -> tuple[np.ndarray, float, float]:
    """The HRZ lumped nodal masses (kg) of ten-node cells of density ``density`` (kg/m^3) times ``scale`` (nc,),
    with the mass added (kg) and its fraction of the body's unscaled mass (dimensionless), logged.

    Parameters
    ----------
    name : str
        The body's name (for the log).
    cells10 : int array (nc, 10)
        Ten-node cells.
    X0 : ndarray (N, 3)
        Reference node positions, m.
    density : float
        The material's density, kg/m^3.
    scale : ndarray (nc,)
        The density factors (:func:`selective_scale`).
    n_nodes : int
        Nodes of the body.
    """
    vol = tet_volumes(cells10, X0)
    mass = hrz_lumped_mass(cells10, vol, density * scale, n_nodes)
    base = float(density * np.sum(vol))
    added = float(density * np.sum((scale - 1.0) * vol))
    log.info("body %s: selective mass scaling of %d of %d cells (density x %.4g at most): %.6g kg added, "
             "%.4g %% of its %.6g kg", name, int(np.count_nonzero(scale > 1.0)), len(scale), float(scale.max()),
             added, 100.0 * added / base, base)
    return mass, added, added / base
