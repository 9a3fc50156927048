"""The impulse metrics of a run's load: what ``force_impulse_Ns`` means in each formulation (issue 32, item 5)."""

from __future__ import annotations

import numpy as np

__all__ = ["impulse_metrics"]


def impulse_metrics(impulse: np.ndarray, formulation: str) -> dict[str, float]:
    """The loop's impulse Σ F·Δt of the held load resultants (N·s; the components of the summed nodal forces) as
    metrics: ``force_impulse_Ns`` the magnitude of the net force's impulse, ``force_impulse_z_Ns`` its y (axial)
    component. In axisymmetry the net force on a body of revolution is axial: the summed radial nodal forces
    (the x component) are a load spread round the ring, whose net force is zero by symmetry, so
    ``force_impulse_Ns`` is |axial impulse| there and the radial part is reported on its own as
    ``radial_load_impulse_Ns`` (∫ Σ F_r dt over the full ring, positive outward: a tube that expands). In 3D the
    load's own figures replace these (the device's, times its symmetry factor)."""
    out = {"force_impulse_z_Ns": float(impulse[1])}
    if formulation == "axisymmetric":
        out.update(force_impulse_Ns=abs(float(impulse[1])), radial_load_impulse_Ns=float(impulse[0]))
    else:
        out["force_impulse_Ns"] = float(np.linalg.norm(impulse))
    return out
