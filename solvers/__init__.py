"""The external-program solvers of pulseform: ``getdp`` (eddy currents) and ``dolfinx`` (explicit
mechanics). Importing the package points numba's cache at the current compiled sources
(:mod:`.numba_cache`)."""
from .numba_cache import configure as _configure_numba_cache
from .numba_cache import warm_up as warm_up_compiler  # noqa: F401 - the warm process's (orchestrator/run/warm.py)

_configure_numba_cache()
