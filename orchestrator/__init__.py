"""pulseform orchestrator: case model, geometry, coupling loop, transfer, results, CLI."""

import pulseform.solvers  # noqa: F401  (first: points numba's cache at the current sources)

__version__ = "0.1.0"
