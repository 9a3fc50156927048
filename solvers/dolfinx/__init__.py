"""Explicit elastic-plastic dynamics with soft contact on DOLFINx."""
