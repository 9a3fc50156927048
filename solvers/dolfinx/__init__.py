"""Explicit elastic-plastic dynamics with soft contact on DOLFINx (package
``pulseform.solvers.dolfinx``).

Public API: :class:`Material` (+ :class:`CowperSymonds`, :class:`JohnsonCook`; the flow curves
:class:`TabulatedFlow`, :class:`Swift`, :class:`Voce`, :class:`Ludwik`, :class:`JohnsonCookFlow`), :class:`BodySpec`,
:class:`ContactPairSpec`, :class:`RigidWallSpec`, :class:`ExplicitSolver`, :class:`ExplicitSolver3D`
(3D bodies on tetrahedra) with :class:`SoftPlaneSpec`, :class:`ImplicitSolver` / :class:`ImplicitSolver3D`
(implicit dynamics, :class:`ImplicitOptions`), :class:`FieldWriter`,
:class:`ContactPenetrationError`, and the metrics helpers in :mod:`.analysis`.
"""
from .analysis import bar_impact_metrics, contact_stress_metrics, energy_error_rel
from .body import BodySpec
from .contact import ContactPairSpec, ContactPenetrationError, RigidWallSpec
from .flow_curves import JohnsonCookFlow, Ludwik, Swift, TabulatedFlow, Voce
from .material import CowperSymonds, JohnsonCook, Material
from .output import FieldWriter
from .solver import ExplicitSolver
from .soft_plane import SoftPlaneSpec
from .solver3d import ExplicitSolver3D
from .implicit import ImplicitOptions, ImplicitSolver, ImplicitSolver3D

__all__ = ["Material", "CowperSymonds", "JohnsonCook", "TabulatedFlow", "Swift", "Voce", "Ludwik",
           "JohnsonCookFlow", "BodySpec", "ContactPairSpec",
           "RigidWallSpec", "ContactPenetrationError", "ExplicitSolver", "ExplicitSolver3D", "SoftPlaneSpec", "FieldWriter",
           "ImplicitOptions", "ImplicitSolver", "ImplicitSolver3D",
           "contact_stress_metrics", "energy_error_rel", "bar_impact_metrics"]
