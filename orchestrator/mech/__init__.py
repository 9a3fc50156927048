"""The mechanics participant: DOLFINx solver built from the case, its adapter, pressure pulses, probes."""
