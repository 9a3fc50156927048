"""The external-program solvers of pulseform: ``getdp`` (eddy currents) and ``dolfinx`` (explicit
mechanics). Importing the package points numba's cache at the current compiled sources
(:mod:`.numba_cache`)."""
from .numba_cache import configure as _configure_numba_cache

_configure_numba_cache()
