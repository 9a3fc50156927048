"""pulseform orchestrator: case model, geometry, coupling loop, transfer, results, CLI."""

__version__ = "0.1.0"
